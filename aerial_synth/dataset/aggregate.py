"""Per-dataset files, rebuilt from every image's metadata at the end of an export: each
format's aggregate files (COCO JSON, YOLO data.yaml, ...) and ``summary.json``.

Rebuilding them from ``meta/*.json`` (never from in-memory state) is what makes ``--resume``
and any worker count end byte-identical to one uninterrupted run.

Each meta file is read once: the formats' passes (:meth:`MetaRecords.map`, and iterating
:class:`MetaRecords`) also count every record they read for ``summary.json``, which reads
only the records no format read. A large export's passes are spread over processes
(:meth:`MetaRecords.map`); this process keeps what is sequential (COCO's annotation ids,
writing). ``tools/bench_aggregate.py --images 2000`` on a shared 2-core host: 9.5-14.2 s
before (two reads of each file), 7.6-9.1 s with 1 process, 3.6-5.4 s with 2, peak RSS
~35 MB; the same bytes (docs/formats.md, "Large exports").
"""

from __future__ import annotations

import math
import os
from collections import deque
from itertools import chain, islice
from pathlib import Path

from .. import __version__
from ..errors import AerialSynthError, ExportError
from ..formats import CATEGORIES, meta
from ..formats.registry import DatasetInfo, get
from ..io_utils import atomic_write_chunks, atomic_write_json, atomic_write_text
from .config import ExportConfig
from .engines.affinity import allowed_cores
from .engines.fork_server import check_entry_point, pool_context
from .engines.parent import watch_parent
from .layout import meta_path, split_of
from .worker import record_counts

__all__ = ["MetaRecords", "POOL_MIN_RECORDS", "aggregate_pool", "dataset_info", "write_aggregates", "summarise"]

#: An export of at least this many images reads its records on a process pool (where more
#: than one core is allowed, see :meth:`MetaRecords.map`); a smaller one in this process. The
#: pool's processes are forks of the export's fork server, which takes ~2 s to start (its
#: imports, in the background; :func:`.export.export_dataset` starts it early for such an
#: export), and a pool then starts in ~0.05 s, the time of ~10 records.
POOL_MIN_RECORDS = 256
#: ... and a pass of :meth:`MetaRecords.map` over fewer records than this runs in this process.
PASS_MIN_RECORDS = 32
#: Records per pool task, at most (fewer in a small pass, so that every process gets work).
CHUNK_RECORDS = 16
#: Tasks in flight per pool process: what bounds the results waiting in memory.
WINDOW_PER_WORKER = 2


def aggregate_pool(cfg: ExportConfig) -> bool:
    """Whether :func:`write_aggregates` (default workers) reads ``cfg``'s records on a pool."""
    return cfg.images >= POOL_MIN_RECORDS and len(allowed_cores()) > 1


def dataset_info(cfg: ExportConfig):
    return DatasetInfo(scene=cfg.scene, scenario=cfg.scenario, seed=cfg.seed,
                       tool_version=__version__, splits=cfg.splits, categories=CATEGORIES)


def _record_tally(r) -> tuple:
    """What ``summary.json`` counts of one record: (classes, dropped reasons, difficult,
    dropped, kept, orientation unclear), small enough to send from a pool process."""
    c = record_counts(r)
    unclear = sum(1 for a in r.annotations if a.kept and a.orientation_unclear)
    return (tuple(c["classes"].items()), tuple(c["dropped_reasons"].items()),
            c["difficult"], c["dropped"], c["kept"], unclear)


class _Tally:
    """The sum of :func:`_record_tally` over records, in any order, with the result of
    adding them in index order (a class outside the catalog's comes after them, in the order
    it first appears)."""

    def __init__(self):
        self.classes = {c: 0 for c in CATEGORIES}
        self.first: dict = {}  # class outside CATEGORIES -> (index, position) of its first record
        self.reasons: dict = {}
        self.difficult = self.dropped = self.kept = self.unclear = 0

    def add(self, i: int, t: tuple) -> None:
        classes, reasons, difficult, dropped, kept, unclear = t
        for pos, (k, n) in enumerate(classes):
            if k not in self.classes:  # outside the catalog, first seen here
                self.classes[k] = 0
                self.first[k] = (i, pos)
            elif k in self.first and (i, pos) < self.first[k]:
                self.first[k] = (i, pos)
            self.classes[k] += n
        for k, n in reasons:
            self.reasons[k] = self.reasons.get(k, 0) + n
        self.difficult += difficult
        self.dropped += dropped
        self.kept += kept
        self.unclear += unclear

    def vehicles_per_class(self) -> dict:
        """Vehicles per class: the catalog's classes in catalog order, then any other."""
        extra = sorted(self.first, key=self.first.__getitem__)
        return {k: self.classes[k] for k in (*(k for k in self.classes if k not in self.first), *extra)}


def summarise(cfg: ExportConfig, records, georeference: dict | None = None) -> dict:
    """``summary.json``: images, splits, vehicles per class, difficult, dropped (+ reasons).
    ``records``: every record (iterated once), or a :class:`MetaRecords`, whose counts of
    the records its passes already read are used (only the others are read)."""
    counted = getattr(records, "summary_counts", None)
    if counted is not None:
        total = counted()
    else:
        total = _Tally()
        for i, r in enumerate(records):
            total.add(i, _record_tally(r))
    summary = {
        "images": cfg.images,
        "splits": cfg.splits,
        "placements": math.ceil(cfg.images / cfg.images_per_placement),
        "vehicles_kept": total.kept,
        "vehicles_per_class": total.vehicles_per_class(),
        "difficult": total.difficult,
        "orientation_unclear": total.unclear,
        "dropped": total.dropped,
        "dropped_reasons": dict(sorted(total.reasons.items())),
        "formats": list(cfg.formats),
    }
    if georeference is not None:
        summary["georeference"] = dict(georeference)
    return summary


class MetaRecords:
    """Every image's :class:`~aerial_synth.formats.meta.ImageRecord` of an export, in index
    order, read from ``meta/`` when asked for: iterating holds one record at a time (a
    100,000-image export's records took ~60 GB as a list). Each iteration reads the files
    again; ``len`` and ``[i]`` work; :meth:`of_split` reads only one split's records;
    :meth:`map` applies a function to every record (of a split) on a process pool.

    workers : processes of :meth:`map`'s pool (default: the cores this process may use,
              :func:`~aerial_synth.dataset.engines.affinity.allowed_cores`); 1 = never a pool
    pool_min: a pass over fewer records runs in this process (:data:`POOL_MIN_RECORDS`)

    Every record read by iterating or by :meth:`map` is also counted for ``summary.json``
    (:meth:`summary_counts`), so that the summary reads no file twice."""

    def __init__(self, cfg: ExportConfig, out: Path, workers: int | None = None,
                 pool_min: int | None = None):
        self.cfg, self.out = cfg, Path(out)
        self.workers = None if workers is None else max(1, int(workers))
        self.pool_min = POOL_MIN_RECORDS if pool_min is None else int(pool_min)
        self._counted = bytearray(cfg.images)
        self._pool_broken = False  # a pool process died: every later pass runs here
        self._tally = _Tally()

    def __len__(self) -> int:
        return self.cfg.images

    def __getitem__(self, i: int):
        i = range(len(self))[i]  # negative indices; IndexError past the end
        return meta.read(meta_path(self.out, i))

    def __iter__(self):
        for i in range(len(self)):
            r = self[i]
            self._count(i, r)
            yield r

    def _read(self, i: int, split: str | None):
        """Record ``i``; with ``split``, checked to be this export's image ``i`` of it."""
        r = self[i]
        if split is not None and (r.split != split or r.index != i):
            raise ExportError(f"{meta_path(self.out, i)}: expected image {i} of split {split!r}, "
                              f"found image {r.index} of split {r.split!r} (not this export's file)")
        return r

    def _count(self, i: int, r) -> None:
        if not self._counted[i]:
            self._counted[i] = 1
            self._tally.add(i, _record_tally(r))

    def of_split(self, split: str):
        """The records of one split, in index order (the split of an index follows from the
        config; a record that says otherwise is not this export's: one-line ExportError)."""
        for i in range(len(self)):
            if split_of(self.cfg, i) != split:
                continue
            r = self._read(i, split)
            self._count(i, r)
            yield r

    def pool_size(self, n: int) -> int:
        """Processes a pass over ``n`` records runs on (1: in this process)."""
        if self._pool_broken or len(self) < self.pool_min or n < max(2, min(PASS_MIN_RECORDS, self.pool_min)):
            return 1
        if self.workers is not None:
            return min(self.workers, n)
        return min(len(allowed_cores()), n)

    def map(self, fn, split: str | None = None):
        """``fn(record)`` for every record (of ``split``: checked as :meth:`of_split` does),
        yielded in index order. ``fn`` must be picklable by reference (a module-level
        function, or a :func:`functools.partial` of one) and return something small.

        In an export of :data:`POOL_MIN_RECORDS` images or more (``pool_min``), a pass over
        :data:`PASS_MIN_RECORDS` records or more is computed in chunks of up to
        :data:`CHUNK_RECORDS` records on a process pool (:func:`.pool.pool_context`, sized
        by :meth:`pool_size`; one pool per pass, shut down when the pass ends or stops), with
        at most :data:`WINDOW_PER_WORKER` chunks per process in flight, so memory holds a
        few chunks of results whatever the export's size; otherwise in this process, chunk
        by chunk (one record alive at a time). The results and their order are the same
        either way. Errors (a missing, corrupt or foreign meta file, ``fn``'s) are raised
        here as the record that caused them would raise them in this process: the first
        one in index order, an ExportError or OSError without the worker's traceback. A pool
        process that dies (killed) leaves the rest of the pass, and every later one, to this
        process, with a warning."""
        if split is None:
            idx = range(len(self))
        else:
            idx = [i for i in range(len(self)) if split_of(self.cfg, i) == split]
        return self._map(fn, idx, split)

    def _map(self, fn, indices, split):
        n = len(indices)
        workers = self.pool_size(n)
        size = max(1, min(CHUNK_RECORDS, -(-n // (4 * workers))))
        chunks = (indices[k:k + size] for k in range(0, n, size))
        if workers <= 1:
            return self._map_here(fn, chunks, split)
        return self._map_pool(fn, chunks, split, workers)

    def _map_here(self, fn, chunks, split):
        for idx in chunks:
            yield from self._merge(idx, *_run_chunk(self, fn, split, idx))

    def _merge(self, idx, results, tallies):
        for i, t in zip(idx, tallies):
            if not self._counted[i]:
                self._counted[i] = 1
                self._tally.add(i, t)
        return results

    def _map_pool(self, fn, chunks, split, workers):
        from concurrent.futures import ProcessPoolExecutor
        from concurrent.futures.process import BrokenProcessPool

        check_entry_point()
        pool = ProcessPoolExecutor(workers, mp_context=pool_context(), initializer=_init_worker,
                                   initargs=(self.cfg, str(self.out), os.getpid()))
        pending: deque = deque()
        unsent: list = []  # chunks the pool refused: it broke while they were submitted
        rest = None  # the chunks left when a process dies
        try:
            def submit(k):
                for idx in islice(chunks, k):
                    if not unsent:
                        try:
                            pending.append((idx, pool.submit(_pool_chunk, fn, split, idx)))
                            continue
                        except BrokenProcessPool:  # a process died since the last result
                            pass
                    unsent.append(idx)  # kept in order, after those pending

            submit(WINDOW_PER_WORKER * workers)
            while pending:
                idx, fut = pending.popleft()
                try:
                    res = fut.result()
                except BrokenProcessPool:  # a process died (killed, or a script's main module
                    # that exports again when a worker imports it): the rest here, same bytes
                    rest = chain([idx], [i for i, _ in pending], unsent, chunks)
                    break
                except (AerialSynthError, OSError) as exc:  # one line, as in this process
                    raise exc.with_traceback(None) from None
                submit(1)
                yield from self._merge(idx, *res)
            if rest is None and unsent:  # the pool broke with nothing left pending
                rest = chain(unsent, chunks)
        finally:
            for _, fut in pending:
                fut.cancel()
            pool.shutdown(wait=True, cancel_futures=True)  # no process left behind
        if rest is not None:
            self._pool_broken = True
            _warn_pool_broken()
            yield from self._map_here(fn, rest, split)

    def summary_counts(self) -> _Tally:
        """The summary's counts of every record: those counted while formats read them,
        plus the others, read now (on a pool when they are many, see :meth:`map`)."""
        missing = [i for i in range(len(self)) if not self._counted[i]]
        for _ in self._map(_nothing, missing, None):
            pass
        return self._tally


def _nothing(record) -> None:
    return None


def _run_chunk(records: MetaRecords, fn, split, indices) -> tuple[list, list]:
    """``fn`` of the records ``indices`` and their :func:`_record_tally` (one record alive
    at a time)."""
    results, tallies = [], []
    for i in indices:
        r = records._read(i, split)
        results.append(fn(r))
        tallies.append(_record_tally(r))
        del r
    return results, tallies


_WORKER_RECORDS: MetaRecords | None = None


def _init_worker(cfg: ExportConfig, out: str, parent_pid: int) -> None:
    """Pool initializer: die with the exporter, leave Ctrl-C to it, read ``out``'s records."""
    import signal

    global _WORKER_RECORDS
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    watch_parent(parent_pid)
    _WORKER_RECORDS = MetaRecords(cfg, Path(out), workers=1)


def _pool_chunk(fn, split, indices) -> tuple[list, list]:
    assert _WORKER_RECORDS is not None
    return _run_chunk(_WORKER_RECORDS, fn, split, indices)


def _warn_pool_broken() -> None:
    import warnings

    warnings.warn("aggregate files: a worker process died, the rest is read in this process (a "
                  "script that exports must guard its entry point with if __name__ == '__main__')",
                  RuntimeWarning, stacklevel=3)


def write_aggregates(cfg: ExportConfig, out: Path, georeference: dict | None = None,
                     workers: int | None = None) -> dict:
    """Every format's aggregate files and ``summary.json``; returns the summary. Records are
    read from ``meta/`` as they are needed (:class:`MetaRecords`), each once, on ``workers``
    processes for a large export (default: every allowed core; see :meth:`MetaRecords.map`),
    and a format's file given as chunks is written chunk by chunk, so memory does not grow
    with the export. The bytes do not depend on ``workers``."""
    check_entry_point()
    out = Path(out)
    records = MetaRecords(cfg, out, workers=workers)
    info = dataset_info(cfg)
    for name in cfg.formats:
        for rel, body in get(name).aggregate_files(records, info).items():
            if isinstance(body, str):
                atomic_write_text(out / rel, body)
                continue
            try:
                atomic_write_chunks(out / rel, body)
            finally:  # a failed write stops the body's pool passes now (see MetaRecords.map)
                close = getattr(body, "close", None)
                if close is not None:
                    close()
    summary = summarise(cfg, records, georeference)
    atomic_write_json(out / "summary.json", summary)
    return summary
