"""Smooth shading normals for organic surfaces (tree-crown clumps).

Crown clumps are low-poly (an icosahedron per clump keeps the ray-cast cost low), and their
flat facets shaded with the geometric normal read as faceted rocks from above. Here the
shading normal of a foliage hit is interpolated from area-weighted vertex normals with the
hit's barycentric coordinates (Embree's ``primitive_uvs``: point = (1 - u - v) a + u b + v c),
the classic Phong normal interpolation. Only the shading changes: faces, labels, depth and
instance ids come from the geometric hit as before.

The per-corner normal table is built once per RayScene for its static objects whose material
is in :data:`SMOOTH_MATERIALS` and cached on the RayScene.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..numba_setup import KERNEL_OPTIONS as _OPTS
from ..scene.model import MATERIAL_IDS

__all__ = ["SMOOTH_MATERIALS", "corner_normals", "smooth_shading_normals",
           "finish_smooth_buffers"]

#: materials whose shading normals are interpolated across faces
SMOOTH_MATERIALS: tuple[str, ...] = ("foliage",)


def corner_normals(rayscene) -> tuple[np.ndarray, np.ndarray]:
    """(row (F_static,) int32: -1 or the face's row in ``corners``; corners (k, 3, 3)
    float32 unit vertex normals at each face corner) for the static faces of smooth
    materials, cached on ``rayscene``."""
    cached = getattr(rayscene, "_smooth_normals_cache", None)
    if cached is not None:
        return cached
    ids = {MATERIAL_IDS[m] for m in SMOOTH_MATERIALS}
    objs = rayscene.scene.objects
    n_static = sum(o.n_triangles for o in objs)
    row = np.full(n_static, -1, np.int32)
    parts = []
    base = 0
    k = 0
    for o in objs:
        nf = o.n_triangles
        if MATERIAL_IDS[o.material] in ids and nf:
            v = np.asarray(o.vertices, np.float64)
            f = np.asarray(o.faces, np.int64)
            fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])  # area-weighted
            vn = np.zeros_like(v)
            for c in range(3):
                np.add.at(vn, f[:, c], fn)
            ln = np.linalg.norm(vn, axis=1, keepdims=True)
            vn = np.where(ln > 0, vn / np.maximum(ln, 1e-30), 0.0)
            parts.append(vn[f].astype(np.float32))
            row[base:base + nf] = np.arange(k, k + nf, dtype=np.int32)
            k += nf
        base += nf
    corners = np.concatenate(parts) if parts else np.zeros((0, 3, 3), np.float32)
    rayscene._smooth_normals_cache = (row, np.ascontiguousarray(corners))
    return rayscene._smooth_normals_cache


@njit(inline="always")
def _smooth_one(i, f, uv, rays, row, corners, normal):  # pragma: no cover - compiled
    """Pixel i (hit face f >= 0): its normal -> the interpolated vertex normal, if f is a
    smooth-material static face (see :func:`smooth_shading_normals`)."""
    if f >= row.shape[0] or row[f] < 0:
        return
    smooth_at(i, row[f], uv[i, 0], uv[i, 1], rays, corners, normal)


@njit(inline="always")
def smooth_at(i, k, u, v, rays, corners, normal):  # pragma: no cover - compiled
    """Pixel i, a hit at barycentric (u, v) (float32) on the face of row k of ``corners``:
    its camera-facing normal -> the interpolated vertex normal (unless that faces away)."""
    w0 = np.float32(1.0) - u - v
    sx = w0 * corners[k, 0, 0] + u * corners[k, 1, 0] + v * corners[k, 2, 0]
    sy = w0 * corners[k, 0, 1] + u * corners[k, 1, 1] + v * corners[k, 2, 1]
    sz = w0 * corners[k, 0, 2] + u * corners[k, 1, 2] + v * corners[k, 2, 2]
    ln = np.sqrt(sx * sx + sy * sy + sz * sz)
    if ln <= np.float32(1e-12):
        return
    sx /= ln
    sy /= ln
    sz /= ln
    gx, gy, gz = normal[i, 0], normal[i, 1], normal[i, 2]  # camera-facing geometric
    if sx * gx + sy * gy + sz * gz < 0:  # same side as the geometric normal
        sx, sy, sz = -sx, -sy, -sz
    if sx * rays[i, 3] + sy * rays[i, 4] + sz * rays[i, 5] >= 0:
        return  # a grazing hit whose smooth normal faces away: keep the facet's
    normal[i, 0] = sx
    normal[i, 1] = sy
    normal[i, 2] = sz


@njit(parallel=True, **_OPTS)
def finish_smooth_buffers(rays, t, gid, pid, uv, lut, offs, face_label, face_instance, row,
                          corners, normal, face, depth, semantic,
                          instance):  # pragma: no cover - compiled
    """One pass over the n primary hits, straight from Embree's answer (no numpy
    temporaries): ``face`` (n,) int64 global face = ``lut[offs[gid] + pid]`` (-1 on miss,
    ``gid`` not a geometry of the scene: see ``RayScene._face_lut``), ``semantic`` (n,)
    uint8 and ``instance`` (n,) uint32 from the per-face tables (0 on miss), ``depth`` (n,)
    = t (0 on miss), the normal turned to the camera, then for hits on smooth
    faces (``row``, ``corners`` from :func:`corner_normals`; ``row`` may be empty) the
    interpolated vertex normal at the hit's barycentric ``uv`` (n, 2)."""
    n = t.shape[0]
    ng = offs.shape[0] - 1
    for i in prange(n):
        g = np.int64(gid[i])
        f = np.int64(-1)
        if g < ng:
            f = lut[offs[g] + np.int64(pid[i])]
        face[i] = f
        if f >= 0:
            semantic[i] = np.uint8(face_label[f])
            instance[i] = np.uint32(face_instance[f])
        else:
            semantic[i] = 0
            instance[i] = 0
        ti = t[i]
        depth[i] = ti if np.isfinite(ti) else np.float32(0.0)
        d = normal[i, 0] * rays[i, 3] + normal[i, 1] * rays[i, 4] + normal[i, 2] * rays[i, 5]
        if d > 0:
            normal[i, 0] = -normal[i, 0]
            normal[i, 1] = -normal[i, 1]
            normal[i, 2] = -normal[i, 2]
        if f >= 0:
            _smooth_one(i, f, uv, rays, row, corners, normal)


@njit(parallel=True, **_OPTS)
def _apply(face, uv, rays, row, corners, normal):  # pragma: no cover - compiled
    for i in prange(face.shape[0]):
        f = face[i]
        if f >= 0:
            _smooth_one(i, f, uv, rays, row, corners, normal)


def smooth_shading_normals(rayscene, face: np.ndarray, uv: np.ndarray, rays: np.ndarray,
                           normal: np.ndarray) -> None:
    """Replace, in place, the (n, 3) float32 camera-facing ``normal`` of every hit on a
    smooth-material static face (``face`` (n,) global face index, -1 = miss) by the
    interpolated vertex normal at the hit's barycentric ``uv`` (n, 2)."""
    row, corners = corner_normals(rayscene)
    if not len(corners):
        return
    _apply(np.ascontiguousarray(face), np.ascontiguousarray(uv, dtype=np.float32),
           np.ascontiguousarray(rays, dtype=np.float32), row, corners, normal)
