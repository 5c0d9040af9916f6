"""Measure the data: oriented-box AP (``eval``), real/synthetic mixes (``mix``) and the
domain-gap report (``stats``). Submodules import their heavy dependencies lazily."""

from __future__ import annotations

from ..lazy import lazy_module_attrs

__all__ = ["evaluate", "run_eval", "Detections", "EvalResult", "make_mix", "MixConfig",
           "dataset_stats", "compare_stats", "run_stats"]

_LAZY = {"evaluate": "ap", "Detections": "ap", "EvalResult": "ap", "run_eval": "evaluation",
         "make_mix": "mix", "MixConfig": "mix", "dataset_stats": "stats", "compare_stats": "stats",
         "run_stats": "stats"}


__getattr__, __dir__ = lazy_module_attrs(__name__, _LAZY, __all__)
