# size: one module on purpose, numba's disk-cache guard (MATERIALS_SHA) in one place; see below
"""Per-pixel kernels of the ray-cast renderer, compiled with numba.

Over 600 lines, kept as one module on purpose: :func:`compose` inlines the helpers of
:mod:`._materials` and the texture helpers here, and numba's disk cache keys a kernel only
by the content of the file that defines it, so every module of inlining kernels needs the
:data:`MATERIALS_SHA` guard below; one module keeps that guard in one place. (The
visibility kernels, which inline nothing, are in :mod:`._vis_kernels`.)

The shading model is described in :mod:`aerial_synth.render.shading`; these functions are
its inner loops, one fused pass over the pixels per stage instead of dozens of
whole-image numpy temporaries. Every pixel is computed independently (``prange`` over
rows), so results do not depend on the number of threads. Compiled code is cached on
disk (``cache=True``); on an empty cache :mod:`.warm` compiles them before the first
frame, once per machine, and says so.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..numba_setup import KERNEL_OPTIONS as _OPTS
from . import _materials

#: sha256 (first 16 hex digits) of ``_materials.py``. :func:`compose` inlines its helpers,
#: but numba's disk cache checks only this file's content, so this line must change
#: whenever ``_materials.py`` does (tests/render/test_materials.py checks it).
MATERIALS_SHA = "433eaa98a3cd0800"


_bilinear = _materials._bil  # wrapped bilinear lookup in a 256 x 256 noise tile (one copy)


@njit(inline="always")
def _tex_coords(rays, t, i):  # pragma: no cover - compiled
    """Texture coordinates (qx, qy) of pixel i's hit: world xy shifted by the height, so
    stacked surfaces (a roof over the ground) get different patterns."""
    ti = t[i]
    px = rays[i, 0] + ti * rays[i, 3]
    py = rays[i, 1] + ti * rays[i, 4]
    pz = rays[i, 2] + ti * rays[i, 5]
    return px + np.float32(0.37) * pz, py - np.float32(0.53) * pz


@njit(inline="always")
def _texel(qx, qy):  # pragma: no cover - compiled
    """(row, col) of the 0.1 m fractal texel at texture coordinates (qx, qy)."""
    return (np.int32(qy * np.float32(10.0)) & 255), (np.int32(qx * np.float32(10.0)) & 255)


@njit(inline="always")
def _leaf_bump(t1, ty, tx, lx, ly):  # pragma: no cover - compiled
    """Extra n.L of a leafy crown: the normal tilted by 0.45 x a noise vector (bx, by, 0),
    unnormalised (cheap and leaf-like)."""
    k2 = ((ty << 8) | tx) + 12345
    k2 &= 0xFFFF
    return np.float32(0.45) * (t1[ty, tx] * lx + t1[k2 >> 8, k2 & 255] * ly)


@njit(parallel=True, **_OPTS)
def surface(
    h, w, rays, t, face, normal, semantic, depth, face_material, tiles, textured, light,
    foliage_id, step, nearest, ndl_out, own_out, src_out,
):  # pragma: no cover - compiled
    """Sun cosine and shadow-ray selection, per pixel i.

    ``ndl_out[i]`` = max(n.L, 0) (with the leafy-crown bump); ``own_out[i]`` True when the
    pixel casts its own shadow ray. With ``step`` > 1 a pixel casts its own ray when it is
    its step x step block's first pixel (always, even facing away from the sun, since its
    block copies it) or differs from it (label, or depth by > 0.2 m); the others take the
    block sample's result (see :func:`spread_shadow`). With ``nearest``, a pixel facing the
    sun that differs from its block's first pixel casts only when none of the other three
    samples at its cell's corners lies on its surface either (:func:`_shadow_source`), and
    ``src_out[i]`` (uint8, n) records the corner it copies (0 - 3; written with ``nearest``
    only, for pixels facing the sun without their own ray).
    """
    lx, ly, lz = light[0], light[1], light[2]
    t1 = tiles[1]
    for r in prange(h):
        rb = (r // step) * step
        cb = 0  # first column of pixel (r, c)'s block: c - c % step, kept without divisions
        for c in range(w):
            if c - cb == step:
                cb = c
            i = r * w + c
            f = face[i]
            if f < 0:
                ndl_out[i] = 0.0
                own_out[i] = False
                continue
            ndl = normal[i, 0] * lx + normal[i, 1] * ly + normal[i, 2] * lz
            if textured and face_material[f] == foliage_id:
                qx, qy = _tex_coords(rays, t, i)
                ty, tx = _texel(qx, qy)
                ndl += _leaf_bump(t1, ty, tx, lx, ly)
            ndl = max(ndl, np.float32(0.0))
            ndl_out[i] = ndl
            if step == 1:
                own = ndl > 0
            elif r == rb and c == cb:
                own = True
            else:
                j = rb * w + cb
                own = ndl > 0 and (
                    semantic[i] != semantic[j] or abs(depth[i] - depth[j]) > np.float32(0.2)
                )
                if nearest and ndl > 0:
                    q = 0
                    if own:
                        q = _shadow_source(i, rb, cb, step, h, w, face, semantic, depth)
                        own = q < 0
                    src_out[i] = q
            own_out[i] = own


@njit(inline="always")
def _shadow_source(i, r0, c0, step, h, w, face, semantic, depth):  # pragma: no cover
    """The block sample whose shadow ray pixel i (in the step x step cell whose first pixel
    is (r0, c0)) copies: the first of the cell's corner samples q = 0: (r0, c0),
    1: (r0, c0 + step), 2: (r0 + step, c0), 3: (r0 + step, c0 + step) on the same surface
    (a hit with the same label, depth within 0.2 m); -1 when none is."""
    for q in range(4):
        rr = r0 + (step if q >= 2 else 0)
        cc = c0 + (step if q % 2 == 1 else 0)
        if rr >= h or cc >= w:
            continue
        j = rr * w + cc
        if face[j] >= 0 and semantic[j] == semantic[i] and (
                abs(depth[i] - depth[j]) <= np.float32(0.2)):
            return q
    return -1


_GATHER_CHUNK = 8192  # pixels per chunk of the parallel gathers


@njit(parallel=True, **_OPTS)
def gather_shadow_rays(own, rays, t, normal, light, peel, disk, seed):  # pragma: no cover
    """(k,) pixel indices with ``own`` (ascending) and their (k, 6) shadow rays towards
    ``light``, starting ``peel`` metres off the surface along its normal. ``disk`` (2, 3):
    two vectors spanning the sun's disk (perpendicular to ``light``, length tan(angular
    radius)); each ray aims at a point of the disk drawn uniformly from a hash of (seed,
    pixel index), so shadow edges get a penumbra as wide as the occluder's distance x the
    disk's angle. Chunks of pixels in parallel, each written at its prefix-sum offset
    (the same arrays as a serial pass)."""
    n = own.shape[0]
    nch = (n + _GATHER_CHUNK - 1) // _GATHER_CHUNK
    start = np.zeros(nch + 1, np.int64)
    for b in prange(nch):
        k = 0
        for i in range(b * _GATHER_CHUNK, min(n, (b + 1) * _GATHER_CHUNK)):
            if own[i]:
                k += 1
        start[b + 1] = k
    for b in range(nch):
        start[b + 1] += start[b]
    k = start[nch]
    idx = np.empty(k, np.int64)
    out = np.empty((k, 6), np.float32)
    golden = np.uint64(0x9E3779B97F4A7C15)
    soft = disk[0, 0] != 0 or disk[0, 1] != 0 or disk[0, 2] != 0
    for b in prange(nch):
        j = start[b]
        for i in range(b * _GATHER_CHUNK, min(n, (b + 1) * _GATHER_CHUNK)):
            if not own[i]:
                continue
            idx[j] = i
            ti = t[i]
            a = np.float32(0.0)
            bb = np.float32(0.0)
            if soft:
                z = _mix64(seed + np.uint64(i + 1) * golden)
                u1 = np.float32((z >> np.uint64(40)) * (1.0 / 16777216.0))
                u2 = np.float32(((z >> np.uint64(16)) & np.uint64(0xFFFFFF)) * (1.0 / 16777216.0))
                rr = np.sqrt(u1)
                a = rr * np.cos(np.float32(2.0 * np.pi) * u2)
                bb = rr * np.sin(np.float32(2.0 * np.pi) * u2)
            for q in range(3):
                out[j, q] = rays[i, q] + ti * rays[i, 3 + q] + peel * normal[i, q]
                out[j, 3 + q] = light[q] + a * disk[0, q] + bb * disk[1, q]
            j += 1
    return idx, out


_BLOCK_FIRST = np.zeros(0, np.uint8)  # no corner table: every pixel copies its block's first


@njit(**_OPTS)
def spread_shadow(h, w, step, own, ndl, idx, vis, lit):  # pragma: no cover - compiled
    """``lit`` (n,) float32, all ones on entry: the sun visibility ``vis`` (k,) float32 of
    each shadow ray (0 blocked, 1 clear, in between through a tree crown's gaps); pixels
    without their own ray copy their block's first pixel (when they face the sun)."""
    spread_shadow_nearest(h, w, step, own, ndl, _BLOCK_FIRST, idx, vis, lit)


@njit(parallel=True, **_OPTS)
def spread_shadow_nearest(h, w, step, own, ndl, src, idx, vis, lit):  # pragma: no cover
    """:func:`spread_shadow` for :func:`surface` with ``nearest``: a pixel without its own
    ray that faces the sun copies the corner sample ``src`` (from :func:`surface`) of its
    cell (its block's first pixel when on the same surface, else the next corner that is;
    an empty ``src``: always its block's first pixel)."""
    scatter_values(idx, vis, lit)
    if step <= 1:
        return
    first = src.shape[0] == 0
    for r in prange(h):
        rb = (r // step) * step
        cb = 0  # c - c % step
        for c in range(w):
            if c - cb == step:
                cb = c
            i = r * w + c
            if not own[i] and ndl[i] > 0:
                q = 0 if first else src[i]
                lit[i] = lit[(rb + (step if q >= 2 else 0)) * w + cb + (step if q % 2 == 1
                                                                          else 0)]


@njit(parallel=True, **_OPTS)
def scatter_values(idx, vals, out):  # pragma: no cover - compiled
    """``out[idx[j]] = vals[j]`` for every j (distinct indices)."""
    for j in prange(idx.shape[0]):
        out[idx[j]] = vals[j]


# compose is over 100 lines on purpose: it is the one fused per-pixel pass of the shader
# (albedo, texture, light, specular, atmosphere); cut into several kernels it would write
# and read back whole-image temporaries between them, which the fusion exists to avoid.
@njit(parallel=True, **_OPTS)
def compose(  # size: the one fused per-pixel pass of the shader (see the comment above)
    h, w, rays, t, face, normal, depth, ndl, lit, has_lit, own, src, lit_step, nearest, ao,
    has_ao, face_material,
    face_albedo, mat_gain, tiles, textured, fine_t, coarse_t, dry_t, wetk_t, spec_t, shine_t,
    f0_t, wet,
    light, sun_rgb, sky_rgb, miss_rgb, veil_rgb, e_sun, e_sky, spec_dim, haze, inv_alt,
    vignetting, wear, wear_ids, refl, has_refl, kind_t, face_tangent, inv_focal, tex_seed,
    zenith_dim, out,
):  # pragma: no cover - compiled
    """Albedo (per-face, times the frame's per-material RGB gain ``mat_gain`` (m, 3)) with
    procedural texture, material detail (:func:`._materials.detail`: pattern kind
    ``kind_t`` (m,) per material, oriented by ``face_tangent`` (k, 2) for faces < k, world x
    for the others; ``inv_focal`` = 1 / focal length in pixels gives the pixel footprint;
    ``tex_seed`` uint64 seeds the cell hashes) and wetness, light (sun x shadow, sky x ambient occlusion), specular + sky reflection, haze and vignetting -> ``out`` (h, w, 3) float32
    linear radiance (tone mapping is :func:`tone`). ``refl`` (n, 3): radiance seen along
    a traced mirror ray (wet roads; < 0 = use the sky), used when ``has_refl``.

    Sun visibility (``has_lit``): with ``lit_step`` 0, ``lit`` (n,) is every pixel's;
    with ``lit_step`` k > 0, ``lit`` holds the shadow rays' results only at the pixels
    marked in ``own`` (ones elsewhere), and each other pixel facing the sun reads the block
    sample :func:`spread_shadow` (or, with ``nearest``, :func:`spread_shadow_nearest` and
    its corners ``src``) would have copied to it: the same values without that pass over
    the image, for frames where nothing blurs ``lit``.

    Haze: transmission (1 - haze) ** (path / altitude) along the pixel's ray (longer, more
    hazy paths towards the edges of a tilted view) and a veil ``veil_rgb`` brighter
    towards the sun (a simple forward-scattering phase term)."""
    lx, ly, lz = light[0], light[1], light[2]
    one = np.float32(1.0)
    zero = np.float32(0.0)
    t0 = tiles[0]
    t1 = tiles[1]
    t2 = tiles[2]
    dry_r, dry_g, dry_b = np.float32(0.42), np.float32(0.36), np.float32(0.20)
    log_clear = np.float32(np.log(max(one - haze, np.float32(1e-3))))
    for r in prange(h):
        vy = (np.float32(r) + np.float32(0.5) - np.float32(h) / 2) / (np.float32(h) / 2)
        # lit_step > 0: first row (flat offset) and column of pixel (r, c)'s block
        lrow = (r // lit_step) * lit_step * w if lit_step > 0 else 0
        lcol = 0
        for c in range(w):
            if c - lcol == lit_step:
                lcol = c
            i = r * w + c
            trans = one
            hz = zero
            dx_, dy_, dz_ = rays[i, 3], rays[i, 4], rays[i, 5]
            dn = np.sqrt(dx_ * dx_ + dy_ * dy_ + dz_ * dz_)
            if haze > 0:
                ti = t[i]
                path = ti * dn * inv_alt if ti < np.float32(1e30) else np.float32(1.6)
                path = min(max(path, np.float32(0.3)), np.float32(3.0))
                trans = np.float32(np.exp(log_clear * path))
                hz = (one - trans) * (one + np.float32(0.4) * (dx_ * lx + dy_ * ly + dz_ * lz)
                                      / dn)
            vig = one
            if vignetting > 0:
                vx = (np.float32(c) + np.float32(0.5) - np.float32(w) / 2) / (np.float32(w) / 2)
                vig = one - vignetting * np.float32(0.5) * (vy * vy + vx * vx)
            f = face[i]
            if f < 0:
                cr, cg, cb = miss_rgb[0], miss_rgb[1], miss_rgb[2]
            else:
                m = face_material[f]
                ar = face_albedo[f, 0] * mat_gain[m, 0]
                ag = face_albedo[f, 1] * mat_gain[m, 1]
                ab = face_albedo[f, 2] * mat_gain[m, 2]
                nc = zero
                sk = spec_t[m]
                f0 = f0_t[m]
                if textured:
                    qx, qy = _tex_coords(rays, t, i)
                    ty, tx = _texel(qx, qy)
                    nf = t0[ty, tx]  # fractal detail, 0.1 m texels (25.6 m period)
                    nc = _bilinear(t2, qx / np.float32(2.0), qy / np.float32(2.0))
                    gain = one + fine_t[m] * nf + coarse_t[m] * nc
                    gain = min(max(gain, np.float32(0.3)), np.float32(2.0))
                    ar *= gain
                    ag *= gain
                    ab *= gain
                    if wear > 0:
                        ar, ag, ab = _wear(m, wear, wear_ids, qx, qy, nf, t0, t1, t2, ar, ag,
                                           ab)
                    kd = kind_t[m]
                    if kd != 0:
                        ti = t[i]
                        wx = rays[i, 0] + ti * dx_
                        wy = rays[i, 1] + ti * dy_
                        tgx = one
                        tgy = zero
                        if f < face_tangent.shape[0]:
                            tgx = face_tangent[f, 0]
                            tgy = face_tangent[f, 1]
                        fp = max(ti * dn * inv_focal, np.float32(1e-3))
                        ar, ag, ab, sk, f0 = _materials.detail(
                            kd, wx * tgx + wy * tgy, wy * tgx - wx * tgy, qx, qy,
                            normal[i, 2], fp, tex_seed, nf, t0, t1, t2, wear, ar, ag, ab,
                            sk, f0)
                    dk = dry_t[m]
                    if dk > 0:  # grass / foliage drift towards dry yellow-brown
                        nd = _bilinear(t1, (qx + np.float32(57.0)) / np.float32(6.0),
                                       (qy + np.float32(57.0)) / np.float32(6.0))
                        d = dk * min(max(nd, zero), np.float32(3.0)) * np.float32(0.5)
                        ar += d * (dry_r - ar)
                        ag += d * (dry_g - ag)
                        ab += d * (dry_b - ab)
                shine = shine_t[m]
                if wet > 0:  # darker porous surfaces, puddles where the coarse noise is high
                    wk = wetk_t[m] * wet
                    pud = zero
                    if wetk_t[m] > 0.5:
                        pud = min(max((nc - (np.float32(1.6) - np.float32(1.2) * wet))
                                      * np.float32(2.0), zero), one)
                    g = (one - np.float32(0.45) * wk) * (one - np.float32(0.5) * pud)
                    ar *= g
                    ag *= g
                    ab *= g
                    sk += np.float32(0.5) * wk
                    f0 += np.float32(0.04) * wk + np.float32(0.3) * pud
                    if wk > 0:
                        shine = np.float32(60.0)
                li = one
                if has_lit:
                    if lit_step == 0 or own[i]:
                        li = lit[i]
                    elif ndl[i] > 0:
                        q = src[i] if nearest else 0
                        li = lit[lrow + (lit_step * w if q >= 2 else 0) + lcol
                                 + (lit_step if q % 2 == 1 else 0)]
                occ = ao[i] if has_ao else one
                nx, ny, nz = normal[i, 0], normal[i, 1], normal[i, 2]
                s_sun = e_sun * ndl[i] * li * trans
                s_sky = e_sky * (np.float32(0.55) + np.float32(0.45) * nz) * occ * trans
                cr = ar * (s_sun * sun_rgb[0] + s_sky * sky_rgb[0])
                cg = ag * (s_sun * sun_rgb[1] + s_sky * sky_rgb[1])
                cb = ab * (s_sun * sun_rgb[2] + s_sky * sky_rgb[2])
                if sk > 0 or f0 > 0:
                    vx_ = -dx_ / dn
                    vy_ = -dy_ / dn
                    vz_ = -dz_ / dn
                    hx, hy, hz_ = vx_ + lx, vy_ + ly, vz_ + lz
                    hn = np.sqrt(hx * hx + hy * hy + hz_ * hz_)
                    ndh = (nx * hx + ny * hy + nz * hz_) / hn
                    ndh = min(max(ndh, zero), one)
                    sp = sk * ndh ** shine * spec_dim * li
                    ndv = min(max(nx * vx_ + ny * vy_ + nz * vz_, zero), one)
                    fres = zero
                    if f0 > 0:
                        fres = f0 + (one - f0) * (one - ndv) ** 5
                    a = sp * np.float32(1.5) * trans
                    # sky radiance in the units of the diffuse terms: e_sky x sky colour,
                    # x a clear sky's gradient: the zenith (seen in roofs, bonnets, water
                    # at nadir) about 0.4 x the horizon (seen in windscreens, oblique views)
                    rz = np.float32(2.0) * ndv * nz - vz_
                    skyg = np.float32(1.2) - zenith_dim * max(rz, zero)
                    b = fres * skyg * e_sky * trans * (
                        np.float32(0.4) + np.float32(0.6) * occ)
                    if has_refl and refl[i, 0] >= 0:  # a traced mirror ray (wet roads)
                        b2 = fres * trans
                        cr += a * sun_rgb[0] + b2 * refl[i, 0]
                        cg += a * sun_rgb[1] + b2 * refl[i, 1]
                        cb += a * sun_rgb[2] + b2 * refl[i, 2]
                    else:
                        cr += a * sun_rgb[0] + b * sky_rgb[0]
                        cg += a * sun_rgb[1] + b * sky_rgb[1]
                        cb += a * sun_rgb[2] + b * sky_rgb[2]
            if haze > 0:
                cr += hz * veil_rgb[0]
                cg += hz * veil_rgb[1]
                cb += hz * veil_rgb[2]
            out[r, c, 0] = cr * vig
            out[r, c, 1] = cg * vig
            out[r, c, 2] = cb * vig


@njit(inline="always")
def _smooth(x):  # pragma: no cover - compiled
    x = min(max(x, np.float32(0.0)), np.float32(1.0))
    return x * x * (np.float32(3.0) - np.float32(2.0) * x)


@njit(inline="always")
def _wear(m, wear, ids, qx, qy, nf, t0, t1, t2, ar, ag, ab):  # pragma: no cover - compiled
    """Surface wear by world position, ``wear`` in [0, 1] (the frame's road age):
    asphalt (ids[0]): repair patches (4 m field, sharp edged, darker or lighter), a crack
    network (zero crossings of a 1.5 m fractal field), oil stains (0.8 m blobs);
    markings (ids[1]): faded towards the asphalt grey in patches at 8 m, 1 m and 0.1 m
    scales; grass (ids[2]): bare soil patches at
    3 m and 12 m scales."""
    one = np.float32(1.0)
    if m == ids[0]:
        p = _bilinear(t1, qx * np.float32(0.25) + np.float32(11.0),
                      qy * np.float32(0.25) + np.float32(5.0))
        if p > np.float32(1.5) - np.float32(0.6) * wear:
            g = np.float32(0.82) if p < np.float32(2.1) else np.float32(1.12)
            ar *= g
            ag *= g
            ab *= g
        c = _bilinear(t0, qx * np.float32(0.66) + np.float32(31.0),
                      qy * np.float32(0.66) + np.float32(17.0))
        cw = np.float32(0.05) * wear
        if abs(c) < cw:
            g = np.float32(0.55) + np.float32(0.45) * abs(c) / cw
            ar *= g
            ag *= g
            ab *= g
        o = _bilinear(t2, qx * np.float32(1.25) + np.float32(91.0),
                      qy * np.float32(1.25) + np.float32(53.0))
        st = _smooth((o - (np.float32(2.4) - np.float32(0.6) * wear)) * np.float32(2.0))
        g = one - np.float32(0.45) * st
        ar *= g
        ag *= g
        ab *= g
    elif m == ids[1]:
        # patchy at three scales: whole dashes (8 m), scuffs (1 m), flakes (0.1 m)
        f = (_bilinear(t1, qx + np.float32(7.0), qy + np.float32(3.0)) + np.float32(0.5) * nf
             + np.float32(0.7) * _bilinear(t2, qx * np.float32(0.125) + np.float32(23.0),
                                           qy * np.float32(0.125) + np.float32(41.0)))
        k = np.float32(0.85) * wear * _smooth((f + np.float32(0.8)) * np.float32(0.6))
        ar += k * (np.float32(0.2) - ar)
        ag += k * (np.float32(0.2) - ag)
        ab += k * (np.float32(0.21) - ab)
    elif m == ids[2]:
        b = _bilinear(t2, qx / np.float32(3.0) + np.float32(13.0),
                      qy / np.float32(3.0) + np.float32(7.0)) + np.float32(0.6) * _bilinear(
            t1, qx / np.float32(12.0) + np.float32(3.0), qy / np.float32(12.0))
        k = _smooth((b - np.float32(1.7) + np.float32(0.6) * wear) * np.float32(1.5) + np.float32(0.3) * nf)
        ar += k * (np.float32(0.40) - ar)
        ag += k * (np.float32(0.33) - ag)
        ab += k * (np.float32(0.23) - ab)
    return ar, ag, ab


@njit(parallel=True, **_OPTS)
def tone(lin, gains, saturation, lut, out):  # pragma: no cover - compiled
    """Camera rendering of linear radiance ``lin`` (h, w, 3) float32 -> ``out`` uint8:
    per-channel gain (exposure x white balance), saturation about the luma (ITU-R 601
    weights, so gray is kept), then the tone look-up table ``lut`` (m,) uint8 indexed by
    value x ``LUT_SCALE`` (values past its end saturate)."""
    h, w, _ = lin.shape
    m = lut.shape[0] - 1
    s = np.float32(LUT_SCALE)
    for r in prange(h):
        for c in range(w):
            cr = lin[r, c, 0] * gains[0]
            cg = lin[r, c, 1] * gains[1]
            cb = lin[r, c, 2] * gains[2]
            y = np.float32(0.299) * cr + np.float32(0.587) * cg + np.float32(0.114) * cb
            cr = y + saturation * (cr - y)
            cg = y + saturation * (cg - y)
            cb = y + saturation * (cb - y)
            out[r, c, 0] = lut[_qlut(cr * s, m)]
            out[r, c, 1] = lut[_qlut(cg * s, m)]
            out[r, c, 2] = lut[_qlut(cb * s, m)]


LUT_SCALE = 4096.0  # look-up table entries per unit of exposed linear value


@njit(inline="always")
def _qlut(x, m):  # pragma: no cover - compiled
    if not x > 0:  # also NaN
        return 0
    if x >= np.float32(m):
        return m
    return np.int64(x)


@njit(parallel=True, **_OPTS)
def gather_ao_rays(h, w, step, rays, t, normal, face, need, n_dirs, peel, seed):  # pragma: no cover
    """Ambient-occlusion probes: one sample pixel per step x step block (its centre) whose
    block is marked in ``need`` (bh * bw,) and hit something casts ``n_dirs``
    cosine-weighted rays over the hemisphere of its normal,
    stratified in azimuth with a per-block rotation from a hash of (seed, block index).
    Returns block index (k,) int64 of each sample and rays (k * n_dirs, 6) float32, in
    block order (rows of blocks in parallel, each written at its prefix-sum offset)."""
    bh = (h + step - 1) // step
    bw = (w + step - 1) // step
    per_row = np.zeros(bh + 1, np.int64)
    for br in prange(bh):
        r = min(br * step + step // 2, h - 1)
        k = 0
        for bc in range(bw):
            c = min(bc * step + step // 2, w - 1)
            if face[r * w + c] >= 0 and need[br * bw + bc]:
                k += 1
        per_row[br + 1] = k
    for br in range(bh):
        per_row[br + 1] += per_row[br]
    k = per_row[bh]
    blocks = np.empty(k, np.int64)
    out = np.empty((k * n_dirs, 6), np.float32)
    golden = np.uint64(0x9E3779B97F4A7C15)
    s = np.uint64(seed)
    two_pi = np.float32(2.0 * np.pi)
    for br in prange(bh):
        r = min(br * step + step // 2, h - 1)
        j = per_row[br]
        for bc in range(bw):
            c = min(bc * step + step // 2, w - 1)
            i = r * w + c
            b = br * bw + bc
            if face[i] < 0 or not need[b]:
                continue
            blocks[j] = b
            nx, ny, nz = normal[i, 0], normal[i, 1], normal[i, 2]
            # tangent frame around the normal
            if abs(nz) < np.float32(0.9):
                ux, uy, uz = -ny, nx, np.float32(0.0)
            else:
                ux, uy, uz = np.float32(0.0), -nz, ny
            un = np.sqrt(ux * ux + uy * uy + uz * uz)
            ux /= un
            uy /= un
            uz /= un
            vx = ny * uz - nz * uy
            vy = nz * ux - nx * uz
            vz = nx * uy - ny * ux
            ti = t[i]
            px = rays[i, 0] + ti * rays[i, 3] + peel * nx
            py = rays[i, 1] + ti * rays[i, 4] + peel * ny
            pz = rays[i, 2] + ti * rays[i, 5] + peel * nz
            z = _mix64(s + np.uint64(b + 1) * golden)
            rot = np.float32((z >> np.uint64(40)) * (1.0 / 16777216.0))
            for d in range(n_dirs):
                z2 = _mix64(z + np.uint64(d + 1) * golden)
                u1 = np.float32(((z2 >> np.uint64(40)) + 0.5) * (1.0 / 16777216.0))
                phi = two_pi * ((np.float32(d) + rot) / np.float32(n_dirs))
                sr = np.sqrt(u1)  # cosine-weighted: sin(theta) = sqrt(u)
                cz = np.sqrt(np.float32(1.0) - u1)
                a = sr * np.cos(phi)
                bb = sr * np.sin(phi)
                row = j * n_dirs + d
                out[row, 0] = px
                out[row, 1] = py
                out[row, 2] = pz
                out[row, 3] = a * ux + bb * vx + cz * nx
                out[row, 4] = a * uy + bb * vy + cz * ny
                out[row, 5] = a * uz + bb * vz + cz * nz
            j += 1
    return blocks, out


@njit(parallel=True, **_OPTS)
def ao_blocks(h, w, step, rays, t, face):  # pragma: no cover - compiled
    """Per step x step block: the highest world z of its hits (-inf if none), the z of its
    sample pixel (the block centre) and whether that sample hit something."""
    bh = (h + step - 1) // step
    bw = (w + step - 1) // step
    zmax = np.full(bh * bw, -np.inf, np.float32)
    zs = np.zeros(bh * bw, np.float32)
    hit = np.zeros(bh * bw, np.bool_)
    for br in prange(bh):
        for bc in range(bw):
            b = br * bw + bc
            m = np.float32(-np.inf)
            for r in range(br * step, min(br * step + step, h)):
                for c in range(bc * step, min(bc * step + step, w)):
                    i = r * w + c
                    if face[i] >= 0:
                        z = rays[i, 2] + t[i] * rays[i, 5]
                        if z > m:
                            m = z
            zmax[b] = m
            r = min(br * step + step // 2, h - 1)
            c = min(bc * step + step // 2, w - 1)
            i = r * w + c
            if face[i] >= 0:
                hit[b] = True
                zs[b] = rays[i, 2] + t[i] * rays[i, 5]
    return zmax, zs, hit


@njit(parallel=True, **_OPTS)
def spread_ao(h, w, step, low, semantic, depth, ao):  # pragma: no cover - compiled
    """``ao`` (n,) float32: unoccluded fraction of the sky hemisphere per pixel, bilinear
    between the four nearest block samples ``low`` (bh * bw,; < 0 = no sample) that lie on
    the same surface (same label, depth within 0.3 m + 5 %), else the pixel's own block
    sample; 1 where none applies."""
    bh = (h + step - 1) // step
    bw = (w + step - 1) // step
    half = step // 2
    for r in prange(h):
        fr = (np.float32(r) - np.float32(half)) / np.float32(step)
        br0 = min(max(np.int64(np.floor(fr)), 0), bh - 1)
        br1 = min(br0 + 1, bh - 1)
        wr = min(max(fr - np.float32(br0), np.float32(0.0)), np.float32(1.0))
        for c in range(w):
            i = r * w + c
            fc = (np.float32(c) - np.float32(half)) / np.float32(step)
            bc0 = min(max(np.int64(np.floor(fc)), 0), bw - 1)
            bc1 = min(bc0 + 1, bw - 1)
            wc = min(max(fc - np.float32(bc0), np.float32(0.0)), np.float32(1.0))
            # most pixels: every sample around them is unoccluded (1) or absent (< 0); the
            # result is then exactly 1 (a weighted mean of ones, or the own block's sample,
            # which is one of the four), so skip the surface tests
            v00 = low[br0 * bw + bc0]
            v01 = low[br0 * bw + bc1]
            v10 = low[br1 * bw + bc0]
            v11 = low[br1 * bw + bc1]
            if ((v00 == 1 or v00 < 0) and (v01 == 1 or v01 < 0) and (v10 == 1 or v10 < 0)
                    and (v11 == 1 or v11 < 0)):
                ao[i] = np.float32(1.0)
                continue
            acc = np.float32(0.0)
            wsum = np.float32(0.0)
            for q in range(4):
                bri = br0 if q < 2 else br1
                bci = bc0 if q % 2 == 0 else bc1
                wq = (wr if q >= 2 else np.float32(1.0) - wr) * (
                    wc if q % 2 == 1 else np.float32(1.0) - wc)
                v = low[bri * bw + bci]
                if v < 0 or wq <= 0:
                    continue
                sr = min(bri * step + half, h - 1)
                sc = min(bci * step + half, w - 1)
                si = sr * w + sc
                if semantic[si] != semantic[i]:
                    continue
                if abs(depth[si] - depth[i]) > np.float32(0.3) + np.float32(0.05) * depth[i]:
                    continue
                acc += wq * v
                wsum += wq
            if wsum > 0:
                ao[i] = acc / wsum
            else:
                v = low[(r // step) * bw + c // step]
                ao[i] = v if v >= 0 else np.float32(1.0)


@njit(inline="always")
def _mix64(z):  # pragma: no cover - compiled
    """splitmix64 finaliser: a well-mixed 64-bit hash of z."""
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@njit(parallel=True, **_OPTS)
def add_noise(img, seed, scale, shot, quantiles):  # pragma: no cover - compiled
    """In place: ``img`` (h, w, 3) uint8 += trunc(sigma * z), saturated to [0, 255], the
    same z for the three channels of a pixel, sigma = sqrt(scale^2 + shot^2 * v / 255) with v
    the pixel's mean value (read noise plus photon noise that grows with brightness). z is
    standard normal: the pixel's hash of (seed, pixel index) picks one of the 2^16
    equal-probability ``quantiles`` (the normal inverse CDF at (k + 0.5) / 2^16).
    Counter-based, so any thread count gives the same image."""
    h, w, _ = img.shape
    golden = np.uint64(0x9E3779B97F4A7C15)
    s = np.uint64(seed)
    s2 = scale * scale
    k2 = shot * shot / np.float32(255.0 * 3.0)
    for r in prange(h):
        for c in range(w):
            z = _mix64(s + np.uint64(r * w + c + 1) * golden)
            sig = scale
            if shot > 0:
                v = np.float32(np.int32(img[r, c, 0]) + np.int32(img[r, c, 1])
                               + np.int32(img[r, c, 2]))
                sig = np.sqrt(s2 + k2 * v)
            d = np.int32(quantiles[np.int64(z >> np.uint64(48))] * sig)
            for ch in range(3):
                v = np.int32(img[r, c, ch]) + d
                img[r, c, ch] = 0 if v < 0 else (255 if v > 255 else v)
