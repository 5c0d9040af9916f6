"""Dataset export (``export_dataset``) and label previews (``show_dataset``)."""

from __future__ import annotations

from ..lazy import lazy_module_attrs

__all__ = ["ExportConfig", "ExportResult", "export_dataset", "show_dataset"]

_LAZY = {"ExportConfig": "export", "ExportResult": "export", "export_dataset": "export",
         "show_dataset": "show"}


__getattr__, __dir__ = lazy_module_attrs(__name__, _LAZY, __all__)
