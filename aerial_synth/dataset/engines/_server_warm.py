"""Warms numba up in the export pool's fork server (imported by that server only, last).

Every worker's first kernel call used to pay numba's one-time set-up of its compiler
contexts (~0.4 s of CPU: the typing and lowering registries) before loading any cached
kernel. That set-up starts no thread, so the fork server can do it once, before it forks
any worker: each worker inherits warm contexts and only loads its kernels' cache files.
Running a kernel here would not do: a parallel kernel starts GNU OpenMP's threads, and a
process forked from one that has is terminated by libgomp.
"""

from __future__ import annotations

from ._server_guard import in_fork_server


def _warm() -> bool:
    if not in_fork_server():
        return False
    # lazy: numba, in the fork server only (threading layer chosen before anything else)
    from ... import numba_setup  # noqa: F401

    try:
        from numba.core.registry import cpu_target

        cpu_target.typing_context.refresh()
        cpu_target.target_context.refresh()
    except (ImportError, AttributeError):  # pragma: no cover - a numba without these
        return False
    return True


WARM = _warm()
