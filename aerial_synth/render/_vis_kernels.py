"""Compiled helpers of the visibility pass (:func:`aerial_synth.render.visibility.compute_visibility`).

Kept apart from the shading kernels (:mod:`._kernels`) so that the two can change
independently. Results do not depend on the number of threads (no parallel loops here).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..numba_setup import KERNEL_OPTIONS as _OPTS

__all__ = ["amodal_cast_mask", "amodal_groups", "box_union_pixels", "instance_boxes"]


@njit(**_OPTS)
def amodal_cast_mask(rows, cols, multi, instance, depth, centre, rot, fx, fy, cx, cy, cand,
                     cid, tol):  # pragma: no cover - compiled
    """Which pixels of the amodal union still need a vehicles-only ray (True = cast).

    rows, cols, multi : (m,) the union's pixels (:func:`box_union_pixels`)
    instance, depth   : (h, w) primary buffers (uint32 ids, z-depth with 0 = nothing hit)
    centre (3,), rot (3, 3) camera-to-world, fx, fy, cx, cy : the pinhole camera (float64)
    cand (k, 12) float64 per candidate vehicle ``cid[k]``: pixel range x0, y0, x1, y1
        ([x0, x1) x [y0, y1), every pixel whose ray can meet its mesh), then a box that
        holds its mesh: centre x, y, cos, sin of its heading, half length, half width,
        z low, z high (world)
    tol : metres added to every box and allowed on depths

    A pixel inside the image skips its ray when the primary hit already tells every vehicle
    its ray meets. Its first surface (depth d0) is the first vehicle hit too when it is a
    vehicle ``v0``, and no other vehicle can lie in front of d0; so when no other candidate
    box reaches d0 along the ray (the ray misses the box, or leaves it before d0 - tol), the
    ray meets ``v0`` only (or no vehicle). A pixel that one box covers (``multi`` False) only
    needs its first vehicle, so ``v0 > 0`` alone settles it.
    """
    h, w = instance.shape
    deep = np.zeros((h, w), np.bool_)  # another vehicle may lie on the ray at d0 or beyond
    for k in range(cid.shape[0]):
        x0, y0 = max(np.int64(cand[k, 0]), 0), max(np.int64(cand[k, 1]), 0)
        x1, y1 = min(np.int64(cand[k, 2]), w), min(np.int64(cand[k, 3]), h)
        bx, by, bc, bs = cand[k, 4], cand[k, 5], cand[k, 6], cand[k, 7]
        hl, hw = cand[k, 8] + tol, cand[k, 9] + tol
        zl, zh = cand[k, 10] - tol, cand[k, 11] + tol
        # the camera centre in the box frame
        ox, oy = centre[0] - bx, centre[1] - by
        lox, loy, loz = bc * ox + bs * oy, -bs * ox + bc * oy, centre[2]
        vk = cid[k]
        for r in range(y0, y1):
            ny = (r + 0.5 - cy) / fy
            for c in range(x0, x1):
                if deep[r, c] or np.int64(instance[r, c]) == vk:
                    continue
                d0 = np.float64(depth[r, c])
                if d0 <= 0:  # nothing hit: no vehicle on the ray
                    continue
                nx = (c + 0.5 - cx) / fx
                dx = rot[0, 0] * nx + rot[0, 1] * ny + rot[0, 2]
                dy = rot[1, 0] * nx + rot[1, 1] * ny + rot[1, 2]
                dz = rot[2, 0] * nx + rot[2, 1] * ny + rot[2, 2]
                ldx, ldy = bc * dx + bs * dy, -bs * dx + bc * dy
                t0, t1 = -np.inf, np.inf
                for o, dd, lo, hi in ((lox, ldx, -hl, hl), (loy, ldy, -hw, hw),
                                      (loz, dz, zl, zh)):
                    if dd == 0.0:
                        if o < lo or o > hi:
                            t0, t1 = np.inf, -np.inf
                    else:
                        ta, tb = (lo - o) / dd, (hi - o) / dd
                        t0 = max(t0, min(ta, tb))
                        t1 = min(t1, max(ta, tb))
                if t0 <= t1 and t1 >= d0 - tol:
                    deep[r, c] = True
    m = rows.shape[0]
    out = np.ones(m, np.bool_)
    for j in range(m):
        r, c = rows[j], cols[j]
        if r < 0 or r >= h or c < 0 or c >= w:
            continue
        if instance[r, c] > 0 and not multi[j]:
            out[j] = False
        elif not deep[r, c]:
            out[j] = False
    return out


@njit(inline="always")
def _grow(box, k, c, r, first):  # pragma: no cover - compiled
    """Box k (x0, y0, x1, y1; pixel c, r inclusive on the low side) takes in pixel (c, r);
    ``first``: the box starts at that pixel."""
    if first:
        box[k, 0], box[k, 1], box[k, 2], box[k, 3] = c, r, c + 1, r + 1
    else:
        box[k, 0] = min(box[k, 0], c)
        box[k, 1] = min(box[k, 1], r)
        box[k, 2] = max(box[k, 2], c + 1)
        box[k, 3] = max(box[k, 3], r + 1)


@njit(**_OPTS)
def amodal_groups(ids, prow, pcol, h, w):  # pragma: no cover - compiled
    """Per vehicle of the (id, pixel) pairs ``ids`` (m,) sorted, with pixel rows / columns
    ``prow``, ``pcol`` (m,) (may lie outside the (h, w) image):

    returns ``inside`` (m,) bool (pixel in the image), and per distinct id (g,): the id,
    its pair count (pixels in and out of the image), its count inside the image, its box
    of all pixels and its box of the pixels inside (g, 4) int64 [x0, y0, x1, y1] (pixel
    edges; [0, 0, 0, 0] without such pixels).
    """
    m = ids.shape[0]
    inside = np.empty(m, np.bool_)
    g = 0
    for j in range(m):
        r, c = prow[j], pcol[j]
        inside[j] = r >= 0 and r < h and c >= 0 and c < w
        if j == 0 or ids[j] != ids[j - 1]:
            g += 1
    uid = np.empty(g, np.int64)
    count = np.zeros(g, np.int64)
    n_in = np.zeros(g, np.int64)
    box_all = np.zeros((g, 4), np.int64)
    box_in = np.zeros((g, 4), np.int64)
    k = -1
    for j in range(m):
        r, c = np.int64(prow[j]), np.int64(pcol[j])
        if j == 0 or ids[j] != ids[j - 1]:
            k += 1
            uid[k] = ids[j]
        _grow(box_all, k, c, r, count[k] == 0)
        count[k] += 1
        if inside[j]:
            _grow(box_in, k, c, r, n_in[k] == 0)
            n_in[k] += 1
    return inside, uid, count, n_in, box_all, box_in


@njit(**_OPTS)
def instance_boxes(instance, ids):  # pragma: no cover - compiled
    """One pass over an (h, w) id image: pixel count and pixel-edge box of each id of
    ``ids`` (k,) (sorted, unique). Returns counts (k,) int64 and boxes (k, 4) int64
    [x0, y0, x1, y1] (x1, y1 exclusive; [w, h, 0, 0] for an id with no pixels), in the
    order of ``ids``; other ids are skipped. Memory follows k, not the largest id (a tiled
    world's ids reach billions)."""
    h, w = instance.shape
    k = ids.shape[0]
    counts = np.zeros(k, np.int64)
    boxes = np.empty((k, 4), np.int64)
    boxes[:, 0] = w
    boxes[:, 1] = h
    boxes[:, 2] = 0
    boxes[:, 3] = 0
    last_v = 0
    j = -1
    for r in range(h):
        for c in range(w):
            v = instance[r, c]
            if v == 0:
                continue
            if v != last_v:  # runs of one id along a row: search once per run
                last_v = v
                j = np.searchsorted(ids, v)
                if j >= k or ids[j] != v:
                    j = -1
            if j < 0:
                continue
            counts[j] += 1
            if c < boxes[j, 0]:
                boxes[j, 0] = c
            if r < boxes[j, 1]:
                boxes[j, 1] = r
            if c + 1 > boxes[j, 2]:
                boxes[j, 2] = c + 1
            if r + 1 > boxes[j, 3]:
                boxes[j, 3] = r + 1
    return counts, boxes


@njit(**_OPTS)
def box_union_pixels(x0, y0, x1, y1):  # pragma: no cover - compiled
    """Pixels of the union of k boxes [x0, x1) x [y0, y1) (may reach outside the image),
    row-major: rows (m,) int32, cols (m,) int32, multi (m,) bool (in more than one box)."""
    k = x0.shape[0]
    if k == 0:
        return np.zeros(0, np.int32), np.zeros(0, np.int32), np.zeros(0, np.bool_)
    ex0, ey0 = x0.min(), y0.min()
    cw, ch = x1.max() - ex0, y1.max() - ey0
    cover = np.zeros((ch, cw), np.uint8)
    for b in range(k):
        for r in range(y0[b] - ey0, y1[b] - ey0):
            for c in range(x0[b] - ex0, x1[b] - ex0):
                if cover[r, c] < 255:
                    cover[r, c] += 1
    m = 0
    for r in range(ch):
        for c in range(cw):
            if cover[r, c]:
                m += 1
    rows = np.empty(m, np.int32)
    cols = np.empty(m, np.int32)
    multi = np.empty(m, np.bool_)
    j = 0
    for r in range(ch):
        for c in range(cw):
            v = cover[r, c]
            if v:
                rows[j] = r + ey0
                cols[j] = c + ex0
                multi[j] = v > 1
                j += 1
    return rows, cols, multi
