"""Per-dataset files, rebuilt from every image's metadata at the end of an export: each
format's aggregate files (COCO JSON, YOLO data.yaml, ...) and ``summary.json``.

Rebuilding them from ``meta/*.json`` (never from in-memory state) is what makes ``--resume``
and any worker count end byte-identical to one uninterrupted run.
"""

from __future__ import annotations

import math
from pathlib import Path

from .. import __version__
from ..io_utils import atomic_write_json, atomic_write_text
from .config import ExportConfig
from .layout import meta_path
from .worker import record_counts

__all__ = ["dataset_info", "write_aggregates", "summarise"]


def dataset_info(cfg: ExportConfig):
    from ..formats import CATEGORIES
    from ..formats.registry import DatasetInfo

    return DatasetInfo(scene=cfg.scene, scenario=cfg.scenario, seed=cfg.seed,
                       tool_version=__version__, splits=cfg.splits, categories=CATEGORIES)


def summarise(cfg: ExportConfig, records, georeference: dict | None = None) -> dict:
    """``summary.json``: images, splits, vehicles per class, difficult, dropped (+ reasons)."""
    from ..formats import CATEGORIES

    total = {"classes": {c: 0 for c in CATEGORIES}, "difficult": 0, "dropped": 0,
             "dropped_reasons": {}, "kept": 0}
    unclear = 0
    for r in records:
        c = record_counts(r)
        for k, n in c["classes"].items():
            total["classes"][k] = total["classes"].get(k, 0) + n
        for k, n in c["dropped_reasons"].items():
            total["dropped_reasons"][k] = total["dropped_reasons"].get(k, 0) + n
        for k in ("difficult", "dropped", "kept"):
            total[k] += c[k]
        unclear += sum(1 for a in r.annotations if a.kept and a.orientation_unclear)
    summary = {
        "images": cfg.images,
        "splits": cfg.splits,
        "placements": math.ceil(cfg.images / cfg.images_per_placement),
        "vehicles_kept": total["kept"],
        "vehicles_per_class": total["classes"],
        "difficult": total["difficult"],
        "orientation_unclear": unclear,
        "dropped": total["dropped"],
        "dropped_reasons": dict(sorted(total["dropped_reasons"].items())),
        "formats": list(cfg.formats),
    }
    if georeference is not None:
        summary["georeference"] = dict(georeference)
    return summary


def write_aggregates(cfg: ExportConfig, out: Path, georeference: dict | None = None) -> dict:
    """Every format's aggregate files and ``summary.json``; returns the summary."""
    from ..formats import meta
    from ..formats.registry import get

    out = Path(out)
    records = [meta.read(meta_path(out, i)) for i in range(cfg.images)]
    info = dataset_info(cfg)
    for name in cfg.formats:
        for rel, text in get(name).aggregate_files(records, info).items():
            atomic_write_text(out / rel, text)
    summary = summarise(cfg, records, georeference)
    atomic_write_json(out / "summary.json", summary)
    return summary
