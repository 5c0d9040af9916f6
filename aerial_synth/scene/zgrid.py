"""Vertical traces over a regular grid by rasterisation: a top-down z-buffer.

A map (:func:`aerial_synth.scene.mapview.render_map`) traces straight down through the
centre of every pixel of a north-up grid, millions of rays that all point the same way.
Like the renderer's z-buffer (:mod:`aerial_synth.render.raster`) this answers them by
triangle instead of by ray: each triangle's pixel centres are found from its box, and each
gets the exact test "does the vertical line through the centre cross the triangle":
with the centre ``q = (x, y, 1)`` and the corners ``P_k = (x_k, y_k, 1)`` (world xy less the
grid's corner), the three products ``e_0 = q . (P_1 x P_2)``, ``e_1 = q . (P_2 x P_0)``,
``e_2 = q . (P_0 x P_1)`` share the sign of twice the triangle's area, and their ratios are
the barycentric weights of the corners, which give the hit height. The highest hit wins
(a ray from above meets it first); on an exact tie the lower global face index. A shared
edge is computed from the same float64 corners in opposite order, so a centre on it is
inside both triangles (watertight). Vertical faces (walls) have no area seen from above
and are never hit, as with Embree's vertical rays.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..numba_setup import KERNEL_OPTIONS
from .model import LABEL_IDS

__all__ = ["bin_rows", "edge_weights", "row_columns", "span", "store_box", "trace_grid"]

#: rows per band (the unit of work of one thread)
BAND_ROWS = 16
#: margin (pixels) of a triangle's box of pixel centres around its corners
_BOX_SLACK_PX = 1e-3


@njit(inline="always")
def span(ax, off, lo, hi):  # pragma: no cover - compiled
    """Narrow [lo, hi] to the x where ax * x + off >= 0, widened by a relative 1e-9 (far
    above the round-off of the root; the exact test is per pixel)."""
    if ax > 0:
        x = -off / ax
        x -= 1e-9 * (abs(x) + 1.0)
        if x > lo:
            lo = x
    elif ax < 0:
        x = -off / ax
        x += 1e-9 * (abs(x) + 1.0)
        if x < hi:
            hi = x
    elif off < 0:
        hi = -np.inf
    return lo, hi


@njit(inline="always")
def row_columns(a0x, a1x, a2x, b0, b1, b2, scale, offset, c_first, c_last):  # pragma: no cover
    """(first, last) column of one row of a triangle's box whose centres can satisfy the
    three edge tests ``a_kx * x + b_k >= 0`` (first > last: none), where column c's centre
    is at ``x = (c - offset) / scale``; a column either side to spare."""
    lo, hi = -np.inf, np.inf
    lo, hi = span(a0x, b0, lo, hi)
    lo, hi = span(a1x, b1, lo, hi)
    lo, hi = span(a2x, b2, lo, hi)
    if not lo <= hi:
        return 1, 0
    c0 = c_first
    if lo > -np.inf:
        v = lo * scale + offset
        if v > c0:
            c0 = int(min(v, c_last + 1.0))
    c1 = c_last
    if hi < np.inf:
        v = hi * scale + offset
        if v < c1:
            c1 = int(max(math.ceil(v), c_first - 1.0))
    return c0, c1


@njit(inline="always")
def edge_weights(a0x, a1x, a2x, b0, b1, b2, x):  # pragma: no cover - compiled
    """(e_0, e_1, e_2, their sum) at a centre of abscissa ``x`` on a row whose offsets
    are ``b_k``; the sum is 0 where the centre is outside (an edge test < 0)."""
    e0 = a0x * x + b0
    e1 = a1x * x + b1
    e2 = a2x * x + b2
    if e0 < 0 or e1 < 0 or e2 < 0:
        return e0, e1, e2, 0.0
    return e0, e1, e2, e0 + e1 + e2


@njit(inline="always")
def _corner(verts, k, x0, y0):  # pragma: no cover - compiled
    return (np.float64(verts[k, 0]) - x0, np.float64(verts[k, 1]) - y0, np.float64(verts[k, 2]))


@njit(inline="always")
def store_box(rows, i, cl, ch, rl, rh, w, h):  # pragma: no cover - compiled
    """rows[i] <- [first row, last row, first column, last column] of the pixels of a
    (h, w) image whose centres lie in [cl, ch] x [rl, rh] (in pixel-centre units: column
    c's centre is at c), with a margin of :data:`_BOX_SLACK_PX`, far above the round-off
    of the corners' projection (the exact test is per pixel); left empty (first > last)
    when none does. Small triangles between pixel centres drop out here."""
    cl = max(cl, -2.0)
    ch = min(ch, w + 2.0)
    rl = max(rl, -2.0)
    rh = min(rh, h + 2.0)
    if not (cl <= ch and rl <= rh):
        return
    c0 = max(int(math.ceil(cl - _BOX_SLACK_PX)), 0)
    c1 = min(int(math.floor(ch + _BOX_SLACK_PX)), w - 1)
    r0 = max(int(math.ceil(rl - _BOX_SLACK_PX)), 0)
    r1 = min(int(math.floor(rh + _BOX_SLACK_PX)), h - 1)
    if c0 > c1 or r0 > r1:
        return
    rows[i, 0] = r0
    rows[i, 1] = r1
    rows[i, 2] = c0
    rows[i, 3] = c1


@njit(parallel=True, **KERNEL_OPTIONS)
def _setup(sv, sf, vv, vf, keep, x0, y0, m, w, h, rows, coef):  # pragma: no cover - compiled
    """rows (n_tri, 4) int32 <- [first row, last row, first column, last column] of the
    grid pixels whose centres each kept triangle can cover (first > last: none), and coef
    (n_tri, 12) <- a_0, a_1, a_2 (turned so that their sum's third term, twice the area,
    is > 0), the corner heights and that area term."""
    ns = sf.shape[0]
    for i in prange(ns + vf.shape[0]):
        rows[i, 0] = 1
        rows[i, 1] = 0
        if not keep[i]:
            continue
        if i < ns:
            p0 = _corner(sv, sf[i, 0], x0, y0)
            p1 = _corner(sv, sf[i, 1], x0, y0)
            p2 = _corner(sv, sf[i, 2], x0, y0)
        else:
            j = i - ns
            p0 = _corner(vv, vf[j, 0], x0, y0)
            p1 = _corner(vv, vf[j, 1], x0, y0)
            p2 = _corner(vv, vf[j, 2], x0, y0)
        # P_a x P_b for P = (x, y, 1): (y_a - y_b, x_b - x_a, x_a y_b - x_b y_a)
        a0x, a0y, a0z = p1[1] - p2[1], p2[0] - p1[0], p1[0] * p2[1] - p2[0] * p1[1]
        a1x, a1y, a1z = p2[1] - p0[1], p0[0] - p2[0], p2[0] * p0[1] - p0[0] * p2[1]
        a2x, a2y, a2z = p0[1] - p1[1], p1[0] - p0[0], p0[0] * p1[1] - p1[0] * p0[1]
        area = a0z + a1z + a2z
        if area == 0 or not np.isfinite(area):
            continue
        s = 1.0 if area > 0 else -1.0
        coef[i, 0] = s * a0x
        coef[i, 1] = s * a0y
        coef[i, 2] = s * a0z
        coef[i, 3] = s * a1x
        coef[i, 4] = s * a1y
        coef[i, 5] = s * a1z
        coef[i, 6] = s * a2x
        coef[i, 7] = s * a2y
        coef[i, 8] = s * a2z
        coef[i, 9] = p0[2]
        coef[i, 10] = p1[2]
        coef[i, 11] = p2[2]
        # column c's centre is at x = (c + 0.5) m, row r's at y = -(r + 0.5) m
        store_box(rows, i, min(p0[0], p1[0], p2[0]) / m - 0.5, max(p0[0], p1[0], p2[0]) / m - 0.5,
                  -max(p0[1], p1[1], p2[1]) / m - 0.5, -min(p0[1], p1[1], p2[1]) / m - 0.5, w, h)


@njit(**KERNEL_OPTIONS)
def bin_rows(rows, band, nb):  # pragma: no cover - compiled
    """(start (nb + 1,) int64, index (m,) int64, vis (k,) int64): the index of every
    triangle whose box of ``rows`` (see :func:`store_box`) is not empty (``vis``,
    ascending) and, for each band of ``band`` rows, the positions in ``vis`` of those that
    overlap it (``index[start[b]:start[b+1]]``, ascending)."""
    n = rows.shape[0]
    count = np.zeros(nb + 1, np.int64)
    nvis = 0
    for i in range(n):
        if rows[i, 0] <= rows[i, 1]:
            nvis += 1
            for b in range(rows[i, 0] // band, rows[i, 1] // band + 1):
                count[b + 1] += 1
    for b in range(nb):
        count[b + 1] += count[b]
    fill = count[:-1].copy()
    index = np.empty(count[nb], np.int64)
    vis = np.empty(nvis, np.int64)
    k = 0
    for i in range(n):
        if rows[i, 0] <= rows[i, 1]:
            for b in range(rows[i, 0] // band, rows[i, 1] // band + 1):
                index[fill[b]] = k
                fill[b] += 1
            vis[k] = i
            k += 1
    return count, index, vis


@njit(parallel=True, **KERNEL_OPTIONS)
def _fill(m, w, band, start, index, vis, rows, coef, zbuf, face):  # pragma: no cover - compiled
    """zbuf / face (h * w,) <- the highest hit's height and global face (-inf / -1: none)."""
    h = zbuf.shape[0] // w
    nb = start.shape[0] - 1
    for b in prange(nb):
        r_lo = b * band
        r_hi = min(h, r_lo + band) - 1
        for i in range(r_lo * w, (r_hi + 1) * w):
            zbuf[i] = -np.inf
            face[i] = -1
        for j in range(start[b], start[b + 1]):
            f = vis[index[j]]
            a0x, a0y, a0z = coef[f, 0], coef[f, 1], coef[f, 2]
            a1x, a1y, a1z = coef[f, 3], coef[f, 4], coef[f, 5]
            a2x, a2y, a2z = coef[f, 6], coef[f, 7], coef[f, 8]
            z0, z1, z2 = coef[f, 9], coef[f, 10], coef[f, 11]
            for r in range(max(rows[f, 0], r_lo), min(rows[f, 1], r_hi) + 1):
                y = -(r + 0.5) * m
                b0 = a0y * y + a0z
                b1 = a1y * y + a1z
                b2 = a2y * y + a2z
                c0, c1 = row_columns(a0x, a1x, a2x, b0, b1, b2, 1.0 / m, -0.5, rows[f, 2],
                                     rows[f, 3])
                for c in range(c0, c1 + 1):
                    e0, e1, e2, s = edge_weights(a0x, a1x, a2x, b0, b1, b2, (c + 0.5) * m)
                    if not s > 0:
                        continue
                    z = (e0 * z0 + e1 * z1 + e2 * z2) / s
                    i = r * w + c
                    if z > zbuf[i]:
                        zbuf[i] = z
                        face[i] = f


def trace_grid(rayscene, origin_xy, m_per_px: float, width: int, height: int,
               ignore=frozenset()) -> tuple[np.ndarray, np.ndarray]:
    """(face (height, width) int64 global face index, -1 = miss; z (height, width) float64
    hit height, -inf on a miss) of the first surface straight below the centre of every
    pixel of a north-up grid: pixel (r, c) is centred on ``origin_xy + ((c + 0.5) m,
    -(r + 0.5) m)`` (``origin_xy`` the top-left corner). ``ignore``: labels to pass
    through (the vehicles too if it holds "vehicle"), as :meth:`RayScene.trace_down`."""
    rayscene.refresh()
    sv, sf = rayscene._static_vertices, rayscene._static_faces
    vv = np.ascontiguousarray(rayscene._veh_vertices, np.float32)
    vf = rayscene._veh_faces
    n_static = len(sf)
    keep = np.ones(n_static + len(vf), np.bool_)
    ign = frozenset(ignore)
    if ign:
        keep[:n_static] = ~np.isin(rayscene._static_face_label, [LABEL_IDS[n] for n in ign])
        if "vehicle" in ign:
            keep[n_static:] = False
    w, h, m = int(width), int(height), float(m_per_px)
    rows = np.empty((len(keep), 4), np.int32)
    coef = np.empty((len(keep), 12), np.float64)
    _setup(sv, sf, vv, vf, keep, float(origin_xy[0]), float(origin_xy[1]), m, w, h, rows, coef)
    nb = -(-h // BAND_ROWS)
    start, index, vis = bin_rows(rows, BAND_ROWS, nb)
    zbuf = np.empty(h * w, np.float64)
    face = np.empty(h * w, np.int64)
    _fill(m, w, BAND_ROWS, start, index, vis, rows, coef, zbuf, face)
    return face.reshape(h, w), zbuf.reshape(h, w)
