"""glibc allocator settings for a process that renders frame after frame in a tight loop.

A 1024 px frame allocates about 150 MB of large arrays (pixel rays, Embree's answers, the
buffers, linear RGB). When a loop frees them all at the end of each frame (``for cam in
cams: render_frame(...)``), glibc gives the free top of its heap back to the system (its
trim threshold is twice its dynamic mmap threshold, at most 64 MiB) and the next frame
maps the memory again, each page zeroed by the kernel on first touch: measured 70-90 ms
of system time a frame on one core, 15 % of a full-preset frame. With the mmap threshold
at its maximum and a trim threshold above a frame's transients, the next frame reuses the
freed memory: 6-8 ms. Peak memory is unchanged (the heap keeps what a frame freed for the
next one, which needs as much).

The exporter does not need it: its frames overlap with the writer thread's encoding of the
previous image, so its heap top is never all free at once (measured: 0.6-0.7 s of system
time over 40 images either way, the same peak RSS). ``tools/bench_render.py`` calls it so
that its frame times match the exporter's (``--allocator default`` shows the churn); a
library user rendering in a loop may call it too. It is never called on import. Settings
given by the user (``GLIBC_TUNABLES`` with ``glibc.malloc.*`` or ``MALLOC_*_`` variables)
are left alone. Only the allocation pattern changes: outputs are byte-identical.
"""

from __future__ import annotations

import functools
import os
import sys

__all__ = ["tune_allocator", "MMAP_THRESHOLD", "TRIM_THRESHOLD"]

#: blocks below this come from the heap, where freed memory is reused (glibc's maximum)
MMAP_THRESHOLD = 32 * 1024 * 1024
#: free memory at the top of the heap kept for reuse (above a frame's transients)
TRIM_THRESHOLD = 512 * 1024 * 1024
_M_TRIM_THRESHOLD = -1  # mallopt parameters, <malloc.h>
_M_MMAP_THRESHOLD = -3
_ENV = ("MALLOC_TRIM_THRESHOLD_", "MALLOC_MMAP_THRESHOLD_", "MALLOC_TOP_PAD_", "MALLOC_MMAP_MAX_")


def _user_settings() -> bool:
    return "glibc.malloc." in os.environ.get("GLIBC_TUNABLES", "") or any(k in os.environ for k in _ENV)


@functools.cache
def tune_allocator() -> bool:
    """Set glibc's mmap and trim thresholds for this process (once; inherited by processes
    it forks). Returns whether they are set: False off Linux/glibc, where the user chose
    their own malloc settings, or where ``mallopt`` refuses."""
    ok = False
    if sys.platform.startswith("linux") and not _user_settings():
        try:
            import ctypes

            libc = ctypes.CDLL(None)
            libc.gnu_get_libc_version  # noqa: B018 - glibc only (musl's mallopt does nothing)
            mallopt = libc.mallopt
        except (OSError, AttributeError):
            mallopt = None
        if mallopt is not None:
            mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
            mallopt.restype = ctypes.c_int
            ok = (mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD) == 1
                  and mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD) == 1)
    return ok
