"""The primary visibility of a pinhole frame by rasterisation instead of one ray per pixel.

A frame's primary rays all leave one point, the camera centre, through the pixel centres of
a pinhole camera without distortion (:meth:`aerial_synth.camera.Camera._all_rays`). For
such a bundle, "which triangle does the ray through pixel (r, c) hit first" is answered by
a z-buffer: project every triangle once and test only the pixels it covers, instead of
walking Embree's BVH a million times. The answer is the ray cast's, computed exactly as a
ray-triangle test, only organised by triangle:

* In camera coordinates (centre at the origin) the ray through a pixel has the direction
  ``d = (x, y, 1)`` (``x``, ``y`` the pixel's normalised image coordinates: the very
  float32 values the camera's rays are made of). It passes through triangle ``p0 p1 p2``
  iff the three triple products ``e_k = d . a_k`` with ``a_0 = p1 x p2``, ``a_1 = p2 x p0``,
  ``a_2 = p0 x p1`` share the sign of ``det = p0 . (p1 x p2)``; the hit is then at
  ``t = det / (e_0 + e_1 + e_2)`` (> 0: in front of the camera; ``t`` is the z-depth, the
  ray parameter of the camera's rays, whose directions have camera-frame z = 1) with the
  barycentric coordinates ``u = e_1 / S``, ``v = e_2 / S`` (Embree's ``primitive_uvs``).
  This is the homogeneous form of rasterisation: it needs no clipping, and triangles that
  reach behind the camera are handled (their pixel range is taken from the part in front
  of a near plane, the per-pixel test does the rest).
* Watertight: two triangles that share an edge compute its ``a_k`` from the same float64
  vertices in opposite order, so their ``e_k`` are exact negatives at every pixel; a pixel
  centre on the edge (``e_k = 0``) is inside both. No pixel falls through a closed mesh
  (Embree's traversal is not built robust; ``tools/crack_count.py`` counts holes of both).
* Nearest hit: smallest ``t``; on an exact tie the lower global face index (deterministic,
  whatever the number of threads).

The image is cut into bands of rows; each band holds the in-view triangles that overlap it
(in face order) and is filled by one thread from a per-row span of columns solved from the
three edge equations, so the work is about the number of covered pixels, not the triangles'
bounding boxes. :func:`raster_primary` returns what :func:`.raycast.cast_buffers` builds
from Embree's answer (faces, z-depth, camera-facing normals with the smooth normals of
crown clumps, labels); tests/render/test_raster.py compares the two.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..numba_setup import KERNEL_OPTIONS
from ..scene.zgrid import bin_rows, edge_weights, row_columns, store_box
from .smooth import corner_normals, smooth_at

__all__ = ["raster_primary", "BAND_ROWS", "NEAR_M"]

#: rows per band: a band is the unit of work of one thread
BAND_ROWS = 8
#: the near plane (metres of z-depth) that bounds the pixel range of a triangle reaching
#: behind the camera; hits closer than this cannot occur in an aerial frame
NEAR_M = 1e-3


@njit(inline="always")
def _cam(verts, k, Rt, c):  # pragma: no cover - compiled
    """Vertex k of ``verts`` in camera coordinates (float64): Rt @ (v - c)."""
    x = np.float64(verts[k, 0]) - c[0]
    y = np.float64(verts[k, 1]) - c[1]
    z = np.float64(verts[k, 2]) - c[2]
    return (Rt[0, 0] * x + Rt[0, 1] * y + Rt[0, 2] * z,
            Rt[1, 0] * x + Rt[1, 1] * y + Rt[1, 2] * z,
            Rt[2, 0] * x + Rt[2, 1] * y + Rt[2, 2] * z)


@njit(inline="always")
def _tri(i, sv, sf, vv, vf, Rt, c):  # pragma: no cover - compiled
    ns = sf.shape[0]
    if i < ns:
        a, b, d = sf[i, 0], sf[i, 1], sf[i, 2]
        return _cam(sv, a, Rt, c), _cam(sv, b, Rt, c), _cam(sv, d, Rt, c)
    j = i - ns
    a, b, d = vf[j, 0], vf[j, 1], vf[j, 2]
    return _cam(vv, a, Rt, c), _cam(vv, b, Rt, c), _cam(vv, d, Rt, c)


@njit(inline="always")
def _grow(px, py, pz, fx, fy, cx, cy, u0, u1, v0, v1):  # pragma: no cover - compiled
    u = fx * px / pz + cx
    v = fy * py / pz + cy
    return min(u0, u), max(u1, u), min(v0, v), max(v1, v)


@njit(inline="always")
def _grow_edge(a, b, near, fx, fy, cx, cy, u0, u1, v0, v1):  # pragma: no cover - compiled
    """Grow the pixel box by vertex a if in front of the near plane, and by the point
    where the edge a-b crosses it."""
    if a[2] >= near:
        u0, u1, v0, v1 = _grow(a[0], a[1], a[2], fx, fy, cx, cy, u0, u1, v0, v1)
    if (a[2] - near) * (b[2] - near) < 0:
        s = (near - a[2]) / (b[2] - a[2])
        u0, u1, v0, v1 = _grow(a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]), near,
                               fx, fy, cx, cy, u0, u1, v0, v1)
    return u0, u1, v0, v1


@njit(parallel=True, **KERNEL_OPTIONS)
def _bounds(sv, sf, vv, vf, Rt, c, fx, fy, cx, cy, w, h, near, rows):  # pragma: no cover
    """rows (n_tri, 4) int32 <- [first row, last row, first column, last column] of the
    pixels whose centres each triangle can cover (first > last: none; the exact test is
    per pixel). The pixel range of a triangle that reaches behind the near plane is that
    of its part in front of it."""
    n = sf.shape[0] + vf.shape[0]
    for i in prange(n):
        rows[i, 0] = 1
        rows[i, 1] = 0
        p0, p1, p2 = _tri(i, sv, sf, vv, vf, Rt, c)
        if p0[2] < near and p1[2] < near and p2[2] < near:
            continue
        u0, u1, v0, v1 = np.inf, -np.inf, np.inf, -np.inf
        u0, u1, v0, v1 = _grow_edge(p0, p1, near, fx, fy, cx, cy, u0, u1, v0, v1)
        u0, u1, v0, v1 = _grow_edge(p1, p2, near, fx, fy, cx, cy, u0, u1, v0, v1)
        u0, u1, v0, v1 = _grow_edge(p2, p0, near, fx, fy, cx, cy, u0, u1, v0, v1)
        # pixel c spans x in [c, c + 1), its centre at c + 0.5; most vehicle triangles are
        # smaller than a pixel and hold no centre: they drop out here
        store_box(rows, i, u0 - 0.5, u1 - 0.5, v0 - 0.5, v1 - 0.5, w, h)


@njit(parallel=True, **KERNEL_OPTIONS)
def _edges(vis, sv, sf, vv, vf, Rt, c, coef):  # pragma: no cover - compiled
    """coef (k, 13) float64 <- a_0, a_1, a_2, det of visible triangle vis[j], turned so
    that det >= 0 (det == 0: seen edge-on, never hit), and its unit geometric normal in
    world coordinates (turned towards the camera: a hit sees the side det > 0 faces)."""
    for j in prange(vis.shape[0]):
        p0, p1, p2 = _tri(vis[j], sv, sf, vv, vf, Rt, c)
        a0x = p1[1] * p2[2] - p1[2] * p2[1]
        a0y = p1[2] * p2[0] - p1[0] * p2[2]
        a0z = p1[0] * p2[1] - p1[1] * p2[0]
        a1x = p2[1] * p0[2] - p2[2] * p0[1]
        a1y = p2[2] * p0[0] - p2[0] * p0[2]
        a1z = p2[0] * p0[1] - p2[1] * p0[0]
        a2x = p0[1] * p1[2] - p0[2] * p1[1]
        a2y = p0[2] * p1[0] - p0[0] * p1[2]
        a2z = p0[0] * p1[1] - p0[1] * p1[0]
        det = p0[0] * a0x + p0[1] * a0y + p0[2] * a0z
        s = 1.0 if det >= 0 else -1.0
        coef[j, 0] = s * a0x
        coef[j, 1] = s * a0y
        coef[j, 2] = s * a0z
        coef[j, 3] = s * a1x
        coef[j, 4] = s * a1y
        coef[j, 5] = s * a1z
        coef[j, 6] = s * a2x
        coef[j, 7] = s * a2y
        coef[j, 8] = s * a2z
        coef[j, 9] = s * det
        # (p1 - p0) x (p2 - p0) = a_0 + a_1 + a_2: det > 0 puts the origin (the camera) on
        # its negative side, so -s * n faces the camera; rotate back to world (R = Rt^T)
        nx = -(coef[j, 0] + coef[j, 3] + coef[j, 6])
        ny = -(coef[j, 1] + coef[j, 4] + coef[j, 7])
        nz = -(coef[j, 2] + coef[j, 5] + coef[j, 8])
        wx = Rt[0, 0] * nx + Rt[1, 0] * ny + Rt[2, 0] * nz
        wy = Rt[0, 1] * nx + Rt[1, 1] * ny + Rt[2, 1] * nz
        wz = Rt[0, 2] * nx + Rt[1, 2] * ny + Rt[2, 2] * nz
        ln = math.sqrt(wx * wx + wy * wy + wz * wz)
        if ln > 0:
            wx /= ln
            wy /= ln
            wz /= ln
        coef[j, 10] = wx
        coef[j, 11] = wy
        coef[j, 12] = wz


@njit(parallel=True, **KERNEL_OPTIONS)
def _raster(xs, ys, fx, cx, band, stride, start, index, vis, rows, coef, zbuf,
            fbuf):  # pragma: no cover - compiled
    """zbuf (h * w,) float64 / fbuf (h * w,) int64 <- the nearest hit's z-depth and its
    triangle's position in ``vis`` for every pixel (inf / -1: none), one band of rows per
    iteration (``coef`` rows are positions in ``vis`` too); iteration k fills band
    (k * stride) % nb (stride coprime with nb), so the contiguous runs of iterations each
    thread takes hold bands from all over the image, which cost alike."""
    h = ys.shape[0]
    w = xs.shape[0]
    nb = start.shape[0] - 1
    for k in prange(nb):
        bi = (k * stride) % nb
        r_lo = bi * band
        r_hi = min(h, r_lo + band) - 1
        for i in range(r_lo * w, (r_hi + 1) * w):
            zbuf[i] = np.inf
            fbuf[i] = -1
        for j in range(start[bi], start[bi + 1]):
            f = index[j]
            det = coef[f, 9]
            if not det > 0:
                continue
            a0x, a0y, a0z = coef[f, 0], coef[f, 1], coef[f, 2]
            a1x, a1y, a1z = coef[f, 3], coef[f, 4], coef[f, 5]
            a2x, a2y, a2z = coef[f, 6], coef[f, 7], coef[f, 8]
            g = vis[f]
            c_first = rows[g, 2]
            c_last = rows[g, 3]
            for r in range(max(rows[g, 0], r_lo), min(rows[g, 1], r_hi) + 1):
                y = np.float64(ys[r])
                b0 = a0y * y + a0z
                b1 = a1y * y + a1z
                b2 = a2y * y + a2z
                c0, c1 = row_columns(a0x, a1x, a2x, b0, b1, b2, fx, cx - 0.5, c_first, c_last)
                row = r * w
                for col in range(c0, c1 + 1):
                    _, _, _, s = edge_weights(a0x, a1x, a2x, b0, b1, b2, np.float64(xs[col]))
                    if not s > 0:
                        continue
                    t = det / s
                    i = row + col
                    if t < zbuf[i]:
                        zbuf[i] = t
                        fbuf[i] = f


@njit(parallel=True, **KERNEL_OPTIONS)
def _finish(xs, ys, rays, zbuf, face, vis, coef, face_label, face_instance, row, corners,
            t, depth, normal, semantic, instance):  # pragma: no cover - compiled
    """The buffers of every pixel from its triangle's position ``face[i]`` in ``vis`` (-1: a
    miss), which becomes the global face index: z-depth ``t`` (float32,
    inf on a miss), ``depth`` (0 on a miss), labels, the unit geometric normal turned to
    the camera and, on smooth faces, the interpolated vertex normal at the hit's
    barycentric coordinates (as ``smooth.finish_smooth_buffers``)."""
    w = xs.shape[0]
    for i in prange(zbuf.shape[0]):
        j = face[i]
        if j < 0:
            t[i] = np.float32(np.inf)
            depth[i] = np.float32(0.0)
            semantic[i] = 0
            instance[i] = 0
            normal[i, 0] = np.float32(0.0)
            normal[i, 1] = np.float32(0.0)
            normal[i, 2] = np.float32(0.0)
            continue
        f = vis[j]
        face[i] = f
        ti = np.float32(zbuf[i])
        t[i] = ti
        depth[i] = ti
        semantic[i] = np.uint8(face_label[f])
        instance[i] = np.uint32(face_instance[f])
        nx = np.float32(coef[j, 10])
        ny = np.float32(coef[j, 11])
        nz = np.float32(coef[j, 12])
        if nx * rays[i, 3] + ny * rays[i, 4] + nz * rays[i, 5] > 0:  # float32 round-off
            nx, ny, nz = -nx, -ny, -nz
        normal[i, 0] = nx
        normal[i, 1] = ny
        normal[i, 2] = nz
        if f < row.shape[0] and row[f] >= 0:
            x = np.float64(xs[i % w])
            y = np.float64(ys[i // w])
            e1 = coef[j, 3] * x + (coef[j, 4] * y + coef[j, 5])
            e2 = coef[j, 6] * x + (coef[j, 7] * y + coef[j, 8])
            s = coef[j, 0] * x + (coef[j, 1] * y + coef[j, 2]) + e1 + e2
            if s > 0:
                smooth_at(i, row[f], np.float32(e1 / s), np.float32(e2 / s), rays, corners,
                          normal)


def image_coords(camera) -> tuple[np.ndarray, np.ndarray]:
    """(x (w,) float32, y (h,) float32): the normalised image coordinates of the pixel
    centres, the float32 values :meth:`Camera._all_rays` builds its rays from."""
    K = camera.K
    x = ((np.arange(camera.width_px, dtype=np.float32) + np.float32(0.5))
         - np.float32(K[0, 2])) / np.float32(K[0, 0])
    y = ((np.arange(camera.height_px, dtype=np.float32) + np.float32(0.5))
         - np.float32(K[1, 2])) / np.float32(K[1, 1])
    return x, y


def raster_faces(rayscene, camera, xs, ys, face: np.ndarray, band: int = BAND_ROWS):
    """(zbuf (n,) float64 z-depth, vis (k,) int64, coef (k, 13)): the nearest triangle of
    ``rayscene`` (every triangle, vehicles included) at each pixel centre of ``camera``
    (``xs``, ``ys``: :func:`image_coords`),
    row-major: its position in ``vis`` (the faces that can cover a pixel) is written into
    ``face`` (n,) int64 (-1 = none), with its z-depth and the coefficients :func:`_finish`
    reads."""
    rayscene.refresh()
    sv, sf = rayscene._static_vertices, rayscene._static_faces
    vv = np.ascontiguousarray(rayscene._veh_vertices, np.float32)
    vf = rayscene._veh_faces
    h, w = camera.height_px, camera.width_px
    K = camera.K
    Rt = np.ascontiguousarray(camera.R.T, np.float64)
    c = np.ascontiguousarray(camera.center, np.float64)
    n_tri = len(sf) + len(vf)
    rows = np.empty((n_tri, 4), np.int32)
    _bounds(sv, sf, vv, vf, Rt, c, float(K[0, 0]), float(K[1, 1]), float(K[0, 2]),
            float(K[1, 2]), w, h, NEAR_M, rows)
    nb = -(-h // band)
    start, index, vis = bin_rows(rows, band, nb)
    coef = np.empty((len(vis), 13), np.float64)
    _edges(vis, sv, sf, vv, vf, Rt, c, coef)
    zbuf = np.empty(h * w, np.float64)
    stride = next(s for s in (37, 31, 29, 23, 19, 17, 13, 11, 7, 5, 3, 1) if math.gcd(s, nb) == 1)
    _raster(xs, ys, float(K[0, 0]), float(K[0, 2]), band, stride, start, index, vis, rows,
            coef, zbuf, face)
    return zbuf, vis, coef


def raster_primary(rayscene, camera) -> dict:
    """The primary buffers of ``camera`` over ``rayscene`` by rasterisation: a dict of
    face (n,) int64 (-1 = miss), t (n,) float32 z-depth (inf on a miss), depth (n,)
    float32 (0 on a miss), normal (n, 3) float32 unit, camera-facing (smooth normals on
    crown clumps), semantic (n,) uint8, instance (n,) uint32 and rays (n, 6) float32 (the
    camera's pixel rays)."""
    n = camera.height_px * camera.width_px
    face = np.empty(n, np.int64)
    xs, ys = image_coords(camera)
    zbuf, vis, coef = raster_faces(rayscene, camera, xs, ys, face)
    rays = camera._all_rays()
    out = dict(face=face, t=np.empty(n, np.float32), depth=np.empty(n, np.float32),
               normal=np.empty((n, 3), np.float32), semantic=np.empty(n, np.uint8),
               instance=np.empty(n, np.uint32), rays=rays)
    row, corners = corner_normals(rayscene)
    _finish(xs, ys, rays, zbuf, face, vis, coef, rayscene.face_label, rayscene.face_instance, row,
            corners, out["t"], out["depth"], out["normal"], out["semantic"], out["instance"])
    return out
