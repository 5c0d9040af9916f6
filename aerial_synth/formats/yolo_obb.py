"""Ultralytics YOLO-OBB labels: ``labels/{train,val}/<image>.txt`` next to
``images/{train,val}/<image>.png``, plus ``data.yaml``.

    class_index x1 y1 x2 y2 x3 y3 x4 y4

Coordinates are the pixel corners divided by image width (x) and height (y), 6 decimals;
corners front-left first, clockwise on screen. Class indices from 0 in :data:`CATEGORIES`
order.

Corners are **not clipped** to [0, 1]: the written box is the true rectangle, so a vehicle cut
by the image border may have a corner a little outside the image (Ultralytics' own DOTA
converter writes such corners too, and its loader accepts them). Clipping each corner on its
own would turn the rectangle into an irregular quadrilateral that Ultralytics refits up to
44 % larger.

Two readers: :func:`from_lines` / :func:`read` are strict (exactly what the exporter writes);
:func:`labels_from_lines` is lenient, for real-world label and prediction files (class names
from a data YAML, an optional confidence column) and returns the one label model,
:class:`~aerial_synth.formats.labels.ImageLabels`, in pixels.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import LabelFormatError
from ..io_utils import atomic_write_text
from ..safe_input import quote
from ._common import (
    CATEGORIES,
    fmt_num,
    parse_coordinate,
    parse_float,
    parse_number,
    polygon4,
    read_text,
)
from .labels import ImageLabels
from .registry import DatasetInfo, LabelFormat

__all__ = [
    "FORMAT",
    "YoloObbFormat",
    "YoloObbObject",
    "to_lines",
    "from_lines",
    "from_annotations",
    "normalize_xy",
    "denormalize_xy",
    "data_yaml_text",
    "text",
    "write",
    "read",
    "labels_from_lines",
]

DECIMALS = 6


@dataclass(frozen=True)
class YoloObbObject:
    """class_index (0-based); polygon_xy_norm: 4 (x, y) corners as fractions of the image
    width / height (the true rectangle: may reach past [0, 1] where the border cuts it)."""

    class_index: int
    polygon_xy_norm: tuple[tuple[float, float], ...]


def normalize_xy(polygon_xy_px, width_px: int, height_px: int) -> np.ndarray:
    """(4, 2) px -> (4, 2) fractions of width / height. Not clipped, so a rectangle in
    pixels stays a rectangle once multiplied back."""
    return np.asarray(polygon_xy_px, dtype=float).reshape(4, 2) / np.array([width_px, height_px])


def denormalize_xy(polygon_xy_norm, width_px: int, height_px: int) -> np.ndarray:
    """(4, 2) fractions of width / height -> (4, 2) px."""
    return np.asarray(polygon_xy_norm, dtype=float).reshape(4, 2) * np.array([width_px, height_px])


def from_annotations(annotations, width_px: int, height_px: int, categories=CATEGORIES):
    out = []
    for a in annotations:
        if not a.kept or a.box is None:
            continue
        if a.cls not in categories:
            raise LabelFormatError(f"YOLO-OBB class: expected one of {', '.join(categories)}, got {a.cls!r}")
        out.append(
            YoloObbObject(categories.index(a.cls), polygon4(normalize_xy(a.box.corners, width_px, height_px)))
        )
    return out


def to_lines(objects) -> list[str]:
    lines = []
    for o in objects:
        p = np.asarray(o.polygon_xy_norm, dtype=float).reshape(8)
        lines.append(f"{int(o.class_index)} " + " ".join(fmt_num(v, DECIMALS) for v in p))
    return lines


def from_lines(lines, where: str = "<yolo-obb>", n_classes: int | None = len(CATEGORIES)):
    """Strict parser: 9 fields per line, integer class, finite coordinates (a border-cut
    vehicle's rectangle may reach past [0, 1])."""
    out = []
    for n, ln in enumerate(lines, start=1):
        ln = ln.rstrip("\r\n")
        if not ln.strip():
            continue
        f = ln.split(" ")
        if len(f) != 9:
            raise LabelFormatError(f"{where}:{n}: expected 9 fields, got {len(f)}: {quote(ln)}")
        if not f[0].isdigit() or (n_classes is not None and int(f[0]) >= n_classes):
            raise LabelFormatError(f"{where}:{n}: expected a class index 0..{(n_classes or 1) - 1}, got {quote(f[0])}")
        xy = [parse_float(t, f"{where}:{n} coordinate {i + 1}") for i, t in enumerate(f[1:])]
        out.append(YoloObbObject(int(f[0]), polygon4(xy)))
    return out


def data_yaml_text(names=CATEGORIES, has_val: bool = True) -> str:
    """``data.yaml`` next to ``images/`` and ``labels/``. No ``path:`` key, so Ultralytics
    takes the folder holding the YAML as the dataset root. Without a val split, ``val``
    points at the train images (Ultralytics requires a val entry)."""
    lines = [
        "# aerial-synth YOLO-OBB dataset (Ultralytics). Dataset root = this file's folder.",
        "train: images/train",
        f"val: images/{'val' if has_val else 'train'}",
        f"nc: {len(names)}",
        "names:",
    ]
    lines += [f"  {i}: {name}" for i, name in enumerate(names)]
    return "\n".join(lines) + "\n"


def text(objects) -> str:
    """The label file's text: one line per object, each ended by a newline (no objects: "")."""
    return "".join(ln + "\n" for ln in to_lines(objects))


def write(path, objects) -> Path:
    return atomic_write_text(path, text(objects))


def read(path, n_classes: int | None = len(CATEGORIES)):
    content = read_text(path)
    return from_lines(content.splitlines(), where=str(path), n_classes=n_classes)


def labels_from_lines(lines, where: str, names, size_wh, *, with_conf: bool = False,
                      name: str = "") -> ImageLabels:
    """Lenient parser of Ultralytics YOLO-OBB lines ``cls x1 y1 .. x4 y4 [conf]``
    (normalised) -> :class:`ImageLabels` in pixels of an image ``size_wh`` (w, h); class
    indices name ``names``; with ``with_conf`` the 10th field is the score (``scores``)."""
    w, h = size_wh
    nf = 10 if with_conf else 9
    what = "'cls x1 y1 x2 y2 x3 y3 x4 y4 conf'" if with_conf else "'cls x1 y1 x2 y2 x3 y3 x4 y4'"
    polys, classes, conf = [], [], []
    for n, raw in enumerate(lines, start=1):
        ln = raw.strip()
        if not ln:
            continue
        f = ln.split()
        if len(f) != nf:
            raise LabelFormatError(f"{where}:{n}: expected {what} ({nf} fields), got {len(f)} fields: {quote(ln)}")
        try:
            c = int(f[0])
        except ValueError:
            raise LabelFormatError(f"{where}:{n}: expected a class index, got {quote(f[0])}") from None
        if not 0 <= c < len(names):
            raise LabelFormatError(
                f"{where}:{n}: expected a class index in 0..{len(names) - 1} (--names), got {c}")
        xy = np.array([parse_coordinate(t, f"{where}:{n}", f"coordinate {i + 1}", 1e3)
                       for i, t in enumerate(f[1:9])])  # normalised: within 1,000 image sides
        polys.append(xy.reshape(4, 2) * (w, h))
        classes.append(names[c])
        if with_conf:
            conf.append(parse_number(f[9], f"{where}:{n}", "confidence"))
    arr = np.asarray(polys, dtype=np.float64).reshape(-1, 4, 2)
    return ImageLabels(name, arr, classes, np.zeros(len(classes), bool), size_wh=(w, h),
                       scores=np.asarray(conf, dtype=np.float64) if with_conf else None)


class YoloObbFormat(LabelFormat):
    """``yolo-obb/images/<split>/<name>.png``, ``yolo-obb/labels/<split>/<name>.txt`` and
    ``yolo-obb/data.yaml``."""

    name = "yolo-obb"
    description = "Ultralytics YOLO-OBB (class index, 8 normalised corners) + data.yaml"

    def image_path(self, split: str, file_name: str) -> str:
        return f"{self.folder}/images/{split}/{file_name}"

    def label_path(self, split: str, name: str) -> str:
        return f"{self.folder}/labels/{split}/{name}.txt"

    def label_text(self, record) -> str:
        return text(from_annotations(record.annotations, record.width_px, record.height_px))

    def aggregate_files(self, records, info: DatasetInfo) -> dict[str, str]:
        has_val = info.splits.get("val", 0) > 0
        return {f"{self.folder}/data.yaml": data_yaml_text(info.categories, has_val)}


FORMAT = YoloObbFormat()
