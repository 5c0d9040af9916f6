"""The shading model run where the rays were cast: :func:`shade_on_device` is
:func:`aerial_synth.render.shading.shade` with every per-pixel stage a Warp kernel
(:mod:`.._warp_shade`), for the ``warp`` backend on a CUDA device (and on the CPU when asked,
which is how the tests compare it with the numba stages).

What stays on the host: solving the auto exposure (from a 1/16 subsample of the metered
luma, as the numba path does), the sensor (OpenCV's 8-bit blur, the noise kernel) and the
optional JPEG artefacts; the frame's 8-bit RGB comes back to the host once, after the
tone curve.
"""

from __future__ import annotations

import math
import time

import numpy as np

from .. import shading as S

__all__ = ["shade_on_device"]

_CONST: dict = {}  # (device, name) -> uploaded constant tables and noise tiles


def _k():
    """The two kernel modules: (shading, ray stages)."""
    from .. import _warp_rays, _warp_shade

    return _warp_shade, _warp_rays


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


def _blur(wp, R, dev, img, h: int, w: int, sigma: float):
    """Float32 (h, w) device image blurred as ``cv2.GaussianBlur(img, (0, 0), sigma)``."""
    kern = _up(wp, dev, _gauss(sigma, False), wp.float32)
    tmp = wp.empty((h, w), dtype=wp.float32, device=dev)
    out = wp.empty((h, w), dtype=wp.float32, device=dev)
    wp.launch(R.blur_rows, dim=(h, w), inputs=[img, kern], outputs=[tmp], device=dev)
    wp.launch(R.blur_cols, dim=(h, w), inputs=[tmp, kern], outputs=[out], device=dev)
    return out


def _scene_tables(ws, wp):
    """Per placement group: the face tables, tangents and crown corner normals on the
    device (made once per vehicle set)."""
    from ..smooth import corner_normals

    got = ws.__dict__.get("_shade_tables")  # dropped when the vehicles change
    if got is not None:
        return got
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
    ws.__dict__["_shade_tables"] = tabs
    return tabs


class _Frame:
    """One frame's shading state on the device (what ``shading.shade`` keeps in locals)."""

    def __init__(self, ws, camera, d: dict, factors: dict, timings):
        import warp as wp  # initialised by the backend (.warp.warp_module) before it calls

        self.wp = wp
        self.K, self.R = _k()
        self.ws, self.camera, self.d, self.f = ws, camera, d, factors
        self.dev = ws.device
        self.h, self.w = camera.height_px, camera.width_px
        self.n = self.h * self.w
        self.step = max(1, int(factors.get("shadow_step", 2)))
        self.nearest = factors.get("shadow_edges", "cast") == "nearest" and self.step > 1
        self.pseed = int(factors.get("pixel_seed", 0))
        self.oc = float(factors["overcast"])
        self.L64 = S.sun_direction(factors["sun_azimuth_deg"], factors["sun_elevation_deg"])
        self.Lv = wp.vec3(*self.L64.astype(np.float32).tolist())
        self.textured = factors.get("texture_seed") is not None
        self.tseed = int(factors["texture_seed"]) if self.textured else 0
        self.tiles = _const(wp, self.dev, f"tiles{self.tseed}",
                            lambda: _up(wp, self.dev, S._noise_tiles(self.tseed), wp.float32))
        # (static id, has static, face map, vehicles id, has vehicles); first, as it brings
        # the vehicles (and so the tables) up to date
        self.meshes = ws._meshes_for(())
        self.tabs = _scene_tables(ws, wp)
        self.timings = timings
        self.tick = time.perf_counter()
        self.depth_h = None

    def mark(self, name: str) -> None:
        if self.timings is not None:
            self.wp.synchronize_device(self.dev)
            now = time.perf_counter()
            self.timings[name] = self.timings.get(name, 0.0) + now - self.tick
            self.tick = now

    def launch(self, kernel, dim, inputs, outputs=()):
        self.wp.launch(kernel, dim=dim, inputs=inputs, outputs=list(outputs), device=self.dev)

    def surface(self):
        """Smooth crown normals, then (ndl, own) per pixel."""
        wp, d, R = self.wp, self.d, self.R
        self.launch(R.smooth_normals, self.n, [d["face"], d["uv"], d["rays"], self.tabs["row"],
                                               self.tabs["corners"]], [d["normal"]])
        ndl = wp.empty(self.n, dtype=wp.float32, device=self.dev)
        own = wp.empty(self.n, dtype=wp.uint8, device=self.dev)
        src = wp.zeros(self.n if self.nearest else 1, dtype=wp.uint8, device=self.dev)
        self.launch(R.surface, self.n, [self.h, self.w, d["rays"], d["t"], d["face"], d["normal"],
                                        d["semantic"], d["depth"], self.tabs["face_mat"],
                                        self.tiles, int(self.textured), self.Lv,
                                        int(S._FOLIAGE), self.step, int(self.nearest)],
                    [ndl, own, src])
        self.mark("surface")
        return ndl, own, src

    def shadows(self, ndl, own, src):
        """(lit (n,), lit_step): ``shading._shadow_pass`` on the device."""
        wp, d, R, f = self.wp, self.d, self.R, self.f
        lit = wp.ones(self.n, dtype=wp.float32, device=self.dev)
        if not bool(f.get("shadows", True)):
            return lit, 0
        disk = S._disk_vectors(self.L64, float(f.get("sun_radius_deg", 0.0)))
        sid, hs, _, vid, hv = self.meshes
        tid_, ht, _, _, _ = self.ws._meshes_for(("tree",))
        self.launch(R.shadow, self.n, [
            d["rays"], d["t"], d["normal"], own, self.Lv, float(S._PEEL),
            wp.vec3(*disk[0].tolist()), wp.vec3(*disk[1].tolist()), int(bool(disk.any())),
            wp.uint64(np.uint64(self.pseed ^ 0x5D15C)), sid, hs, tid_, ht, vid, hv,
            int(self.textured), self.tiles], [lit])
        self.mark("shadow_rays")
        lit_step = 0
        sig = (0.5 + 6.0 * self.oc) if self.oc > 0.02 else (0.6 if disk.any() else 0.0)
        if sig <= 0 and S._SPREAD_IN_COMPOSE:
            lit_step = self.step
        elif self.step > 1:
            self.launch(R.spread_shadow, self.n, [self.w, self.step, int(self.nearest), own,
                                                  ndl, src], [lit])
        if sig > 0:
            lit = _blur(wp, R, self.dev, lit.reshape((self.h, self.w)), self.h, self.w,
                        sig).reshape((self.n,))
        self.mark("shadow_spread")
        return lit, lit_step

    def ambient_occlusion(self):
        """``shading._ao_pass`` on the device: ao (n,) or (1,) ones without it."""
        wp, d, R = self.wp, self.d, self.R
        cfg = self.f.get("ambient_occlusion")
        if not cfg:
            return wp.ones(1, dtype=wp.float32, device=self.dev)
        ao_step, n_dirs, radius = int(cfg["step_px"]), int(cfg["rays"]), float(cfg["radius_m"])
        h, w = self.h, self.w
        bh, bw = -(-h // ao_step), -(-w // ao_step)
        nb = bh * bw
        zmax, zs, zn, low = (wp.empty(nb, dtype=wp.float32, device=self.dev) for _ in range(4))
        hit = wp.empty(nb, dtype=wp.uint8, device=self.dev)
        self.launch(R.ao_blocks, nb, [h, w, ao_step, bw, d["rays"], d["t"], d["face"]],
                    [zmax, zs, hit])
        self.depth_h = d["depth"].numpy().reshape(h, w)
        dd = self.depth_h[::16, ::16]
        dd = dd[dd > 0]
        px_m = float(np.median(dd)) / float(self.camera.K[0][0]) if len(dd) else 0.1
        kr = int(min(math.ceil(radius / max(px_m * ao_step, 1e-3)), 32))
        self.launch(R.dilate_blocks, nb, [bh, bw, kr, zmax], [zn])
        sid, hs, _, vid, hv = self.meshes
        self.launch(R.ao_cast, nb, [h, w, ao_step, bw, d["rays"], d["t"], d["normal"],
                                    d["face"], zn, zs, hit, n_dirs, float(S._PEEL),
                                    wp.uint64(np.uint64(self.pseed ^ 0xA0)), radius, sid, hs,
                                    vid, hv], [low])
        ao = wp.empty(self.n, dtype=wp.float32, device=self.dev)
        self.launch(R.spread_ao, self.n, [h, w, ao_step, low, d["semantic"], d["depth"]], [ao])
        self.mark("ambient_occlusion")
        return ao

    def reflections(self, light, gains_d, wetk):
        """``shading._wet_reflections`` on the device: (refl, has_refl)."""
        wp, d, R = self.wp, self.d, self.R
        sun_col, sky_col, e_sun, e_sky, _ = light
        if not (bool(self.f.get("wet_reflections", False)) and float(self.f["wet"]) > 0):
            return wp.empty((1, 3), dtype=wp.float32, device=self.dev), False
        gh, gw = -(-self.h // 2), -(-self.w // 2)
        grid = wp.empty((gh * gw, 3), dtype=wp.float32, device=self.dev)
        sid, hs, smap, vid, hv = self.meshes
        self.launch(R.reflect_blocks, gh * gw, [
            self.h, self.w, gw, d["rays"], d["t"], d["normal"], d["face"],
            self.tabs["face_mat"], self.tabs["face_alb"], gains_d, wetk, float(S._PEEL),
            self.Lv, wp.vec3(*sun_col.tolist()), wp.vec3(*sky_col.tolist()), float(e_sun),
            float(e_sky), sid, hs, smap, vid, hv, self.ws._meshes.n_static], [grid])
        refl = wp.empty((self.n, 3), dtype=wp.float32, device=self.dev)
        self.launch(R.reflect_spread, self.n, [self.w, gw, d["face"], self.tabs["face_mat"],
                                               wetk, grid], [refl])
        self.mark("wet_reflections")
        return refl, True

    def compose(self, ndl, own, src, lit, lit_step, ao):
        """Linear radiance (n, 3) float32: ``_kernels.compose`` as :func:`.._warp_shade.compose`."""
        wp, d, K, f = self.wp, self.d, self.K, self.f
        light = S._light(f, self.oc)
        sun_col, sky_col, e_sun, e_sky, veil = light
        gains_d = _up(wp, self.dev, S.material_gains(f).astype(np.float32), wp.float32)
        tb = K.Tables()
        for k, v in (("fine", S._FINE), ("coarse", S._COARSE), ("dry", S._DRY),
                     ("wetk", S._WETK), ("spec", S._SPEC), ("shine", S._SHINE), ("f0", S._F0),
                     ("kind", S._KIND.astype(np.int32))):
            dt = wp.int32 if k == "kind" else wp.float32
            setattr(tb, k, _const(wp, self.dev, k, lambda v=v, dt=dt: _up(wp, self.dev, v, dt)))
        tb.face_mat, tb.face_alb = self.tabs["face_mat"], self.tabs["face_alb"]
        tb.face_tangent, tb.gains = self.tabs["face_tangent"], gains_d
        refl, has_refl = self.reflections(light, gains_d, tb.wetk)
        lt = K.Light()
        lt.light = self.Lv
        lt.sun_rgb, lt.sky_rgb = wp.vec3(*sun_col.tolist()), wp.vec3(*sky_col.tolist())
        lt.miss_rgb = wp.vec3(*(sky_col * np.float32(0.25)).astype(np.float32).tolist())
        lt.veil_rgb = wp.vec3(*np.asarray(veil, np.float32).tolist())
        lt.e_sun, lt.e_sky = float(e_sun), float(e_sky)
        f32 = lambda x: float(np.float32(x))
        lt.spec_dim, lt.haze = f32(1.0 - 0.9 * self.oc), f32(f["haze"])
        lt.inv_alt = f32(1.0 / max(float(self.camera.altitude_m), 1.0))
        lt.vignetting, lt.wear = f32(f.get("vignetting", 0.0)), f32(f.get("road_wear", 0.0))
        lt.wet, lt.inv_focal = f32(f["wet"]), f32(1.0 / float(self.camera.K[0][0]))
        lt.zenith_dim = f32(0.72 * (1.0 - self.oc))
        lt.tex_seed = wp.uint64(np.uint64(S._tex_hash_seed(self.tseed)))
        lt.textured, lt.has_lit = int(self.textured), int(bool(f.get("shadows", True)))
        lt.lit_step, lt.has_ao, lt.has_refl = int(lit_step), int(bool(f.get(
            "ambient_occlusion"))), int(has_refl)
        lt.nearest = int(self.nearest)
        lt.wear_ids = wp.vec3i(*[int(x) for x in S._WEAR_IDS])
        lin = wp.empty((self.n, 3), dtype=wp.float32, device=self.dev)
        self.launch(K.compose, self.n, [self.h, self.w, d["rays"], d["t"], d["face"],
                                        d["normal"], ndl, lit, own, src, ao, refl, self.tiles,
                                        tb, lt], [lin])
        self.mark("compose")
        return lin


def shade_on_device(ws, camera, d: dict, factors: dict, timings: dict | None = None):
    """((H, W, 3) uint8 RGB, the depth buffer if it was copied to the host or None) of the
    frame whose primary buffers ``d`` (WarpScene device arrays: rays, face, t, normal, uv,
    semantic, depth) are on ``ws.device``; adds the metered ``exposure_gain`` and
    ``tone_power`` to ``factors``, as ``shading.shade`` does."""
    fr = _Frame(ws, camera, d, factors, timings)
    ndl, own, src = fr.surface()
    lit, lit_step = fr.shadows(ndl, own, src)
    ao = fr.ambient_occlusion()
    lin = fr.compose(ndl, own, src, lit, lit_step, ao)
    rgb = _camera(fr.wp, fr.K, fr.R, fr.dev, lin, factors, fr.h, fr.w)
    out = np.ascontiguousarray(rgb.numpy().reshape(fr.h, fr.w, 3))
    fr.mark("tone")
    # the sensor on the host, OpenCV's 8-bit blur bit for bit (a float blur on the device
    # moved pixels by one level, which the JPEG artefacts that follow spread further)
    out = S._sensor_pass(out, factors, fr.pseed)
    fr.mark("sensor")
    q = factors.get("jpeg_quality")
    if q:
        import cv2

        ok, enc = cv2.imencode(".jpg", out[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, int(q)])
        if ok:
            out = np.ascontiguousarray(cv2.imdecode(enc, cv2.IMREAD_COLOR)[..., ::-1])
    fr.mark("jpeg")
    return out, fr.depth_h


def _camera(wp, K, R, dev, lin, factors, h, w):
    """``shading._camera_pass`` on the device: (n, 3) uint8."""
    from ..tone import tone_lut

    gains = S.camera_gains(factors)

    def metered():  # as the host meters it, on the device
        y = wp.empty((h, w), dtype=wp.float32, device=dev)
        wts = (S._LUMA * gains).astype(np.float32)
        wp.launch(K.luma, dim=h * w, inputs=[lin, wp.vec3(*wts.tolist()), w], outputs=[y],
                  device=dev)
        if factors["blur_sigma_px"] > 0.05:
            y = _blur(wp, R, dev, y, h, w, float(factors["blur_sigma_px"]))
        return y.numpy()[::4, ::4].reshape(-1).astype(np.float64)

    gain, power, shoulder = S.exposure(factors, metered)
    rgb = wp.empty((h * w, 3), dtype=wp.uint8, device=dev)
    g = (gains * gain).astype(np.float32)
    lut = _up(wp, dev, tone_lut(shoulder, power), wp.uint8)
    wp.launch(K.tone, dim=h * w, inputs=[lin, wp.vec3(*g.tolist()),
                                         float(np.float32(factors.get("saturation", 1.0))), lut],
              outputs=[rgb], device=dev)
    if factors.get("grayscale"):
        wp.launch(K.grayscale, dim=h * w, inputs=[rgb], device=dev)
    return rgb
