"""Training data on the fly: an export's images rendered in memory, never written.

:func:`iter_samples` ``(config, start=0, stop=None)`` takes the :class:`ExportConfig` that
``export`` takes and yields the :class:`~aerial_synth.dataset.sample.Sample` of every index
in ``start..stop-1``: the pixels export encodes and the labels it writes, in every format
(:meth:`Sample.label_text`), because both call
:func:`~aerial_synth.dataset.sample.render_sample`. No torch here; the PyTorch dataset for
Ultralytics is :mod:`aerial_synth.stream.torch` (the ``[train]`` extra).

Shards: :func:`shard_indices` ``(n, k, K)`` gives worker ``k`` of ``K`` its indices
(whole placement groups, round robin), so K workers together make 0..n-1, each once.

Epochs: :func:`epoch_config` gives epoch ``e`` its own images: epoch 0 is the export
itself, epoch e > 0 the export with the seed that ``(seed, e)`` names
(:func:`epoch_seed`), so the image ``(seed, epoch, index)`` is image ``index`` of
``export --seed epoch_seed(seed, epoch)``: reproducible with the CLI.
"""

from __future__ import annotations

from .core import (
    EPOCH_STREAM,
    epoch_config,
    epoch_seed,
    iter_samples,
    plan_of,
    shard_indices,
)

__all__ = ["EPOCH_STREAM", "epoch_config", "epoch_seed", "iter_samples", "plan_of", "shard_indices"]
