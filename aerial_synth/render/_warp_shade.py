# size: the numba shader's per-pixel stages as Warp kernels, one module like _kernels.py
"""The shading model's per-pixel stages as Warp kernels, so that on a CUDA device a frame is
shaded where its rays were cast (``--backend warp``; :func:`.backends.warp.shade_on_device`).

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

__all__ = ["surface", "shadow", "spread_shadow", "blur_rows", "blur_cols", "ao_blocks",
           "dilate_blocks", "ao_cast", "spread_ao", "reflect_blocks", "reflect_spread",
           "compose", "luma", "tone", "grayscale", "smooth_normals"]

_GOLDEN = wp.constant(wp.uint64(0x9E3779B97F4A7C15))
_INV24 = wp.constant(1.0 / 16777216.0)
_TWO_PI = wp.constant(6.2831854820251465)  # np.float32(2 pi)

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
    return float(wp.float64(z >> wp.uint64(40)) * wp.float64(_INV24))


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


# ------------------------------------------------------------------ surface and shadows
@wp.kernel
def surface(h: int, w: int, rays: wp.array2d(dtype=float), t: wp.array(dtype=float),
            face: wp.array(dtype=wp.int64), normal: wp.array2d(dtype=float),
            semantic: wp.array(dtype=wp.uint8), depth: wp.array(dtype=float),
            face_mat: wp.array(dtype=wp.int32), tiles: wp.array3d(dtype=float), textured: int,
            light: wp.vec3, foliage_id: int, step: int, ndl_out: wp.array(dtype=float),
            own_out: wp.array(dtype=wp.uint8)):
    """:func:`._kernels.surface` (``nearest`` off)."""
    i = wp.tid()
    r = i // w
    c = i - r * w
    f = face[i]
    if f < wp.int64(0):
        ndl_out[i] = 0.0
        own_out[i] = wp.uint8(0)
        return
    ndl = normal[i, 0] * light[0] + normal[i, 1] * light[1] + normal[i, 2] * light[2]
    if textured != 0 and face_mat[f] == foliage_id:
        q = tex_coords(rays, t, i)
        ty = int(q[1] * 10.0) & 255
        tx = int(q[0] * 10.0) & 255
        k2 = ((ty << 8) | tx) + 12345
        k2 = k2 & 0xFFFF
        ndl += 0.45 * (tiles[1, ty, tx] * light[0] + tiles[1, k2 >> 8, k2 & 255] * light[1])
    ndl = wp.max(ndl, 0.0)
    ndl_out[i] = ndl
    own = False
    if step == 1:
        own = ndl > 0.0
    else:
        rb = (r // step) * step
        cb = (c // step) * step
        if r == rb and c == cb:
            own = True
        else:
            j = rb * w + cb
            own = ndl > 0.0 and (semantic[i] != semantic[j]
                                 or wp.abs(depth[i] - depth[j]) > 0.2)
    own_out[i] = wp.where(own, wp.uint8(1), wp.uint8(0))


@wp.kernel
def shadow(rays: wp.array2d(dtype=float), t: wp.array(dtype=float),
           normal: wp.array2d(dtype=float), own: wp.array(dtype=wp.uint8), light: wp.vec3,
           peel: float, disk0: wp.vec3, disk1: wp.vec3, soft: int, seed: wp.uint64,
           sid: wp.uint64, hs: int, tid_: wp.uint64, ht: int, vid: wp.uint64, hv: int,
           textured: int, tiles: wp.array3d(dtype=float), lit: wp.array(dtype=float)):
    """:func:`._kernels.gather_shadow_rays` + the occlusion tests + the crown gaps of
    ``shading._crown_gaps``, one pixel with its own ray per thread: ``lit`` (all ones on
    entry) gets 0 (blocked), 1 (clear) or the light through a crown's gaps."""
    i = wp.tid()
    if own[i] == wp.uint8(0):
        return
    a = float(0.0)
    b = float(0.0)
    if soft != 0:
        z = mix64(seed + wp.uint64(i + 1) * _GOLDEN)
        u1 = float(wp.float64(z >> wp.uint64(40)) * wp.float64(_INV24))
        u2 = float(wp.float64((z >> wp.uint64(16)) & wp.uint64(0xFFFFFF)) * wp.float64(_INV24))
        rr = wp.sqrt(u1)
        a = rr * wp.cos(_TWO_PI * u2)
        b = rr * wp.sin(_TWO_PI * u2)
    ti = t[i]
    o = wp.vec3(rays[i, 0] + ti * rays[i, 3] + peel * normal[i, 0],
                rays[i, 1] + ti * rays[i, 4] + peel * normal[i, 1],
                rays[i, 2] + ti * rays[i, 5] + peel * normal[i, 2])
    d = light + a * disk0 + b * disk1
    if not occluded_any(sid, hs, vid, hv, o, d, 1.0e30):
        lit[i] = 1.0
        return
    vis = float(0.0)
    if textured != 0 and not occluded_any(tid_, ht, vid, hv, o, d, 1.0e30):
        k = 6.0 / wp.max(d[2], 0.05)
        x = o[0] + k * d[0]
        y = o[1] + k * d[1]
        n = bil(tiles, 0, x * 2.0 + 41.0, y * 2.0 + 23.0)
        vis = wp.min(wp.max((n - 0.4) * 0.9, 0.0), 0.85)
    lit[i] = vis


@wp.kernel
def spread_shadow(w: int, step: int, own: wp.array(dtype=wp.uint8),
                  ndl: wp.array(dtype=float), lit: wp.array(dtype=float)):
    """:func:`._kernels.spread_shadow` after its scatter: a pixel without its own ray that
    faces the sun copies its block's first pixel (never written here: no race)."""
    i = wp.tid()
    if own[i] != wp.uint8(0) or ndl[i] <= 0.0:
        return
    r = i // w
    c = i - r * w
    lit[i] = lit[((r // step) * step) * w + (c // step) * step]


@wp.func
def reflect101(p: int, n: int):
    """OpenCV's BORDER_REFLECT_101 index."""
    if n == 1:
        return 0
    q = int(p)
    while q < 0 or q >= n:
        if q < 0:
            q = -q
        if q >= n:
            q = 2 * n - 2 - q
    return q


@wp.kernel
def blur_rows(src: wp.array2d(dtype=float), kern: wp.array(dtype=float),
              out: wp.array2d(dtype=float)):
    """One row pass of a separable float32 Gaussian (kernel ``kern``, REFLECT_101)."""
    r, c = wp.tid()
    w = src.shape[1]
    half = kern.shape[0] // 2
    acc = float(0.0)
    for k in range(kern.shape[0]):
        acc += kern[k] * src[r, reflect101(c + k - half, w)]
    out[r, c] = acc


@wp.kernel
def blur_cols(src: wp.array2d(dtype=float), kern: wp.array(dtype=float),
              out: wp.array2d(dtype=float)):
    """The column pass of :func:`blur_rows`."""
    r, c = wp.tid()
    h = src.shape[0]
    half = kern.shape[0] // 2
    acc = float(0.0)
    for k in range(kern.shape[0]):
        acc += kern[k] * src[reflect101(r + k - half, h), c]
    out[r, c] = acc


# ------------------------------------------------------------------ ambient occlusion
@wp.kernel
def ao_blocks(h: int, w: int, step: int, bw: int, rays: wp.array2d(dtype=float),
              t: wp.array(dtype=float), face: wp.array(dtype=wp.int64),
              zmax: wp.array(dtype=float), zs: wp.array(dtype=float),
              hit: wp.array(dtype=wp.uint8)):
    """:func:`._kernels.ao_blocks`, one block per thread."""
    b = wp.tid()
    br = b // bw
    bc = b - br * bw
    m = float(-1.0e38)
    found = bool(False)
    for r in range(br * step, wp.min(br * step + step, h)):
        for c in range(bc * step, wp.min(bc * step + step, w)):
            i = r * w + c
            if face[i] >= wp.int64(0):
                z = rays[i, 2] + t[i] * rays[i, 5]
                if z > m or not found:
                    m = z
                    found = True
    zmax[b] = wp.where(found, m, -1.0e38)
    r = wp.min(br * step + step // 2, h - 1)
    c = wp.min(bc * step + step // 2, w - 1)
    i = r * w + c
    if face[i] >= wp.int64(0):
        hit[b] = wp.uint8(1)
        zs[b] = rays[i, 2] + t[i] * rays[i, 5]
    else:
        hit[b] = wp.uint8(0)
        zs[b] = 0.0


@wp.kernel
def dilate_blocks(bh: int, bw: int, kr: int, zmax: wp.array(dtype=float),
                  out: wp.array(dtype=float)):
    """``cv2.dilate`` of the (bh, bw) block maxima with a (2 kr + 1) square (border
    ignored)."""
    b = wp.tid()
    br = b // bw
    bc = b - br * bw
    m = float(-1.0e38)
    for r in range(wp.max(br - kr, 0), wp.min(br + kr + 1, bh)):
        for c in range(wp.max(bc - kr, 0), wp.min(bc + kr + 1, bw)):
            m = wp.max(m, zmax[r * bw + c])
    out[b] = m


@wp.kernel
def ao_cast(h: int, w: int, step: int, bw: int, rays: wp.array2d(dtype=float),
            t: wp.array(dtype=float), normal: wp.array2d(dtype=float),
            face: wp.array(dtype=wp.int64), zn: wp.array(dtype=float),
            zs: wp.array(dtype=float), hit: wp.array(dtype=wp.uint8), n_dirs: int,
            peel: float, seed: wp.uint64, radius: float, sid: wp.uint64, hs: int,
            vid: wp.uint64, hv: int, low: wp.array(dtype=float)):
    """:func:`._kernels.gather_ao_rays` + their occlusion test within ``radius``: ``low``
    per block = unoccluded fraction (1 without rays, -1 without a hit)."""
    b = wp.tid()
    if hit[b] == wp.uint8(0):
        low[b] = -1.0
        return
    if not (zn[b] - zs[b] > 0.15):
        low[b] = 1.0
        return
    br = b // bw
    bc = b - br * bw
    r = wp.min(br * step + step // 2, h - 1)
    c = wp.min(bc * step + step // 2, w - 1)
    i = r * w + c
    nx = normal[i, 0]
    ny = normal[i, 1]
    nz = normal[i, 2]
    ux = float(0.0)
    uy = float(0.0)
    uz = float(0.0)
    if wp.abs(nz) < 0.9:
        ux = -ny
        uy = nx
    else:
        uy = -nz
        uz = ny
    un = wp.sqrt(ux * ux + uy * uy + uz * uz)
    ux = ux / un
    uy = uy / un
    uz = uz / un
    vx = ny * uz - nz * uy
    vy = nz * ux - nx * uz
    vz = nx * uy - ny * ux
    ti = t[i]
    o = wp.vec3(rays[i, 0] + ti * rays[i, 3] + peel * nx, rays[i, 1] + ti * rays[i, 4] + peel * ny,
                rays[i, 2] + ti * rays[i, 5] + peel * nz)
    z = mix64(seed + wp.uint64(b + 1) * _GOLDEN)
    rot = float(wp.float64(z >> wp.uint64(40)) * wp.float64(_INV24))
    blocked = int(0)
    for d in range(n_dirs):
        z2 = mix64(z + wp.uint64(d + 1) * _GOLDEN)
        u1 = float((wp.float64(z2 >> wp.uint64(40)) + wp.float64(0.5)) * wp.float64(_INV24))
        phi = _TWO_PI * ((float(d) + rot) / float(n_dirs))
        sr = wp.sqrt(u1)
        cz = wp.sqrt(1.0 - u1)
        a = sr * wp.cos(phi)
        bb = sr * wp.sin(phi)
        dv = wp.vec3(a * ux + bb * vx + cz * nx, a * uy + bb * vy + cz * ny,
                     a * uz + bb * vz + cz * nz)
        if occluded_any(sid, hs, vid, hv, o, dv, radius):
            blocked += 1
    low[b] = float(wp.float64(1.0) - wp.float64(blocked) / wp.float64(n_dirs))


@wp.kernel
def spread_ao(h: int, w: int, step: int, low: wp.array(dtype=float),
              semantic: wp.array(dtype=wp.uint8), depth: wp.array(dtype=float),
              ao: wp.array(dtype=float)):
    """:func:`._kernels.spread_ao`."""
    i = wp.tid()
    r = i // w
    c = i - r * w
    bh = (h + step - 1) // step
    bw = (w + step - 1) // step
    half = step // 2
    fr = (float(r) - float(half)) / float(step)
    br0 = wp.min(wp.max(int(wp.floor(fr)), 0), bh - 1)
    br1 = wp.min(br0 + 1, bh - 1)
    wr = wp.min(wp.max(fr - float(br0), 0.0), 1.0)
    fc = (float(c) - float(half)) / float(step)
    bc0 = wp.min(wp.max(int(wp.floor(fc)), 0), bw - 1)
    bc1 = wp.min(bc0 + 1, bw - 1)
    wc = wp.min(wp.max(fc - float(bc0), 0.0), 1.0)
    v00 = low[br0 * bw + bc0]
    v01 = low[br0 * bw + bc1]
    v10 = low[br1 * bw + bc0]
    v11 = low[br1 * bw + bc1]
    if ((v00 == 1.0 or v00 < 0.0) and (v01 == 1.0 or v01 < 0.0) and (v10 == 1.0 or v10 < 0.0)
            and (v11 == 1.0 or v11 < 0.0)):
        ao[i] = 1.0
        return
    acc = float(0.0)
    wsum = float(0.0)
    for q in range(4):
        bri = wp.where(q < 2, br0, br1)
        bci = wp.where(q % 2 == 0, bc0, bc1)
        wq = wp.where(q >= 2, wr, 1.0 - wr) * wp.where(q % 2 == 1, wc, 1.0 - wc)
        v = low[bri * bw + bci]
        if v < 0.0 or wq <= 0.0:
            continue
        sr = wp.min(bri * step + half, h - 1)
        sc = wp.min(bci * step + half, w - 1)
        si = sr * w + sc
        if semantic[si] != semantic[i]:
            continue
        if wp.abs(depth[si] - depth[i]) > 0.3 + 0.05 * depth[i]:
            continue
        acc += wq * v
        wsum += wq
    if wsum > 0.0:
        ao[i] = acc / wsum
    else:
        v = low[(r // step) * bw + c // step]
        ao[i] = wp.where(v >= 0.0, v, 1.0)


# ------------------------------------------------------------------ wet reflections
@wp.kernel
def reflect_blocks(h: int, w: int, gw: int, rays: wp.array2d(dtype=float),
                   t: wp.array(dtype=float), normal: wp.array2d(dtype=float),
                   face: wp.array(dtype=wp.int64), face_mat: wp.array(dtype=wp.int32),
                   face_alb: wp.array2d(dtype=float), gains: wp.array2d(dtype=float),
                   wetk: wp.array(dtype=float), peel: float, light: wp.vec3,
                   sun_col: wp.vec3, sky_col: wp.vec3, e_sun: float, e_sky: float,
                   sid: wp.uint64, hs: int, smap: wp.array(dtype=wp.int64), vid: wp.uint64,
                   hv: int, n_static: int, grid: wp.array2d(dtype=float)):
    """``shading._wet_reflections``' traced mirror ray, one per 2 x 2 block whose first
    pixel is wet: the radiance it sees, in ``grid`` (-1: no sample)."""
    g = wp.tid()
    gr = g // gw
    gc = g - gr * gw
    i = (2 * gr) * w + 2 * gc
    f = face[i]
    grid[g, 0] = -1.0
    if f < wp.int64(0):
        return
    if not (wetk[face_mat[f]] > 0.5):
        return
    raw = wp.vec3(rays[i, 3], rays[i, 4], rays[i, 5])
    d = raw / wp.length(raw)
    n = wp.vec3(normal[i, 0], normal[i, 1], normal[i, 2])
    ti = t[i]
    p = wp.vec3(rays[i, 0], rays[i, 1], rays[i, 2]) + ti * raw + peel * n
    rdir = d - 2.0 * wp.dot(d, n) * n
    hf = wp.int64(-1)
    hn = wp.vec3(0.0, 0.0, 0.0)
    tmax = float(1.0e30)
    if hs != 0:
        q = wp.mesh_query_ray(sid, p, rdir, tmax)
        if q.result:
            hf = smap[q.face]
            hn = q.normal
            tmax = q.t
    if hv != 0:
        q2 = wp.mesh_query_ray(vid, p, rdir, tmax)
        if q2.result and q2.t < tmax:
            hf = wp.int64(n_static) + wp.int64(q2.face)
            hn = q2.normal
    col = wp.vec3(0.0, 0.0, 0.0)
    if hf < wp.int64(0):
        col = sky_col * (1.2 * e_sky)
    else:
        m = face_mat[hf]
        if wp.dot(hn, rdir) > 0.0:
            hn = -hn
        ndl = wp.max(wp.dot(hn, light), 0.0)
        for k in range(3):
            alb = face_alb[hf, k] * gains[m, k]
            col[k] = alb * (e_sun * ndl * sun_col[k] + e_sky * (0.55 + 0.45 * hn[2]) * sky_col[k])
    for k in range(3):
        grid[g, k] = col[k]


@wp.kernel
def reflect_spread(w: int, gw: int, face: wp.array(dtype=wp.int64),
                   face_mat: wp.array(dtype=wp.int32), wetk: wp.array(dtype=float),
                   grid: wp.array2d(dtype=float), refl: wp.array2d(dtype=float)):
    """Every wet pixel takes its 2 x 2 block's sample (``refl`` -1: none)."""
    i = wp.tid()
    r = i // w
    c = i - r * w
    g = (r // 2) * gw + c // 2
    refl[i, 0] = -1.0
    f = face[i]
    if f < wp.int64(0):
        return
    if not (wetk[face_mat[f]] > 0.5) or grid[g, 0] < 0.0:
        return
    for k in range(3):
        refl[i, k] = grid[g, k]


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
def detail(kind: int, u: float, v: float, qx: float, qy: float, nz: float, fp: float,
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
def compose(h: int, w: int, rays: wp.array2d(dtype=float), t: wp.array(dtype=float),
            face: wp.array(dtype=wp.int64), normal: wp.array2d(dtype=float),
            ndl: wp.array(dtype=float), lit: wp.array(dtype=float),
            own: wp.array(dtype=wp.uint8), ao: wp.array(dtype=float),
            refl: wp.array2d(dtype=float), tiles: wp.array3d(dtype=float), tb: Tables,
            lt: Light, out: wp.array2d(dtype=float)):
    """:func:`._kernels.compose` (``nearest`` off): linear radiance per pixel."""
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
                li = lit[((r // lt.lit_step) * lt.lit_step) * w + (c // lt.lit_step) * lt.lit_step]
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


@wp.kernel
def smooth_normals(face: wp.array(dtype=wp.int64), uv: wp.array2d(dtype=float),
                   rays: wp.array2d(dtype=float), row: wp.array(dtype=wp.int32),
                   corners: wp.array3d(dtype=float), normal: wp.array2d(dtype=float)):
    """:func:`.smooth.smooth_shading_normals` (``smooth._smooth_one``): a hit on a
    smooth-material face gets the interpolated vertex normal."""
    i = wp.tid()
    f = face[i]
    if f < wp.int64(0) or f >= wp.int64(row.shape[0]):
        return
    k = row[f]
    if k < 0:
        return
    u = uv[i, 0]
    v = uv[i, 1]
    w0 = 1.0 - u - v
    s = wp.vec3(w0 * corners[k, 0, 0] + u * corners[k, 1, 0] + v * corners[k, 2, 0],
                w0 * corners[k, 0, 1] + u * corners[k, 1, 1] + v * corners[k, 2, 1],
                w0 * corners[k, 0, 2] + u * corners[k, 1, 2] + v * corners[k, 2, 2])
    ln = wp.length(s)
    if ln <= 1.0e-12:
        return
    s = s / ln
    g = wp.vec3(normal[i, 0], normal[i, 1], normal[i, 2])
    if wp.dot(s, g) < 0.0:
        s = -s
    if s[0] * rays[i, 3] + s[1] * rays[i, 4] + s[2] * rays[i, 5] >= 0.0:
        return
    for q in range(3):
        normal[i, q] = s[q]
