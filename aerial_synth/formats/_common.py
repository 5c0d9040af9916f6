"""Shared bits of the label formats."""

from __future__ import annotations

import numpy as np

from ..errors import LabelFormatError
from ..safe_input import LABEL_GSD_RANGE_M, MAX_COORD_PX, load_json, quote, shown
from ..safe_input import read_text as safe_read_text
from ..vehicles import CLASSES

__all__ = ["CATEGORIES", "fmt_num", "parse_float", "parse_number", "polygon4", "read_text",
           "read_json"]

#: Detection classes, in class-index order (YOLO index 0.., COCO id 1..), as DOTA/EAGLE name
#: them. The one list is the vehicle catalog's (``aerial_synth.vehicles.CLASSES``).
CATEGORIES: tuple[str, ...] = CLASSES


def fmt_num(x: float, decimals: int) -> str:
    """Fixed-point text with ``decimals`` digits; never "-0.00"."""
    s = f"{float(x):.{decimals}f}"
    if s.startswith("-") and float(s) == 0.0:
        s = s[1:]
    return s


def parse_float(token: str, where: str) -> float:
    try:
        v = float(token)
    except ValueError:
        raise LabelFormatError(f"{where}: expected a number, got {quote(token)}") from None
    if not np.isfinite(v):
        raise LabelFormatError(f"{where}: expected a finite number, got {quote(token)}")
    return v


def parse_coordinate(token: str, where: str, what: str, limit: float = MAX_COORD_PX) -> float:
    """:func:`parse_number` within +-``limit`` (pixels, or image widths when normalised)."""
    v = parse_number(token, where, what)
    if abs(v) > limit:
        raise LabelFormatError(f"{where}: expected {what} within +-{limit:g}, got {quote(token)}")
    return v


def parse_number(token: str, where: str, what: str) -> float:
    """A finite float; else LabelFormatError "<where>: expected <what> as a (finite) number"."""
    try:
        v = float(token)
    except ValueError:
        raise LabelFormatError(f"{where}: expected {what} as a number, got {quote(token)}") from None
    if not np.isfinite(v):
        raise LabelFormatError(f"{where}: expected {what} as a finite number, got {quote(token)}")
    return v


def parse_gsd(token: str, where: str) -> float:
    """A ``gsd:`` header's value within :data:`LABEL_GSD_RANGE_M`; LabelFormatError otherwise."""
    v = parse_number(token, where, "gsd")
    lo, hi = LABEL_GSD_RANGE_M
    if not lo <= v <= hi:
        raise LabelFormatError(f"{where}: expected gsd in {lo:g}..{hi:g} metres per pixel, "
                               f"got {quote(token)}")
    return v


def polygon4(points) -> tuple[tuple[float, float], ...]:
    """(4, 2) array-like -> tuple of 4 (x, y) float tuples."""
    p = np.asarray(points, dtype=float).reshape(4, 2)
    return tuple((float(x), float(y)) for x, y in p)


def read_text(path) -> str:
    """A label file's UTF-8 text; a file that is not UTF-8 text raises LabelFormatError."""
    # a link out of the input folder, a FIFO or a device is never read
    return safe_read_text(path, shown(path), LabelFormatError)


def read_json(path):
    """A JSON file's value; malformed JSON raises LabelFormatError naming the line."""
    return load_json(read_text(path), str(path), LabelFormatError)  # with a nesting budget
