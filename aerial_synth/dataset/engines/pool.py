"""The process-pool engine: ``--workers K`` processes forked from the export's fork server
(:func:`~aerial_synth.dataset.engines.fork_server.pool_context`), each with its share of the cores.

Worker k of the pool pins itself to the k-th share of the cores (:func:`init_pool_worker`).
An untiled export hands its loaded scene and catalog to the workers (pickled: milliseconds,
against seconds to load the scene again in every worker); a tiled one lets each worker
build its own tiles. One task only (a one-group export) runs in this process, as the serial
engine does.

A worker that dies (SIGKILL from the OOM killer, a crash) breaks the pool: the tasks not
yet returned are run again on a new pool, less the images already on disk (an image's bytes
do not depend on who renders it), up to :data:`MAX_POOL_RESTARTS` times; then one
ExportError. (``multiprocessing.Pool``, used before, waited forever for the task of a
killed worker.)
"""

from __future__ import annotations

import os
import signal
import time
import warnings
from collections.abc import Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from ...errors import ExportError
from ...formats.registry import BUILTIN, get, names, register
from ...render.budget import frame_gb
from ...scene.model import Scene
from ..config import ExportConfig
from ..layout import is_done
from ..output import remove_stray_temps
from ..worker import ImageWorker
from ._server_guard import ENTRY_POINT_EXIT
from .affinity import allowed_cores, limit_threads, pin_share
from .fork_server import pool_context, start_pool_server
from .parent import watch_parent
from .serial import SerialEngine

__all__ = ["ENGINE", "PoolEngine", "MAX_POOL_RESTARTS", "init_pool_worker", "run_group", "shareable"]

#: How often the local pool is started again after one of its workers died (killed by the
#: OOM killer, say) before the export gives up, as Dask gives up on a task after 3 deaths.
MAX_POOL_RESTARTS = 3


class PoolEngine(SerialEngine):
    name = "pool"

    def warm_up(self) -> bool:
        start_pool_server()  # imports the workers' modules while the scene loads here
        return True

    def run(self, tasks) -> Iterator[int]:
        if len(tasks) <= 1:  # nothing to share out: this process renders it
            yield from super().run(tasks)
            return
        cfg, build, workers = self.cfg, self.build, self.workers
        extra = [get(n) for n in cfg.formats if n not in BUILTIN]  # run-time formats travel along
        ctx = pool_context()
        shared = shareable(cfg, self.scene, self.catalog)
        remaining = [list(t) for t in tasks]
        restarts = 0
        while remaining:
            size = min(int(workers), len(remaining))
            nthreads = max(1, len(allowed_cores()) // size)
            slots = ctx.Value("i", 0)  # worker k of the pool takes the k-th share of the cores
            pool = ProcessPoolExecutor(size, mp_context=ctx, initializer=init_pool_worker,
                                       initargs=(cfg, str(build), nthreads, os.getpid(), extra, slots, size,
                                                 *shared))
            broken = None
            pending = {}
            try:
                try:
                    for t in remaining:  # (the pool starts its processes here)
                        pending[pool.submit(run_group, t)] = t
                except BrokenProcessPool as exc:  # a worker died while the tasks were handed out
                    broken = exc
                except (BrokenPipeError, EOFError) as exc:  # a child died while it was starting
                    raise _not_started(workers, f" ({type(exc).__name__})") from None
                while pending:
                    finished, _ = wait(pending, return_when=FIRST_COMPLETED)
                    for fut in finished:
                        t = pending.pop(fut)
                        try:
                            res = fut.result()
                        except BrokenProcessPool as exc:
                            broken = exc
                            continue
                        remaining.remove(t)
                        yield len(res)
                    if broken is not None:
                        break
            except BaseException:
                _stop_pool(pool)  # Ctrl-C, an error in a task: the workers stop now
                raise
            if broken is None:
                pool.shutdown(wait=True)  # workers exit normally (their exit handlers run)
                break
            codes = _stop_pool(pool, kill_stuck=True)
            if ENTRY_POINT_EXIT in codes:  # a worker ran an unguarded script again and stopped
                raise _not_started(workers)
            restarts += 1
            remove_stray_temps(build)  # the dead worker's temporaries
            before = sum(len(t) for t in remaining)
            remaining = [r for r in ([i for i in t if not is_done(cfg, build, i)] for t in remaining) if r]
            yield before - sum(len(t) for t in remaining)  # finished before the pool broke
            how = _death(codes)
            if restarts > MAX_POOL_RESTARTS:
                raise ExportError(
                    f"--workers {workers}: a worker process died {restarts} times ({how}; out of memory? one "
                    f"{cfg.camera.width_px} x {cfg.camera.height_px} px frame needs about "
                    f"{frame_gb(cfg.camera.width_px, cfg.camera.height_px):.1f} GB per "
                    "worker); the images done are kept: rerun with --resume, with fewer workers or smaller "
                    "images"
                )
            if remaining:
                warnings.warn(f"a worker process died ({how}); its pool's {sum(len(t) for t in remaining)} "
                              f"unfinished images (the first: image {remaining[0][0]}) are rendered again on a "
                              f"new pool (restart {restarts} of at most {MAX_POOL_RESTARTS})", RuntimeWarning,
                              stacklevel=2)


def shareable(cfg: ExportConfig, scene, catalog) -> tuple:
    """(scene, catalog) to hand to the workers of an untiled export, else (None, None)."""
    if getattr(cfg, "tile_m", None) is not None or scene is None:
        return None, None
    return (scene, catalog) if isinstance(scene, Scene) else (None, None)


def _not_started(workers, why: str = "") -> ExportError:
    return ExportError(f"--workers {workers}: the worker processes did not start{why}; a script that "
                       "exports must guard its entry point with if __name__ == '__main__'")


def _stop_pool(pool, kill_stuck: bool = False) -> list:
    """Stop a ProcessPoolExecutor's workers now: cancel what has not started, terminate the
    workers (SIGTERM: they exit normally, see :func:`init_pool_worker`), reap them;
    returns their exit codes (None: unknown). Python 3.14 has ``terminate_workers()``;
    before it the processes are only in the executor's ``_processes`` (which ``shutdown``
    drops, and which a broken pool keeps: the first death's code is there, the others
    were terminated by the pool). Exit codes are read only once the pool's manager thread
    has ended: a fork-server process's code can be read once, and a second reader at the
    same time gets 255."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    for p in procs:
        try:
            p.terminate()  # sends SIGTERM unless the code is known (does not read it)
        except (OSError, AttributeError, ValueError):
            pass
    # after a worker died, the others may never end on SIGTERM (see _kill_stuck); on Ctrl-C
    # they end on their own, only later than a grace could promise, and a kill would leave
    # numba's semaphores to the resource tracker's warning
    killed = _kill_stuck(procs) if kill_stuck else set()
    pool.shutdown(wait=True, cancel_futures=True)
    codes = []
    for p in procs:
        try:
            p.join(timeout=5)
            # a worker killed here had been told to stop: its SIGKILL is not a cause of death
            codes.append(-signal.SIGTERM if p.pid in killed else p.exitcode)
        except (OSError, AttributeError, ValueError, AssertionError):
            codes.append(None)
    return codes


#: seconds a worker of a broken pool has to end after SIGTERM before it is killed
STOP_GRACE_S = 5.0


def _running(pid) -> bool:
    """Whether process ``pid`` still runs (not gone, not a zombie), read from /proc without
    reaping it (a fork-server child's exit code can be read once: the pool reads it)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as fh:  # guard: /proc
            return fh.read().rsplit(b")", 1)[1].split()[0] not in (b"Z", b"X")
    except (OSError, IndexError):
        return False


def _kill_stuck(procs) -> set:
    """SIGKILL the workers still running :data:`STOP_GRACE_S` after their SIGTERM; returns
    their pids. A worker can ignore SIGTERM for good: one killed while it held the result
    queue's lock leaves the others blocked on that lock, and concurrent.futures catches the
    SystemExit of their SIGTERM handler and tries the same put again; the pool's shutdown then
    waited for them forever (seen in a clean-clone run of the pool-death test)."""
    pids = [p.pid for p in procs if getattr(p, "pid", None)]
    if not os.path.isdir("/proc"):
        return set()
    deadline = time.monotonic() + STOP_GRACE_S
    while time.monotonic() < deadline and any(_running(pid) for pid in pids):
        time.sleep(0.02)
    killed = set()
    for pid in pids:
        if _running(pid):
            try:
                os.kill(pid, signal.SIGKILL)
                killed.add(pid)
            except OSError:
                pass
    return killed


def _death(codes) -> str:
    """How the first dead worker of a broken pool ended, in words."""
    for c in codes:
        if c is not None and c < 0 and -c != signal.SIGTERM:
            try:
                return f"killed by {signal.Signals(-c).name}"
            except ValueError:
                return f"killed by signal {-c}"
    for c in codes:
        if c not in (None, 0, 128 + signal.SIGTERM, -signal.SIGTERM):
            return f"exit status {c}"
    return "ended abruptly"


# ---------------------------------------------------------------- the pool workers' side

_POOL_WORKER: ImageWorker | None = None
_STOPPING = False  # SIGTERM came: no further task starts
_SIGTERM_EXIT = 128 + 15  # the shell's status of a process ended by SIGTERM (15 on every POSIX)


def _exit_on_sigterm(signum, frame):
    global _STOPPING
    _STOPPING = True
    raise SystemExit(128 + signum)


def init_pool_worker(cfg: ExportConfig, out: str, nthreads: int, parent_pid: int,
                     extra_formats=(), slots=None, pool_size: int = 0, scene=None, catalog=None) -> None:
    """Pool initializer: watch the parent, share the cores, register run-time formats.

    Cores: the ``pool_size`` workers of the pool take the slots 0, 1, ... of the shared
    counter ``slots`` (a ``multiprocessing.Value``) in start order, and worker ``k`` pins
    itself to its share of the cores (:func:`..affinity.pin_share`) before open3d or numba
    start a thread; its numba/OpenMP threads follow the share. Without a counter (or where
    pinning is refused) it only sets ``nthreads`` threads.

    ``scene``/``catalog``: the parent's (already loaded and validated) objects, pickled
    to the worker in a few milliseconds instead of loading the scene again (seconds).

    Ctrl-C is the parent's to handle (it stops the pool): workers ignore SIGINT, so an
    interrupted export prints no worker tracebacks. The pool then stops its workers with
    SIGTERM, which a worker turns into a normal exit: its exit handlers release what it
    registered with multiprocessing's resource tracker (numba's lock of its threading
    layer), which would otherwise report leaked semaphores after "interrupted". A
    ``ProcessPoolExecutor`` worker catches the SystemExit of its task and reads the next
    one from its queue: :func:`run_group` then ends at once, so the few tasks queued
    ahead do not run after Ctrl-C."""
    global _POOL_WORKER
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _exit_on_sigterm)
    watch_parent(parent_pid)
    share = None
    if slots is not None and int(pool_size) > 1:
        with slots.get_lock():
            k = slots.value
            slots.value += 1
        share = pin_share(k % int(pool_size), int(pool_size))
    if share is None:
        limit_threads(nthreads)
    else:
        nthreads = len(share)
    for fmt in extra_formats:  # formats registered at run time in the parent
        if fmt.name not in names():
            register(fmt)
    _POOL_WORKER = ImageWorker.for_config(cfg, Path(out), nthreads=nthreads, scene=scene, catalog=catalog)


def run_group(indices: list[int]) -> list[tuple[int, dict]]:
    """Pool task: the images of one run of a placement group, in order; returns once every
    one of their files is on disk."""
    assert _POOL_WORKER is not None
    if _STOPPING:
        raise SystemExit(_SIGTERM_EXIT)
    return _POOL_WORKER.render_run(indices)


ENGINE = PoolEngine
