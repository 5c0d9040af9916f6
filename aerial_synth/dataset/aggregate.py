"""Per-dataset files, rebuilt from every image's metadata at the end of an export: each
format's aggregate files (COCO JSON, YOLO data.yaml, ...) and ``summary.json``.

Rebuilding them from ``meta/*.json`` (never from in-memory state) is what makes ``--resume``
and any worker count end byte-identical to one uninterrupted run.
"""

from __future__ import annotations

import math
from pathlib import Path

from .. import __version__
from ..errors import ExportError
from ..io_utils import atomic_write_chunks, atomic_write_json, atomic_write_text
from .config import ExportConfig
from .layout import meta_path, split_of
from .worker import record_counts

__all__ = ["MetaRecords", "dataset_info", "write_aggregates", "summarise"]


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


class MetaRecords:
    """Every image's :class:`~aerial_synth.formats.meta.ImageRecord` of an export, in index
    order, read from ``meta/`` when asked for: iterating holds one record at a time (a
    100,000-image export's records took ~60 GB as a list). Each iteration reads the files
    again; ``len`` and ``[i]`` work; :meth:`of_split` reads only one split's records."""

    def __init__(self, cfg: ExportConfig, out: Path):
        self.cfg, self.out = cfg, Path(out)

    def __len__(self) -> int:
        return self.cfg.images

    def __getitem__(self, i: int):
        from ..formats import meta

        i = range(len(self))[i]  # negative indices; IndexError past the end
        return meta.read(meta_path(self.out, i))

    def __iter__(self):
        return (self[i] for i in range(len(self)))

    def of_split(self, split: str):
        """The records of one split, in index order (the split of an index follows from the
        config; a record that says otherwise is not this export's: one-line ExportError)."""
        for i in range(len(self)):
            if split_of(self.cfg, i) != split:
                continue
            r = self[i]
            if r.split != split or r.index != i:
                raise ExportError(f"{meta_path(self.out, i)}: expected image {i} of split {split!r}, "
                                  f"found image {r.index} of split {r.split!r} (not this export's file)")
            yield r


def write_aggregates(cfg: ExportConfig, out: Path, georeference: dict | None = None) -> dict:
    """Every format's aggregate files and ``summary.json``; returns the summary. Records are
    read from ``meta/`` as they are needed (:class:`MetaRecords`) and a format's file given
    as chunks is written chunk by chunk, so memory does not grow with the export."""
    from ..formats.registry import get

    out = Path(out)
    records = MetaRecords(cfg, out)
    info = dataset_info(cfg)
    for name in cfg.formats:
        for rel, body in get(name).aggregate_files(records, info).items():
            if isinstance(body, str):
                atomic_write_text(out / rel, body)
            else:
                atomic_write_chunks(out / rel, body)
    summary = summarise(cfg, records, georeference)
    atomic_write_json(out / "summary.json", summary)
    return summary
