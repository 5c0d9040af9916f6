"""The shading model run where the rays were cast: :func:`shade_on_device` is
:func:`aerial_synth.render.shading.shade` with every per-pixel stage a Warp kernel
(:mod:`.._warp_shade`), for the ``warp`` backend on a CUDA device (and on the CPU when asked,
which is how the tests compare it with the numba stages).

What stays on the host: solving the auto exposure (from a 1/16 subsample of the metered
luma, as the numba path does), the sensor (OpenCV's 8-bit blur, the noise kernel) and the
optional JPEG artefacts; the frame's 8-bit RGB comes back to the host once, after the
tone curve. Options the device path does not have
(``shadow_edges="nearest"``) make :func:`supported` False, and the backend shades on the
host instead.
"""

from __future__ import annotations

import math
import time

import numpy as np

from .. import shading as S

__all__ = ["shade_on_device", "supported"]

_CONST: dict = {}  # (device, name) -> uploaded constant tables and noise tiles


def supported(factors: dict) -> bool:
    """Whether :func:`shade_on_device` has every option ``factors`` asks for."""
    step = max(1, int(factors.get("shadow_step", 2)))
    return not (factors.get("shadow_edges", "cast") == "nearest" and step > 1)


def _k():
    from .. import _warp_shade

    return _warp_shade


def _up(wp, dev, a, dtype):
    return wp.array(np.ascontiguousarray(a), dtype=dtype, device=dev)


def _const(wp, dev: str, name: str, make):
    key = (dev, name)
    if key not in _CONST:
        _CONST[key] = make()
    return _CONST[key]


def _gauss(sigma: float, u8: bool) -> np.ndarray:
    """OpenCV's Gaussian kernel for ``GaussianBlur(src, (0, 0), sigma)`` of a uint8 (``u8``)
    or float32 image."""
    import cv2

    n = int(np.rint(sigma * (3 if u8 else 4) * 2 + 1)) | 1
    return cv2.getGaussianKernel(n, sigma, cv2.CV_32F).reshape(-1).astype(np.float32)


def _blur(wp, K, dev, img, h: int, w: int, sigma: float):
    """Float32 (h, w) device image blurred as ``cv2.GaussianBlur(img, (0, 0), sigma)``."""
    kern = _up(wp, dev, _gauss(sigma, False), wp.float32)
    tmp = wp.empty((h, w), dtype=wp.float32, device=dev)
    out = wp.empty((h, w), dtype=wp.float32, device=dev)
    wp.launch(K.blur_rows, dim=(h, w), inputs=[img, kern], outputs=[tmp], device=dev)
    wp.launch(K.blur_cols, dim=(h, w), inputs=[tmp, kern], outputs=[out], device=dev)
    return out


def _scene_tables(ws, wp, K):
    """Per placement group: the face tables, tangents and crown corner normals on the
    device (made once per vehicle set)."""
    from ..smooth import corner_normals

    key = ("shade_tables", id(ws._veh_src))
    got = ws.__dict__.get("_shade_tables")
    if got is not None and got[0] == key:
        return got[1]
    dev = ws.device
    fm = np.ascontiguousarray(ws.face_material, np.int32)
    fa = np.ascontiguousarray(ws.face_albedo, np.float32).reshape(-1, 3)
    if not len(fm):
        fm, fa = np.zeros(1, np.int32), np.zeros((1, 3), np.float32)
    tang = S._face_tangents_cached(ws)
    row, corners = corner_normals(ws)
    tabs = {
        "face_mat": _up(wp, dev, fm, wp.int32),
        "face_alb": _up(wp, dev, fa, wp.float32),
        "face_tangent": _up(wp, dev, tang.reshape(-1, 2) if len(tang) else
                            np.zeros((0, 2), np.float32), wp.float32),
        "row": _up(wp, dev, row if len(row) else np.full(1, -1, np.int32), wp.int32),
        "corners": _up(wp, dev, corners if len(corners) else np.zeros((1, 3, 3), np.float32),
                       wp.float32),
    }
    ws.__dict__["_shade_tables"] = (key, tabs)
    return tabs


def shade_on_device(ws, camera, d: dict, factors: dict, timings: dict | None = None):
    """(H, W, 3) uint8 RGB of the frame whose primary buffers ``d`` (WarpScene device
    arrays: rays, face, t, normal, uv, semantic, depth) are on ``ws.device``; adds the
    metered ``exposure_gain`` and ``tone_power`` to ``factors``, as ``shade`` does."""
    from .warp import warp_module

    wp = warp_module()
    K = _k()
    dev = ws.device
    tick = [time.perf_counter()]

    def mark(name):
        if timings is not None:
            wp.synchronize_device(dev)
            now = time.perf_counter()
            timings[name] = timings.get(name, 0.0) + now - tick[0]
            tick[0] = now

    h, w = camera.height_px, camera.width_px
    n = h * w
    step = max(1, int(factors.get("shadow_step", 2)))
    pseed = int(factors.get("pixel_seed", 0))
    oc = float(factors["overcast"])
    wet = float(factors["wet"])
    L64 = S.sun_direction(factors["sun_azimuth_deg"], factors["sun_elevation_deg"])
    L = L64.astype(np.float32)
    Lv = wp.vec3(*L.tolist())
    textured = factors.get("texture_seed") is not None
    tseed = int(factors["texture_seed"]) if textured else 0
    tiles = _const(wp, dev, f"tiles{tseed}",
                   lambda: _up(wp, dev, S._noise_tiles(tseed), wp.float32))
    tabs = _scene_tables(ws, wp, K)
    sid, hs, smap, vid, hv = ws._meshes_for(())
    rays, t, face, normal = d["rays"], d["t"], d["face"], d["normal"]
    semantic, depth = d["semantic"], d["depth"]
    wp.launch(K.smooth_normals, dim=n, inputs=[face, d["uv"], rays, tabs["row"],
                                               tabs["corners"]], outputs=[normal], device=dev)
    ndl = wp.empty(n, dtype=wp.float32, device=dev)
    own = wp.empty(n, dtype=wp.uint8, device=dev)
    wp.launch(K.surface, dim=n, inputs=[h, w, rays, t, face, normal, semantic, depth,
                                        tabs["face_mat"], tiles, int(textured), Lv,
                                        int(S._FOLIAGE), step], outputs=[ndl, own], device=dev)
    mark("surface")

    has_lit = bool(factors.get("shadows", True))
    lit = wp.ones(n, dtype=wp.float32, device=dev)
    lit_step = 0
    if has_lit:
        disk = S._disk_vectors(L64, float(factors.get("sun_radius_deg", 0.0)))
        tid_, ht, _, _, _ = ws._meshes_for(("tree",))
        wp.launch(K.shadow, dim=n, inputs=[
            rays, t, normal, own, Lv, float(S._PEEL), wp.vec3(*disk[0].tolist()),
            wp.vec3(*disk[1].tolist()), int(bool(disk.any())),
            wp.uint64(np.uint64(pseed ^ 0x5D15C)), sid, hs, tid_, ht, vid, hv, int(textured),
            tiles], outputs=[lit], device=dev)
        mark("shadow_rays")
        sig = (0.5 + 6.0 * oc) if oc > 0.02 else (0.6 if disk.any() else 0.0)
        if sig <= 0 and S._SPREAD_IN_COMPOSE:
            lit_step = step
        elif step > 1:
            wp.launch(K.spread_shadow, dim=n, inputs=[w, step, own, ndl], outputs=[lit],
                      device=dev)
        if sig > 0:
            lit = _blur(wp, K, dev, lit.reshape((h, w)), h, w, sig).reshape((n,))
        mark("shadow_spread")

    ao_cfg = factors.get("ambient_occlusion")
    ao = wp.ones(1, dtype=wp.float32, device=dev)
    depth_h = None
    if ao_cfg:
        ao_step, n_dirs = int(ao_cfg["step_px"]), int(ao_cfg["rays"])
        radius = float(ao_cfg["radius_m"])
        bh, bw = -(-h // ao_step), -(-w // ao_step)
        nb = bh * bw
        zmax = wp.empty(nb, dtype=wp.float32, device=dev)
        zs = wp.empty(nb, dtype=wp.float32, device=dev)
        hit = wp.empty(nb, dtype=wp.uint8, device=dev)
        wp.launch(K.ao_blocks, dim=nb, inputs=[h, w, ao_step, bw, rays, t, face],
                  outputs=[zmax, zs, hit], device=dev)
        depth_h = depth.numpy().reshape(h, w)
        dd = depth_h[::16, ::16]
        dd = dd[dd > 0]
        px_m = float(np.median(dd)) / float(camera.K[0][0]) if len(dd) else 0.1
        kr = int(min(math.ceil(radius / max(px_m * ao_step, 1e-3)), 32))
        zn = wp.empty(nb, dtype=wp.float32, device=dev)
        wp.launch(K.dilate_blocks, dim=nb, inputs=[bh, bw, kr, zmax], outputs=[zn], device=dev)
        low = wp.empty(nb, dtype=wp.float32, device=dev)
        wp.launch(K.ao_cast, dim=nb, inputs=[
            h, w, ao_step, bw, rays, t, normal, face, zn, zs, hit, n_dirs, float(S._PEEL),
            wp.uint64(np.uint64(pseed ^ 0xA0)), radius, sid, hs, vid, hv], outputs=[low],
            device=dev)
        ao = wp.empty(n, dtype=wp.float32, device=dev)
        wp.launch(K.spread_ao, dim=n, inputs=[h, w, ao_step, low, semantic, depth],
                  outputs=[ao], device=dev)
        mark("ambient_occlusion")

    sun_col, sky_col, e_sun, e_sky, veil = S._light(factors, oc)
    alt = max(float(camera.altitude_m), 1.0)
    gains_m = S.material_gains(factors)
    gains_d = _up(wp, dev, gains_m.astype(np.float32), wp.float32)
    mats = {k: _const(wp, dev, k, lambda v=v, dt=dtype: _up(wp, dev, v, dt))
            for k, v, dtype in (("fine", S._FINE, wp.float32), ("coarse", S._COARSE, wp.float32),
                                ("dry", S._DRY, wp.float32), ("wetk", S._WETK, wp.float32),
                                ("spec", S._SPEC, wp.float32), ("shine", S._SHINE, wp.float32),
                                ("f0", S._F0, wp.float32),
                                ("kind", S._KIND.astype(np.int32), wp.int32))}
    has_refl = bool(factors.get("wet_reflections", False)) and wet > 0
    refl = wp.empty((1, 3), dtype=wp.float32, device=dev)
    if has_refl:
        gh, gw = -(-h // 2), -(-w // 2)
        grid = wp.empty((gh * gw, 3), dtype=wp.float32, device=dev)
        wp.launch(K.reflect_blocks, dim=gh * gw, inputs=[
            h, w, gw, rays, t, normal, face, tabs["face_mat"], tabs["face_alb"], gains_d,
            mats["wetk"], float(S._PEEL), Lv, wp.vec3(*sun_col.tolist()),
            wp.vec3(*sky_col.tolist()), float(e_sun), float(e_sky), sid, hs, smap, vid, hv,
            ws._meshes.n_static], outputs=[grid], device=dev)
        refl = wp.empty((n, 3), dtype=wp.float32, device=dev)
        wp.launch(K.reflect_spread, dim=n, inputs=[w, gw, face, tabs["face_mat"],
                                                   mats["wetk"], grid], outputs=[refl],
                  device=dev)
        mark("wet_reflections")

    tb = K.Tables()
    tb.face_mat, tb.face_alb, tb.face_tangent = (tabs["face_mat"], tabs["face_alb"],
                                                 tabs["face_tangent"])
    tb.gains = gains_d
    for k in ("fine", "coarse", "dry", "wetk", "spec", "shine", "f0", "kind"):
        setattr(tb, k, mats[k])
    lt = K.Light()
    lt.light = Lv
    lt.sun_rgb, lt.sky_rgb = wp.vec3(*sun_col.tolist()), wp.vec3(*sky_col.tolist())
    lt.miss_rgb = wp.vec3(*(sky_col * np.float32(0.25)).astype(np.float32).tolist())
    lt.veil_rgb = wp.vec3(*np.asarray(veil, np.float32).tolist())
    lt.e_sun, lt.e_sky = float(e_sun), float(e_sky)
    lt.spec_dim = float(np.float32(1.0 - 0.9 * oc))
    lt.haze = float(np.float32(factors["haze"]))
    lt.inv_alt = float(np.float32(1.0 / alt))
    lt.vignetting = float(np.float32(factors.get("vignetting", 0.0)))
    lt.wear = float(np.float32(factors.get("road_wear", 0.0)))
    lt.wet = float(np.float32(wet))
    lt.inv_focal = float(np.float32(1.0 / float(camera.K[0][0])))
    lt.zenith_dim = float(np.float32(0.72 * (1.0 - oc)))
    lt.tex_seed = wp.uint64(np.uint64(S._tex_hash_seed(tseed)))
    lt.textured, lt.has_lit, lt.lit_step = int(textured), int(has_lit), int(lit_step)
    lt.has_ao, lt.has_refl = int(bool(ao_cfg)), int(has_refl)
    lt.wear_ids = wp.vec3i(*[int(x) for x in S._WEAR_IDS])
    lin = wp.empty((n, 3), dtype=wp.float32, device=dev)
    wp.launch(K.compose, dim=n, inputs=[h, w, rays, t, face, normal, ndl, lit, own, ao, refl,
                                        tiles, tb, lt], outputs=[lin], device=dev)
    mark("compose")

    rgb = _camera(wp, K, dev, lin, factors, h, w)
    out = np.ascontiguousarray(rgb.numpy().reshape(h, w, 3))
    mark("tone")
    # the sensor on the host, OpenCV's 8-bit blur bit for bit (a float blur on the device
    # moved pixels by one level, which the JPEG artefacts that follow spread further)
    out = S._sensor_pass(out, factors, pseed)
    mark("sensor")
    q = factors.get("jpeg_quality")
    if q:
        import cv2

        ok, enc = cv2.imencode(".jpg", out[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, int(q)])
        if ok:
            out = np.ascontiguousarray(cv2.imdecode(enc, cv2.IMREAD_COLOR)[..., ::-1])
    mark("jpeg")
    return out, depth_h


def _camera(wp, K, dev, lin, factors, h, w):
    """``shading._camera_pass`` on the device: (n, 3) uint8."""
    from ..tone import solve_tone, tone_lut

    wb = float(factors["white_balance"])
    tint = float(factors.get("tint", 0.0))
    gains = np.array([math.exp(wb / 2), math.exp(tint), math.exp(-wb / 2)])
    gains /= float(S._LUMA @ gains)
    shoulder = float(factors.get("tone_shoulder", 0.25))
    if factors.get("exposure_mode", "fixed") == "auto":
        y = wp.empty((h, w), dtype=wp.float32, device=dev)
        wts = (S._LUMA * gains).astype(np.float32)
        wp.launch(K.luma, dim=h * w, inputs=[lin, wp.vec3(*wts.tolist()), w], outputs=[y],
                  device=dev)
        if factors["blur_sigma_px"] > 0.05:
            y = _blur(wp, K, dev, y, h, w, float(factors["blur_sigma_px"]))
        sub = y.numpy()[::4, ::4].reshape(-1).astype(np.float64)
        gain, power = solve_tone(sub, float(factors["key_gray"]),
                                 float(factors["target_gray_sd"]), shoulder)
    else:
        gain, power = float(factors["exposure"]), 1.0 / 2.2
    factors["exposure_gain"] = float(gain)
    factors["tone_power"] = float(power)
    rgb = wp.empty((h * w, 3), dtype=wp.uint8, device=dev)
    g = (gains * gain).astype(np.float32)
    lut = _up(wp, dev, tone_lut(shoulder, power), wp.uint8)
    wp.launch(K.tone, dim=h * w, inputs=[lin, wp.vec3(*g.tolist()),
                                         float(np.float32(factors.get("saturation", 1.0))), lut],
              outputs=[rgb], device=dev)
    if factors.get("grayscale"):
        wp.launch(K.grayscale, dim=h * w, inputs=[rgb], device=dev)
    return rgb
