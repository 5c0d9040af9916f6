"""The Warp kernels of the ``warp`` render backend (:mod:`.backends.warp`): BVH ray queries
on ``wp.Mesh`` that run unchanged on a CUDA device or on the CPU.

Imported only by that backend, and only once NVIDIA Warp (the ``[gpu]`` extra) is known to
be installed: this module imports ``warp`` at the top because Warp compiles kernels from
module-level definitions. Kernels are compiled on first use and cached by Warp on disk.

A RayScene's triangles live in two kinds of mesh (see :class:`.backends.warp.WarpScene`):
static meshes (the scene's triangles, one per ignore-set, each with a map from its faces to
the RayScene's global face index) and one vehicles mesh (every vehicle, faces in global
order from ``n_static``). "No mesh" is passed as id 0 with its flag 0.
"""

from __future__ import annotations

import warp as wp

__all__ = ["primary", "cast", "occluded"]

_FAR = 1.0e30


@wp.func
def _first_hit(static_id: wp.uint64, has_static: int, static_map: wp.array(dtype=wp.int64),
               veh_id: wp.uint64, has_veh: int, n_static: int, o: wp.vec3, d: wp.vec3,
               max_t: float):
    """The nearest hit of the ray o + t d (t < max_t, in units of |d|) on the static mesh
    and the vehicles mesh: (global face or -1, t, warp u, warp v, unit face normal). On an
    exact tie the static face wins (the lower global index, as the raster primary)."""
    face = wp.int64(-1)
    t = float(_FAR)
    u = float(0.0)
    v = float(0.0)
    nrm = wp.vec3(0.0, 0.0, 0.0)
    tmax = max_t
    if has_static != 0:
        q = wp.mesh_query_ray(static_id, o, d, tmax)
        if q.result:
            face = static_map[q.face]
            t = q.t
            u = q.u
            v = q.v
            nrm = q.normal
            tmax = q.t
    if has_veh != 0:
        q2 = wp.mesh_query_ray(veh_id, o, d, tmax)
        if q2.result and q2.t < tmax:
            face = wp.int64(n_static) + wp.int64(q2.face)
            t = q2.t
            u = q2.u
            v = q2.v
            nrm = q2.normal
    return face, t, u, v, nrm


@wp.kernel
def primary(static_id: wp.uint64, has_static: int, static_map: wp.array(dtype=wp.int64),
            veh_id: wp.uint64, has_veh: int, n_static: int, center: wp.vec3, rot: wp.mat33,
            fx: float, fy: float, cx: float, cy: float, width: int,
            face_label: wp.array(dtype=wp.int32), face_instance: wp.array(dtype=wp.int32),
            rays: wp.array2d(dtype=wp.float32), face: wp.array(dtype=wp.int64),
            t_out: wp.array(dtype=wp.float32), normal: wp.array2d(dtype=wp.float32),
            uv: wp.array2d(dtype=wp.float32), instance: wp.array(dtype=wp.uint32),
            semantic: wp.array(dtype=wp.uint8), depth: wp.array(dtype=wp.float32)):
    """One pixel's primary ray (from the camera centre through the pixel centre, direction
    ``rot @ (x, y, 1)`` with the float32 operations of ``Camera._all_rays``, so ``t`` is the
    z-depth) and its first surface: global face (-1 miss), t (inf miss), the geometric
    normal turned to the camera, Embree-convention barycentrics (hit = (1 - u - v) a + u b
    + v c), instance id, semantic id and depth (0 miss)."""
    i = wp.tid()
    r = i // width
    c = i - r * width
    x = ((float(c) + 0.5) - cx) / fx
    y = ((float(r) + 0.5) - cy) / fy
    d = wp.vec3((rot[0, 0] * x + rot[0, 1] * y) + rot[0, 2],
                (rot[1, 0] * x + rot[1, 1] * y) + rot[1, 2],
                (rot[2, 0] * x + rot[2, 1] * y) + rot[2, 2])
    for k in range(3):
        rays[i, k] = center[k]
        rays[i, 3 + k] = d[k]
    f, t, wu, wv, n = _first_hit(static_id, has_static, static_map, veh_id, has_veh, n_static,
                                 center, d, float(_FAR))
    face[i] = f
    if f >= wp.int64(0):
        if wp.dot(n, d) > 0.0:
            n = -n
        t_out[i] = t
        depth[i] = t
        semantic[i] = wp.uint8(face_label[f])
        instance[i] = wp.uint32(face_instance[f])
        uv[i, 0] = wv  # warp: hit = u a + v b + (1 - u - v) c
        uv[i, 1] = 1.0 - wu - wv
    else:
        t_out[i] = wp.inf
        depth[i] = 0.0
        semantic[i] = wp.uint8(0)
        instance[i] = wp.uint32(0)
        uv[i, 0] = 0.0
        uv[i, 1] = 0.0
    for k in range(3):
        normal[i, k] = n[k]


@wp.kernel
def cast(static_id: wp.uint64, has_static: int, static_map: wp.array(dtype=wp.int64),
         veh_id: wp.uint64, has_veh: int, n_static: int, rays: wp.array2d(dtype=wp.float32),
         face: wp.array(dtype=wp.int64), t_out: wp.array(dtype=wp.float32),
         normal: wp.array2d(dtype=wp.float32)):
    """Closest hits of arbitrary rays (n, 6): global face (-1 miss), t in units of the
    direction's length (inf miss), the unit face normal as wound (0 miss)."""
    i = wp.tid()
    o = wp.vec3(rays[i, 0], rays[i, 1], rays[i, 2])
    d = wp.vec3(rays[i, 3], rays[i, 4], rays[i, 5])
    f, t, wu, wv, n = _first_hit(static_id, has_static, static_map, veh_id, has_veh, n_static,
                                 o, d, float(_FAR))
    face[i] = f
    if f >= wp.int64(0):
        t_out[i] = t
    else:
        t_out[i] = wp.inf
    for k in range(3):
        normal[i, k] = n[k]


@wp.kernel
def occluded(static_id: wp.uint64, has_static: int, veh_id: wp.uint64, has_veh: int,
             rays: wp.array2d(dtype=wp.float32), tnear: float, tfar: float,
             out: wp.array(dtype=wp.uint8)):
    """Any-hit test of rays (n, 6) against both meshes, for hits with tnear < t < tfar (in
    units of the direction's length): 1 blocked, 0 clear."""
    i = wp.tid()
    d = wp.vec3(rays[i, 3], rays[i, 4], rays[i, 5])
    o = wp.vec3(rays[i, 0], rays[i, 1], rays[i, 2]) + tnear * d
    span = tfar - tnear
    hit = False
    if has_static != 0:
        hit = wp.mesh_query_ray_anyhit(static_id, o, d, span)
    if not hit and has_veh != 0:
        hit = wp.mesh_query_ray_anyhit(veh_id, o, d, span)
    out[i] = wp.where(hit, wp.uint8(1), wp.uint8(0))
