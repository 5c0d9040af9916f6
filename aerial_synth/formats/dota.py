"""DOTA v1 labels: one ``labelTxt/<image>.txt`` per image.

    imagesource:aerial-synth
    gsd:<metres per pixel>
    x1 y1 x2 y2 x3 y3 x4 y4 category difficult

Corners in pixels (image frame, x right, y down), front-left first then clockwise on screen;
category ``small-vehicle`` or ``large-vehicle``; difficult 0 or 1.

Two readers: :func:`from_lines` / :func:`read` are strict (exactly what the exporter writes);
:func:`labels_from_lines` / :func:`read_labels` are lenient, for real-world files (headers
optional, blank lines, 9 or 10 fields, ``difficult`` 2 as the devkit's splitter writes, any
one-word category, empty files) and return the one label model,
:class:`~aerial_synth.formats.labels.ImageLabels`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import LabelFormatError
from ..io_utils import atomic_write_text
from ..safe_input import LABEL_GSD_RANGE_M, quote
from ._common import (
    CATEGORIES,
    MAX_COORD_PX,
    fmt_num,
    parse_coordinate,
    parse_float,
    parse_gsd,
    polygon4,
    read_text,
)
from .labels import ImageLabels, read_lines
from .registry import LabelFormat

__all__ = ["FORMAT", "DotaFormat", "DotaObject", "DotaLabel", "to_lines", "from_lines",
           "from_annotations", "from_labels", "text", "write", "read", "labels_from_lines",
           "read_labels"]

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


def from_labels(labels: ImageLabels) -> list[DotaObject]:
    """The objects of an :class:`~aerial_synth.formats.labels.ImageLabels` (to write it)."""
    return [DotaObject(polygon4(p), c, int(bool(d)))
            for p, c, d in zip(labels.polygons_xy_px, labels.classes, labels.difficult)]


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
        raise LabelFormatError(f"{where}:1: expected 'imagesource:<source>', got {quote(lines[0])}")
    if not lines[1].startswith("gsd:"):
        raise LabelFormatError(f"{where}:2: expected 'gsd:<metres per pixel>', got {quote(lines[1])}")
    g = lines[1][4:].strip()
    gsd = None if g in ("null", "") else parse_gsd(g, f"{where}:2")
    objects = []
    for n, ln in enumerate(lines[2:], start=3):
        f = ln.split(" ")
        if len(f) != 10:
            raise LabelFormatError(f"{where}:{n}: expected 10 fields, got {len(f)}: {quote(ln)}")
        xy = [parse_float(t, f"{where}:{n} coordinate {i + 1}") for i, t in enumerate(f[:8])]
        if categories is not None and f[8] not in categories:
            raise LabelFormatError(
                f"{where}:{n}: expected category in {', '.join(categories)}, got {quote(f[8])}"
            )
        if f[9] not in ("0", "1"):
            raise LabelFormatError(f"{where}:{n}: expected difficult 0 or 1, got {quote(f[9])}")
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


def labels_from_lines(lines, where: str = "<labelTxt>", name: str = "") -> ImageLabels:
    """Lenient DOTA v1 parser for real-world files -> :class:`ImageLabels`.

    Header lines ``imagesource:...`` and ``gsd:...`` are optional (real DOTA has them, the
    devkit skips them); blank lines are skipped. Object lines: ``x1 y1 .. x4 y4 category``
    with an optional ``difficult`` (an integer; anything but 0 is difficult, as the devkit's
    splitter writes 2 for small cut-off parts). Any one-word category."""
    fast = _lenient_fast(lines)
    if fast is not None:
        polys, classes, diff, gsd, source = fast
        return ImageLabels(name, polys, classes, diff, gsd, source)
    polys, classes, diff = [], [], []
    gsd = None
    source = None
    for n, raw in enumerate(lines, start=1):
        ln = raw.strip()
        if not ln:
            continue
        if ln.startswith("imagesource:"):
            source = ln[len("imagesource:"):]
            continue
        if ln.startswith("gsd:"):
            g = ln[4:].strip()
            if g not in ("", "null", "None", "none"):
                gsd = parse_gsd(g, f"{where}:{n}")
            continue
        f = ln.split()
        if len(f) not in (9, 10):
            raise LabelFormatError(
                f"{where}:{n}: expected 'x1 y1 x2 y2 x3 y3 x4 y4 category [difficult]' "
                f"(9 or 10 fields), got {len(f)} fields: {quote(ln)}")
        xy = [parse_coordinate(t, f"{where}:{n}", f"coordinate {i + 1}") for i, t in enumerate(f[:8])]
        d = 0
        if len(f) == 10:
            try:
                d = int(f[9])
            except ValueError:
                raise LabelFormatError(
                    f"{where}:{n}: expected difficult as an integer (0 or 1), got {quote(f[9])}") from None
        polys.append(xy)
        classes.append(f[8])
        diff.append(d != 0)
    arr = np.asarray(polys, dtype=np.float64).reshape(-1, 4, 2)
    return ImageLabels(name, arr, classes, np.asarray(diff, dtype=bool), gsd, source)


def _lenient_fast(lines):
    """The common case in one numpy conversion; None when anything is unusual (the
    line-by-line parser then finds and names the line)."""
    body = []
    gsd = source = None
    for raw in lines:
        ln = raw.strip()
        if not ln:
            continue
        if ln.startswith("imagesource:"):
            source = ln[len("imagesource:"):]
        elif ln.startswith("gsd:"):
            g = ln[4:].strip()
            if g not in ("", "null", "None", "none"):
                try:
                    gsd = float(g)
                except ValueError:
                    return None
                if not LABEL_GSD_RANGE_M[0] <= gsd <= LABEL_GSD_RANGE_M[1]:  # NaN too
                    return None  # the line-by-line parser names it
        else:
            body.append(ln.split())
    if any(len(f) != 10 for f in body) or any(f[9] not in ("0", "1", "2") for f in body):
        return None
    try:
        xy = np.array([f[:8] for f in body], dtype=np.float64).reshape(-1, 4, 2)
    except ValueError:
        return None
    if not np.isfinite(xy).all() or (xy.size and np.abs(xy).max() > MAX_COORD_PX):
        return None
    return xy, [f[8] for f in body], np.array([f[9] != "0" for f in body], bool), gsd, source


def read_labels(path, name: str | None = None) -> ImageLabels:
    """A real-world DOTA label file, read leniently (:func:`labels_from_lines`)."""
    path = Path(path)
    lab = labels_from_lines(read_lines(path), str(path), path.stem if name is None else name)
    lab.label_path = path
    return lab


class DotaFormat(LabelFormat):
    """``dota/<split>/images/<name>.png`` + ``dota/<split>/labelTxt/<name>.txt``."""

    name = "dota"
    description = "DOTA v1 labelTxt (8 corner px, class, difficult)"

    def label_path(self, split: str, name: str) -> str:
        return f"{self.folder}/{split}/labelTxt/{name}.txt"

    def label_text(self, record) -> str:
        return text(from_annotations(record.annotations), record.gsd_m)


FORMAT = DotaFormat()
