"""Frame buffers: the first surface on the ray through each pixel centre.

The first surface on the ray through each pixel centre (see
:meth:`aerial_synth.camera.Camera.pixel_rays`; found by the z-buffer of :mod:`.raster`, or
by one Embree ray per pixel with ``cast_buffers(method="embree")``) gives

- ``instance`` (H, W) uint32: vehicle id of the first hit (placement ids; 0 = background),
- ``semantic`` (H, W) uint8: semantic id (:data:`aerial_synth.scene.model.LABEL_IDS`; 0 =
  nothing hit),
- ``depth`` (H, W) float32: z-depth along the optical axis in metres (0 = nothing hit),

plus per-pixel hit data the shader needs (face index, normal, world position). Every render
backend (:mod:`.backends`) starts from these buffers, so labels never depend on the backend.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Buffers", "PRIMARY", "cast_buffers"]


@dataclass
class Buffers:
    """Per-pixel first surfaces (row-major flat arrays of n = H * W).

    face   : (n,) int64 global face index (-1 = miss)
    t      : (n,) float32 z-depth, metres (inf = miss)
    normal : (n, 3) float32 geometric normal facing the camera (world)
    """

    height_px: int
    width_px: int
    instance: np.ndarray  # (H, W) uint32
    semantic: np.ndarray  # (H, W) uint8
    depth: np.ndarray  # (H, W) float32
    face: np.ndarray
    t: np.ndarray
    normal: np.ndarray
    rays: np.ndarray  # (n, 6) float32


#: how :func:`cast_buffers` finds each pixel's first surface: "raster" (the z-buffer of
#: :mod:`.raster`, exact ray-triangle tests organised by triangle, ~5x faster) or "embree"
#: (one Embree ray per pixel centre)
PRIMARY = "raster"


def cast_buffers(rayscene, camera, method: str | None = None) -> Buffers:
    """The first surface at every pixel centre: instance / semantic / depth and hit data.

    method : "raster" or "embree" (default :data:`PRIMARY`). Both answer the same question
    (which triangle a ray from the camera centre through the pixel centre meets first) and
    agree but for pixels where a ray grazes an edge (tests/render/test_raster.py); the
    raster's answer is watertight.

    With "embree", Embree's answer is read without copies and turned into faces, labels, depth and
    camera-facing normals, with the smooth shading normals of crown clumps
    (:mod:`.smooth`), in one compiled pass (:func:`.smooth.finish_smooth_buffers`); the
    result is the same as mapping :meth:`RayScene.cast_rays` hits and then
    :func:`.smooth.smooth_shading_normals` (tests/render/test_smooth_normals.py)."""
    # numba kernels cached on disk: importing them needs a writable cache, and the commands
    # check their output folder before they render
    from . import raster, smooth  # lazy: numba kernels (see above)

    h, w = camera.height_px, camera.width_px
    method = PRIMARY if method is None else method
    if method == "raster":
        o = raster.raster_primary(rayscene, camera)
        return Buffers(h, w, o["instance"].reshape(h, w), o["semantic"].reshape(h, w),
                       o["depth"].reshape(h, w), o["face"], o["t"], o["normal"], o["rays"])
    if method != "embree":
        raise ValueError(f"cast_buffers: method must be 'raster' or 'embree', not {method!r}")
    n = h * w
    rays = camera._all_rays()
    ans = rayscene._cast_raw(rays)
    lut, offs = ans["lut"]
    t = ans["t_hit"]
    normal = ans["primitive_normals"]
    if not (normal.flags.writeable and normal.flags.c_contiguous):
        normal = np.array(normal, np.float32)
    face = np.empty(n, np.int64)
    depth = np.empty(n, np.float32)
    semantic = np.empty(n, np.uint8)
    instance = np.empty(n, np.uint32)
    # shading only: crown clumps get interpolated vertex normals (faces, labels untouched)
    row, corners = smooth.corner_normals(rayscene)
    smooth.finish_smooth_buffers(rays, t, ans["geometry_ids"], ans["primitive_ids"],
                          np.ascontiguousarray(ans["primitive_uvs"], dtype=np.float32), lut,
                          offs, rayscene.face_label, rayscene.face_instance, row, corners,
                          normal, face, depth, semantic, instance)
    return Buffers(h, w, instance.reshape(h, w), semantic.reshape(h, w), depth.reshape(h, w),
                   face, t, normal, rays)
