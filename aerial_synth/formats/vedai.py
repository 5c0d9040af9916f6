"""VEDAI annotation files (read only: aerial-synth does not write VEDAI).

    xc yc angle class contained occluded x1 x2 x3 x4 y1 y2 y3 y4

One line per object, pixels. Class codes map to DOTA-style names (:data:`VEDAI_CLASSES`;
cars, vans and pick-ups are small vehicles); an object is difficult when occluded or not
wholly contained in the image. Not a registered export format (no ``FORMAT``).
"""

from __future__ import annotations

import numpy as np

from ..errors import LabelFormatError
from ._common import parse_number
from .labels import ImageLabels

__all__ = ["VEDAI_CLASSES", "labels_from_lines"]

#: VEDAI class codes -> DOTA-style names (cars, vans and pick-ups are small vehicles).
VEDAI_CLASSES = {
    1: "small-vehicle", 2: "large-vehicle", 4: "large-vehicle", 5: "large-vehicle",
    7: "motorcycle", 8: "large-vehicle", 9: "small-vehicle", 10: "other", 11: "small-vehicle",
    23: "boat", 31: "plane",
}


def labels_from_lines(lines, where: str, name: str = "") -> ImageLabels:
    """VEDAI annotation lines -> :class:`ImageLabels` (difficult = occluded or not contained)."""
    polys, classes, diff = [], [], []
    for n, raw in enumerate(lines, start=1):
        ln = raw.strip()
        if not ln:
            continue
        f = ln.split()
        if len(f) != 14:
            raise LabelFormatError(
                f"{where}:{n}: expected VEDAI 'xc yc angle class contained occluded x1..x4 y1..y4' "
                f"(14 fields), got {len(f)}")
        v = [parse_number(t, f"{where}:{n}", f"field {i + 1}") for i, t in enumerate(f)]
        xs, ys = v[6:10], v[10:14]
        polys.append(list(zip(xs, ys)))
        code = int(v[3])
        classes.append(VEDAI_CLASSES.get(code, f"vedai-{code}"))
        diff.append(v[4] == 0 or v[5] != 0)
    return ImageLabels(name, np.asarray(polys, dtype=np.float64).reshape(-1, 4, 2), classes,
                       np.asarray(diff, dtype=bool))
