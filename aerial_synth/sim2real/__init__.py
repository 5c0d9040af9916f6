"""What the data is worth: train a detector per synthetic set and score it on real images
(``aerial-synth sim2real``). Ultralytics and torch are the optional ``[train]`` extra,
imported only by :mod:`.ultra` when a run starts. See docs/sim2real.md."""

from __future__ import annotations

import importlib

__all__ = ["Sim2RealConfig", "Sim2RealError", "run_sim2real", "parse_arms"]

_LAZY = {"Sim2RealConfig": "config", "Sim2RealError": "config", "parse_arms": "config",
         "run_sim2real": "pipeline"}


def __getattr__(name: str):
    mod = _LAZY.get(name)
    if mod is None:
        raise AttributeError(f"module 'aerial_synth.sim2real' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{mod}"), name)
    globals()[name] = value
    return value
