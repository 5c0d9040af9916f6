"""Memory a frame needs, and a check before rendering one that cannot fit.

A 1024 x 1024 frame is ~120 MB of buffers (rays, hits, normals, labels, shading terms, the
RGB and its writer's copy); the size options accept up to 16384 x 16384 px, whose frame
needs ~30 GB. Without a check, such a run loads the scene, writes its first files and is
then killed by the kernel's OOM killer, with no message. :func:`check_frame_memory`
refuses it first, in one line, before anything is written.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import RenderError

__all__ = ["FRAME_BYTES_PER_PX", "frame_bytes", "frame_gb", "available_memory_bytes", "check_frame_memory",
           "check_memory"]

#: Peak resident memory a frame adds per pixel: 112 B measured for ``aerial-synth render``
#: (peak RSS 0.97 GB at 2048 x 2048 px, 2.35 GB at 4096 x 4096), 102 B for one export
#: image with the full preset and 98 B with the fast one (city_park, 400 vehicles).
FRAME_BYTES_PER_PX = 112


def frame_bytes(width_px: int, height_px: int) -> int:
    """Memory one frame of ``width_px`` x ``height_px`` adds to its process (bytes)."""
    return FRAME_BYTES_PER_PX * int(width_px) * int(height_px)


def frame_gb(width_px: int, height_px: int) -> float:
    """:func:`frame_bytes` in GB (10^9 bytes), as the error messages give it."""
    return frame_bytes(width_px, height_px) / 1e9


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


def check_frame_memory(width_px: int, height_px: int, processes: int = 1, error=None,
                       available: int | None = None) -> None:
    """Raise ``error`` (default :class:`~aerial_synth.errors.RenderError`) in one line
    when ``processes`` frames of this size cannot fit in the memory available now (the
    scene and the process itself come on top: a frame that passes may still be too large,
    one that fails cannot fit). ``available`` overrides the reading (tests)."""
    if available is None:
        room = address_space_room()
        if room is not None and frame_bytes(width_px, height_px) > room:
            raise (error or RenderError)(
                f"--width/--height: a frame of {int(width_px)} x {int(height_px)} px needs about "
                f"{frame_bytes(width_px, height_px) / 1e9:.1f} GB of memory, the address-space "
                f"limit (ulimit -v) leaves {room / 1e9:.1f} GB; render smaller images or raise "
                f"the limit (a 1024 x 1024 frame needs {frame_bytes(1024, 1024) / 1e6:.0f} MB)")
    avail = available_memory_bytes() if available is None else int(available)
    if avail is None:
        return
    need = int(processes) * frame_bytes(width_px, height_px)
    if need > avail:
        who = (f"{int(processes)} frames (one per worker) of {int(width_px)} x {int(height_px)} px need"
               if int(processes) > 1 else f"a frame of {int(width_px)} x {int(height_px)} px needs")
        raise (error or RenderError)(
            f"--width/--height: {who} about "
            f"{need / 1e9:.1f} GB of memory, {avail / 1e9:.1f} GB are available here; "
            f"render smaller images{' or use fewer workers' if int(processes) > 1 else ''} "
            f"(a 1024 x 1024 frame needs {frame_bytes(1024, 1024) / 1e6:.0f} MB)"
        )


def check_memory(need_bytes: int, what: str, advice: str, error=None,
                 available: int | None = None) -> None:
    """Refuse work that needs ``need_bytes`` of memory before any of it is allocated: one
    line ``{what} needs about X GB of memory, <the limit that stops it>; {advice}``. The
    limits are the address-space limit (``ulimit -v``) and the memory available now
    (:func:`available_memory_bytes`, a container's cgroup limit included); ``available``
    overrides the latter (tests)."""
    err = error or RenderError
    need = int(need_bytes)
    room = address_space_room() if available is None else None
    if room is not None and need > room:
        raise err(f"{what} needs about {need / 1e9:.1f} GB of memory, the address-space limit "
                  f"(ulimit -v) leaves {room / 1e9:.1f} GB; {advice}")
    avail = available_memory_bytes() if available is None else int(available)
    if avail is not None and need > avail:
        raise err(f"{what} needs about {need / 1e9:.1f} GB of memory, {avail / 1e9:.1f} GB are "
                  f"available here; {advice}")
