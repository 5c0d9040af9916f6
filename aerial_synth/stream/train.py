"""Train an Ultralytics OBB detector from the stream (the ``[train]`` extra): every epoch
sees new images, rendered in the DataLoader's workers, none written to disk.

:func:`stream_datasets` ``(config, ...)`` is the constructor a caller (sim2real's arms, a
script) needs: the training :class:`~.dataset.StreamDataset` of ``config`` (epoch ``e`` is
:func:`~aerial_synth.stream.epoch_config` ``(config, e)``) and a fixed validation one
(``val_config``, default: ``config``'s :data:`VAL_EPOCH`, ``val_images`` images).
:func:`stream_trainer_class` turns any Ultralytics OBB trainer class into one fed by those
datasets (sim2real passes its offline trainer, :mod:`aerial_synth.sim2real.ultra`), and
:func:`train_from_stream` trains with it. Nothing here sets Ultralytics' settings: a caller
that must stay offline sets them first (sim2real's ``ultra`` does).
"""

from __future__ import annotations

import dataclasses
import os
import time
from dataclasses import dataclass
from pathlib import Path

from .. import validators as v
from ..dataset.config import ExportConfig
from ..errors import ConfigError
from .core import epoch_config, plan_of
from .dataset import EpochSampler, StreamDataset

__all__ = ["VAL_EPOCH", "StreamTrainResult", "stream_datasets", "stream_trainer_class", "train_from_stream"]

#: the epoch whose images validate a stream run (never a training epoch in practice)
VAL_EPOCH = 1_000_000


def stream_datasets(config: ExportConfig, *, imgsz: int | None = None, val_config: ExportConfig | None = None,
                    val_images: int | None = None, pool: int | None = None, refresh: float = 0.25,
                    nthreads: int = 1) -> tuple[StreamDataset, StreamDataset]:
    """(train, val) datasets of ``config``: train renders epoch e's images; val is fixed
    (``val_config``, or ``config`` at :data:`VAL_EPOCH` with ``val_images`` images,
    default a quarter of ``config.images``, at least 1)."""
    cfg = plan_of(config).cfg
    if val_config is None:
        n = max(1, cfg.images // 4) if val_images is None else v.integer("val_images", val_images, 1,
                                                                         error=ConfigError)
        val_config = dataclasses.replace(epoch_config(cfg, VAL_EPOCH), images=n)
    train = StreamDataset(cfg, imgsz=imgsz, pool=pool, refresh=refresh, nthreads=nthreads)
    val = StreamDataset(plan_of(val_config).cfg, imgsz=imgsz, nthreads=nthreads)
    return train, val


def _loader(dataset: StreamDataset, batch: int, workers: int, train: bool):
    """Ultralytics' repeating DataLoader over (epoch, index) keys: each pass is the next
    epoch (training) or the same images again (validation). Workers are spawned, not
    forked: a fork of a process whose OpenMP runtime (torch's, numba's) has started
    threads can hang at its first parallel region."""
    from ultralytics.data.build import InfiniteDataLoader

    sampler = EpochSampler(dataset, shuffle=train, start_epoch=dataset.epoch, advance=train)
    return InfiniteDataLoader(dataset, batch_size=min(batch, len(dataset)), sampler=sampler,
                              num_workers=workers, collate_fn=StreamDataset.collate_fn, drop_last=False,
                              multiprocessing_context="spawn" if workers > 0 else None)


def stream_trainer_class(train_ds: StreamDataset, val_ds: StreamDataset, base=None, workers: int = 2):
    """An Ultralytics trainer class (``base``, default ``OBBTrainer``) whose data are the two
    stream datasets: no dataset folder, one DataLoader pass per epoch, training images
    rendered in ``workers`` DataLoader processes (Ultralytics' own loader uses none on a CPU:
    there the rendering, not the network, is the slow part). Its instances note (epoch,
    image, digest of the pixels) of every training image in ``stream_seen``."""
    if base is None:
        from ultralytics.models.yolo.obb import OBBTrainer as base

    class StreamOBBTrainer(base):
        """``base`` with the stream as its data."""

        def __init__(self, *a, **k):
            self.stream_seen: list = []
            super().__init__(*a, **k)

        def get_dataset(self):
            names = {i: n for i, n in enumerate(train_ds.classes)}
            return {"train": "stream:train", "val": "stream:val", "names": names, "nc": len(names),
                    "channels": 3}

        def get_dataloader(self, dataset_path, batch_size=16, rank=0, mode="train"):
            train = mode == "train"
            return _loader(train_ds if train else val_ds, batch_size, workers if train else 0, train)

        def plot_training_labels(self):
            pass

        def preprocess_batch(self, batch):
            """Notes every training image, then Ultralytics' own preprocessing."""
            import hashlib

            for f, img in zip(batch["im_file"], batch["img"]):
                self.stream_seen.append((int(self.epoch), f, hashlib.sha256(img.numpy().tobytes()).hexdigest()))
            return super().preprocess_batch(batch)

    return StreamOBBTrainer


def _data_yaml(run_dir: Path, classes) -> Path:
    """A data yaml for Ultralytics' own checks (the final validation of the best weights
    reads one): the class names, and an empty folder as the image folders (the images come
    from the stream)."""
    import yaml

    from ..io_utils import atomic_write_text

    empty = run_dir / "stream-data"
    empty.mkdir(parents=True, exist_ok=True)
    body = {"path": os.path.realpath(empty), "train": ".", "val": ".", "names": dict(enumerate(classes))}
    return atomic_write_text(run_dir / "stream.yaml", yaml.safe_dump(body, sort_keys=False))


@dataclass
class StreamTrainResult:
    """weights: best (else last) weights; seen: (epoch, image name, sha256 of the BGR CHW
    uint8 pixels) of every training image, in order."""

    weights: Path
    epochs: int
    seconds: float
    seen: list
    val_map50: float | None
    val_images: int = 0
    val_map50_95: float | None = None


def train_from_stream(config: ExportConfig, run_dir: Path, *, epochs: int | None, imgsz: int,
                      model: str = "yolo11n-obb.yaml", device: str = "cpu", batch: int = 8, workers: int = 2,
                      seed: int = 0, val_images: int | None = None, pool: int | None = None, refresh: float = 0.25,
                      trainer_base=None, amp_check=None, minutes: float | None = None,
                      amp: bool = False) -> StreamTrainResult:
    """Train ``model`` (a yaml: from scratch; or a ``.pt`` file) for ``epochs`` epochs, or
    ``minutes`` (Ultralytics' time limit) when given, on the stream of ``config``
    (``config.images`` images an epoch, each epoch new ones; ``pool``: pool mode);
    validation on :func:`stream_datasets`' fixed set. ``run_dir``: Ultralytics' run.
    ``trainer_base``: the trainer class to feed (:func:`stream_trainer_class`);
    ``amp_check``: a context manager to train in (sim2real's offline AMP check)."""
    import contextlib

    from ultralytics import YOLO

    train_ds, val_ds = stream_datasets(config, imgsz=imgsz, val_images=val_images, pool=pool, refresh=refresh)
    run_dir = Path(run_dir)
    net = YOLO(model, task="obb")
    kw = dict(data=str(_data_yaml(run_dir, train_ds.classes)), imgsz=imgsz, device=device, seed=seed, deterministic=True, batch=batch,
              workers=workers, plots=False, amp=bool(amp), project=os.path.realpath(run_dir.parent), name=run_dir.name,
              exist_ok=True, verbose=False, pretrained=False, cache=False, val=True, patience=0,
              close_mosaic=0, mosaic=0.0, trainer=stream_trainer_class(train_ds, val_ds, trainer_base, workers))
    if minutes is not None:
        kw.update(epochs=100000, time=float(minutes) / 60.0)
    else:
        kw.update(epochs=int(epochs))
    t0 = time.perf_counter()
    with amp_check or contextlib.nullcontext():
        metrics = net.train(**kw)
    tr = net.trainer
    best = Path(tr.best) if Path(tr.best).is_file() else Path(tr.last)
    rd = getattr(metrics, "results_dict", None) or {}
    return StreamTrainResult(best, int(tr.epoch) + 1, time.perf_counter() - t0, list(tr.stream_seen),
                             rd.get("metrics/mAP50(B)"), len(val_ds), rd.get("metrics/mAP50-95(B)"))
