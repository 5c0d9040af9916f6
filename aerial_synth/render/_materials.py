"""Procedural surface detail per material, in world coordinates (numba, called from
:func:`aerial_synth.render._kernels.compose`, which inlines the small helpers).

Every pattern is a pure function of the hit's world position, the face's tangent, the
texture noise tiles and a hash of (texture seed, cell index), so a place keeps its look
from frame to frame and the image does not depend on the thread count.

Editing this file: numba's disk cache of ``compose`` checks only ``_kernels.py``, so
update ``_kernels.MATERIALS_SHA`` to the new file's sha256 (a test checks it).

Coordinates: ``u`` runs along the face's tangent (down the slope of a pitched face, along
the longest outline edge of a flat one: the run of a sidewalk or road strip), ``v`` across
it, both horizontal, in metres. Thin lines (paving joints, roof courses, standing seams)
are box-filtered analytically over the pixel's footprint ``fp`` (metres): a 1.5 cm joint
seen at 0.12 m GSD darkens its pixels by the share it covers instead of aliasing into
dotted lines.

Kinds (``KIND_*``; shading.py maps materials to kinds with a table):
gravel roof (speckled grain, dark stones, drainage stains), tiled roof (courses down the
slope, staggered tiles with their own tone, the shadow line under each course, weathering),
metal roof (standing seams every 0.5 m down the slope with a lit ridge and a shadowed
side, panel tone and sheen), tyre tracks (darker, smoother, streaked along the lane, a
polished sheen), asphalt (rectangular repair patches aligned with the road, with a dark
sealed rim), paving and concrete (joint grid with a dirty halo, slab-to-slab tone), grass
and soil (a 25 m patch layer on top of the 3 m / 12 m ones), water (wind ripples that
break up the sky reflection and the sun glint).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..numba_setup import KERNEL_OPTIONS

KIND_NONE = 0
KIND_GRAVEL = 1
KIND_TILES = 2
KIND_METAL = 3
KIND_TRACK = 4
KIND_ASPHALT = 5
KIND_PAVING = 6
KIND_CONCRETE = 7
KIND_VEGETATION = 8
KIND_WATER = 9

# pattern sizes, metres
TILE_COURSE_M = 0.32  # tile course pitch down the slope
TILE_WIDTH_M = 0.28
SEAM_PITCH_M = 0.5  # standing-seam spacing across the slope
PAVING_SLAB_M = 1.6  # sidewalk slabs
CONCRETE_SLAB_M = 3.0  # drives, lots, plazas
JOINT_M = 0.015  # joint (saw cut) width


@njit(inline="always")
def _mix(z):  # pragma: no cover - compiled
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@njit(inline="always")
def hash01(a, b, seed):  # pragma: no cover - compiled
    """Uniform float32 in [0, 1) from integer cell (a, b) and a uint64 seed."""
    za = np.uint64(a & np.int64(0xFFFFFFFF)) * np.uint64(0x9E3779B97F4A7C15)
    zb = np.uint64(b & np.int64(0xFFFFFFFF)) * np.uint64(0xC2B2AE3D27D4EB4F)
    z = _mix(za ^ zb ^ seed)
    return np.float32((z >> np.uint64(40)) * (1.0 / 16777216.0))


@njit(inline="always")
def _cum(x, period, width):  # pragma: no cover - compiled
    """Integral over [0, x] of the indicator of lines [k period, k period + width)."""
    k = np.floor(x / period)
    return k * width + min(x - k * period, width)


@njit(inline="always")
def line_cover(x, fp, period, width):  # pragma: no cover - compiled
    """Share of the footprint [x - fp/2, x + fp/2] covered by lines [k period,
    k period + width): the exact box filter of a periodic line pattern (no aliasing)."""
    h = np.float32(0.5) * fp
    c = (_cum(x + h, period, width) - _cum(x - h, period, width)) / fp
    return min(max(np.float32(c), np.float32(0.0)), np.float32(1.0))


@njit(inline="always")
def _bil(tile, x, y):  # pragma: no cover - compiled
    fx0 = np.floor(x)
    fy0 = np.floor(y)
    fx = np.float32(x - fx0)
    fy = np.float32(y - fy0)
    x0 = np.int64(fx0) & 255
    y0 = np.int64(fy0) & 255
    x1 = (x0 + 1) & 255
    y1 = (y0 + 1) & 255
    a = tile[y0, x0] * (np.float32(1.0) - fx) + tile[y0, x1] * fx
    b = tile[y1, x0] * (np.float32(1.0) - fx) + tile[y1, x1] * fx
    return a * (np.float32(1.0) - fy) + b * fy


@njit(inline="always")
def _sm(x):  # pragma: no cover - compiled
    x = min(max(x, np.float32(0.0)), np.float32(1.0))
    return x * x * (np.float32(3.0) - np.float32(2.0) * x)


# detail is over 100 lines on purpose: a numba helper called from compose's per-pixel
# loop, one branch per material kind; split into helpers it would pass a dozen per-pixel
# values in and out of each, with nothing gained in reading. It is compiled on its own, not
# inlined into compose at numba's level (inline="always" was): compose's first compile cost
# 22 % less CPU time (61.8 -> 48.4 s for every render kernel, issue 36), same pixels.
@njit(**KERNEL_OPTIONS)
def detail(kind, u, v, qx, qy, nz, fp, seed, nf, t0, t1, t2, wear, ar, ag, ab, sk, f0):  # size: one branch per material kind (comment above)
    # pragma: no cover - compiled
    """Surface detail of one pixel: returns (ar, ag, ab, sk, f0), the albedo and the
    specular strength / sky-reflection F0 after the material's pattern.

    kind : KIND_* of the material; u, v : tangent-frame coordinates (metres); qx, qy : the
    shared texture coordinates; nz : the normal's up component; fp : pixel footprint
    (metres); seed : uint64 per texture seed; nf : the 0.1 m fractal texel already looked
    up; t0..t2 : noise tiles; wear : the frame's road age."""
    one = np.float32(1.0)
    g = one
    if kind == KIND_GRAVEL:
        # grain: a hash per 6 cm cell (sub-pixel at 0.12 m: mottled, softened by the
        # sensor blur), a few dark stones, large soft drainage stains where water stands
        iu = np.int64(np.floor(u * np.float32(16.0)))
        iv = np.int64(np.floor(v * np.float32(16.0)))
        hg = hash01(iu, iv, seed ^ np.uint64(0x6A7E1))
        g = np.float32(0.86) + np.float32(0.28) * hg
        if hg > np.float32(0.95):
            g *= np.float32(0.6)
        st = _bil(t2, qx * np.float32(0.3) + np.float32(71.0),
                  qy * np.float32(0.3) + np.float32(19.0))
        k = _sm((st - np.float32(0.7)) * np.float32(0.9))
        ar *= g * (one - np.float32(0.34) * k)
        ag *= g * (one - np.float32(0.36) * k)
        ab *= g * (one - np.float32(0.40) * k)
        return ar, ag, ab, sk, f0
    if kind == KIND_TILES:
        s = u / max(abs(nz), np.float32(0.3))  # distance down the slope
        fps = fp / max(abs(nz), np.float32(0.3))
        ci = np.int64(np.floor(s / np.float32(TILE_COURSE_M)))
        tv = v / np.float32(TILE_WIDTH_M) + np.float32(0.5) * np.float32(ci & 1)
        ti = np.int64(np.floor(tv))
        ht = hash01(ci, ti, seed ^ np.uint64(0x711E5))
        g = np.float32(0.84) + np.float32(0.3) * ht
        # the shadowed lower edge of each course (the next course overlaps it) and the
        # thin gaps between neighbouring tiles
        cs = line_cover(s + np.float32(0.07), fps, np.float32(TILE_COURSE_M),
                        np.float32(0.07))
        cg = line_cover(tv * np.float32(TILE_WIDTH_M), fp, np.float32(TILE_WIDTH_M),
                        np.float32(0.012))
        g *= (one - np.float32(0.5) * cs) * (one - np.float32(0.35) * cg)
        # weathering: darker (moss, soot) in 2 m patches
        wthr = _bil(t1, qx * np.float32(0.5) + np.float32(33.0),
                    qy * np.float32(0.5) + np.float32(91.0))
        g *= one - np.float32(0.12) * _sm(wthr * np.float32(0.7))
        return ar * g, ag * g, ab * g, sk, f0
    if kind == KIND_METAL:
        # standing seams run down the slope, every SEAM_PITCH_M across it: a lit ridge
        # (4 cm) and its shadowed side (4 cm)
        pitch = np.float32(SEAM_PITCH_M)
        lit = line_cover(v, fp, pitch, np.float32(0.04))
        sh = line_cover(v - np.float32(0.04), fp, pitch, np.float32(0.04))
        pi = np.int64(np.floor(v / pitch))
        hp = hash01(pi, np.int64(7), seed ^ np.uint64(0x3E7A1))
        g = (np.float32(0.92) + np.float32(0.16) * hp) * (
            one + np.float32(0.5) * lit - np.float32(0.5) * sh)
        sk *= np.float32(0.6) + np.float32(0.8) * hp  # panels are not quite planar
        return ar * g, ag * g, ab * g, sk, f0
    if kind == KIND_TRACK:
        # rubber and polish along the lane: smoother, darker, streaks along u
        streak = _bil(t1, v * np.float32(5.0) + np.float32(13.0),
                      u * np.float32(0.08) + np.float32(29.0))
        g = np.float32(0.88) + np.float32(0.06) * streak - np.float32(0.04) * nf
        return ar * g, ag * g, ab * g, sk, f0
    if kind == KIND_ASPHALT:
        if wear <= 0:
            return ar, ag, ab, sk, f0
        # rectangular repair patches aligned with the road: one chance per 7 m x 3.5 m
        # cell, a rectangle inside it, darker (fresh) or lighter (aged), sealed rim
        cu = np.float32(7.0)
        cv = np.float32(3.5)
        iu = np.int64(np.floor(u / cu))
        iv = np.int64(np.floor(v / cv))
        s2 = seed ^ np.uint64(0x9A7C4)
        if hash01(iu, iv, s2) < np.float32(0.22) * wear:
            fu = u / cu - np.float32(iu)
            fv = v / cv - np.float32(iv)
            a0 = np.float32(0.05) + np.float32(0.35) * hash01(iu, iv, s2 + np.uint64(1))
            a1 = min(a0 + np.float32(0.2) + np.float32(0.5) * hash01(iu, iv, s2 + np.uint64(2)),
                     np.float32(0.97))
            b0 = np.float32(0.05) + np.float32(0.3) * hash01(iu, iv, s2 + np.uint64(3))
            b1 = min(b0 + np.float32(0.25) + np.float32(0.5) * hash01(iu, iv, s2 + np.uint64(4)),
                     np.float32(0.97))
            if a0 <= fu <= a1 and b0 <= fv <= b1:
                dark = hash01(iu, iv, s2 + np.uint64(5)) < np.float32(0.6)
                g = np.float32(0.76) if dark else np.float32(1.12)
                e = min(min(fu - a0, a1 - fu) * cu, min(fv - b0, b1 - fv) * cv)
                if e < np.float32(0.06):  # bitumen seal along the cut
                    g *= np.float32(0.75)
        return ar * g, ag * g, ab * g, sk, f0
    if kind == KIND_PAVING or kind == KIND_CONCRETE:
        slab = np.float32(PAVING_SLAB_M) if kind == KIND_PAVING else np.float32(CONCRETE_SLAB_M)
        # joints at the slab edges (centred on k * slab): a dark cut and a dirty halo
        jw = np.float32(JOINT_M)
        ju = line_cover(u + np.float32(0.5) * jw, fp, slab, jw)
        jv = line_cover(v + np.float32(0.5) * jw, fp, slab, jw)
        hw = np.float32(0.08)
        hu = line_cover(u + np.float32(0.5) * hw, fp, slab, hw)
        hv = line_cover(v + np.float32(0.5) * hw, fp, slab, hw)
        j = one - (one - ju) * (one - jv)
        halo = one - (one - hu) * (one - hv)
        iu = np.int64(np.floor(u / slab + np.float32(0.5) * jw / slab))
        iv = np.int64(np.floor(v / slab + np.float32(0.5) * jw / slab))
        hs = hash01(iu, iv, seed ^ np.uint64(0x51AB))
        g = (np.float32(0.94) + np.float32(0.12) * hs) * (one - np.float32(0.6) * j) * (
            one - np.float32(0.1) * halo)
        return ar * g, ag * g, ab * g, sk, f0
    if kind == KIND_VEGETATION:
        # a 25 m patch layer: lighter / darker, greener / yellower fields
        p = _bil(t2, qx * np.float32(0.04) + np.float32(101.0),
                 qy * np.float32(0.04) + np.float32(67.0))
        q = _bil(t1, qx * np.float32(0.05) + np.float32(5.0),
                 qy * np.float32(0.05) + np.float32(151.0))
        g = one + np.float32(0.1) * p
        ar *= g * (one + np.float32(0.05) * q)
        ag *= g
        ab *= g * (one - np.float32(0.05) * q)
        return ar, ag, ab, sk, f0
    if kind == KIND_WATER:
        # wind ripples (streaks across the wind, 0.3 m x 2 m) break up the sky reflection
        # and scatter the sun glint; darker and lighter cat's paws at 10 m
        r = _bil(t0, qx * np.float32(3.0) + np.float32(0.4) * qy, qy * np.float32(0.6))
        cp = _bil(t2, qx * np.float32(0.1) + np.float32(47.0),
                  qy * np.float32(0.1) + np.float32(3.0))
        k = max(one + np.float32(0.35) * r + np.float32(0.3) * cp, np.float32(0.2))
        return ar, ag, ab, sk * (one + np.float32(0.8) * r * r), f0 * k
    return ar, ag, ab, sk, f0
