"""The stream's core (no torch): samples, shards and epochs of an export's plan."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator

import numpy as np

from .. import validators as v
from ..dataset.config import ExportConfig
from ..dataset.plan import ExportPlan, build_plan
from ..dataset.sample import Sample, renderer_for
from ..errors import ConfigError

__all__ = ["EPOCH_STREAM", "epoch_config", "epoch_seed", "iter_samples", "plan_of", "shard_indices"]

#: the seed stream of epoch seeds: epoch e > 0 renders with seed
#: ``SeedSequence([seed, EPOCH_STREAM, e])``'s first 63-bit word
EPOCH_STREAM = 0x45504F  # "EPO"


def plan_of(config: ExportConfig | ExportPlan) -> ExportPlan:
    """The plan of ``config`` (an ExportConfig, or a plan as it is)."""
    if isinstance(config, ExportPlan):
        return config
    if not isinstance(config, ExportConfig):
        raise ConfigError(f"stream: expected an ExportConfig, got {type(config).__name__}")
    return build_plan(config)


def iter_samples(config: ExportConfig | ExportPlan, start: int = 0, stop: int | None = None,
                 *, indices=None, nthreads: int = 0) -> Iterator[Sample]:
    """The samples of ``config`` for ``start..stop-1`` (``stop`` None: ``config.images``), or
    for ``indices`` (any order) when given: each exactly what export writes for that index.
    ``nthreads``: ray-casting threads (0: all)."""
    plan = plan_of(config)
    n = plan.cfg.images
    if indices is None:
        start = v.integer("start", start, 0, n, error=ConfigError)
        stop = n if stop is None else v.integer("stop", stop, start, n, error=ConfigError)
        indices = range(start, stop)
    else:
        indices = [v.integer("index", i, 0, n - 1, error=ConfigError) for i in indices]
    r = renderer_for(plan, nthreads=nthreads)
    for i in indices:
        yield r.sample(i)


def shard_indices(n: int, k: int, K: int, images_per_placement: int = 1) -> list[int]:
    """Worker ``k`` of ``K``'s indices among 0..n-1: whole placement groups (of
    ``images_per_placement`` images), group g going to worker g mod K, so every worker
    places each of its groups once and the K shards cover 0..n-1 exactly once."""
    n = v.integer("images", n, 0, error=ConfigError)
    K = v.integer("shards", K, 1, error=ConfigError)
    k = v.integer("shard", k, 0, K - 1, error=ConfigError)
    ipp = v.integer("images_per_placement", images_per_placement, 1, error=ConfigError)
    return [i for i in range(n) if (i // ipp) % K == k]


def epoch_seed(seed: int, epoch: int) -> int:
    """The dataset seed of epoch ``epoch`` (0: ``seed`` itself)."""
    epoch = v.integer("epoch", epoch, 0, error=ConfigError)
    if epoch == 0:
        return int(seed)
    word = np.random.SeedSequence([int(seed), EPOCH_STREAM, epoch]).generate_state(1, np.uint64)[0]
    return int(word >> np.uint64(1))


def epoch_config(config: ExportConfig, epoch: int) -> ExportConfig:
    """``config`` for epoch ``epoch``: the same export with :func:`epoch_seed`'s seed."""
    if isinstance(config, ExportPlan):
        config = config.cfg
    s = epoch_seed(config.seed, epoch)
    return config if s == config.seed else dataclasses.replace(config, seed=s)
