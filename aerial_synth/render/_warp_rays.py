"""The shading model's ray-casting stages as Warp kernels (see :mod:`._warp_shade`): smooth
crown normals, the sun cosine and shadow-ray selection, shadow rays with the crown gaps cast
in place, their spread and OpenCV's float Gaussian blur, ambient occlusion per block, and
the wet-road mirror rays. Each names the numba kernel or ``shading`` function it follows.

Imported only once Warp is known to be installed (it imports ``warp`` at the top).
"""

from __future__ import annotations

import warp as wp

from ._warp_shade import GOLDEN, INV24, TWO_PI, bil, mix64, occluded_any, tex_coords

__all__ = ["smooth_normals", "surface", "shadow", "spread_shadow", "blur_rows", "blur_cols",
           "ao_blocks", "dilate_blocks", "ao_cast", "spread_ao", "reflect_blocks",
           "reflect_spread"]


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


# ------------------------------------------------------------------ surface and shadows
@wp.kernel
def surface(h: int, w: int, rays: wp.array2d(dtype=float), t: wp.array(dtype=float),
            face: wp.array(dtype=wp.int64), normal: wp.array2d(dtype=float),
            semantic: wp.array(dtype=wp.uint8), depth: wp.array(dtype=float),
            face_mat: wp.array(dtype=wp.int32), tiles: wp.array3d(dtype=float), textured: int,
            light: wp.vec3, foliage_id: int, step: int, nearest: int,
            ndl_out: wp.array(dtype=float), own_out: wp.array(dtype=wp.uint8),
            src_out: wp.array(dtype=wp.uint8)):
    """:func:`._kernels.surface`; with ``nearest`` a pixel facing the sun that differs from
    its block's first pixel copies the first corner sample on its surface (``src_out``)
    and casts its own ray only when there is none."""
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
        tq = tex_coords(rays, t, i)
        ty = int(tq[1] * 10.0) & 255
        tx = int(tq[0] * 10.0) & 255
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
            if nearest != 0 and ndl > 0.0:
                q = int(0)
                if own:
                    q = shadow_source(i, rb, cb, step, h, w, face, semantic, depth)
                    own = q < 0
                src_out[i] = wp.uint8(wp.max(q, 0))
    own_out[i] = wp.where(own, wp.uint8(1), wp.uint8(0))


@wp.func
def shadow_source(i: int, r0: int, c0: int, step: int, h: int, w: int,
                  face: wp.array(dtype=wp.int64), semantic: wp.array(dtype=wp.uint8),
                  depth: wp.array(dtype=float)):
    """:func:`._kernels._shadow_source`: the first corner sample of pixel i's cell on its
    surface (0-3), -1 when none is."""
    for q in range(4):
        rr = r0 + wp.where(q >= 2, step, 0)
        cc = c0 + wp.where(q % 2 == 1, step, 0)
        if rr >= h or cc >= w:
            continue
        j = rr * w + cc
        if face[j] >= wp.int64(0) and semantic[j] == semantic[i] and (
                wp.abs(depth[i] - depth[j]) <= 0.2):
            return q
    return -1


@wp.func
def corner_index(r: int, c: int, w: int, step: int, q: int):
    """Flat index of corner sample q of the step x step cell of pixel (r, c)."""
    return ((r // step) * step + wp.where(q >= 2, step, 0)) * w + (c // step) * step + wp.where(
        q % 2 == 1, step, 0)


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
        z = mix64(seed + wp.uint64(i + 1) * GOLDEN)
        u1 = float(wp.float64(z >> wp.uint64(40)) * wp.float64(INV24))
        u2 = float(wp.float64((z >> wp.uint64(16)) & wp.uint64(0xFFFFFF)) * wp.float64(INV24))
        rr = wp.sqrt(u1)
        a = rr * wp.cos(TWO_PI * u2)
        b = rr * wp.sin(TWO_PI * u2)
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
def spread_shadow(w: int, step: int, nearest: int, own: wp.array(dtype=wp.uint8),
                  ndl: wp.array(dtype=float), src: wp.array(dtype=wp.uint8),
                  lit: wp.array(dtype=float)):
    """:func:`._kernels.spread_shadow` (``nearest``: :func:`._kernels.spread_shadow_nearest`)
    after its scatter: a pixel without its own ray that faces the sun copies its block's
    first pixel (or the corner ``src``); corners are never written here: no race."""
    i = wp.tid()
    if own[i] != wp.uint8(0) or ndl[i] <= 0.0:
        return
    r = i // w
    c = i - r * w
    q = int(0)
    if nearest != 0:
        q = int(src[i])
    lit[i] = lit[corner_index(r, c, w, step, q)]


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
    z = mix64(seed + wp.uint64(b + 1) * GOLDEN)
    rot = float(wp.float64(z >> wp.uint64(40)) * wp.float64(INV24))
    blocked = int(0)
    for d in range(n_dirs):
        z2 = mix64(z + wp.uint64(d + 1) * GOLDEN)
        u1 = float((wp.float64(z2 >> wp.uint64(40)) + wp.float64(0.5)) * wp.float64(INV24))
        phi = TWO_PI * ((float(d) + rot) / float(n_dirs))
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
