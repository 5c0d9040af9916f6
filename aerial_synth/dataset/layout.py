"""Where an export's files go: names, splits, per-format image and label paths.

Every per-format path comes from the format registry (:mod:`aerial_synth.formats.registry`);
this module only joins them to the dataset root. ``meta/``, ``manifest.json`` and
``summary.json`` belong to the dataset itself.
"""

from __future__ import annotations

from pathlib import Path

from ..formats.registry import get, names
from ..safe_input import image_file_complete
from .config import ExportConfig

__all__ = [
    "DATASET_FILES",
    "image_name",
    "split_of",
    "image_paths",
    "label_paths",
    "meta_path",
    "owned_names",
    "is_done",
]

#: entries of a dataset folder that are not a format's folder
DATASET_FILES = ("manifest.json", "summary.json", "meta")


def image_name(index: int) -> str:
    return f"{index:06d}"


def split_of(cfg: ExportConfig, index: int) -> str:
    return "train" if index < cfg.n_train else "val"


def _formats(cfg: ExportConfig):
    return [get(name) for name in cfg.formats]


def image_paths(cfg: ExportConfig, out: Path, index: int) -> list[Path]:
    """Where image ``index`` lives, one path per format (first = the one written, the others
    are hard links to it)."""
    name, sp = image_name(index), split_of(cfg, index)
    file_name = f"{name}.{cfg.image_ext}"
    return [Path(out) / f.image_path(sp, file_name) for f in _formats(cfg)]


def label_paths(cfg: ExportConfig, out: Path, index: int) -> dict[str, Path]:
    """Per-image label files by format name (formats without one, e.g. COCO, are absent)."""
    name, sp = image_name(index), split_of(cfg, index)
    out_paths = {}
    for f in _formats(cfg):
        rel = f.label_path(sp, name)
        if rel is not None:
            out_paths[f.name] = Path(out) / rel
    return out_paths


def meta_path(out: Path, index: int) -> Path:
    return Path(out) / "meta" / f"{image_name(index)}.json"


def owned_names() -> tuple[str, ...]:
    """Top-level entries an aerial-synth dataset may hold: its own files and every registered
    format's folder. Anything else in a dataset folder is the user's and is kept."""
    return DATASET_FILES + tuple(dict.fromkeys(get(n).folder for n in names()))


def is_done(cfg: ExportConfig, out: Path, index: int) -> bool:
    """Image ``index`` is complete: its metadata (written last), label files and whole image
    files (header of the configured size, container end present) exist. A file cut short
    is made again by ``--resume``, never carried into the finished dataset."""
    if not meta_path(out, index).is_file():
        return False
    size = (cfg.camera.width_px, cfg.camera.height_px)
    return all(image_file_complete(p, size) for p in image_paths(cfg, out, index)) and all(
        p.is_file() for p in label_paths(cfg, out, index).values()
    )
