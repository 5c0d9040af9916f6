"""Ultralytics YOLO-OBB labels: ``labels/{train,val}/<image>.txt`` next to
``images/{train,val}/<image>.png``, plus ``data.yaml``.

    class_index x1 y1 x2 y2 x3 y3 x4 y4

Coordinates are the pixel corners divided by image width/height, clipped to [0, 1]
(6 decimals); corners front-left first, clockwise on screen. Class indices from 0 in
:data:`CATEGORIES` order.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..io_utils import atomic_write_text
from ._common import CATEGORIES, LabelFormatError, fmt_num, parse_float, polygon4

__all__ = [
    "YoloObbObject",
    "to_lines",
    "from_lines",
    "from_annotations",
    "normalize_xy",
    "denormalize_xy",
    "data_yaml_text",
    "write",
    "read",
]

DECIMALS = 6


@dataclass(frozen=True)
class YoloObbObject:
    """class_index (0-based); polygon_xy_norm: 4 (x, y) corners in [0, 1] of width/height."""

    class_index: int
    polygon_xy_norm: tuple[tuple[float, float], ...]


def normalize_xy(polygon_xy_px, width_px: int, height_px: int) -> np.ndarray:
    """(4, 2) px -> (4, 2) in [0, 1] (clipped)."""
    p = np.asarray(polygon_xy_px, dtype=float).reshape(4, 2) / np.array([width_px, height_px])
    return np.clip(p, 0.0, 1.0)


def denormalize_xy(polygon_xy_norm, width_px: int, height_px: int) -> np.ndarray:
    """(4, 2) in [0, 1] -> (4, 2) px."""
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
        p = np.clip(np.asarray(o.polygon_xy_norm, dtype=float).reshape(8), 0.0, 1.0)
        lines.append(f"{int(o.class_index)} " + " ".join(fmt_num(v, DECIMALS) for v in p))
    return lines


def from_lines(lines, where: str = "<yolo-obb>", n_classes: int | None = len(CATEGORIES)):
    """Strict parser: 9 fields per line, integer class, coordinates in [0, 1]."""
    out = []
    for n, ln in enumerate(lines, start=1):
        ln = ln.rstrip("\r\n")
        if not ln.strip():
            continue
        f = ln.split(" ")
        if len(f) != 9:
            raise LabelFormatError(f"{where}:{n}: expected 9 fields, got {len(f)}: {ln!r}")
        if not f[0].isdigit() or (n_classes is not None and int(f[0]) >= n_classes):
            raise LabelFormatError(f"{where}:{n}: expected a class index 0..{(n_classes or 1) - 1}, got {f[0]!r}")
        xy = [parse_float(t, f"{where}:{n} coordinate {i + 1}") for i, t in enumerate(f[1:])]
        if min(xy) < 0.0 or max(xy) > 1.0:
            raise LabelFormatError(f"{where}:{n}: expected coordinates in [0, 1], got {ln!r}")
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


def write(path, objects) -> Path:
    lines = to_lines(objects)
    return atomic_write_text(path, "".join(ln + "\n" for ln in lines))


def read(path, n_classes: int | None = len(CATEGORIES)):
    text = Path(path).read_text(encoding="utf-8")
    return from_lines(text.splitlines(), where=str(path), n_classes=n_classes)
