"""Write one image: the export's unit of work, :func:`~.sample.render_sample` plus the writers.

:func:`render_image` ``(cfg, out_dir, index)`` is engine-agnostic and deterministic: it
renders image ``index`` of the export described by ``cfg`` (:mod:`.sample`: pixels, labels
and metadata, no I/O) into ``out_dir`` and returns its counts. The bytes it writes depend
only on (cfg, index), never on which process runs it or in which order, so any engine
(:mod:`.engines`) can call it. The seed streams are the plan's (:mod:`.plan`).

Pool workers watch their parent (:mod:`.parent`): a worker checks it between images and
before every file it writes, and an orphaned worker exits at once, quietly, without writing.
The engines that run workers are in :mod:`.engines`.
"""

from __future__ import annotations

import os
import queue
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from ..errors import ExportError
from ..formats import meta
from ..formats.registry import get as get_format
from ..io_utils import atomic_write_bytes, atomic_write_text
from .config import ExportConfig
from .engines.parent import check_parent
from .layout import image_paths, meta_path
from .plan import build_plan
from .sample import SampleRenderer

__all__ = [
    "ImageWorker",
    "render_image",
    "encode_image",
    "write_image_files",
    "record_counts",
]


# ------------------------------------------------------------------- worker


class ImageWorker:
    """One process's export worker: :func:`~.sample.render_sample`'s renderer for the export's
    plan (scene, catalog and the current placement group, memoised) and a writer thread.
    Make one with :meth:`for_config`."""

    @staticmethod
    def for_config(cfg: ExportConfig, out, nthreads: int = 0, scene=None, catalog=None) -> "ImageWorker":
        """The worker of the export ``cfg`` writing into ``out`` (any scene source: plain,
        mix or tiled, :class:`~.plan.SceneSource`)."""
        return ImageWorker(cfg, out, nthreads=nthreads, scene=scene, catalog=catalog)

    def __init__(self, cfg: ExportConfig, out: Path, nthreads: int = 0, scene=None, catalog=None):
        self.cfg = cfg
        self.out = Path(out)
        self.plan = build_plan(cfg)
        self.renderer = SampleRenderer(self.plan, nthreads=nthreads, scene=scene, catalog=catalog)
        self._writer: ImageWriter | None = None

    @property
    def scene(self):
        """The first placement group's scene (a tiled export's TiledWorld)."""
        return self.renderer.scene(0)

    @property
    def catalog(self):
        return self.renderer.catalog

    def record(self, index: int):
        """Render and annotate image ``index``: (ImageRecord, RGB (H, W, 3) uint8)."""
        s = self.renderer.sample(index)
        return s.meta, s.rgb

    def render(self, index: int, wait: bool = True) -> dict:
        """Render and annotate image ``index``, and write its files; returns its summary
        counts. The files are encoded and written by this worker's writer thread while the
        next image renders; with ``wait`` (the default) this returns only once they are on
        disk (or raises the writer's error). With ``wait=False`` call :meth:`drain` before
        reporting the image as finished."""
        check_parent()
        self._writer_error()  # a failed write stops the run before more rendering
        rec, rgb = self.record(index)
        self.writer.submit(self.cfg, self.out, rec, rgb)
        if wait:
            self.drain()
        return record_counts(rec)

    @property
    def writer(self) -> "ImageWriter":
        if self._writer is None:
            self._writer = ImageWriter(threads=encode_threads(self.plan.render))
        return self._writer

    def _writer_error(self) -> None:
        if self._writer is not None:
            self._writer.raise_error()

    @property
    def written(self) -> int:
        """Images whose files are on disk (written by this worker so far)."""
        return 0 if self._writer is None else self._writer.written

    def drain(self) -> None:
        """Wait until every submitted image's files are on disk; raise the first write error
        (the image that failed has no metadata file, so it is not done)."""
        if self._writer is not None:
            self._writer.drain()

    def render_run(self, indices, progress=None) -> list[tuple[int, dict]]:
        """Render a run of images in order, writing in the background; returns once all
        their files are on disk: [(index, counts)]. ``progress(n)`` is called in this
        thread with the number of images newly on disk."""
        out: list[tuple[int, dict]] = []
        for n in self.iter_run(indices, out):
            if progress is not None:
                progress(n)
        return out

    def iter_run(self, indices, out: list | None = None) -> Iterator[int]:
        """:meth:`render_run` as a generator: yields the number of images newly on disk as
        they land (the last once all are); appends (index, counts) to ``out``."""
        out = [] if out is None else out
        seen = self.written
        try:
            for i in indices:
                check_parent()
                out.append((int(i), self.render(int(i), wait=False)))
                if self.written != seen:
                    n, seen = self.written - seen, self.written
                    yield n
        except BaseException as exc:
            if self._writer is not None:  # nothing keeps writing after a failure
                try:
                    self._writer.drain()
                except BaseException as werr:  # both failed: report both
                    if exc.__context__ is None:
                        exc.__context__ = werr
            raise
        self.drain()
        if self.written != seen:
            yield self.written - seen

    def close(self) -> None:
        """Drain and stop the writer thread."""
        if self._writer is not None:
            w, self._writer = self._writer, None
            w.close()


# Engine-agnostic entry point -------------------------------------------------------------

_CACHE: dict = {}


def render_image(cfg: ExportConfig, out_dir, index: int) -> dict:
    """Render image ``index`` of the export ``cfg`` into ``out_dir`` (deterministic; the
    scene, catalog and current placement are cached per process). Returns its counts."""
    key = (cfg, str(out_dir))
    w = _CACHE.get(key)
    if w is None:
        for old in _CACHE.values():
            old.close()
        _CACHE.clear()
        w = _CACHE[key] = ImageWorker.for_config(cfg, Path(out_dir))
    return w.render(int(index))  # waits: the files are on disk when this returns


# ------------------------------------------------------------------ writing


def encode_threads(render_config) -> int:
    """Writer threads for a worker rendering with ``render_config``: 1 on the CPU (the
    export's processes encode in parallel already), up to 8 on a device (``--device cuda``:
    one process renders faster than one core encodes; the encoders release the GIL)."""
    if render_config.device == "cpu":
        return 1
    return max(1, min(8, (os.cpu_count() or 1) - 1))


class ImageWriter:
    """Background threads (``threads``, default one) that encode and write images; one
    thread writes them in the order they were submitted, several in parallel (each image's
    files are written atomically, its metadata last, whatever the order). PNG/JPEG encoding
    and file writes release the GIL, so the next frame renders meanwhile.

    At most ``depth`` images wait in the queue (``submit`` blocks beyond that), so memory
    stays bounded. The first error raised while writing is kept and raised in the
    submitting thread by the next :meth:`submit`, :meth:`drain` or :meth:`raise_error`;
    images queued after a failure are not written (until the next :meth:`drain`). Every write is atomic and the
    metadata is written last (see :func:`write_image_files`), so an image whose write
    failed or was cut short is simply not done."""

    def __init__(self, depth: int = 1, threads: int = 1):
        n = max(1, int(threads))
        self._q: queue.Queue = queue.Queue(maxsize=max(1, int(depth), n))
        self._error: BaseException | None = None  # to raise in the submitting thread
        self._failed = False  # a write failed: skip the queued images until drained
        self.written = 0
        self._count = threading.Lock()
        self._threads = [threading.Thread(target=self._loop, daemon=True,
                                          name="aerial-synth-writer" + (f"-{k}" if k else ""))
                         for k in range(n)]
        self._thread = self._threads[0]
        for t in self._threads:
            t.start()

    def _loop(self) -> None:
        while True:
            job = self._q.get()
            if job is None:
                self._q.task_done()
                return
            try:
                if not self._failed:
                    cfg, out, rec, rgb = job
                    _write_files(cfg, out, rec, encode_image(rgb, cfg.image_ext))
                    with self._count:
                        self.written += 1
            except BaseException as exc:  # kept for the submitting thread
                with self._count:
                    self._failed = True
                    if self._error is None:
                        self._error = exc
            finally:
                self._q.task_done()

    def raise_error(self) -> None:
        """Raise the first write error, once (the writer writes again after a drain)."""
        if self._error is not None:
            err, self._error = self._error, None
            raise err

    def submit(self, cfg: ExportConfig, out: Path, record, rgb: np.ndarray) -> None:
        """Queue one image (its RGB pixels, which the caller no longer changes)."""
        self.raise_error()
        if not all(t.is_alive() for t in self._threads):
            raise ExportError("the image writer thread has stopped")
        # The queue counts the image as unfinished in the same step that queues it: a put
        # cut short (SIGTERM's SystemExit or Ctrl-C while the queue is full) counts nothing,
        # where a count of our own, raised before the put, stayed up and drain() waited
        # forever (an interrupted export hung).
        self._q.put((cfg, Path(out), record, rgb))

    def drain(self, raise_error: bool = True) -> None:
        """Wait until every submitted image is written (or failed)."""
        done = self._q.all_tasks_done  # queue.Queue's condition for its unfinished_tasks
        with done:
            while self._q.unfinished_tasks > 0 and all(t.is_alive() for t in self._threads):
                done.wait(0.5)
            if self._q.unfinished_tasks == 0:
                self._failed = False  # the images after a failure were all skipped
        if raise_error:
            self.raise_error()

    def close(self) -> None:
        try:
            self.drain()
        finally:
            for _ in self._threads:
                self._q.put(None)
            for t in self._threads:
                t.join()


def encode_image(rgb: np.ndarray, ext: str) -> bytes:
    """(H, W, 3) uint8 RGB -> PNG (:func:`aerial_synth.png.encode_png`, lossless) or JPEG
    (OpenCV, quality 95) bytes."""
    a = np.ascontiguousarray(rgb, dtype=np.uint8)
    if ext == "png":
        from ..png import encode_png  # lazy: numba kernels cached on disk (checked --out first)

        return encode_png(a)
    import cv2  # lazy: OpenCV only for JPEG (start-up time)

    ok, buf = cv2.imencode(".jpg", cv2.cvtColor(a, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 95])
    if not ok:
        raise ExportError(f"could not encode an image as {ext}")
    return buf.tobytes()


def _link_or_copy(src: Path, dst: Path) -> None:
    dst.parent.mkdir(parents=True, exist_ok=True)
    tmp = dst.with_name(f".{dst.name}.{os.getpid()}.lnk")
    try:
        if tmp.exists():
            tmp.unlink()
        os.link(src, tmp)
        os.replace(tmp, dst)
    except OSError:
        try:
            tmp.unlink()
        except OSError:
            pass
        atomic_write_bytes(dst, src.read_bytes())  # guard: an image file of its own build


def write_image_files(cfg: ExportConfig, out: Path, record, rgb: np.ndarray) -> None:
    """The image (once, hard-linked into every other format's folder), every format's
    per-image label file, then the metadata (the image's "done" mark), each atomically."""
    _write_files(cfg, out, record, encode_image(rgb, cfg.image_ext))


def _write_files(cfg: ExportConfig, out: Path, record, data: bytes) -> None:
    out = Path(out)
    paths = image_paths(cfg, out, record.index)
    check_parent()
    atomic_write_bytes(paths[0], data)
    for p in paths[1:]:
        check_parent()
        _link_or_copy(paths[0], p)
    for name in cfg.formats:
        fmt = get_format(name)
        rel = fmt.label_path(record.split, record.name)
        if rel is None:
            continue
        body = fmt.label_text(record)
        check_parent()
        atomic_write_text(out / rel, body)
    check_parent()
    meta.write(meta_path(out, record.index), record)


def record_counts(record) -> dict:
    c = {"classes": {}, "difficult": 0, "dropped": 0, "dropped_reasons": {}, "kept": 0}
    for a in record.annotations:
        if a.status == "dropped":
            c["dropped"] += 1
            for r in a.reasons:
                c["dropped_reasons"][r] = c["dropped_reasons"].get(r, 0) + 1
            continue
        c["kept"] += 1
        c["classes"][a.cls] = c["classes"].get(a.cls, 0) + 1
        if a.status == "difficult":
            c["difficult"] += 1
    return c
