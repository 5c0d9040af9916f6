"""Georeferenced scenes: the local frame, its float64 origin and the CRS.

Ray casting runs in float32 (Embree), which resolves about 0.5 m at UTM-sized coordinates
(500,000 m east, 5,300,000 m north). Every loaded mesh scene is therefore moved to a *local*
frame near 0 on load: ``original_xyz = local_xyz + Scene.origin`` (float64 metres).

The rule (:func:`choose_origin`), per axis, on the float64 bounds of the whole scene:

* bounds within ``FAR_M`` (10 km) of 0 on that axis: origin 0 (a scene near 0 is unchanged);
* otherwise: the centre of the bounds rounded to a multiple of ``GRID_M`` (1 km).

So the origin is deterministic, and a scene shifted by a multiple of 1 km (every UTM-like
false easting/northing a test or a user applies in whole kilometres) recentres to exactly
the coordinates of the unshifted one. Local coordinates then stay within half the scene
extent + 0.5 km of 0, where float32 resolves better than 1 mm up to 8 km.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import SceneError
from ..validators import show

__all__ = [
    "FAR_M",
    "GRID_M",
    "SceneWarning",
    "choose_origin",
    "origin_fits",
    "check_crs",
    "parse_origin",
    "float32_step_m",
]

#: Bounds farther than this from 0 (metres, per axis) are recentred.
FAR_M = 10_000.0
#: The origin of a recentred axis is a multiple of this (metres).
GRID_M = 1_000.0


class SceneWarning(UserWarning):
    """Something about a scene file that loads but deserves attention (e.g. precision)."""


def choose_origin(lo, hi) -> tuple[float, float, float]:
    """The local frame's origin (float64 metres) for float64 bounds ``lo``/``hi`` (3,).

    Per axis: 0 if ``max(|lo|, |hi|) <= FAR_M``, else ``round(centre / GRID_M) * GRID_M``
    (halves round up, so the rule does not depend on the platform's rounding mode).
    """
    lo = np.asarray(lo, dtype=np.float64).reshape(3)
    hi = np.asarray(hi, dtype=np.float64).reshape(3)
    out = []
    for a, b in zip(lo, hi):
        if max(abs(a), abs(b)) <= FAR_M:
            out.append(0.0)
        else:
            c = 0.5 * (a + b)
            out.append(float(math.floor(c / GRID_M + 0.5) * GRID_M))
    return (out[0], out[1], out[2])


def origin_fits(lo, hi, origin) -> bool:
    """True when the bounds ``lo``/``hi`` minus ``origin`` lie within ``FAR_M`` of 0."""
    o = np.asarray(origin, dtype=np.float64).reshape(3)
    lo = np.asarray(lo, dtype=np.float64).reshape(3) - o
    hi = np.asarray(hi, dtype=np.float64).reshape(3) - o
    return bool(np.all(np.maximum(np.abs(lo), np.abs(hi)) <= FAR_M))


def float32_step_m(magnitude_m: float) -> float:
    """Spacing of float32 numbers near ``magnitude_m`` (the resolution of a coordinate)."""
    return float(np.spacing(np.float32(abs(magnitude_m))))


def parse_origin(value: Any, where: str) -> tuple[float, float, float]:
    """A stored origin: 3 finite numbers (bools refused). Raises SceneError naming ``where``."""
    if (
        not isinstance(value, (list, tuple))
        or len(value) != 3
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
        or not all(math.isfinite(float(v)) for v in value)
    ):
        raise SceneError(f"{where}: expected [x, y, z] as 3 finite numbers (metres), got {show(value)}")
    return (float(value[0]), float(value[1]), float(value[2]))


def check_crs(value: Any, where: str) -> str:
    """A CRS string that pyproj understands (``EPSG:32632``, a WKT or PROJ string).

    Returns it stripped, as written. Raises SceneError naming ``where``.
    """
    if not isinstance(value, str) or not value.strip():
        raise SceneError(f"{where}: expected a CRS string such as 'EPSG:32632', got {show(value)}")
    text = value.strip()
    try:
        from pyproj import CRS
        from pyproj.exceptions import CRSError
    except ImportError:  # pragma: no cover - pyproj is a dependency
        return text
    try:
        CRS.from_user_input(text)
    except CRSError:
        raise SceneError(
            f"{where}: expected a CRS that pyproj knows (e.g. 'EPSG:32632'), got {show(text)}"
        ) from None
    return text
