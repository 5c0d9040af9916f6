"""Ties the export pool's fork server to the exporter (imported by that server only).

:func:`aerial_synth.dataset.pool.pool_context` lists this module first among the modules
the fork server imports before it forks any worker. The server is the exporter's child and
the workers are the server's, and each worker asks for SIGKILL when its parent dies; the
server itself would only exit once its last worker has. So here, in the server, the same
request is made about the exporter: a killed exporter takes the server with it, which takes
the workers at once, mid-write or not (their temporary files never become the image's).
Linux only (``prctl``); elsewhere the workers' own checks of the exporter apply.
"""

from __future__ import annotations

import os
import sys


def _in_fork_server() -> bool:
    return sys.argv[:1] == ["-c"] and "multiprocessing.forkserver" in sys.modules


def _guard() -> bool:
    if not (_in_fork_server() and hasattr(os, "sched_getaffinity")):
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
