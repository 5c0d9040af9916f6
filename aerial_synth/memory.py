"""Memory a process may still take, and a check before work that cannot fit.

:func:`available_memory_bytes` (MemAvailable, capped by a container's cgroup limit),
:func:`address_space_room` (``ulimit -v``) and :func:`check_memory`, which refuses work in one
line naming the limit that stops it, before anything is allocated ("memory before
allocation", issue 37). ``render.budget`` sizes frames with them; ``evaluate.mix`` (rescaled
real images) and ``vehicles.preview`` (the contact sheet's ray grid) check their own work.
"""

from __future__ import annotations

import os
from pathlib import Path

from .errors import ConfigError

__all__ = ["RENDER_PROCESS_VM_BYTES", "address_space_room", "available_memory_bytes", "check_memory"]


def _read_int(path: Path) -> int | None:
    try:
        text = path.read_text().strip()  # guard: cgroup files
    except OSError:
        return None
    return int(text) if text.isdigit() else None  # "max" (no limit) -> None


def _cgroup_room() -> int | None:
    """Bytes this process's cgroup may still take (v2, else v1), None without a limit."""
    try:
        lines = Path("/proc/self/cgroup").read_text().splitlines()  # guard: /proc
    except OSError:
        return None
    for line in lines:
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        hier, controllers, rel = parts
        if hier == "0" and controllers == "":  # cgroup v2
            base = Path("/sys/fs/cgroup") / rel.lstrip("/")
            limit, used = _read_int(base / "memory.max"), _read_int(base / "memory.current")
        elif "memory" in controllers.split(","):  # cgroup v1
            base = Path("/sys/fs/cgroup/memory") / rel.lstrip("/")
            limit = _read_int(base / "memory.limit_in_bytes")
            used = _read_int(base / "memory.usage_in_bytes")
            if limit is not None and limit >= 1 << 60:  # v1's "no limit"
                limit = None
        else:
            continue
        if limit is not None:
            return max(0, limit - (used or 0))
    return None


#: Virtual size of a rendering process before its frame: 2.4 GB measured after an export's
#: scene load (open3d alone maps 1.8 GB of address space, little of it resident).
RENDER_PROCESS_VM_BYTES = 2_500_000_000


def address_space_room() -> int | None:
    """Bytes of address space a rendering process may still map under ``RLIMIT_AS``
    (``ulimit -v``): the soft limit less the larger of this process's virtual size and
    :data:`RENDER_PROCESS_VM_BYTES`; None without a limit. Each process has its own (a
    pool's workers inherit it), so it caps one frame, not a pool's."""
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, OSError, ValueError, AttributeError):
        return None
    if soft == resource.RLIM_INFINITY or soft < 0:
        return None
    used = 0
    try:
        for line in Path("/proc/self/status").read_text().splitlines():  # guard: /proc
            if line.startswith("VmSize:"):
                used = int(line.split()[1]) * 1024
                break
    except (OSError, ValueError, IndexError):
        used = 0
    return max(0, int(soft) - max(used, RENDER_PROCESS_VM_BYTES))


def available_memory_bytes() -> int | None:
    """Memory a new allocation can take without swapping or an OOM kill: the kernel's
    MemAvailable, capped by the room left under this process's cgroup limit (a
    container's). None where neither can be read."""
    avail = None
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():  # guard: /proc
            if line.startswith("MemAvailable:"):
                avail = int(line.split()[1]) * 1024
                break
    except (OSError, ValueError, IndexError):
        avail = None
    if avail is None and hasattr(os, "sysconf"):
        try:
            avail = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (OSError, ValueError):
            avail = None
    room = _cgroup_room()
    if room is not None:
        avail = room if avail is None else min(avail, room)
    return avail


def check_memory(need_bytes: int, what: str, advice: str, error=None,
                 available: int | None = None) -> None:
    """Refuse work that needs ``need_bytes`` of memory before any of it is allocated (raise
    ``error``, default ConfigError): one line ``{what} needs about X GB of memory, <the limit
    that stops it>; {advice}``. The limits are the address-space limit (``ulimit -v``) and
    the memory available now
    (:func:`available_memory_bytes`, a container's cgroup limit included); ``available``
    overrides the latter (tests)."""
    err = error or ConfigError
    need = int(need_bytes)
    room = address_space_room() if available is None else None
    if room is not None and need > room:
        raise err(f"{what} needs about {need / 1e9:.1f} GB of memory, the address-space limit "
                  f"(ulimit -v) leaves {room / 1e9:.1f} GB; {advice}")
    avail = available_memory_bytes() if available is None else int(available)
    if avail is not None and need > avail:
        raise err(f"{what} needs about {need / 1e9:.1f} GB of memory, {avail / 1e9:.1f} GB are "
                  f"available here; {advice}")
