"""Worker processes die with the exporter that started them.

Pool workers (the image pool, the aggregate files' readers) call :func:`watch_parent` once:
on Linux they ask the kernel to kill them when the parent dies
(``prctl(PR_SET_PDEATHSIG, SIGKILL)``), and everywhere :func:`check_parent` is called
between images and before every file they write; an orphaned worker exits at once,
quietly, without writing.
"""

from __future__ import annotations

import ctypes
import os
import signal

__all__ = ["watch_parent", "check_parent", "alive"]

_PARENT_PID: int | None = None  # this process's parent when the watch started
_EXPORTER_PID: int | None = None  # the exporting process (the parent, or its fork server's parent)


def watch_parent(parent_pid: int) -> None:
    """Die with the exporter ``parent_pid``: PR_SET_PDEATHSIG on Linux, and
    :func:`check_parent` everywhere. A worker forked by the pool's fork server has that
    server as its parent; the server exits when the exporter does, so the death signal
    still follows the exporter, and :func:`check_parent` also asks after the exporter.

    A worker's results go back through a pipe that only the exporter reads: a worker that
    finishes a task in the milliseconds between the exporter's death and its own (the kill
    chain runs through the fork server) would get a BrokenPipeError and print its traceback
    on the user's terminal. SIGPIPE's default action is restored instead (Python ignores it),
    so that write ends the worker silently, as the death signal would a moment later."""
    global _PARENT_PID, _EXPORTER_PID
    if hasattr(signal, "SIGPIPE"):
        signal.signal(signal.SIGPIPE, signal.SIG_DFL)
    _EXPORTER_PID = int(parent_pid)
    _PARENT_PID = os.getppid()
    if _PARENT_PID != _EXPORTER_PID and not alive(_EXPORTER_PID):
        os._exit(0)
    if hasattr(os, "sched_getaffinity"):  # Linux
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            PR_SET_PDEATHSIG = 1
            libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):  # no prctl: the pid checks still apply
            pass
    check_parent()  # the parent may have died before prctl took effect


def alive(pid: int) -> bool:
    """Whether process ``pid`` exists."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # exists, but not ours to signal
        return True
    return True


def check_parent() -> None:
    """Exit at once, quietly and without writing, when this worker's parent is gone (or,
    for a worker of the fork server, the exporter). A no-op outside a watched worker."""
    if _PARENT_PID is None:
        return
    if os.getppid() != _PARENT_PID or (_EXPORTER_PID != _PARENT_PID and not alive(_EXPORTER_PID)):
        os._exit(0)
