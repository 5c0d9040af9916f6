"""Export engine on Dask distributed: the same task graph as the local pool, on a cluster.

``aerial-synth export ... --dask tcp://HOST:8786`` runs on an existing cluster (a
``dask scheduler`` and ``dask worker`` processes, see docs/scale.md); ``--dask local:K``
starts a ``LocalCluster`` of K worker processes on the loopback interface.

The task graph is the local one: placement groups, then images, split at **image
granularity** (:func:`plan_tasks`): each task is a contiguous run of images of one
placement group, and a group is cut into as many runs as needed to give every worker work
(a small export uses every worker). A worker that needs a group's placement recomputes it
deterministically from ``SeedSequence([seed, group, 1])`` (and keeps it for the next run of
the same group), so the bytes of every image depend only on (parameters, index): the
output is byte-identical to ``--workers 1`` whatever the engine or the number of workers,
and ``--resume`` works whichever engine wrote the first part.

Workers write into the output folder themselves, with the same atomic writes as the local
pool; on a multi-machine cluster that folder must be on a filesystem every worker sees at
the same path. A worker that dies mid-image loses nothing: its temporary files never
become the image's files, the scheduler gives its task to another worker, and the
stray temporaries are removed before the aggregates are written. The scene the client
scatters to the workers can die with them (Dask's memory manager keeps a single replica
once no waiting task needs more); the scheduler then cancels the tasks that read it and
the engine submits them again without it (:data:`MAX_RESUBMITS`), each worker loading the
scene itself.

Cores: the K worker processes of one host (numbered by address, :func:`host_slots`) each
pin themselves to their own share of the host's cores before their first ray cast
(:mod:`.affinity`; open3d's ray queries use every core the process may run on, whatever
thread count they are given) and set numba and OpenMP threads to the share's size, so K
processes do not oversubscribe the cores. A worker whose slot is unknown (one that joined
after the export started) is not pinned and uses ``cores // processes on its host``
threads (:func:`threads_per_worker`).
"""

from __future__ import annotations

import os
import re
import time
from collections.abc import Iterator
from concurrent.futures import CancelledError
from pathlib import Path

from ...errors import ExportError
from ...formats.registry import BUILTIN, get, names, register
from ...io_utils import atomic_write_text
from ...render.budget import frame_gb
from ..output import remove_stray_temps
from ..worker import ImageWorker
from .affinity import limit_threads, pin_share
from .base import Engine, plan_tasks
from .fork_server import FORK_SERVER_PRELOAD, start_pool_server

__all__ = ["ENGINE", "DaskEngine", "DaskCluster", "plan_tasks", "threads_per_worker", "limit_threads",
           "parse_dask_address", "probe_scheduler", "host_slots", "worker_slot", "LocalStart",
           "LOCAL_CLUSTER_CONFIG", "FORK_SERVER_PRELOAD"]

#: An unreachable scheduler is reported within this many seconds (the CLI promises 10).
CONNECT_TIMEOUT_S = 6.0
#: How often one task is submitted again after the scheduler cancelled it (lost input data)
MAX_RESUBMITS = 3
#: How long an export waits for a scheduler without workers to get one
WORKER_WAIT_S = 30.0
#: Dask settings of a ``--dask local:K`` cluster (the engine's own; an external cluster keeps
#: its configuration). Dask's defaults wake each worker's event loop every 10 ms to sample
#: the task thread's stack (a profile nobody reads: there is no dashboard) and every 20 ms
#: to time the loop, and the nannies poll each worker's memory every 100 ms. On a worker
#: pinned to one core every wake-up takes the core (and the GIL) from the render thread,
#: and the scheduler's and nannies' loops run in the exporter, on the workers' cores:
#: measured with two busy pinned workers, 0.3 s of event-loop CPU per worker and 0.35 s in
#: the exporter per 8 s (~4 % + 2 % of the cores) with the defaults, 0.03 s and 0.05 s with
#: these.
LOCAL_CLUSTER_CONFIG = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "5s",
    "distributed.worker.memory.monitor-interval": "500ms",
}
_LOCAL = re.compile(r"^local:(\d+)$")
_TCP = re.compile(r"^(tcp|tls)://[^\s/:]+(:\d+)?$")


# ------------------------------------------------------------------ helpers


def threads_per_worker(workers_on_host: int, ncpu: int | None = None) -> int:
    """Threads per worker process so that ``workers_on_host`` processes share the cores."""
    ncpu = ncpu or os.cpu_count() or 1
    return max(1, int(ncpu) // max(1, int(workers_on_host)))


def parse_dask_address(text: str) -> tuple[str, object]:
    """``("local", K)`` or ``("tcp", "tcp://host:port")``; one-line ExportError otherwise."""
    s = str(text).strip()
    m = _LOCAL.match(s)
    if m:
        k = int(m.group(1))
        if not 1 <= k <= 256:
            raise ExportError(f"--dask: expected local:K with K in 1..256 worker processes, got {text!r}")
        return "local", k
    if _TCP.match(s):
        return "tcp", s if re.search(r":\d+$", s) else s + ":8786"
    raise ExportError(f"--dask: expected tcp://HOST:PORT (a running dask scheduler) or local:K, got {text!r}")


def probe_scheduler(spec: str, timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """Check ``--dask`` before any slow work: the address parses, Dask is installed, and a
    ``tcp://`` scheduler accepts a TCP connection within ``timeout_s``. One-line
    ExportError otherwise (the export then writes nothing)."""
    import importlib.util
    import socket

    kind, arg = parse_dask_address(spec)
    if importlib.util.find_spec("distributed") is None:  # not imported here: ~0.4 s (see LocalStart)
        raise ExportError("--dask: needs Dask distributed; install it with pip install 'aerial-synth[dask]'")
    if kind != "tcp":
        return
    host, port = str(arg).split("://", 1)[1].rsplit(":", 1)
    t0 = time.perf_counter()
    try:
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except OSError as exc:
        raise ExportError(
            f"--dask {arg}: cannot reach a Dask scheduler there ({exc.strerror or type(exc).__name__} "
            f"after {time.perf_counter() - t0:.1f} s); start one with 'dask scheduler' or check the address"
        ) from None


def _cancel_reason(exc: BaseException) -> str:
    """The scheduler's reason for a cancelled future, as one short phrase."""
    reason = getattr(exc, "reason", None)
    return f"reason: {reason}" if reason else (str(exc).splitlines() or ["no reason given"])[0]


# ------------------------------------------------------------------ worker side

_STATE: dict = {}


def _render_run(cfg, out: str, indices: list[int], nthreads_by_worker: dict, extra_formats=(),
                slots: dict | None = None, scene=None, catalog=None) -> list:
    """Dask task: render a run of images of one placement group (in order); returns once
    their files are on disk (so a finished task never loses an image to a dead worker)."""
    from distributed import get_worker

    for fmt in extra_formats:  # formats registered at run time in the client
        if fmt.name not in names():
            register(fmt)
    me = get_worker()
    n = int(nthreads_by_worker.get(me.address, 1))
    slot = worker_slot(slots or {}, me.address, me.name)
    share = pin_share(*slot) if slot else None  # before this process's first ray cast
    if share is not None:
        n = len(share)
    limit_threads(n)  # numba's thread count is per calling thread: set it in this one
    key = (cfg, out, n)
    w = _STATE.get(key)
    if w is None:
        for old in _STATE.values():
            old.close()
        _STATE.clear()
        w = _STATE[key] = ImageWorker.for_config(cfg, Path(out), nthreads=n, scene=scene, catalog=catalog)
    return w.render_run(indices)


def host_slots(workers: dict) -> dict:
    """Core shares for the workers of a cluster: ``workers`` is the scheduler's
    ``{address: {"host": ..., "name": ...}}``; returns ``{"address": {address: (k, K)},
    "name": {name: (k, K)}}`` where the K worker processes of one host are numbered
    0..K-1 in address order (host, port). A worker the nanny restarted keeps its name but
    not its address, so it finds its slot by name (names unique across the cluster only)."""
    by_host: dict = {}
    for addr, info in workers.items():
        host = (info or {}).get("host") or addr.rsplit(":", 1)[0]
        by_host.setdefault(host, []).append(addr)

    def port(a):
        tail = a.rsplit(":", 1)[-1]
        return (0, int(tail), a) if tail.isdigit() else (1, 0, a)

    by_addr, by_name, seen = {}, {}, {}
    for addrs in by_host.values():
        addrs.sort(key=port)
        for k, a in enumerate(addrs):
            by_addr[a] = (k, len(addrs))
            name = (workers[a] or {}).get("name")
            if name is not None:
                seen[name] = seen.get(name, 0) + 1
                by_name[name] = (k, len(addrs))
    by_name = {nm: sl for nm, sl in by_name.items() if seen[nm] == 1}
    return {"address": by_addr, "name": by_name}


def worker_slot(slots: dict, address: str, name=None) -> tuple | None:
    """This worker's (k, K) from :func:`host_slots`, or None when unknown (no pinning)."""
    sl = (slots.get("address") or {}).get(address)
    if sl is None and name is not None:
        sl = (slots.get("name") or {}).get(name)
    return None if sl is None else (int(sl[0]), int(sl[1]))


def _cpu_count() -> int:
    return os.cpu_count() or 1


def _sees(path: str, token: str) -> str:
    """Worker side of :meth:`DaskCluster.check_output`: "ok" when this process reads ``token``
    in the file ``path`` (the client's probe in the output folder) and can write a file
    beside it, else "cannot read" or "cannot write"."""
    try:
        if Path(path).read_text(encoding="utf-8") != token:  # guard: its own token file
            return "cannot read"
    except (OSError, UnicodeDecodeError):
        return "cannot read"
    mine = Path(f"{path}.{os.getpid()}.tmp")
    try:
        mine.write_text(token, encoding="utf-8")  # guard: a token file of its own in the build
        mine.unlink()
    except OSError:
        return "cannot write"
    return "ok"


# ------------------------------------------------------------------ client side


class DaskCluster:
    """A connection to a Dask cluster (or a LocalCluster it owns). Use as a context manager
    or call :meth:`close`."""

    def __init__(self, client, cluster=None, address: str = ""):
        self.client = client
        self.cluster = cluster
        self.address = address

    @classmethod
    def connect(cls, spec: str, timeout_s: float = CONNECT_TIMEOUT_S) -> "DaskCluster":
        """``spec``: ``tcp://HOST:PORT`` or ``local:K``. An unreachable scheduler raises a
        one-line ExportError within ``timeout_s`` (plus the import of distributed)."""
        kind, arg = parse_dask_address(spec)
        try:
            import logging

            from distributed import Client, LocalCluster
        except ImportError:
            raise ExportError("--dask: needs Dask distributed; install it with pip install 'aerial-synth[dask]'") from None
        if kind == "local":
            import dask

            k = int(arg)
            nthreads = threads_per_worker(k)
            try:
                # MALLOC_TRIM_THRESHOLD_ (Dask's default) turns off glibc's adaptive mmap
                # threshold: every large frame buffer then costs fresh page faults (~40 % per
                # image measured); unset it for our workers.
                # Worker processes fork from the export's fork server where there is one
                # (pool.pool_context: open3d, numba, the renderer and Dask already
                # imported); they then take the server's environment, which has no
                # MALLOC_TRIM_THRESHOLD_, and set their thread counts when pinned.
                import multiprocessing as mp

                method = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
                with dask.config.set({"distributed.nanny.pre-spawn-environ.OMP_NUM_THREADS": str(nthreads),
                                      "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
                                      "distributed.worker.multiprocessing-method": method,
                                      **LOCAL_CLUSTER_CONFIG}):
                    # memory_limit=0: no per-worker limit. Dask's default splits the memory
                    # evenly and has the nanny kill a worker above 95 % of its share: with 8
                    # workers on 24 GB, one 8192 px frame (7.5 GB) was killed 4 times over
                    # although it fits. The export checks instead that one frame per worker
                    # fits in the memory available (render.budget.check_frame_memory).
                    cluster = LocalCluster(n_workers=k, threads_per_worker=1, processes=True,
                                           host="127.0.0.1", dashboard_address=None,
                                           silence_logs=logging.ERROR, memory_limit=0)
            except Exception as exc:  # e.g. a script without an ``if __name__ == "__main__"`` guard
                raise ExportError(
                    f"--dask {spec}: the LocalCluster's worker processes did not start ({type(exc).__name__}: "
                    f"{' '.join(str(exc).split())[:200]}); a script that exports must guard its entry point "
                    "with if __name__ == '__main__'"
                ) from None
            try:
                client = Client(cluster, timeout=f"{max(timeout_s, 30.0)}s")
                client.wait_for_workers(k, timeout=120)
            except Exception:
                cluster.close()
                raise
            return cls(client, cluster, cluster.scheduler_address)
        t0 = time.perf_counter()
        try:
            client = Client(str(arg), timeout=f"{timeout_s}s")
        except (OSError, TimeoutError) as exc:
            raise ExportError(
                f"--dask {arg}: cannot reach a Dask scheduler there ({type(exc).__name__} after "
                f"{time.perf_counter() - t0:.1f} s); start one with 'dask scheduler' or check the address"
            ) from None
        except Exception as exc:  # something else answers there (a web server, another protocol)
            raise ExportError(
                f"--dask {arg}: the service at that address does not speak Dask's protocol "
                f"({type(exc).__name__}); give the scheduler's address (port 8786 by default)"
            ) from None
        return cls(client, None, str(arg))

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self) -> None:
        try:
            self.client.close()
        finally:
            if self.cluster is not None:
                self.cluster.close()

    def worker_threads(self) -> dict:
        """{worker address: threads}: each host's cores shared by its worker processes."""
        ncpu = self.client.run(_cpu_count)
        hosts: dict[str, int] = {}
        for addr in ncpu:
            h = addr.rsplit(":", 1)[0]
            hosts[h] = hosts.get(h, 0) + 1
        return {addr: threads_per_worker(hosts[addr.rsplit(":", 1)[0]], n) for addr, n in ncpu.items()}

    def _scatter(self, scene, catalog) -> tuple:
        if scene is None:
            return None, None
        try:
            return tuple(self.client.scatter([scene, catalog], broadcast=True, hash=False))
        except Exception:  # workers then load the scene themselves
            return None, None

    def n_workers(self) -> int:
        return len(self.client.scheduler_info(n_workers=-1).get("workers", {}))

    def wait_for_workers(self, timeout_s: float | None = None) -> None:
        """Return once the cluster has a worker; one-line ExportError after ``timeout_s``
        (default :data:`WORKER_WAIT_S`; a scheduler without workers would leave the export
        waiting for ever)."""
        if self.n_workers():
            return
        timeout_s = WORKER_WAIT_S if timeout_s is None else float(timeout_s)
        try:
            self.client.wait_for_workers(1, timeout=timeout_s)
        except Exception:  # distributed raises TimeoutError (older: asyncio's)
            raise ExportError(
                f"--dask {self.address}: the scheduler has no workers (waited {timeout_s:g} s); "
                f"start some with 'dask worker {self.address}' (docs/scale.md)"
            ) from None

    def check_output(self, build: Path) -> None:
        """Every worker must write into the client's output folder at the same path (a
        filesystem they share): one that does not see it would write the images onto its
        own disk, where the export never finds them. The client writes a probe file there
        and each worker reads it back and writes a file beside it; one-line ExportError naming
        the workers that cannot."""
        token = f"{os.getpid()}-{time.time_ns()}"
        probe = Path(build) / f".aerial-synth-probe-{token}.tmp"  # a stray temp if killed here
        atomic_write_text(probe, token)
        try:
            seen = self.client.run(_sees, str(probe), token)
        finally:
            probe.unlink(missing_ok=True)
        bad = sorted((a, why) for a, why in seen.items() if why != "ok")
        if bad:
            more = f" and {len(bad) - 3} more" if len(bad) > 3 else ""
            who = ", ".join(f"{a} ({why})" for a, why in bad[:3])
            raise ExportError(
                f"--dask {self.address}: worker(s) {who}{more}: every worker must read and write the "
                f"export's files under {Path(build).parent} at that path, on a shared filesystem "
                "(docs/scale.md)"
            )

    def run(self, cfg, build, indices, bar=None, scene=None, catalog=None) -> int:
        """Render ``indices`` of the export ``cfg`` into ``build``; returns images finished.
        Progress: ``bar.update(n)`` per finished task (a tqdm bar or anything alike)."""
        done = 0
        for n in self.iter_run(cfg, build, self.plan(cfg, build, indices), scene, catalog):
            done += n
            if bar is not None:
                bar.update(n)
        return done

    def plan(self, cfg, build, indices) -> list[list[int]]:
        """Wait for a worker, check that they all see ``build``, then cut ``indices`` into
        about two tasks per worker (:func:`plan_tasks`)."""
        indices = list(indices)
        if not indices:
            return []
        self.wait_for_workers()
        self.check_output(Path(build))
        return plan_tasks(indices, cfg.images_per_placement, max(1, self.n_workers()))

    def iter_run(self, cfg, build, tasks, scene=None, catalog=None) -> Iterator[int]:
        """Render ``tasks`` of the export ``cfg`` into ``build``; yields images finished per
        task. ``scene``/``catalog``: the client's loaded objects, scattered once to every
        worker (instead of every worker loading the scene again); None = each worker loads
        them."""
        from distributed import KilledWorker, as_completed

        if not tasks:
            return
        indices = [i for t in tasks for i in t]
        threads = self.worker_threads()
        slots = host_slots(self.client.scheduler_info(n_workers=-1).get("workers", {}))
        extra = [get(n) for n in cfg.formats if n not in BUILTIN]
        out = str(Path(build).resolve())  # guard: the build folder it made
        token = f"{os.getpid()}-{time.time_ns()}"
        shared = self._scatter(scene, catalog)

        def submit(t, attempt, data):
            key = f"aerial-synth-image-{t[0]:06d}-{t[-1]:06d}-{token}" + (f"-r{attempt}" if attempt else "")
            return self.client.submit(_render_run, cfg, out, t, threads, extra, slots, *data, key=key,
                                      pure=False)

        futures = [submit(t, 0, shared) for t in tasks]
        task_of = {f.key: (t, 0) for f, t in zip(futures, tasks)}
        try:
            pending = as_completed(futures)
            for fut in pending:
                try:
                    res = fut.result()
                except CancelledError as exc:
                    # The scheduler cancels a task whose input it lost: the scattered scene
                    # when every worker holding a replica died (its memory manager drops
                    # replicas no waiting task needs, so one worker may hold the only one).
                    # Run it again without the scattered data: the worker loads the scene.
                    t, attempt = task_of.pop(fut.key)
                    if attempt >= MAX_RESUBMITS:
                        raise ExportError(
                            f"--dask: the scheduler cancelled the task of images {t[0]}..{t[-1]} "
                            f"{attempt + 1} times ({_cancel_reason(exc)}); rerun with --resume"
                        ) from None
                    new = submit(t, attempt + 1, (None, None))
                    task_of[new.key] = (t, attempt + 1)
                    futures.append(new)
                    pending.add(new)
                    continue
                yield len(res)
        except KilledWorker as exc:  # the scheduler gave up on a task after its workers died
            for f in futures:
                f.cancel()
            t = task_of.get(getattr(exc, "task", None), (indices, 0))[0]
            raise ExportError(
                f"--dask: every worker that ran images {t[0]}..{t[-1]} died (out of memory? one "
                f"{cfg.camera.width_px} x {cfg.camera.height_px} px frame needs about "
                f"{frame_gb(cfg.camera.width_px, cfg.camera.height_px):.1f} GB); the images done are kept: rerun with --resume"
            ) from None
        except Exception:
            for f in futures:
                f.cancel()
            raise
        remove_stray_temps(Path(build))  # temporaries of a worker that died mid-image


class LocalStart:
    """A ``--dask local:K`` cluster starting in a background thread, so that its start (the
    import of Dask, the scheduler, the nannies, the workers forked from the export's fork
    server) runs while the exporter loads and checks the scene instead of after it. For
    any other ``spec`` (None, ``tcp://...``) nothing starts and :meth:`engine` is None.

    :meth:`engine` waits for it and hands over the :class:`DaskCluster` (or raises the
    start's one-line ExportError); :meth:`close` waits for it and closes a cluster not
    handed over (the export calls it on every way out, so no cluster outlives a failed
    export). Usable as a context manager that closes it."""

    def __init__(self, spec: str | None):
        import threading

        self.spec = spec
        self._engine: DaskCluster | None = None
        self._error: BaseException | None = None
        self._closed = False
        self._thread = None
        if spec is not None and parse_dask_address(spec)[0] == "local":
            self._thread = threading.Thread(target=self._start, name="aerial-synth-dask-start", daemon=True)
            self._thread.start()

    def _start(self) -> None:
        try:
            self._engine = DaskCluster.connect(self.spec)
        except BaseException as exc:  # raised in the exporting thread by engine()
            self._error = exc

    def engine(self) -> DaskCluster | None:
        """Wait for the start; the engine is then the caller's to close."""
        if self._thread is None:
            return None
        self._thread.join()
        if self._error is not None:
            err, self._error = self._error, None
            raise err
        if self._engine is None or self._closed:
            raise ExportError(f"--dask {self.spec}: the LocalCluster was closed")
        eng, self._engine = self._engine, None
        return eng

    def close(self) -> None:
        """Wait for the start, then close the cluster (idempotent)."""
        if self._thread is not None:
            self._thread.join()
        self._closed = True
        eng, self._engine = self._engine, None
        if eng is not None:
            eng.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class DaskEngine(Engine):
    """``--dask tcp://HOST:PORT`` (a running cluster) or ``--dask local:K`` (a LocalCluster
    started in the background while the scene loads, its workers forked from the export's
    fork server)."""

    name = "dask"

    def __init__(self, workers: int | None = None, address: str | None = None):
        super().__init__(workers, address)
        self._kind = parse_dask_address(address)[0] if address is not None else None
        self._starting: LocalStart | None = None
        self._cluster: DaskCluster | None = None

    def check(self) -> None:
        probe_scheduler(self.address)  # a bad or unreachable --dask, before the slow checks

    @property
    def local_processes(self) -> int | None:
        kind, arg = parse_dask_address(self.address)
        return int(arg) if kind == "local" else None  # a tcp:// cluster's workers run elsewhere

    def warm_up(self) -> bool:
        if self._kind != "local":
            return False
        start_pool_server(dask=True)  # the LocalCluster's workers fork from it too
        return True

    def start(self) -> None:
        self._starting = LocalStart(self.address)  # --dask local:K: starts while the scene loads

    def connect(self) -> None:
        cluster = self._starting.engine() if self._starting is not None else None
        self._cluster = cluster if cluster is not None else DaskCluster.connect(self.address)

    def plan(self, indices) -> list[list[int]]:
        return self._cluster.plan(self.cfg, self.build, indices)

    def run(self, tasks) -> Iterator[int]:
        yield from self._cluster.iter_run(self.cfg, self.build, tasks, self.scene, self.catalog)

    def close(self) -> None:
        cluster, self._cluster = self._cluster, None
        starting, self._starting = self._starting, None
        try:
            if cluster is not None:
                cluster.close()
        finally:
            if starting is not None:
                starting.close()


ENGINE = DaskEngine
