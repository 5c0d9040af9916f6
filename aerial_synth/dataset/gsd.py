"""Per-image ground resolution: ``export --gsd LO:HI`` and ``export --altitude LO:HI``.

Real imagery spans about 0.05 m GSD (drone frames) to 0.3 m (DOTA, aerial surveys); an
export at one GSD teaches a detector one object scale. With a range, every image draws its
own nadir GSD, and its DOTA header (``gsd:``) and metadata (``gsd_m``, ``camera``) carry it.

The camera. A range keeps the lens and moves the camera: the focal length is fixed and the
altitude follows the drawn GSD (``altitude = gsd x focal_px``). Holding the altitude and
changing the lens instead would need a 137 degree field of view for 0.3 m at 60 m and
1024 px, where a 15 degree tilt already looks at the horizon. The lens is the one that puts
the camera at ``--altitude`` at the range's geometric centre:

- ``--gsd LO:HI`` (``--altitude A``): ``focal_px = A / sqrt(LO x HI)``; with the defaults,
  ``--gsd 0.05:0.3`` gives focal 490 px (the thesis camera is 500 px) and altitudes from
  24.5 m to 147 m;
- ``--altitude LO:HI`` (``--gsd G`` or the default 0.12 m): ``focal_px = sqrt(LO x HI) / G``
  and the image's GSD is ``altitude / focal_px``.

One range at a time: both would fix the same focal length twice.

A scene smaller than the top of the range's frames (the 240 m depot at 0.3 m: 307 m frames)
draws over the part of the range whose frames fit (:func:`scene_cap_m`), so no frame shows
the void beyond the scene's edge; the draw stays log-uniform there.

The distribution: log-uniform (``log gsd`` uniform in ``[log LO, log HI]``). GSD is a scale,
and what a detector sees is the object's size in pixels, ``1 / gsd``: log-uniform gives the
same share of images to every octave of scale (0.05-0.1 m as many as 0.1-0.2 m), which is
how feature pyramids split the work, and it is the same distribution whether one thinks in
GSD or in pixels per metre. A uniform draw on 0.05:0.3 would put 80 % of the images above
0.1 m and leave drone-scale vehicles (90 px cars) to a few percent. Uniform in GSD is one
option away should a measurement favour it (:data:`DISTRIBUTIONS`).

Determinism: image ``i`` draws from ``SeedSequence([seed, i, GSD_STREAM])``, a stream of its
own (the camera pose and rendering streams ``SeedSequence([seed, i])`` are untouched), so
the draw depends on (seed, i) only, never on the worker count, and an export without a
range is byte-identical to one made before ranges existed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..camera import DEFAULT_GSD_M, CameraConfig
from ..errors import ExportError

__all__ = ["GSD_STREAM", "DISTRIBUTIONS", "FOOTPRINT_MARGIN", "GsdRange", "parse_range", "arg_range",
           "scene_cap_m", "image_gsd_m", "image_camera_config", "widest_camera_config"]

#: third SeedSequence word of an image's GSD draw: [seed, index, GSD_STREAM] (placement
#: groups use [seed, group, 1], see .seeds)
GSD_STREAM = 2
#: how a range is drawn: "log-uniform" (the default, see the module text) or "uniform"
DISTRIBUTIONS = ("log-uniform", "uniform")


def parse_range(option: str, value, *, error=ExportError,
                hi: float = math.inf, lo: float = 0.0) -> float | tuple[float, float]:
    """``"0.12"`` -> 0.12; ``"0.05:0.3"`` -> (0.05, 0.3); numbers and 2-sequences pass
    through checked. Values must be finite, > 0, >= ``lo`` and <= ``hi``, and a range's LO < HI;
    anything else raises ``error`` with one line naming ``option``."""
    if isinstance(value, (list, tuple)):
        parts = list(value)
        text = ":".join(str(p) for p in parts)
    elif isinstance(value, str):
        text = value.strip()
        parts = text.split(":")
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        parts, text = [value], str(value)
    else:
        raise error(f"{option}: expected a number > 0 or a range LO:HI, got {value!r}")
    if len(parts) not in (1, 2):
        raise error(f"{option}: expected a number > 0 or a range LO:HI, got {text!r}")
    nums = []
    for p in parts:
        try:
            x = float(p)
        except (TypeError, ValueError):
            raise error(f"{option}: expected a number > 0 or a range LO:HI of numbers, "
                        f"got {text!r}") from None
        if not (math.isfinite(x) and x > 0):
            raise error(f"{option}: expected values > 0 (metres), got {text!r}")
        if x > hi:
            raise error(f"{option}: expected values <= {hi:g} (metres), got {text!r}")
        if x < lo:
            raise error(f"{option}: expected values >= {lo:g} (metres), got {text!r}")
        nums.append(x)
    if len(nums) == 1:
        return nums[0]
    lo, hi = nums
    if not lo < hi:
        raise error(f"{option}: expected a range LO:HI with LO < HI, got {text!r}")
    return (lo, hi)


def camera_range(option: str, hi: float, lo: float = 0.0):
    """argparse ``type=`` of :func:`parse_range` with the camera's bounds ``lo``, ``hi`` (its
    one-line error, exit status 2): ``render.cli.add_camera_args(..., ranges=camera_range)``."""
    return arg_range(option, hi, lo)


def arg_range(option: str, hi: float = math.inf, lo: float = 0.0):
    """argparse ``type=`` of :func:`parse_range` (its one-line error, exit status 2)."""
    import argparse

    def conv(text: str):
        try:
            return parse_range(option, text, hi=hi, lo=lo)
        except ExportError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    conv.__name__ = "range"
    return conv


@dataclass(frozen=True)
class GsdRange:
    """The per-image camera of a ranged export.

    focal_px     : fixed focal length, pixels
    gsd_lo_m, gsd_hi_m : the nadir GSD range, metres per pixel
    distribution : one of :data:`DISTRIBUTIONS`
    """

    focal_px: float
    gsd_lo_m: float
    gsd_hi_m: float
    distribution: str = "log-uniform"

    @classmethod
    def of(cls, cfg) -> "GsdRange | None":
        """The range of an ExportConfig (``gsd_range`` or ``altitude_range``), else None."""
        g, a = getattr(cfg, "gsd_range", None), getattr(cfg, "altitude_range", None)
        if g is not None:
            f = float(cfg.camera.altitude_m) / math.sqrt(g[0] * g[1])
            return cls(f, float(g[0]), float(g[1]))
        if a is not None:
            gsd = float(cfg.camera.gsd_m) if cfg.camera.gsd_m is not None else DEFAULT_GSD_M
            f = math.sqrt(a[0] * a[1]) / gsd
            return cls(f, a[0] / f, a[1] / f)
        return None

    def draw(self, rng: np.random.Generator, cap_m: float | None = None) -> float:
        """One nadir GSD in [gsd_lo_m, gsd_hi_m], metres per pixel. ``cap_m`` narrows the
        top of the range (never below gsd_lo_m); the same uniform is mapped to the narrower
        range, so the draw stays log-uniform (or uniform) there."""
        u = float(rng.random())
        lo_m = self.gsd_lo_m
        hi_m = self.gsd_hi_m if cap_m is None else max(lo_m, min(self.gsd_hi_m, float(cap_m)))
        if hi_m <= lo_m:
            return lo_m
        if self.distribution == "uniform":
            return lo_m + u * (hi_m - lo_m)
        lo, hi = math.log(lo_m), math.log(hi_m)
        return min(hi_m, max(lo_m, math.exp(lo + u * (hi - lo))))

    def camera_config(self, cfg, gsd_m: float):
        """The CameraConfig of an image at ``gsd_m``: this lens, altitude gsd x focal."""
        cam = cfg.camera
        return CameraConfig(altitude_m=gsd_m * self.focal_px, width_px=cam.width_px,
                            height_px=cam.height_px, focal_px=self.focal_px,
                            max_tilt_deg=cam.max_tilt_deg)


#: a frame's ground footprint at nadir times this must fit in the scene for the draw to
#: reach a GSD (tilt up to 15 degrees and the aim's jitter widen the footprint)
FOOTPRINT_MARGIN = 1.5


def scene_cap_m(cfg, scene_xy_bounds) -> float | None:
    """The largest GSD whose frame still fits in a scene of these bounds
    ([[xmin, ymin], [xmax, ymax]], metres): a depot of 240 m x 200 m shows void beyond its
    edge at 0.3 m GSD (307 m frames). None without bounds."""
    if scene_xy_bounds is None:
        return None
    b = np.asarray(scene_xy_bounds, dtype=np.float64)
    extent = float(np.min(b[1, :2] - b[0, :2]))
    return extent / (max(cfg.camera.width_px, cfg.camera.height_px) * FOOTPRINT_MARGIN)


def image_gsd_m(cfg, index: int, scene_xy_bounds=None) -> float | None:
    """Image ``index``'s drawn nadir GSD (None without a range), from
    ``SeedSequence([seed, index, GSD_STREAM])``; in a scene too small for the range's top,
    drawn over the part of the range whose frames fit (:func:`scene_cap_m`)."""
    r = GsdRange.of(cfg)
    if r is None:
        return None
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, int(index), GSD_STREAM]))
    return r.draw(rng, scene_cap_m(cfg, scene_xy_bounds))


def image_camera_config(cfg, index: int, scene_xy_bounds=None):
    """Image ``index``'s CameraConfig: ``cfg.camera_config()`` without a range, else the
    range's lens at the image's drawn GSD (:func:`image_gsd_m`)."""
    r = GsdRange.of(cfg)
    if r is None:
        return cfg.camera_config()
    return r.camera_config(cfg, image_gsd_m(cfg, index, scene_xy_bounds))


def widest_camera_config(cfg):
    """The camera of a ranged export that sees farthest (its highest GSD): what footprints,
    render pads and camera reach must allow for. None without a range."""
    r = GsdRange.of(cfg)
    return None if r is None else r.camera_config(cfg, r.gsd_hi_m)
