"""Core partitioning: K render processes on one host, each on its own share of the cores.

Why pinning and not only thread counts: open3d's ``RaycastingScene`` runs its queries
(``cast_rays``, ``test_occlusions``) in a TBB ``parallel_for`` whose pool is sized by the
process's CPU affinity, whatever ``nthreads`` the scene was built with. Two unpinned worker
processes on a 2-core host therefore run 2 + 2 ray threads on 2 cores (measured: 0.73-0.77 s
per image each against 0.58 s alone), while two processes pinned to one core each cast
rays 1.85x as fast as one.

So worker ``k`` of ``K`` processes sharing a host takes the cores
``allowed[k * n // K : (k + 1) * n // K]`` of the host's allowed set (``n`` of them,
:func:`partition_cores`), pins itself to them (:func:`pin_share`, every thread of the
process, before open3d/TBB or numba start their pools where possible) and sets numba,
OpenMP and BLAS threads to the size of its share. A single worker keeps every core. Where
the platform has no ``sched_setaffinity`` or refuses it, or ``AERIAL_SYNTH_NO_PIN=1`` is
set, nothing is pinned (the thread counts are still set) and nothing fails.
"""

from __future__ import annotations

import os

__all__ = ["NO_PIN_ENV", "allowed_cores", "partition_cores", "pin_share", "pin_cores", "current_share", "limit_threads"]

_PINNED: tuple | None = None  # (k, K, cores) applied in this process
#: set to 1 to turn pinning off (e.g. on a host shared with other busy processes, where a
#: pinned worker cannot move away from a busy core); thread counts are still shared.
NO_PIN_ENV = "AERIAL_SYNTH_NO_PIN"


def allowed_cores() -> list[int]:
    """The cores this process may run on (sorted), or ``range(cpu_count)`` where the
    platform cannot tell."""
    try:
        return sorted(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return list(range(os.cpu_count() or 1))


def partition_cores(allowed, k: int, K: int) -> list[int]:
    """Worker ``k``'s share (0 <= k < K) of the cores ``allowed`` when ``K`` workers share
    them: the contiguous block ``[k * n // K, (k + 1) * n // K)`` of the sorted cores. The K
    shares are disjoint and cover every core when ``K <= n``; when ``K > n`` each worker
    gets one core, ``allowed[k * n // K]`` (each core then serves ``K / n`` workers, as
    evenly as integers allow)."""
    cores = sorted({int(c) for c in allowed})
    n, K, k = len(cores), int(K), int(k)
    if n == 0:
        raise ValueError("partition_cores: no cores to share")
    if K < 1 or not 0 <= k < K:
        raise ValueError(f"partition_cores: expected 0 <= k < K, got k={k}, K={K}")
    share = cores[k * n // K:(k + 1) * n // K]
    return share or [cores[k * n // K]]


def limit_threads(nthreads: int) -> int:
    """Limit this process's compute threads: numba (the shading kernels; set for the
    calling thread, so call it in the thread that renders), OpenMP (``OMP_NUM_THREADS``
    for libraries that start their OpenMP runtime later) and BLAS pools where
    ``threadpoolctl`` is installed. open3d's ray queries follow the process's affinity
    (:func:`pin_share`), not a thread count. Returns the number applied."""
    n = max(1, int(nthreads))
    os.environ["OMP_NUM_THREADS"] = str(n)
    try:
        import numba

        # lazy: numba, only where threads are set (the threading layer, before numba starts it)
        from ... import numba_setup  # noqa: F401

        numba.set_num_threads(max(1, min(n, numba.config.NUMBA_NUM_THREADS)))
    except ImportError:  # pragma: no cover - numba is a core dependency
        pass
    try:
        from threadpoolctl import threadpool_limits

        threadpool_limits(n)
    except ImportError:
        pass
    return n


def _set_thread_counts(n: int) -> None:
    limit_threads(n)


def pin_cores(cores) -> bool:
    """Pin this process (every thread it has, and so every thread it starts later) to
    ``cores``. False where the platform does not support it or refuses it."""
    cores = {int(c) for c in cores}
    if not hasattr(os, "sched_setaffinity") or not cores:
        return False
    try:
        os.sched_setaffinity(0, cores)  # the calling thread (threads it starts inherit it)
    except (OSError, ValueError):
        return False
    try:  # threads that already run (a Dask worker's event loop and executor, a TBB pool)
        tids = [int(t) for t in os.listdir("/proc/self/task")]
    except OSError:
        tids = []
    for tid in tids:
        try:
            os.sched_setaffinity(tid, cores)
        except (OSError, ValueError):  # the thread ended meanwhile
            pass
    return True


def pin_share(k: int | None, K: int | None, allowed=None) -> list[int] | None:
    """Worker ``k`` of ``K`` on this host: pin to its share of ``allowed`` (default: this
    process's allowed cores) and set numba/OpenMP/BLAS threads to the share's size.
    Returns the share, or None when nothing was pinned (``K <= 1``, ``k`` unknown, or the
    platform refused); the thread counts are set either way once K is known. Calling it
    again with the same (k, K) does nothing."""
    global _PINNED
    if K is None or int(K) <= 1 or k is None or not 0 <= int(k) < int(K):
        return None
    if os.environ.get(NO_PIN_ENV, "").strip() not in ("", "0"):
        _set_thread_counts(max(1, len(allowed_cores() if allowed is None else list(allowed)) // int(K)))
        return None
    if _PINNED is not None and _PINNED[:2] == (int(k), int(K)):
        return list(_PINNED[2])
    base = allowed_cores() if allowed is None else sorted(allowed)
    if _PINNED is not None:  # pinned before for another layout: share the original set
        base = sorted(_PINNED[3])
    share = partition_cores(base, int(k), int(K))
    ok = pin_cores(share)
    _set_thread_counts(len(share) if ok else max(1, len(base) // int(K)))
    if not ok:
        return None
    _PINNED = (int(k), int(K), tuple(share), tuple(base))
    return share


def current_share() -> tuple | None:
    """(k, K, cores) applied by :func:`pin_share` in this process, or None."""
    return None if _PINNED is None else _PINNED[:3]
