"""Ties the export pool's fork server to the exporter (imported by that server only).

:func:`aerial_synth.dataset.engines.fork_server.pool_context` lists this module first among the modules
the fork server imports before it forks any worker. The server is the exporter's child and
the workers are the server's, and each worker asks for SIGKILL when its parent dies; the
server itself would only exit once its last worker has. So here, in the server, the same
request is made about the exporter: a killed exporter takes the server with it, which takes
the workers at once, mid-write or not (their temporary files never become the image's).
Linux only (``prctl``); elsewhere the workers' own checks of the exporter apply.

It also makes a worker forked from the server leave quietly (:func:`_quiet_main_fixup`)
when it would run an unguarded script's export again.
"""

from __future__ import annotations

import os
import sys

from ...errors import EntryPointError


def in_fork_server() -> bool:
    return sys.argv[:1] == ["-c"] and "multiprocessing.forkserver" in sys.modules


def _guard() -> bool:
    if not (in_fork_server() and hasattr(os, "sched_getaffinity")):
        return False
    try:
        import ctypes
        import signal

        libc = ctypes.CDLL(None, use_errno=True)
        PR_SET_PDEATHSIG = 1
        if libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) != 0:
            return False
    except (OSError, AttributeError):
        return False
    if os.getppid() == 1:  # the exporter died before the request took effect
        os._exit(0)
    return True


GUARDED = _guard()

#: exit status of a worker that stopped in :func:`.pool.check_entry_point`
ENTRY_POINT_EXIT = 3


def _quiet_main_fixup() -> bool:
    """Workers forked from this server run the parent's main module first (multiprocessing's
    ``spawn.prepare``). A script without an ``if __name__ == '__main__'`` guard exports
    again there and :func:`.pool.check_entry_point` stops it: the worker then exits with
    :data:`ENTRY_POINT_EXIT` instead of printing a traceback, and its parent reports the
    missing guard in one line."""
    if not in_fork_server():
        return False
    import multiprocessing.spawn as spawn

    def quiet(fixup):
        def run(*args, **kwargs):
            try:
                return fixup(*args, **kwargs)
            except EntryPointError:
                sys.stderr.flush()
                os._exit(ENTRY_POINT_EXIT)
        return run

    done = False
    for name in ("_fixup_main_from_path", "_fixup_main_from_name"):
        fixup = getattr(spawn, name, None)
        if callable(fixup):
            setattr(spawn, name, quiet(fixup))
            done = True
    return done


QUIET_MAIN = _quiet_main_fixup()
