"""``manifest.json``: marks a folder as an aerial-synth dataset and records every parameter.

Keys: ``format`` ("aerial-synth-dataset"), ``version``, ``tool``, ``tool_version``, ``versions``
(aerial-synth and the numeric libraries that produced the output), ``status``
("incomplete" while exporting, "complete" at the end), ``parameters`` (``ExportConfig``),
``seeding`` and ``georeference`` (the scene's float64 origin and CRS).
"""

from __future__ import annotations

from pathlib import Path

from .. import __version__
from ..errors import ConfigError
from ..safe_input import load_json_file
from ..versions import versions
from .config import PLACEMENT_STREAM, ExportConfig

__all__ = ["MANIFEST_FORMAT", "MANIFEST_VERSION", "read_manifest", "is_dataset", "manifest"]

MANIFEST_FORMAT = "aerial-synth-dataset"
MANIFEST_VERSION = 1


def read_manifest(out) -> dict | None:
    """The manifest of folder ``out`` as a dict, or None when it holds no readable one."""
    p = Path(out) / "manifest.json"
    try:
        if not p.is_file():
            return None
        d = load_json_file(p, str(p))  # a regular file within the budgets
    except (OSError, ConfigError):  # unreadable, broken or nested too deep: no manifest
        return None
    return d if isinstance(d, dict) and d.get("format") == MANIFEST_FORMAT else None


def is_dataset(path) -> bool:
    """True when ``path`` holds an aerial-synth dataset (its manifest)."""
    return read_manifest(Path(path)) is not None


def manifest(cfg: ExportConfig, status: str, georeference: dict | None = None) -> dict:
    d = {
        "format": MANIFEST_FORMAT,
        "version": MANIFEST_VERSION,
        "tool": "aerial-synth",
        "tool_version": __version__,
        "versions": versions(),
        "status": status,
        "parameters": cfg.to_dict(),
        "seeding": {
            "image": "numpy SeedSequence([seed, index]).spawn(2) -> camera, render",
            "placement": f"numpy SeedSequence([seed, index // images_per_placement, {PLACEMENT_STREAM}])",
        },
    }
    if georeference is not None:
        d["georeference"] = dict(georeference)
    return d
