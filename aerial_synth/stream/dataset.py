"""PyTorch side of the stream (the ``[train]`` extra): a dataset that renders in the
DataLoader's workers, an epoch-aware sampler, and a pool mode.

:class:`StreamDataset` ``(config, imgsz=None, pool=None, refresh=0.25)``:

- item ``(epoch, index)`` is the sample :func:`~aerial_synth.dataset.sample.render_sample`
  makes for image ``index`` of :func:`~aerial_synth.stream.epoch_config` ``(config, epoch)``:
  the image that (seed, epoch, index) names. A plain index takes the dataset's own
  :attr:`epoch` (:meth:`set_epoch`), so a plain ``DataLoader`` works too;
- :class:`EpochSampler` hands the DataLoader (epoch, index) keys: each pass over it is one
  epoch (the first pass ``start_epoch``), shuffled from ``SeedSequence([seed, epoch])``.
  The keys are made in the main process, so workers that prefetch across an epoch boundary
  still render the right epoch's images;
- pool mode (``pool=P``): P images are held, and each epoch after the first re-renders
  ``round(refresh * P)`` of them, drawn from ``SeedSequence([seed, EPOCH_STREAM, epoch,
  POOL_STREAM])``; slot ``j`` at epoch ``e`` holds image ``j`` of the last epoch ``<= e``
  that refreshed it (:meth:`born`). A worker keeps the images it rendered and renders a
  slot again only when it was refreshed.

Items are Ultralytics' OBB training dicts (``img`` 3xHxW uint8, ``cls`` (n, 1), ``bboxes``
(n, 5) normalised xywhr, ``batch_idx``, ``im_file``, ``ori_shape``, ``resized_shape``,
``ratio_pad``), made from the sample's labels; :meth:`StreamDataset.collate_fn` batches them.
"""

from __future__ import annotations

import numpy as np

from .. import validators as v
from ..dataset.config import ExportConfig
from ..errors import ConfigError
from ..vehicles import CLASSES as DETECTION_CLASSES
from .core import EPOCH_STREAM, epoch_config, plan_of

__all__ = ["POOL_STREAM", "EpochSampler", "StreamDataset", "obb_targets"]

#: the pool's refresh draws: ``SeedSequence([seed, EPOCH_STREAM, epoch, POOL_STREAM])``
POOL_STREAM = 0x504F4F  # "POO"


def obb_targets(polygons_px: np.ndarray, w: int, h: int) -> np.ndarray:
    """(n, 4, 2) pixel polygons -> (n, 5) [cx/w, cy/h, bw/w, bh/h, angle rad] as Ultralytics'
    OBB targets (``xyxyxyxy2xywhr``: the minimum-area rectangle, angle in [0, pi/2))."""
    from ultralytics.utils.ops import xyxyxyxy2xywhr

    p = np.asarray(polygons_px, np.float32).reshape(-1, 8)
    if len(p) == 0:
        return np.zeros((0, 5), np.float32)
    out = np.asarray(xyxyxyxy2xywhr(p), np.float32).reshape(-1, 5)
    out[:, [0, 2]] /= float(w)
    out[:, [1, 3]] /= float(h)
    return out


class StreamDataset:
    """A map-style dataset of an export's images rendered on demand (see the module's text).

    config  : the ExportConfig that ``export`` takes (its images are one epoch)
    imgsz   : the square training size; frames of another size are resized to it (None: as
              rendered)
    classes : the class list (index = class id; default: the detection classes)
    pool, refresh : pool mode (P images held, a fraction re-rendered each epoch)
    nthreads : ray-casting threads per worker (0: all cores; 1 suits many workers)
    """

    def __init__(self, config: ExportConfig, imgsz: int | None = None, classes=DETECTION_CLASSES,
                 pool: int | None = None, refresh: float = 0.25, nthreads: int = 1):
        self.config = plan_of(config).cfg
        n = self.config.images
        if pool is not None:
            pool = v.integer("pool", pool, 1, n, error=ConfigError)
        self.pool = pool
        self.refresh = float(v.in_range("refresh", refresh, 0.0, 1.0, error=ConfigError))
        self.imgsz = None if imgsz is None else v.integer("imgsz", imgsz, 32, error=ConfigError)
        self.classes = tuple(classes)
        self.nthreads = int(nthreads)
        self.epoch = 0
        self._cache: dict = {}  # pool mode: (born epoch, slot) -> item, this worker
        self._born: dict = {}  # (epoch, slot) -> born epoch

    def __len__(self) -> int:
        return self.pool if self.pool is not None else self.config.images

    def set_epoch(self, epoch: int) -> None:
        """The epoch of keys below ``len(self)`` (a sampler's keys carry their own)."""
        self.epoch = v.integer("epoch", epoch, 0, error=ConfigError)

    # -- naming: (epoch, index) -> the image rendered ---------------------------------------
    def split_key(self, key) -> tuple[int, int]:
        """(epoch, index) of item ``key``: an (epoch, index) pair (what :class:`EpochSampler`
        yields) or an index (of :attr:`epoch`)."""
        if isinstance(key, (tuple, list)):
            epoch, i = (int(k) for k in key)
        else:
            epoch, i = self.epoch, int(key)
        if not 0 <= i < len(self) or epoch < 0:
            raise IndexError(f"stream item {key!r}: expected an index in 0..{len(self) - 1} "
                             "and an epoch >= 0")
        return epoch, i

    def refreshed(self, epoch: int) -> np.ndarray:
        """Pool slots re-rendered in ``epoch`` (every slot in epoch 0)."""
        P = self.pool
        if epoch == 0:
            return np.arange(P)
        k = int(round(self.refresh * P))
        rng = np.random.default_rng(np.random.SeedSequence([self.config.seed, EPOCH_STREAM, int(epoch), POOL_STREAM]))
        return np.sort(rng.permutation(P)[:k])

    def born(self, epoch: int, slot: int) -> int:
        """The epoch whose image pool slot ``slot`` holds at ``epoch``."""
        key = (int(epoch), int(slot))
        if key not in self._born:
            e = int(epoch)
            while e > 0 and int(slot) not in set(self.refreshed(e).tolist()):
                e -= 1
            self._born[key] = e
        return self._born[key]

    def image_of(self, key: int) -> tuple[int, int]:
        """(epoch, index) of the image item ``key`` shows: the sample of ``index`` in
        ``epoch_config(config, epoch)``."""
        epoch, i = self.split_key(key)
        return (self.born(epoch, i), i) if self.pool is not None else (epoch, i)

    def sample(self, epoch: int, index: int):
        """The :class:`~aerial_synth.dataset.sample.Sample` (seed, epoch, index) names."""
        from ..dataset.sample import renderer_for

        plan = plan_of(epoch_config(self.config, epoch))
        return renderer_for(plan, nthreads=self.nthreads).sample(index)

    # -- items ------------------------------------------------------------------------------
    def __getitem__(self, key: int) -> dict:
        name = self.image_of(key)
        if self.pool is not None and name in self._cache:
            return self._cache[name]
        item = self.item(self.sample(*name), name)
        if self.pool is not None:
            live = {(self.born(self.split_key(key)[0], j), j) for j in range(self.pool)}
            self._cache = {k: it for k, it in self._cache.items() if k in live}
            self._cache[name] = item
        return item

    def item(self, s, name: tuple[int, int]) -> dict:
        """Ultralytics' training dict of sample ``s`` (named (epoch, index))."""
        import torch

        rgb = s.rgb
        h0, w0 = rgb.shape[:2]
        poly = np.asarray(s.labels.polygons_xy_px, np.float64).reshape(-1, 4, 2).copy()
        h, w = h0, w0
        if self.imgsz is not None and (h0, w0) != (self.imgsz, self.imgsz):
            import cv2

            r = self.imgsz / max(h0, w0)
            w, h = max(1, round(w0 * r)), max(1, round(h0 * r))
            rgb = cv2.resize(rgb, (w, h), interpolation=cv2.INTER_AREA if r < 1 else cv2.INTER_LINEAR)
            poly[..., 0] *= w / w0
            poly[..., 1] *= h / h0
        ids = {c: k for k, c in enumerate(self.classes)}
        keep = [k for k, c in enumerate(s.labels.classes) if c in ids]
        cls = np.array([ids[s.labels.classes[k]] for k in keep], np.float32).reshape(-1, 1)
        boxes = obb_targets(poly[keep], w, h)
        img = np.ascontiguousarray(rgb[..., ::-1].transpose(2, 0, 1))  # Ultralytics: BGR, CHW
        return {
            "img": torch.from_numpy(img),
            "cls": torch.from_numpy(cls),
            "bboxes": torch.from_numpy(boxes),
            "batch_idx": torch.zeros(len(keep)),
            "im_file": f"stream/seed{self.config.seed}/epoch{name[0]}/{s.meta.name}",
            "ori_shape": (h0, w0),
            "resized_shape": (h, w),
            "ratio_pad": ((h / h0, w / w0), (0, 0)),
        }

    @staticmethod
    def collate_fn(batch: list[dict]) -> dict:
        """Ultralytics' batch: images stacked, targets concatenated with their image's index."""
        import torch

        out = {}
        for k in batch[0]:
            vals = [b[k] for b in batch]
            if k == "img":
                out[k] = torch.stack(vals, 0)
            elif k in ("cls", "bboxes"):
                out[k] = torch.cat(vals, 0)
            elif k == "batch_idx":
                out[k] = torch.cat([b + i for i, b in enumerate(vals)], 0)
            else:
                out[k] = vals
        return out


class EpochSampler:
    """(epoch, index) keys for a :class:`StreamDataset`: pass ``p`` over the sampler is epoch
    ``start_epoch + p`` (``advance``; else every pass is ``start_epoch``), its indices shuffled
    from ``SeedSequence([seed, epoch])`` (``shuffle``) or ascending."""

    def __init__(self, dataset: StreamDataset, shuffle: bool = True, start_epoch: int = 0,
                 advance: bool = True):
        self.n = len(dataset)
        self.seed = dataset.config.seed
        self.shuffle = bool(shuffle)
        self.epoch = int(start_epoch)
        self.advance = bool(advance)

    def __len__(self) -> int:
        return self.n

    def set_epoch(self, epoch: int) -> None:
        """The epoch of the next pass."""
        self.epoch = int(epoch)

    def __iter__(self):
        e = self.epoch
        self.epoch += int(self.advance)
        order = np.arange(self.n)
        if self.shuffle:
            order = np.random.default_rng(np.random.SeedSequence([self.seed, e])).permutation(self.n)
        return iter([(e, int(i)) for i in order])
