"""Dataset export (``export_dataset``) and label previews (``show_dataset``)."""

from __future__ import annotations

import importlib

__all__ = ["ExportConfig", "ExportResult", "export_dataset", "show_dataset"]

_LAZY = {"ExportConfig": "export", "ExportResult": "export", "export_dataset": "export",
         "show_dataset": "show"}


def __getattr__(name: str):
    mod = _LAZY.get(name)
    if mod is None:
        raise AttributeError(f"module 'aerial_synth.dataset' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{mod}"), name)
    globals()[name] = value
    return value
