"""Measure the data: oriented-box AP (``eval``), real/synthetic mixes (``mix``) and the
domain-gap report (``stats``). Submodules import their heavy dependencies lazily."""

from __future__ import annotations

import importlib

__all__ = ["evaluate", "run_eval", "Detections", "EvalResult", "make_mix", "MixConfig",
           "dataset_stats", "compare_stats", "run_stats"]

_LAZY = {"evaluate": "ap", "Detections": "ap", "EvalResult": "ap", "run_eval": "evaluation",
         "make_mix": "mix", "MixConfig": "mix", "dataset_stats": "stats", "compare_stats": "stats",
         "run_stats": "stats"}


def __getattr__(name: str):
    mod = _LAZY.get(name)
    if mod is None:
        raise AttributeError(f"module 'aerial_synth.evaluate' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{mod}"), name)
    globals()[name] = value
    return value
