"""DOTA v1 labels: one ``labelTxt/<image>.txt`` per image.

    imagesource:aerial-synth
    gsd:<metres per pixel>
    x1 y1 x2 y2 x3 y3 x4 y4 category difficult

Corners in pixels (image frame, x right, y down), front-left first then clockwise on screen;
category ``small-vehicle`` or ``large-vehicle``; difficult 0 or 1.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..io_utils import atomic_write_text
from ._common import CATEGORIES, LabelFormatError, fmt_num, parse_float, polygon4, read_text
from .registry import LabelFormat

__all__ = ["FORMAT", "DotaFormat", "DotaObject", "DotaLabel", "to_lines", "from_lines",
           "from_annotations", "text", "write", "read"]

IMAGE_SOURCE = "aerial-synth"
DECIMALS = 2


@dataclass(frozen=True)
class DotaObject:
    """polygon_xy_px: 4 (x, y) corners, px, image; category; difficult 0/1."""

    polygon_xy_px: tuple[tuple[float, float], ...]
    category: str
    difficult: int = 0


@dataclass(frozen=True)
class DotaLabel:
    image_source: str
    gsd_m: float | None
    objects: tuple[DotaObject, ...]


def from_annotations(annotations) -> list[DotaObject]:
    """Kept :class:`~aerial_synth.annotate.VehicleAnnotation` s -> DOTA objects."""
    return [
        DotaObject(polygon4(a.box.corners), a.cls, int(a.difficult))
        for a in annotations
        if a.kept and a.box is not None
    ]


def to_lines(objects, gsd_m: float | None, image_source: str = IMAGE_SOURCE) -> list[str]:
    """DOTA v1 text lines (no newlines) for one image."""
    gsd = "null" if gsd_m is None else f"{float(gsd_m):.6g}"
    lines = [f"imagesource:{image_source}", f"gsd:{gsd}"]
    for o in objects:
        if any(c.isspace() for c in o.category) or not o.category:
            raise LabelFormatError(f"DOTA category: expected one word, got {o.category!r}")
        xy = " ".join(fmt_num(v, DECIMALS) for p in o.polygon_xy_px for v in p)
        lines.append(f"{xy} {o.category} {int(o.difficult)}")
    return lines


def from_lines(lines, where: str = "<labelTxt>", categories=CATEGORIES) -> DotaLabel:
    """Strict DOTA v1 parser: exactly two header lines (``imagesource:...``, ``gsd:...``),
    then exactly 10 space-separated fields per object line. ``categories=None`` accepts any
    one-word category."""
    lines = [ln.rstrip("\r\n") for ln in lines]
    if len(lines) < 2:
        raise LabelFormatError(f"{where}: expected 2 header lines, got {len(lines)} lines")
    if not lines[0].startswith("imagesource:"):
        raise LabelFormatError(f"{where}:1: expected 'imagesource:<source>', got {lines[0]!r}")
    if not lines[1].startswith("gsd:"):
        raise LabelFormatError(f"{where}:2: expected 'gsd:<metres per pixel>', got {lines[1]!r}")
    g = lines[1][4:].strip()
    gsd = None if g in ("null", "") else parse_float(g, f"{where}:2 gsd")
    objects = []
    for n, ln in enumerate(lines[2:], start=3):
        f = ln.split(" ")
        if len(f) != 10:
            raise LabelFormatError(f"{where}:{n}: expected 10 fields, got {len(f)}: {ln!r}")
        xy = [parse_float(t, f"{where}:{n} coordinate {i + 1}") for i, t in enumerate(f[:8])]
        if categories is not None and f[8] not in categories:
            raise LabelFormatError(
                f"{where}:{n}: expected category in {', '.join(categories)}, got {f[8]!r}"
            )
        if f[9] not in ("0", "1"):
            raise LabelFormatError(f"{where}:{n}: expected difficult 0 or 1, got {f[9]!r}")
        objects.append(DotaObject(polygon4(xy), f[8], int(f[9])))
    return DotaLabel(lines[0][len("imagesource:"):], gsd, tuple(objects))


def text(objects, gsd_m, image_source: str = IMAGE_SOURCE) -> str:
    """The file's text: the lines, each ended by a newline."""
    return "\n".join(to_lines(objects, gsd_m, image_source)) + "\n"


def write(path, objects, gsd_m, image_source: str = IMAGE_SOURCE) -> Path:
    return atomic_write_text(path, text(objects, gsd_m, image_source))


def read(path, categories=CATEGORIES) -> DotaLabel:
    content = read_text(path)
    return from_lines(content.splitlines(), where=str(path), categories=categories)


class DotaFormat(LabelFormat):
    """``dota/<split>/images/<name>.png`` + ``dota/<split>/labelTxt/<name>.txt``."""

    name = "dota"
    description = "DOTA v1 labelTxt (8 corner px, class, difficult)"

    def label_path(self, split: str, name: str) -> str:
        return f"{self.folder}/{split}/labelTxt/{name}.txt"

    def label_text(self, record) -> str:
        return text(from_annotations(record.annotations), record.gsd_m)


FORMAT = DotaFormat()
