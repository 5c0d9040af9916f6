"""Shaded RGB from the primary hits: albedo, procedural texture, sun + sky, shadows, sensor.

The shader only decides colour; every label comes from the ray cast.

Model (float32, one fused pass over the pixels per stage: the numba kernels in
:mod:`aerial_synth.render._kernels`):

- **Albedo** from the RayScene's per-face tables (``face_albedo``, ``face_material``),
  with procedural texture: fractal noise tiles looked up by the hit's *world* position (a
  surface keeps its pattern across frames and overlapping tiles), at a fine fractal scale
  (0.1 m texels) and two smooth bilinear ones (2 m, 6 m), with amplitudes per material (asphalt
  grain, grass patches, leafy crowns, nearly clean paint). The noise tiles depend only on
  ``RenderConfig.texture_seed``.
- **Light**: Lambert sun term times a hard shadow from shadow rays (Embree any-hit test
  towards the sun, one per 2 x 2 block plus every pixel at an object edge; trees and
  buildings shade roads and vehicles, vehicles shade the road), plus sky ambient weighted
  by the normal's up component. Overcast dims the sun, raises the sky and softens shadows.
- **Specular**: Blinn-Phong sun highlight and a Fresnel sky reflection per material
  (glossy paint, dark reflective glass, matte tyres and trim, water); wet roads darken and
  gain sheen and puddles.
- **Atmosphere and sensor**: haze towards a grey-blue veil, exposure and white balance,
  vignetting, a tone curve, Gaussian blur, additive Gaussian noise, optional JPEG.

Sun azimuth is in degrees clockwise from north (90 = east), elevation above the horizon.
Every factor is drawn from the ranges of :class:`RenderConfig` with the frame's generator and
recorded in ``Frame.factors``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from functools import lru_cache

import numpy as np

from ..errors import ConfigError
from ..scene.model import MATERIAL_IDS, MATERIALS

__all__ = ["RenderConfig", "sample_factors", "shade", "sun_direction"]


def _range(name: str, value, lo: float, hi: float) -> tuple[float, float]:
    try:
        a, b = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ConfigError(f"render config {name}: expected (low, high), got {value!r}") from None
    if not (math.isfinite(a) and math.isfinite(b) and lo <= a <= b <= hi):
        raise ConfigError(
            f"render config {name}: expected {lo:g} <= low <= high <= {hi:g}, got ({a:g}, {b:g})"
        )
    return (a, b)


def _prob(name: str, value) -> float:
    v = float(value)
    if not 0.0 <= v <= 1.0:
        raise ConfigError(f"render config {name}: expected a probability in [0, 1], got {value!r}")
    return v


@dataclass(frozen=True)
class RenderConfig:
    """Ranges of the influence factors (each drawn uniformly per frame) and switches.

    A fixed value is a range with low == high, e.g. ``sun_elevation_deg=(40, 40)``.
    overcast / wet / jpeg apply with their probability, then their strength is drawn.
    """

    sun_azimuth_deg: tuple[float, float] = (0.0, 360.0)
    sun_elevation_deg: tuple[float, float] = (25.0, 70.0)
    haze: tuple[float, float] = (0.0, 0.3)
    overcast_probability: float = 0.25
    overcast: tuple[float, float] = (0.3, 1.0)
    wet_probability: float = 0.15
    wet: tuple[float, float] = (0.4, 1.0)
    exposure: tuple[float, float] = (0.9, 1.1)
    white_balance: tuple[float, float] = (-0.04, 0.04)
    blur_sigma_px: tuple[float, float] = (0.4, 0.8)
    noise_sigma: tuple[float, float] = (0.004, 0.012)
    jpeg_probability: float = 0.5
    jpeg_quality: tuple[float, float] = (70.0, 95.0)
    vignetting: tuple[float, float] = (0.0, 0.15)
    shadows: bool = True
    texture: bool = True
    texture_seed: int = 0
    backend: str = "raycast"

    def __post_init__(self) -> None:
        s = object.__setattr__
        s(self, "sun_azimuth_deg", _range("sun_azimuth_deg", self.sun_azimuth_deg, 0, 360))
        s(self, "sun_elevation_deg", _range("sun_elevation_deg", self.sun_elevation_deg, 1, 90))
        s(self, "haze", _range("haze", self.haze, 0, 1))
        s(self, "overcast", _range("overcast", self.overcast, 0, 1))
        s(self, "wet", _range("wet", self.wet, 0, 1))
        s(self, "exposure", _range("exposure", self.exposure, 0.05, 20))
        s(self, "white_balance", _range("white_balance", self.white_balance, -0.5, 0.5))
        s(self, "blur_sigma_px", _range("blur_sigma_px", self.blur_sigma_px, 0, 10))
        s(self, "noise_sigma", _range("noise_sigma", self.noise_sigma, 0, 0.5))
        s(self, "jpeg_quality", _range("jpeg_quality", self.jpeg_quality, 1, 100))
        s(self, "vignetting", _range("vignetting", self.vignetting, 0, 0.9))
        for p in ("overcast_probability", "wet_probability", "jpeg_probability"):
            s(self, p, _prob(p, getattr(self, p)))
        if self.backend not in ("raycast", "pyrender"):
            raise ConfigError(
                f"render config backend: expected one of raycast, pyrender, got {self.backend!r}"
            )
        s(self, "texture_seed", int(self.texture_seed))

    def to_dict(self) -> dict:
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            out[f.name] = list(v) if isinstance(v, tuple) else v
        return out

    @classmethod
    def from_mapping(cls, data) -> "RenderConfig":
        if not data:
            return cls()
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ConfigError(
                f"render config: unknown key(s) {unknown}; expected {', '.join(sorted(names))}"
            )
        kw = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
        return cls(**kw)


def sample_factors(cfg: RenderConfig, rng: np.random.Generator) -> dict:
    """Draw every influence factor for one frame (fixed draw order: deterministic)."""
    u = rng.uniform
    f = {
        "sun_azimuth_deg": float(u(*cfg.sun_azimuth_deg)),
        "sun_elevation_deg": float(u(*cfg.sun_elevation_deg)),
        "haze": float(u(*cfg.haze)),
    }
    oc_on, oc = rng.random() < cfg.overcast_probability, float(u(*cfg.overcast))
    f["overcast"] = oc if oc_on else 0.0
    wet_on, wet = rng.random() < cfg.wet_probability, float(u(*cfg.wet))
    f["wet"] = wet if wet_on else 0.0
    f["exposure"] = float(u(*cfg.exposure))
    f["white_balance"] = float(u(*cfg.white_balance))
    f["blur_sigma_px"] = float(u(*cfg.blur_sigma_px))
    f["noise_sigma"] = float(u(*cfg.noise_sigma))
    jp_on, q = rng.random() < cfg.jpeg_probability, int(round(u(*cfg.jpeg_quality)))
    f["jpeg_quality"] = q if jp_on else None
    f["vignetting"] = float(u(*cfg.vignetting))
    f["shadows"] = bool(cfg.shadows)
    f["texture_seed"] = cfg.texture_seed if cfg.texture else None
    return f


def sun_direction(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    """(3,) unit vector towards the sun, world (x east, y north, z up)."""
    a, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    return np.array([math.sin(a) * math.cos(e), math.cos(a) * math.cos(e), math.sin(e)])


# ----------------------------------------------------------------------- materials
def _table(default: float, **values: float) -> np.ndarray:
    t = np.full(len(MATERIALS), default, np.float32)
    for k, v in values.items():
        t[MATERIAL_IDS[k]] = v
    return t


# texture amplitudes (relative albedo change per unit of noise, noise std ~ 1)
_FINE = _table(0.05, asphalt=0.10, marking=0.09, concrete=0.08, paving=0.08, grass=0.2,
               soil=0.18, water=0.04, roof=0.07, wall=0.06, foliage=0.35, bark=0.12,
               paint=0.008, glass=0.0, tyre=0.05, trim=0.02, cargo=0.02, metal=0.03)
_COARSE = _table(0.04, asphalt=0.08, grass=0.16, soil=0.12, foliage=0.15, roof=0.08,
                 water=0.1, paint=0.0, glass=0.0, tyre=0.0, trim=0.0, cargo=0.02)
# hue shift with coarse noise: grass/foliage drift towards dry yellow-brown
_DRY = _table(0.0, grass=0.35, foliage=0.2, soil=0.1)
# specular strength / shininess / sky reflection at normal incidence (F0)
_SPEC = _table(0.0, paint=0.35, glass=0.9, water=0.8, metal=0.3, roof=0.03, cargo=0.1,
               light_front=0.5, light_rear=0.4, trim=0.05, marking=0.02)
_SHINE = _table(20.0, paint=80.0, glass=300.0, water=400.0, metal=40.0, light_front=100.0,
                light_rear=100.0)
_F0 = _table(0.0, paint=0.05, glass=0.09, water=0.06, metal=0.2, light_front=0.05,
             light_rear=0.05, cargo=0.02)
# how strongly wetness darkens and glosses a material
_WETK = _table(0.0, asphalt=1.0, marking=0.7, concrete=0.9, paving=0.9, soil=0.6, roof=0.4,
               grass=0.2)

_FOLIAGE = MATERIAL_IDS["foliage"]
_PEEL = 0.03  # shadow-ray origin offset along the normal, metres


@lru_cache(maxsize=4)
def _noise_tiles(seed: int) -> np.ndarray:
    """(3, 256, 256) float32 periodic fractal noise tiles, zero mean, unit std."""
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x7E47]))
    n = 256
    fy = np.fft.fftfreq(n)[:, None]
    fx = np.fft.rfftfreq(n)[None, :]
    f = np.sqrt(fx * fx + fy * fy)
    f[0, 0] = 1.0
    out = np.empty((3, n, n), np.float32)
    for i, beta in enumerate((1.0, 1.6, 2.2)):
        spec = np.fft.rfft2(rng.standard_normal((n, n)))
        spec *= f ** (-beta)
        spec[0, 0] = 0
        t = np.fft.irfft2(spec, s=(n, n))
        out[i] = ((t - t.mean()) / t.std()).astype(np.float32)
    out.setflags(write=False)
    return out


@lru_cache(maxsize=1)
def _normal_quantiles() -> np.ndarray:
    """(65536,) float32 standard normal inverse CDF at (k + 0.5) / 65536 (|z| <= 4.3)."""
    from scipy.special import ndtri

    q = ndtri((np.arange(65536, dtype=np.float64) + 0.5) / 65536.0).astype(np.float32)
    q.setflags(write=False)
    return q


def _tone_lut() -> np.ndarray:
    """12-bit linear (0..4 in steps of 1/1024) -> 8-bit display value: soft shoulder + gamma."""
    x = np.arange(4096, dtype=np.float64) / 1024.0
    y = x / (1.0 + 0.25 * x) * 1.25
    return np.clip(np.power(np.clip(y, 0, 1), 1 / 2.2) * 255.0 + 0.5, 0, 255).astype(np.uint8)


_LUT = _tone_lut()


def shade(rayscene, camera, buffers, factors: dict, rng: np.random.Generator,
          timings: dict | None = None, shadow_step: int = 2) -> np.ndarray:
    """Shaded RGB (H, W, 3) uint8 for the primary hits in ``buffers`` under ``factors``.

    timings : optional dict that receives seconds per shading stage (for benchmarks).
    shadow_step : 1 = one shadow ray per pixel; k = one per k x k block plus every pixel
                  that differs from its block's first pixel (another label, or a depth
                  jump over 0.2 m), so object edges stay exact and only shadow edges
                  inside one surface are coarser.
    """
    import time

    import cv2

    from . import _kernels as K

    tick = [time.perf_counter()]

    def mark(name):
        if timings is not None:
            now = time.perf_counter()
            timings[name] = timings.get(name, 0.0) + now - tick[0]
            tick[0] = now

    h, w = buffers.height_px, buffers.width_px
    n = h * w
    step = max(1, int(shadow_step))
    oc = float(factors["overcast"])
    wet = np.float32(factors["wet"])
    L = sun_direction(factors["sun_azimuth_deg"], factors["sun_elevation_deg"]).astype(np.float32)
    textured = factors.get("texture_seed") is not None
    tiles = _noise_tiles(int(factors["texture_seed"]) if textured else 0)
    if len(rayscene.face_material):
        face_mat, face_alb = rayscene.face_material, rayscene.face_albedo
    else:  # empty scene: every ray misses
        face_mat, face_alb = np.zeros(1, np.uint8), np.zeros((1, 3), np.float32)
    ndl = np.empty(n, np.float32)
    own = np.empty(n, np.bool_)
    mark("setup")
    K.surface(h, w, buffers.rays, buffers.t, buffers.face, buffers.normal,
              buffers.semantic.reshape(-1), buffers.depth.reshape(-1), face_mat, tiles, textured,
              L, _FOLIAGE, step, ndl, own)
    mark("surface")

    has_lit = bool(factors.get("shadows", True))
    lit = np.ones(n if has_lit else 1, np.float32)
    if has_lit:
        idx, srays = K.gather_shadow_rays(own, buffers.rays, buffers.t, buffers.normal, L,
                                          np.float32(_PEEL))
        occ = rayscene.test_occlusions(srays) if len(idx) else np.zeros(0, bool)
        mark("shadow_rays")
        K.spread_shadow(h, w, step, own, ndl, idx, occ, lit)
        if oc > 0.02:  # overcast: a softer, wider shadow edge
            lit = cv2.GaussianBlur(lit.reshape(h, w), (0, 0), 0.5 + 6.0 * oc).reshape(-1)
        mark("shadow_spread")

    elev = math.radians(factors["sun_elevation_deg"])
    warm = max(0.0, 1.0 - elev / math.radians(45.0))
    wb = factors["white_balance"]
    cam_gain = np.array([1.0 + wb, 1.0, 1.0 - wb], np.float32) * np.float32(factors["exposure"])
    sun_col = np.array([1.0, 0.96 - 0.05 * warm, 0.90 - 0.12 * warm], np.float32)
    sky_col = np.array([0.60, 0.68, 0.85], np.float32)
    sky_col = sky_col + np.float32(oc) * (np.array([0.85, 0.86, 0.88], np.float32) - sky_col)
    e_sun = np.float32(1.15 * (1.0 - 0.85 * oc))
    e_sky = np.float32(0.30 + 0.45 * oc)
    veil = np.array([0.62, 0.66, 0.72], np.float32) * np.float32(0.8 + 0.4 * e_sky)
    alt = max(float(camera.altitude_m), 1.0)
    rgb = np.empty((h, w, 3), np.uint8)
    K.compose(h, w, buffers.rays, buffers.t, buffers.face, buffers.normal,
              buffers.depth.reshape(-1), ndl, lit, has_lit, face_mat, face_alb, tiles, textured,
              _FINE, _COARSE, _DRY, _WETK, _SPEC, _SHINE, _F0, wet, L,
              (sun_col * cam_gain).astype(np.float32), (sky_col * cam_gain).astype(np.float32),
              (sky_col * np.float32(0.25)).astype(np.float32),
              (veil * cam_gain).astype(np.float32), e_sun, e_sky,
              np.float32(1.0 - 0.9 * oc), np.float32(factors["haze"]), np.float32(1.0 / alt),
              np.float32(factors.get("vignetting", 0.0)), _LUT, rgb)
    mark("compose")

    # ---------------------------------------------------------------- sensor
    sig = factors["blur_sigma_px"]
    if sig > 0.05:
        rgb = cv2.GaussianBlur(rgb, (0, 0), sig)
    ns = factors["noise_sigma"]
    if ns > 0:
        seed = int(rng.integers(0, 2**63, dtype=np.int64))
        K.add_noise(rgb, np.uint64(seed), np.float32(ns * 255.0), _normal_quantiles())
    mark("sensor")
    q = factors.get("jpeg_quality")
    if q:
        ok, enc = cv2.imencode(".jpg", rgb[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, int(q)])
        if ok:
            rgb = np.ascontiguousarray(cv2.imdecode(enc, cv2.IMREAD_COLOR)[..., ::-1])
    mark("jpeg")
    return np.ascontiguousarray(rgb)
