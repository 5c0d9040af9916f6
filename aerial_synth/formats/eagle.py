"""EAGLE-style labels: one ``labels/<image>.txt`` per image.

The EAGLE paper describes its labels as "four points and orientation" with two difficulty
flags; the exact file spec is not public, so these columns are aerial-synth's own and are
documented in docs/formats.md:

    # aerial-synth EAGLE-style v1: x1 y1 x2 y2 x3 y3 x4 y4 orientation_deg class visibility_difficult orientation_unclear
    x1 y1 x2 y2 x3 y3 x4 y4 orientation_deg class visibility_difficult orientation_unclear

12 space-separated fields per object; corners in px (front-left first, clockwise on screen);
orientation_deg = heading of the vehicle in the image, [0, 360), 0 = +x (right), 90 = up;
class small-vehicle/large-vehicle; flags 0/1.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..errors import LabelFormatError
from ..io_utils import atomic_write_text
from ..safe_input import quote
from ._common import CATEGORIES, fmt_num, parse_float, polygon4, read_text
from .registry import LabelFormat

__all__ = ["FORMAT", "EagleFormat", "HEADER", "EagleObject", "to_lines", "from_lines",
           "from_annotations", "text", "write", "read"]

HEADER = (
    "# aerial-synth EAGLE-style v1: x1 y1 x2 y2 x3 y3 x4 y4 orientation_deg class "
    "visibility_difficult orientation_unclear"
)
DECIMALS = 2
N_FIELDS = 12


@dataclass(frozen=True)
class EagleObject:
    polygon_xy_px: tuple[tuple[float, float], ...]
    orientation_deg: float
    category: str
    visibility_difficult: int = 0
    orientation_unclear: int = 0


def from_annotations(annotations) -> list[EagleObject]:
    return [
        EagleObject(
            polygon4(a.box.corners),
            float(a.heading_img_deg) % 360.0,
            a.cls,
            int(a.difficult),
            int(a.orientation_unclear),
        )
        for a in annotations
        if a.kept and a.box is not None
    ]


def to_lines(objects) -> list[str]:
    lines = [HEADER]
    for o in objects:
        xy = " ".join(fmt_num(v, DECIMALS) for p in o.polygon_xy_px for v in p)
        ang = fmt_num(o.orientation_deg % 360.0, DECIMALS)
        if ang == "360.00":
            ang = "0.00"
        lines.append(
            f"{xy} {ang} {o.category} {int(o.visibility_difficult)} {int(o.orientation_unclear)}"
        )
    return lines


def from_lines(lines, where: str = "<eagle>", categories=CATEGORIES) -> list[EagleObject]:
    """Strict parser: lines starting with '#' are comments; every other line has 12 fields."""
    out = []
    for n, ln in enumerate(lines, start=1):
        ln = ln.rstrip("\r\n")
        if ln.startswith("#"):
            continue
        f = ln.split(" ")
        if len(f) != N_FIELDS:
            raise LabelFormatError(f"{where}:{n}: expected {N_FIELDS} fields, got {len(f)}: {quote(ln)}")
        xy = [parse_float(t, f"{where}:{n} coordinate {i + 1}") for i, t in enumerate(f[:8])]
        ang = parse_float(f[8], f"{where}:{n} orientation_deg")
        if not 0.0 <= ang < 360.0:
            raise LabelFormatError(f"{where}:{n}: expected orientation_deg in [0, 360), got {quote(f[8])}")
        if categories is not None and f[9] not in categories:
            raise LabelFormatError(
                f"{where}:{n}: expected class in {', '.join(categories)}, got {quote(f[9])}"
            )
        for k, name in ((10, "visibility_difficult"), (11, "orientation_unclear")):
            if f[k] not in ("0", "1"):
                raise LabelFormatError(f"{where}:{n}: expected {name} 0 or 1, got {quote(f[k])}")
        out.append(EagleObject(polygon4(xy), ang, f[9], int(f[10]), int(f[11])))
    return out


def text(objects) -> str:
    """The file's text: the header and object lines, each ended by a newline."""
    return "\n".join(to_lines(objects)) + "\n"


def write(path, objects) -> Path:
    return atomic_write_text(path, text(objects))


def read(path, categories=CATEGORIES) -> list[EagleObject]:
    content = read_text(path)
    return from_lines(content.splitlines(), where=str(path), categories=categories)


class EagleFormat(LabelFormat):
    """``eagle/<split>/images/<name>.png`` + ``eagle/<split>/labels/<name>.txt``."""

    name = "eagle"
    description = "EAGLE-style text (8 corner px, orientation, class, two flags)"

    def label_path(self, split: str, name: str) -> str:
        return f"{self.folder}/{split}/labels/{name}.txt"

    def label_text(self, record) -> str:
        return text(from_annotations(record.annotations))


FORMAT = EagleFormat()
