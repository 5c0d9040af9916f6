"""The shading model's per-pixel stages as Warp kernels, so that on a CUDA device a frame is
shaded where its rays were cast (``--backend warp``; :mod:`.backends._warp_device`): the
shared helpers, ``compose`` with every material pattern, and the camera's tone curve. The
stages that cast rays (shadows, ambient occlusion, wet-road mirrors) are in
:mod:`._warp_rays`.

Each kernel is the Warp form of the numba kernel of :mod:`._kernels` / :mod:`._materials`
named in its docstring, with the same float32 arithmetic in the same order where Warp has
it; the ray-casting gathers become kernels that cast their rays in place (no compaction),
and OpenCV's Gaussian blurs become separable convolutions with OpenCV's kernels and
borders. tests/render/test_warp_backend.py holds the result to the raycast backend's image
within :data:`aerial_synth.render.agreement.TOLERANCES`.

Imported only once Warp is known to be installed (it imports ``warp`` at the top).
"""

from __future__ import annotations

import warp as wp

__all__ = ["compose", "luma", "tone", "grayscale", "Light", "Tables", "GOLDEN", "INV24",
           "TWO_PI", "bil", "mix64", "occluded_any", "tex_coords"]

GOLDEN = wp.constant(wp.uint64(0x9E3779B97F4A7C15))
INV24 = wp.constant(1.0 / 16777216.0)
TWO_PI = wp.constant(6.2831854820251465)  # np.float32(2 pi)

KIND_GRAVEL = wp.constant(1)
KIND_TILES = wp.constant(2)
KIND_METAL = wp.constant(3)
KIND_TRACK = wp.constant(4)
KIND_ASPHALT = wp.constant(5)
KIND_PAVING = wp.constant(6)
KIND_CONCRETE = wp.constant(7)
KIND_VEGETATION = wp.constant(8)
KIND_WATER = wp.constant(9)


# ------------------------------------------------------------------ helpers
@wp.func
def mix64(z: wp.uint64):
    """splitmix64 finaliser (:func:`._kernels._mix64`)."""
    z = (z ^ (z >> wp.uint64(30))) * wp.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> wp.uint64(27))) * wp.uint64(0x94D049BB133111EB)
    return z ^ (z >> wp.uint64(31))


@wp.func
def hash01(a: wp.int64, b: wp.int64, seed: wp.uint64):
    """:func:`._materials.hash01`."""
    za = wp.uint64(a & wp.int64(0xFFFFFFFF)) * wp.uint64(0x9E3779B97F4A7C15)
    zb = wp.uint64(b & wp.int64(0xFFFFFFFF)) * wp.uint64(0xC2B2AE3D27D4EB4F)
    z = mix64(za ^ zb ^ seed)
    return float(wp.float64(z >> wp.uint64(40)) * wp.float64(INV24))


@wp.func
def bil(tiles: wp.array3d(dtype=float), k: int, x: float, y: float):
    """Wrapped bilinear lookup in tile k (:func:`._materials._bil`)."""
    fx0 = wp.floor(x)
    fy0 = wp.floor(y)
    fx = x - fx0
    fy = y - fy0
    x0 = int(fx0) & 255
    y0 = int(fy0) & 255
    x1 = (x0 + 1) & 255
    y1 = (y0 + 1) & 255
    a = tiles[k, y0, x0] * (1.0 - fx) + tiles[k, y0, x1] * fx
    b = tiles[k, y1, x0] * (1.0 - fx) + tiles[k, y1, x1] * fx
    return a * (1.0 - fy) + b * fy


@wp.func
def smooth01(x: float):
    x = wp.min(wp.max(x, 0.0), 1.0)
    return x * x * (3.0 - 2.0 * x)


@wp.func
def cum(x: float, period: float, width: float):
    k = wp.floor(x / period)
    return k * width + wp.min(x - k * period, width)


@wp.func
def line_cover(x: float, fp: float, period: float, width: float):
    """:func:`._materials.line_cover`."""
    h = 0.5 * fp
    c = (cum(x + h, period, width) - cum(x - h, period, width)) / fp
    return wp.min(wp.max(c, 0.0), 1.0)


@wp.func
def hit_point(rays: wp.array2d(dtype=float), t: wp.array(dtype=float), i: int):
    ti = t[i]
    return wp.vec3(rays[i, 0] + ti * rays[i, 3], rays[i, 1] + ti * rays[i, 4],
                   rays[i, 2] + ti * rays[i, 5])


@wp.func
def tex_coords(rays: wp.array2d(dtype=float), t: wp.array(dtype=float), i: int):
    """:func:`._kernels._tex_coords`: (qx, qy)."""
    p = hit_point(rays, t, i)
    return wp.vec2(p[0] + 0.37 * p[2], p[1] - 0.53 * p[2])


@wp.func
def occluded_any(sid: wp.uint64, hs: int, vid: wp.uint64, hv: int, o: wp.vec3, d: wp.vec3,
                 tfar: float):
    hit = False
    if hs != 0:
        hit = wp.mesh_query_ray_anyhit(sid, o, d, tfar)
    if not hit and hv != 0:
        hit = wp.mesh_query_ray_anyhit(vid, o, d, tfar)
    return hit


# ------------------------------------------------------------------ compose
@wp.func
def wear_fn(m: int, wear: float, ids: wp.vec3i, qx: float, qy: float, nf: float,
            tiles: wp.array3d(dtype=float), alb: wp.vec3):
    """:func:`._kernels._wear`."""
    ar = alb[0]
    ag = alb[1]
    ab = alb[2]
    if m == ids[0]:
        p = bil(tiles, 1, qx * 0.25 + 11.0, qy * 0.25 + 5.0)
        if p > 1.5 - 0.6 * wear:
            g = wp.where(p < 2.1, 0.82, 1.12)
            ar *= g
            ag *= g
            ab *= g
        c = bil(tiles, 0, qx * 0.66 + 31.0, qy * 0.66 + 17.0)
        cw = 0.05 * wear
        if wp.abs(c) < cw:
            g = 0.55 + 0.45 * wp.abs(c) / cw
            ar *= g
            ag *= g
            ab *= g
        o = bil(tiles, 2, qx * 1.25 + 91.0, qy * 1.25 + 53.0)
        st = smooth01((o - (2.4 - 0.6 * wear)) * 2.0)
        g = 1.0 - 0.45 * st
        ar *= g
        ag *= g
        ab *= g
    elif m == ids[1]:
        f = (bil(tiles, 1, qx + 7.0, qy + 3.0) + 0.5 * nf
             + 0.7 * bil(tiles, 2, qx * 0.125 + 23.0, qy * 0.125 + 41.0))
        k = 0.85 * wear * smooth01((f + 0.8) * 0.6)
        ar += k * (0.2 - ar)
        ag += k * (0.2 - ag)
        ab += k * (0.21 - ab)
    elif m == ids[2]:
        b = bil(tiles, 2, qx / 3.0 + 13.0, qy / 3.0 + 7.0) + 0.6 * bil(
            tiles, 1, qx / 12.0 + 3.0, qy / 12.0)
        k = smooth01((b - 1.7 + 0.6 * wear) * 1.5 + 0.3 * nf)
        ar += k * (0.40 - ar)
        ag += k * (0.33 - ag)
        ab += k * (0.23 - ab)
    return wp.vec3(ar, ag, ab)


@wp.func
def detail(  # size: one branch per material kind, as _materials.detail
        kind: int, u: float, v: float, qx: float, qy: float, nz: float, fp: float,
           seed: wp.uint64, nf: float, tiles: wp.array3d(dtype=float), wear: float,
           alb: wp.vec3, spec: wp.vec2):
    """:func:`._materials.detail`: (albedo, (specular strength, F0))."""
    ar = alb[0]
    ag = alb[1]
    ab = alb[2]
    sk = spec[0]
    f0 = spec[1]
    g = float(1.0)
    if kind == KIND_GRAVEL:
        iu = wp.int64(wp.floor(u * 16.0))
        iv = wp.int64(wp.floor(v * 16.0))
        hg = hash01(iu, iv, seed ^ wp.uint64(0x6A7E1))
        g = 0.86 + 0.28 * hg
        if hg > 0.95:
            g *= 0.6
        st = bil(tiles, 2, qx * 0.3 + 71.0, qy * 0.3 + 19.0)
        k = smooth01((st - 0.7) * 0.9)
        ar *= g * (1.0 - 0.34 * k)
        ag *= g * (1.0 - 0.36 * k)
        ab *= g * (1.0 - 0.40 * k)
    elif kind == KIND_TILES:
        s = u / wp.max(wp.abs(nz), 0.3)
        fps = fp / wp.max(wp.abs(nz), 0.3)
        ci = wp.int64(wp.floor(s / 0.32))
        tv = v / 0.28 + 0.5 * float(ci & wp.int64(1))
        ti = wp.int64(wp.floor(tv))
        ht = hash01(ci, ti, seed ^ wp.uint64(0x711E5))
        g = 0.84 + 0.3 * ht
        cs = line_cover(s + 0.07, fps, 0.32, 0.07)
        cg = line_cover(tv * 0.28, fp, 0.28, 0.012)
        g *= (1.0 - 0.5 * cs) * (1.0 - 0.35 * cg)
        wthr = bil(tiles, 1, qx * 0.5 + 33.0, qy * 0.5 + 91.0)
        g *= 1.0 - 0.12 * smooth01(wthr * 0.7)
        ar *= g
        ag *= g
        ab *= g
    elif kind == KIND_METAL:
        pitch = float(0.5)
        lt = line_cover(v, fp, pitch, 0.04)
        sh = line_cover(v - 0.04, fp, pitch, 0.04)
        pi = wp.int64(wp.floor(v / pitch))
        hp = hash01(pi, wp.int64(7), seed ^ wp.uint64(0x3E7A1))
        g = (0.92 + 0.16 * hp) * (1.0 + 0.5 * lt - 0.5 * sh)
        sk *= 0.6 + 0.8 * hp
        ar *= g
        ag *= g
        ab *= g
    elif kind == KIND_TRACK:
        streak = bil(tiles, 1, v * 5.0 + 13.0, u * 0.08 + 29.0)
        g = 0.88 + 0.06 * streak - 0.04 * nf
        ar *= g
        ag *= g
        ab *= g
    elif kind == KIND_ASPHALT:
        if wear > 0.0:
            cu = float(7.0)
            cv = float(3.5)
            iu = wp.int64(wp.floor(u / cu))
            iv = wp.int64(wp.floor(v / cv))
            s2 = seed ^ wp.uint64(0x9A7C4)
            if hash01(iu, iv, s2) < 0.22 * wear:
                fu = u / cu - float(iu)
                fv = v / cv - float(iv)
                a0 = 0.05 + 0.35 * hash01(iu, iv, s2 + wp.uint64(1))
                a1 = wp.min(a0 + 0.2 + 0.5 * hash01(iu, iv, s2 + wp.uint64(2)), 0.97)
                b0 = 0.05 + 0.3 * hash01(iu, iv, s2 + wp.uint64(3))
                b1 = wp.min(b0 + 0.25 + 0.5 * hash01(iu, iv, s2 + wp.uint64(4)), 0.97)
                if a0 <= fu and fu <= a1 and b0 <= fv and fv <= b1:
                    dark = hash01(iu, iv, s2 + wp.uint64(5)) < 0.6
                    g = wp.where(dark, 0.76, 1.12)
                    e = wp.min(wp.min(fu - a0, a1 - fu) * cu, wp.min(fv - b0, b1 - fv) * cv)
                    if e < 0.06:
                        g *= 0.75
            ar *= g
            ag *= g
            ab *= g
    elif kind == KIND_PAVING or kind == KIND_CONCRETE:
        slab = wp.where(kind == KIND_PAVING, 1.6, 3.0)
        jw = float(0.015)
        ju = line_cover(u + 0.5 * jw, fp, slab, jw)
        jv = line_cover(v + 0.5 * jw, fp, slab, jw)
        hw = float(0.08)
        hu = line_cover(u + 0.5 * hw, fp, slab, hw)
        hv = line_cover(v + 0.5 * hw, fp, slab, hw)
        j = 1.0 - (1.0 - ju) * (1.0 - jv)
        halo = 1.0 - (1.0 - hu) * (1.0 - hv)
        iu = wp.int64(wp.floor(u / slab + 0.5 * jw / slab))
        iv = wp.int64(wp.floor(v / slab + 0.5 * jw / slab))
        hsl = hash01(iu, iv, seed ^ wp.uint64(0x51AB))
        g = (0.94 + 0.12 * hsl) * (1.0 - 0.6 * j) * (1.0 - 0.1 * halo)
        ar *= g
        ag *= g
        ab *= g
    elif kind == KIND_VEGETATION:
        p = bil(tiles, 2, qx * 0.04 + 101.0, qy * 0.04 + 67.0)
        q = bil(tiles, 1, qx * 0.05 + 5.0, qy * 0.05 + 151.0)
        g = 1.0 + 0.1 * p
        ar *= g * (1.0 + 0.05 * q)
        ag *= g
        ab *= g * (1.0 - 0.05 * q)
    elif kind == KIND_WATER:
        r = bil(tiles, 0, qx * 3.0 + 0.4 * qy, qy * 0.6)
        cp = bil(tiles, 2, qx * 0.1 + 47.0, qy * 0.1 + 3.0)
        k = wp.max(1.0 + 0.35 * r + 0.3 * cp, 0.2)
        sk = sk * (1.0 + 0.8 * r * r)
        f0 = f0 * k
    return wp.vec3(ar, ag, ab), wp.vec2(sk, f0)


@wp.struct
class Light:
    light: wp.vec3
    sun_rgb: wp.vec3
    sky_rgb: wp.vec3
    miss_rgb: wp.vec3
    veil_rgb: wp.vec3
    e_sun: float
    e_sky: float
    spec_dim: float
    haze: float
    inv_alt: float
    vignetting: float
    wear: float
    wet: float
    inv_focal: float
    zenith_dim: float
    tex_seed: wp.uint64
    textured: int
    has_lit: int
    lit_step: int
    has_ao: int
    has_refl: int
    nearest: int
    wear_ids: wp.vec3i


@wp.struct
class Tables:
    face_mat: wp.array(dtype=wp.int32)
    face_alb: wp.array2d(dtype=float)
    face_tangent: wp.array2d(dtype=float)
    gains: wp.array2d(dtype=float)
    fine: wp.array(dtype=float)
    coarse: wp.array(dtype=float)
    dry: wp.array(dtype=float)
    wetk: wp.array(dtype=float)
    spec: wp.array(dtype=float)
    shine: wp.array(dtype=float)
    f0: wp.array(dtype=float)
    kind: wp.array(dtype=wp.int32)


@wp.kernel
def compose(  # size: the one fused per-pixel pass, as _kernels.compose
        h: int, w: int, rays: wp.array2d(dtype=float), t: wp.array(dtype=float),
            face: wp.array(dtype=wp.int64), normal: wp.array2d(dtype=float),
            ndl: wp.array(dtype=float), lit: wp.array(dtype=float),
            own: wp.array(dtype=wp.uint8), src: wp.array(dtype=wp.uint8),
            ao: wp.array(dtype=float),
            refl: wp.array2d(dtype=float), tiles: wp.array3d(dtype=float), tb: Tables,
            lt: Light, out: wp.array2d(dtype=float)):
    """:func:`._kernels.compose`: linear radiance per pixel."""
    i = wp.tid()
    r = i // w
    c = i - r * w
    light = lt.light
    log_clear = wp.log(wp.max(1.0 - lt.haze, 1.0e-3))
    vy = (float(r) + 0.5 - float(h) / 2.0) / (float(h) / 2.0)
    trans = float(1.0)
    hz = float(0.0)
    dx_ = rays[i, 3]
    dy_ = rays[i, 4]
    dz_ = rays[i, 5]
    dn = wp.sqrt(dx_ * dx_ + dy_ * dy_ + dz_ * dz_)
    if lt.haze > 0.0:
        ti = t[i]
        path = float(1.6)
        if ti < 1.0e30:
            path = ti * dn * lt.inv_alt
        path = wp.min(wp.max(path, 0.3), 3.0)
        trans = wp.exp(log_clear * path)
        hz = (1.0 - trans) * (1.0 + 0.4 * (dx_ * light[0] + dy_ * light[1] + dz_ * light[2])
                              / dn)
    vig = float(1.0)
    if lt.vignetting > 0.0:
        vx = (float(c) + 0.5 - float(w) / 2.0) / (float(w) / 2.0)
        vig = 1.0 - lt.vignetting * 0.5 * (vy * vy + vx * vx)
    f = face[i]
    col = wp.vec3(0.0, 0.0, 0.0)
    if f < wp.int64(0):
        col = lt.miss_rgb
    else:
        m = tb.face_mat[f]
        alb = wp.vec3(tb.face_alb[f, 0] * tb.gains[m, 0], tb.face_alb[f, 1] * tb.gains[m, 1],
                      tb.face_alb[f, 2] * tb.gains[m, 2])
        nc = float(0.0)
        sp = wp.vec2(tb.spec[m], tb.f0[m])
        if lt.textured != 0:
            q = tex_coords(rays, t, i)
            qx = q[0]
            qy = q[1]
            ty = int(qy * 10.0) & 255
            tx = int(qx * 10.0) & 255
            nf = tiles[0, ty, tx]
            nc = bil(tiles, 2, qx / 2.0, qy / 2.0)
            gain = 1.0 + tb.fine[m] * nf + tb.coarse[m] * nc
            gain = wp.min(wp.max(gain, 0.3), 2.0)
            alb = alb * gain
            if lt.wear > 0.0:
                alb = wear_fn(m, lt.wear, lt.wear_ids, qx, qy, nf, tiles, alb)
            kd = tb.kind[m]
            if kd != 0:
                ti = t[i]
                wx = rays[i, 0] + ti * dx_
                wy = rays[i, 1] + ti * dy_
                tgx = float(1.0)
                tgy = float(0.0)
                if f < wp.int64(tb.face_tangent.shape[0]):
                    tgx = tb.face_tangent[f, 0]
                    tgy = tb.face_tangent[f, 1]
                fp = wp.max(ti * dn * lt.inv_focal, 1.0e-3)
                alb, sp = detail(kd, wx * tgx + wy * tgy, wy * tgx - wx * tgy, qx, qy,
                                 normal[i, 2], fp, lt.tex_seed, nf, tiles, lt.wear, alb, sp)
            dk = tb.dry[m]
            if dk > 0.0:
                nd = bil(tiles, 1, (qx + 57.0) / 6.0, (qy + 57.0) / 6.0)
                d = dk * wp.min(wp.max(nd, 0.0), 3.0) * 0.5
                alb = wp.vec3(alb[0] + d * (0.42 - alb[0]), alb[1] + d * (0.36 - alb[1]),
                              alb[2] + d * (0.20 - alb[2]))
        sk = sp[0]
        f0 = sp[1]
        shine = tb.shine[m]
        if lt.wet > 0.0:
            wk = tb.wetk[m] * lt.wet
            pud = float(0.0)
            if tb.wetk[m] > 0.5:
                pud = wp.min(wp.max((nc - (1.6 - 1.2 * lt.wet)) * 2.0, 0.0), 1.0)
            g = (1.0 - 0.45 * wk) * (1.0 - 0.5 * pud)
            alb = alb * g
            sk += 0.5 * wk
            f0 += 0.04 * wk + 0.3 * pud
            if wk > 0.0:
                shine = 60.0
        li = float(1.0)
        if lt.has_lit != 0:
            if lt.lit_step == 0 or own[i] != wp.uint8(0):
                li = lit[i]
            elif ndl[i] > 0.0:
                qc = int(0)
                if lt.nearest != 0:
                    qc = int(src[i])
                s_ = lt.lit_step
                li = lit[((r // s_) * s_ + wp.where(qc >= 2, s_, 0)) * w + (c // s_) * s_
                         + wp.where(qc % 2 == 1, s_, 0)]
        occ = float(1.0)
        if lt.has_ao != 0:
            occ = ao[i]
        nx = normal[i, 0]
        ny = normal[i, 1]
        nz = normal[i, 2]
        s_sun = lt.e_sun * ndl[i] * li * trans
        s_sky = lt.e_sky * (0.55 + 0.45 * nz) * occ * trans
        col = wp.vec3(alb[0] * (s_sun * lt.sun_rgb[0] + s_sky * lt.sky_rgb[0]),
                      alb[1] * (s_sun * lt.sun_rgb[1] + s_sky * lt.sky_rgb[1]),
                      alb[2] * (s_sun * lt.sun_rgb[2] + s_sky * lt.sky_rgb[2]))
        if sk > 0.0 or f0 > 0.0:
            vx_ = -dx_ / dn
            vy_ = -dy_ / dn
            vz_ = -dz_ / dn
            hx = vx_ + light[0]
            hy = vy_ + light[1]
            hz_ = vz_ + light[2]
            hn = wp.sqrt(hx * hx + hy * hy + hz_ * hz_)
            ndh = (nx * hx + ny * hy + nz * hz_) / hn
            ndh = wp.min(wp.max(ndh, 0.0), 1.0)
            spc = sk * wp.pow(ndh, shine) * lt.spec_dim * li
            ndv = wp.min(wp.max(nx * vx_ + ny * vy_ + nz * vz_, 0.0), 1.0)
            fres = float(0.0)
            if f0 > 0.0:
                fres = f0 + (1.0 - f0) * wp.pow(1.0 - ndv, 5.0)
            a = spc * 1.5 * trans
            rz = 2.0 * ndv * nz - vz_
            skyg = 1.2 - lt.zenith_dim * wp.max(rz, 0.0)
            b = fres * skyg * lt.e_sky * trans * (0.4 + 0.6 * occ)
            if lt.has_refl != 0 and refl[i, 0] >= 0.0:
                b2 = fres * trans
                col = wp.vec3(col[0] + a * lt.sun_rgb[0] + b2 * refl[i, 0],
                              col[1] + a * lt.sun_rgb[1] + b2 * refl[i, 1],
                              col[2] + a * lt.sun_rgb[2] + b2 * refl[i, 2])
            else:
                col = wp.vec3(col[0] + a * lt.sun_rgb[0] + b * lt.sky_rgb[0],
                              col[1] + a * lt.sun_rgb[1] + b * lt.sky_rgb[1],
                              col[2] + a * lt.sun_rgb[2] + b * lt.sky_rgb[2])
    if lt.haze > 0.0:
        col = col + hz * lt.veil_rgb
    for k in range(3):
        out[i, k] = col[k] * vig


# ------------------------------------------------------------------ camera and sensor
@wp.kernel
def luma(lin: wp.array2d(dtype=float), wts: wp.vec3, w: int, out: wp.array2d(dtype=float)):
    """``cv2.transform`` of linear RGB by one row of weights: (h, w) float32."""
    i = wp.tid()
    r = i // w
    out[r, i - r * w] = wts[0] * lin[i, 0] + wts[1] * lin[i, 1] + wts[2] * lin[i, 2]


@wp.func
def qlut(x: float, m: int):
    if not x > 0.0:
        return 0
    if x >= float(m):
        return m
    return int(x)


@wp.kernel
def tone(lin: wp.array2d(dtype=float), gains: wp.vec3, saturation: float,
         lut: wp.array(dtype=wp.uint8), out: wp.array2d(dtype=wp.uint8)):
    """:func:`._kernels.tone`."""
    i = wp.tid()
    m = lut.shape[0] - 1
    s = float(4096.0)
    cr = lin[i, 0] * gains[0]
    cg = lin[i, 1] * gains[1]
    cb = lin[i, 2] * gains[2]
    y = 0.299 * cr + 0.587 * cg + 0.114 * cb
    cr = y + saturation * (cr - y)
    cg = y + saturation * (cg - y)
    cb = y + saturation * (cb - y)
    out[i, 0] = lut[qlut(cr * s, m)]
    out[i, 1] = lut[qlut(cg * s, m)]
    out[i, 2] = lut[qlut(cb * s, m)]


@wp.kernel
def grayscale(img: wp.array2d(dtype=wp.uint8)):
    """``cv2.cvtColor(RGB2GRAY)`` (14-bit fixed point, as OpenCV), written to all three
    channels in place."""
    i = wp.tid()
    y = (int(img[i, 0]) * 4899 + int(img[i, 1]) * 9617 + int(img[i, 2]) * 1868 + 8192) >> 14
    v = wp.uint8(wp.min(y, 255))
    img[i, 0] = v
    img[i, 1] = v
    img[i, 2] = v
