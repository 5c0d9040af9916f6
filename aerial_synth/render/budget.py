"""Memory a frame needs, and a check before rendering one that cannot fit.

A 1024 x 1024 frame is ~120 MB of buffers (rays, hits, normals, labels, shading terms, the
RGB and its writer's copy); the size options accept up to 16384 x 16384 px, whose frame
needs ~30 GB. Without a check, such a run loads the scene, writes its first files and is
then killed by the kernel's OOM killer, with no message. :func:`check_frame_memory`
refuses it first, in one line, before anything is written.
"""

from __future__ import annotations

from ..errors import RenderError
from ..memory import (  # their home since issue 37; here for the frame checks and callers
    RENDER_PROCESS_VM_BYTES,
    address_space_room,
    available_memory_bytes,
    check_memory,
)

__all__ = ["FRAME_BYTES_PER_PX", "frame_bytes", "frame_gb", "available_memory_bytes", "check_frame_memory",
           "check_memory", "RENDER_PROCESS_VM_BYTES", "address_space_room"]

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

