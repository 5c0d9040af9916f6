"""Configuration of ``aerial-synth sim2real`` and the checks of its inputs (no torch here).

An *arm* is one synthetic training set: ``--synthetic DIR`` (named after the folder) or
``--synthetic NAME=DIR[,DIR...]`` (several exports trained as one set). Each DIR is an
aerial-synth export with ``yolo-obb/`` or a YOLO-OBB folder (``data.yaml``, ``images/``,
``labels/``); its GSD comes from the export's ``manifest.json`` (or ``--gsd``).
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import validators as V
from ..errors import EvaluationError
from ..evaluate.labels import IMAGE_EXTS, find_data_yaml, parse_names
from ..safe_input import LABEL_GSD_RANGE_M, MAX_COORD_PX, load_json_file, user_regex

__all__ = ["Sim2RealError", "Arm", "SyntheticSet", "Sim2RealConfig", "parse_arm", "parse_arms",
           "inspect_synthetic", "parse_real_scale", "DEFAULT_MODEL", "REAL_SCALES"]

DEFAULT_MODEL = "yolo11n-obb.yaml"
#: how real images meet the detector: "arm" rescales each to the arm's synthetic GSD (needs
#: every image's GSD); "native" predicts them at their own pixels (no GSD needed): what a
#: detector meets when nobody rescales for it, and what a GSD range is meant to cover
REAL_SCALES = ("arm", "native")
ARM_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


class Sim2RealError(EvaluationError):
    """Bad input to ``aerial-synth sim2real``."""


@dataclass(frozen=True)
class Arm:
    name: str
    dirs: tuple[Path, ...]


def parse_arm(text: str) -> Arm:
    """``DIR`` or ``NAME=DIR[,DIR...]``."""
    name, sep, rest = str(text).partition("=")
    if sep and ARM_NAME.match(name.strip()) and rest.strip():
        dirs = tuple(Path(d.strip()) for d in rest.split(",") if d.strip())
        return Arm(name.strip(), dirs)
    p = Path(text)
    nm = Path(os.path.realpath(p)).name if str(text).strip() else ""  # a link loop: no RuntimeError
    if not nm or not ARM_NAME.match(nm):
        raise Sim2RealError(f"--synthetic: expected DIR or NAME=DIR[,DIR] (NAME of letters, digits, "
                            f"_ . -), got {text!r}")
    return Arm(nm, (p,))


def parse_arms(values) -> tuple[Arm, ...]:
    arms = [parse_arm(v) for v in values or ()]
    if not arms:
        raise Sim2RealError("--synthetic: expected at least one synthetic set (DIR or NAME=DIR)")
    seen = set()
    for a in arms:
        if a.name in seen:
            raise Sim2RealError(f"--synthetic: arm name {a.name!r} given twice; name each set "
                                f"(NAME=DIR) differently")
        seen.add(a.name)
    return tuple(arms)


def parse_real_scale(text: str) -> tuple[str, ...]:
    """``arm``, ``native`` or both (comma list, first = the report's headline)."""
    vals = tuple(v.strip() for v in str(text).split(","))
    if not vals or any(v not in REAL_SCALES for v in vals) or len(set(vals)) != len(vals):
        raise Sim2RealError(f"--real-scale: expected arm, native or a comma list of both (first = "
                            f"headline), got {text!r}")
    return vals


@dataclass(frozen=True)
class SyntheticSet:
    """One YOLO-OBB folder of an arm: ``root`` (with the data YAML), train/val image folders,
    class names, GSD (m/px, None when unknown) and image counts."""

    root: Path
    train_images: Path
    val_images: Path | None
    names: tuple[str, ...]
    gsd_m: float | None
    n_train: int
    n_val: int


def _images(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_EXTS and p.is_file())


def _export_gsd(d: Path) -> float | None:
    """The export's nadir GSD: ``parameters.gsd_m`` of its manifest, else (a GSD derived from
    the altitude) the median ``gsd_m`` of its per-image metadata (``meta/*.json``)."""
    for base in (d, d.parent):
        m = base / "manifest.json"
        if not m.is_file():
            continue
        try:
            g = load_json_file(m, str(m), Sim2RealError).get("parameters", {}).get("gsd_m")
        except (EvaluationError, AttributeError):  # unreadable: as if absent
            g = None
        if isinstance(g, (int, float)) and g > 0:
            return float(g)
        vals = []
        for f in sorted((base / "meta").glob("*.json")) if (base / "meta").is_dir() else ():
            try:
                v = load_json_file(f, str(f), Sim2RealError).get("gsd_m")
            except (EvaluationError, AttributeError):
                continue
            if isinstance(v, (int, float)) and v > 0:
                vals.append(float(v))
        return float(np.median(vals)) if vals else None
    return None


def inspect_synthetic(d: Path, option: str) -> SyntheticSet:
    """Check one synthetic folder: YOLO-OBB layout, every image with a label file.
    ``option`` prefixes the folder in messages (``--synthetic NAME=``)."""
    where = f"{option}{d}"
    if not d.exists():
        raise Sim2RealError(f"{where}: no such folder")
    if not d.is_dir():
        raise Sim2RealError(f"{where}: expected a folder, found a file")
    root = d / "yolo-obb" if (d / "yolo-obb").is_dir() else d
    yaml_path = find_data_yaml(root) if (root / "images").is_dir() and (root / "labels").is_dir() else None
    if yaml_path is None:
        raise Sim2RealError(f"{where}: expected a YOLO-OBB dataset (yolo-obb/ with data.yaml, "
                            f"images/, labels/; export it with --format yolo-obb), found none")
    names = tuple(parse_names(str(yaml_path), option=f"{where}: {yaml_path.name}"))
    img = root / "images"
    train = img / "train" if (img / "train").is_dir() else img
    val = img / "val" if (img / "val").is_dir() else None
    counts = []
    for folder in (train, val):
        if folder is None:
            counts.append(0)
            continue
        files = _images(folder)
        lab = root / "labels" / folder.relative_to(img)
        for f in files:
            if not (lab / (f.stem + ".txt")).is_file():
                raise Sim2RealError(f"{where}: image {f} has no label file {lab / (f.stem + '.txt')}")
        counts.append(len(files))
    if counts[0] == 0:
        raise Sim2RealError(f"{where}: no training images in {train}")
    return SyntheticSet(root, train, val, names, _export_gsd(d), counts[0], counts[1])


@dataclass(frozen=True)
class Sim2RealConfig:
    """Everything ``sim2real`` needs; validated at construction (see docs/sim2real.md)."""

    arms: tuple[Arm, ...]
    real: Path
    out: Path
    model: str = DEFAULT_MODEL
    weights: Path | None = None
    minutes: float | None = None
    epochs: int | None = None
    imgsz: int = 640
    device: str = "auto"
    seed: int = 0
    batch: int = 8
    workers: int = 2
    tile: int | None = None
    overlap: int | None = None
    gsd: float | None = None
    real_gsd: float | None = None
    real_scale: tuple[str, ...] = ("arm",)
    real_classes: tuple[str, ...] | None = ("small-vehicle", "large-vehicle")
    conf: float = 0.001
    merge_iou: float = 0.3
    iou_type: str = "auto"
    ignore_border: dict = field(default_factory=dict)
    group: str | None = None
    contact_images: int = 6
    force: bool = False

    def _check_types(self) -> None:
        """Every number is a finite number of the right kind, in its range, before anything
        compares it (NaN passed ``x < 1`` tests; a string gave a plain TypeError): each field
        is converted or refused in one line naming its option (as ``ExportConfig``)."""
        E, s = Sim2RealError, object.__setattr__
        if not isinstance(self.arms, tuple) or not self.arms or \
                not all(isinstance(a, Arm) for a in self.arms):
            raise E(f"--synthetic: expected at least one synthetic set, got {V.show(self.arms)}")
        if self.minutes is not None:
            s(self, "minutes", V.in_range("--minutes", self.minutes, 0.0, 7 * 24 * 60.0,
                                          lo_open=True, error=E))
        if self.epochs is not None:
            s(self, "epochs", V.integer("--epochs", self.epochs, 1, 100_000, error=E))
        for name, opt, lo, hi in (("imgsz", "--imgsz", 32, 8192), ("seed", "--seed", 0, 2**32 - 1),
                                  ("batch", "--batch", 1, 4096), ("workers", "--workers", 0, 256),
                                  ("contact_images", "--contact-images", 0, 1000)):
            s(self, name, V.integer(opt, getattr(self, name), lo, hi, error=E))
        for name, opt in (("tile", "--tile"), ("overlap", "--overlap")):
            if getattr(self, name) is not None:
                s(self, name, V.integer(opt, getattr(self, name), 0, 1 << 20, error=E))
        for name, opt, lo, hi in (("conf", "--conf", 0.0, 1.0), ("merge_iou", "--merge-iou", 0.0, 1.0)):
            s(self, name, V.in_range(opt, getattr(self, name), lo, hi, error=E))
        for name, opt in (("gsd", "--gsd"), ("real_gsd", "--real-gsd")):
            if getattr(self, name) is not None:
                s(self, name, V.in_range(opt, getattr(self, name), *LABEL_GSD_RANGE_M, error=E))
        if not isinstance(self.ignore_border, Mapping):
            raise E(f"--ignore-border: expected a mapping class: pixels, got {V.show(self.ignore_border)}")
        s(self, "ignore_border", {k: V.in_range(f"--ignore-border {k if k is not None else '*'}", v,
                                                0.0, MAX_COORD_PX, error=E)
                                  for k, v in self.ignore_border.items()})
        if self.group is not None:
            user_regex(self.group, "--group", E)  # RE2: no match can backtrack

    def __post_init__(self):
        if self.minutes is not None and self.epochs is not None:
            raise Sim2RealError("sim2real: expected --minutes or --epochs, not both")
        if self.minutes is None and self.epochs is None:
            object.__setattr__(self, "minutes", 10.0)
        self._check_types()
        if self.imgsz < 32 or self.imgsz % 32:
            raise Sim2RealError(f"--imgsz: expected a multiple of 32 (>= 32), got {self.imgsz!r}")
        tile = self.imgsz if self.tile is None else self.tile
        if tile < 32:
            raise Sim2RealError(f"--tile: expected an integer >= 32, got {tile!r}")
        overlap = tile // 5 if self.overlap is None else self.overlap
        if not (0 <= overlap < tile):
            raise Sim2RealError(f"--overlap: expected 0 <= overlap < --tile ({tile}), got {overlap!r}")
        object.__setattr__(self, "tile", tile)
        object.__setattr__(self, "overlap", overlap)
        if self.weights is not None:
            w = Path(self.weights)
            if not w.is_file():
                raise Sim2RealError(f"--weights {w}: no such file (sim2real never downloads weights)")
        elif not str(self.model).endswith((".yaml", ".yml")):
            raise Sim2RealError(f"--model: expected a model yaml (e.g. {DEFAULT_MODEL}; built from "
                                f"scratch, nothing downloaded), got {self.model!r}; use --weights FILE "
                                f"for a local .pt")
        rs = self.real_scale
        text = rs if isinstance(rs, str) else ",".join(map(str, rs)) if isinstance(rs, (tuple, list)) else repr(rs)
        object.__setattr__(self, "real_scale", parse_real_scale(text))  # a tuple, checked
        if not (0.0 <= self.conf < 1.0):
            raise Sim2RealError(f"--conf: expected a number in [0, 1), got {self.conf!r}")
        if not (0.0 < self.merge_iou < 1.0):
            raise Sim2RealError(f"--merge-iou: expected a number in (0, 1), got {self.merge_iou!r}")
        if self.batch < 1 or self.workers < 0 or self.seed < 0 or self.contact_images < 0:
            raise Sim2RealError("sim2real: --batch >= 1, --workers >= 0, --seed >= 0 expected")
