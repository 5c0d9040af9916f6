"""Shaded RGB from the primary hits: albedo, texture and wear, sun + sky, shadows, ambient
occlusion, atmosphere, camera and sensor. The shader only decides colour; every label comes
from the ray cast. Full description and the sources of every spread: docs/rendering.md.

Stages (float32, one fused numba pass over the pixels each, :mod:`._kernels`):

- **Albedo** from the RayScene's per-face tables times a per-frame gain per material
  (asphalt age, concrete, ground, vegetation dryness; random colours in ``randomise``
  mode), with procedural texture and wear (patches, cracks, oil stains, faded markings,
  bare soil) looked up by the hit's *world* position (``texture_seed``).
- **Light**: Lambert sun x shadow rays aimed at points of the sun's disk (one per
  ``shadow_step`` block plus every pixel at an object edge; penumbra; dappled light through
  tree crowns), blue sky light x ray-cast ambient occlusion (per ``ao_step`` block,
  interpolated on each surface). Overcast dims the sun, raises the sky, softens shadows.
- **Specular**: Blinn-Phong sun highlight and a Fresnel sky reflection per material; wet
  roads darken and gain sheen and puddles.
- **Atmosphere**: transmission by path length (view angle), a coloured veil.
- **Camera**: auto exposure to a drawn key gray and gray sd (or a fixed gain), white
  balance, tint, saturation, panchromatic frames, a tone curve with a soft shoulder.
- **Sensor**: chromatic blur, noise growing with brightness, optional JPEG.

Sun azimuth is in degrees clockwise from north (90 = east), elevation above the horizon.
Every factor is drawn from the ranges of :class:`~aerial_synth.render.config.RenderConfig`
with the frame's generator (:func:`~aerial_synth.render.config.sample_factors`) and recorded
in ``Frame.factors`` (with ``pixel_seed``, the seed of every per-pixel hash).
"""

from __future__ import annotations

import math
import time
import weakref
from functools import lru_cache

import cv2
import numpy as np

from ..scene.model import DEFAULT_COLOR_FOR_MATERIAL, MATERIAL_IDS, MATERIALS
from . import _kernels as K
from . import _materials as M
from .tone import solve_tone, tone_lut

__all__ = ["shade", "material_gains", "sun_direction", "face_tangents"]


_ASPHALT = [MATERIAL_IDS["asphalt"], MATERIAL_IDS["track"]]  # tracks age with the road
_WEAR_IDS = np.array([MATERIAL_IDS[k] for k in ("asphalt", "marking", "grass")], np.int64)
_DRY_RGB = np.array([0.40, 0.36, 0.24], np.float32)  # dry grass / straw albedo
# foliage's share of the frame's vegetation_dryness mix towards straw (_DRY_RGB, luma 0.36):
# a late-summer or autumn canopy turns olive-brown but stays dark (senescent leaves reflect
# ~0.1-0.2 of red light, as in the USGS spectral library's dry-leaf spectra, and a
# crown's inner shade halves that, scene/procedural/trees.py),
# so k = 0.06 raises a broadleaf crown's luma by ~20 % at dryness 0.8 (gain = 1 + k x dry x
# (straw / base - 1) on the dark canopy base, ~7 x below straw in red). Was 0.4, which on
# the dark canopy base would make dry crowns ~2.3 x brighter (paler than the lawns).
_FOLIAGE_DRY_GAIN = 0.06
_CONCRETE = [MATERIAL_IDS[k] for k in ("concrete", "paving")]
_GROUND = [MATERIAL_IDS[k] for k in ("grass", "soil")]
_WATER = MATERIAL_IDS["water"]
_GLASS = MATERIAL_IDS["glass"]


def material_gains(factors: dict) -> np.ndarray:
    """(n_materials, 3) float32 albedo gain per material for this frame: aged or fresh
    asphalt, lighter or darker concrete and ground; random colours in ``randomise`` mode."""
    g = np.ones((len(MATERIALS), 3), np.float32)
    g[_ASPHALT] *= np.float32(factors.get("asphalt_albedo", 1.0))
    g[_CONCRETE] *= np.float32(factors.get("concrete_albedo", 1.0))
    g[_GROUND] *= np.float32(factors.get("ground_albedo", 1.0))
    dry = float(factors.get("vegetation_dryness", 0.0))
    for name, k in (("grass", 1.0), ("foliage", _FOLIAGE_DRY_GAIN)):  # towards dry straw
        base = np.asarray(DEFAULT_COLOR_FOR_MATERIAL[name], np.float32)
        g[MATERIAL_IDS[name]] *= 1.0 + k * dry * (_DRY_RGB / base - 1.0)
    # open water reflects 2-8 % of visible light from below its surface; the base albedo
    # (luma ~0.18) is that of shallow or turbid water, so x 0.4 (its sky reflection, a
    # specular term, comes on top)
    g[_WATER] *= np.float32(0.4)
    # glass: the dark cabin seen through it (car windows read near black from above)
    g[_GLASS] *= np.float32(0.5)
    if factors.get("material_rgb_gain") is not None:
        g *= np.asarray(factors["material_rgb_gain"], np.float32)
    return g


def sun_direction(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    """(3,) unit vector towards the sun, world (x east, y north, z up)."""
    a, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    return np.array([math.sin(a) * math.cos(e), math.cos(a) * math.cos(e), math.sin(e)])


# --------------------------------------------------------------------------- tone
_LUMA = np.array([0.299, 0.587, 0.114])


# ----------------------------------------------------------------------- materials
def _table(default: float, **values: float) -> np.ndarray:
    t = np.full(len(MATERIALS), default, np.float32)
    for k, v in values.items():
        t[MATERIAL_IDS[k]] = v
    return t


# texture amplitudes (relative albedo change per unit of noise, noise std ~ 1). Foliage
# 0.5 / 0.2 (was 0.35 / 0.15): the dark gaps between leaf clusters of real crowns (gray
# sd / mean 0.27-0.50 in hand-cut tree areas of the DOTA samples P1470 and P1053, ours
# 0.28 -> 0.30 on 20 jam frames); ~10 % of foliage texels reach the gain's floor of 0.3
_FINE = _table(0.05, asphalt=0.10, marking=0.09, concrete=0.08, paving=0.08, grass=0.2,
               soil=0.18, water=0.04, roof=0.07, wall=0.06, foliage=0.5, bark=0.12,
               paint=0.008, glass=0.0, tyre=0.05, trim=0.02, cargo=0.02, metal=0.03,
               roof_gravel=0.08, roof_tiles=0.04, roof_metal=0.015, track=0.05)
_COARSE = _table(0.04, asphalt=0.08, grass=0.16, soil=0.12, foliage=0.2, roof=0.08,
                 water=0.1, paint=0.0, glass=0.0, tyre=0.0, trim=0.0, cargo=0.02,
                 roof_gravel=0.1, roof_tiles=0.06, roof_metal=0.03, track=0.06)
# hue shift with coarse noise: grass/foliage drift towards dry yellow-brown. The kernel
# mixes towards the absolute straw albedo (_DRY_RGB, luma 0.36) by up to 1.5 x this value
# where a 6 m noise field is high; on the dark canopy (luma ~0.04-0.085, scene/procedural/
# trees.py) foliage=0.2 made whitish-yellow patches 2-3 x the crown's luma, so 0.04: at most
# ~25 % lighter and yellower (a stressed or turning tree), ~4 % on average
_DRY = _table(0.0, grass=0.35, foliage=0.04, soil=0.1)
# specular strength / shininess / sky reflection at normal incidence (F0)
_SPEC = _table(0.0, paint=0.35, glass=0.9, water=0.8, metal=0.3, roof=0.03, cargo=0.1,
               light_front=0.5, light_rear=0.4, trim=0.05, marking=0.02, roof_metal=0.3,
               roof_tiles=0.03, track=0.07)
_SHINE = _table(20.0, paint=80.0, glass=300.0, water=400.0, metal=40.0, light_front=100.0,
                light_rear=100.0, roof_metal=30.0, track=25.0)
_F0 = _table(0.0, paint=0.05, glass=0.05, water=0.06, metal=0.2, light_front=0.05,
             light_rear=0.05, cargo=0.02, roof_metal=0.12, track=0.025)
# how strongly wetness darkens and glosses a material
_WETK = _table(0.0, asphalt=1.0, marking=0.7, concrete=0.9, paving=0.9, soil=0.6, roof=0.4,
               grass=0.2, track=1.0, roof_gravel=0.5, roof_tiles=0.4, roof_metal=0.2)


def _kinds() -> np.ndarray:
    """(n_materials,) int64 pattern kind of each material (:mod:`._materials`)."""
    t = np.zeros(len(MATERIALS), np.int64)
    for name, kind in (("roof_gravel", M.KIND_GRAVEL), ("roof_tiles", M.KIND_TILES),
                       ("roof_metal", M.KIND_METAL), ("track", M.KIND_TRACK),
                       ("asphalt", M.KIND_ASPHALT), ("paving", M.KIND_PAVING),
                       ("concrete", M.KIND_CONCRETE), ("grass", M.KIND_VEGETATION),
                       ("soil", M.KIND_VEGETATION), ("water", M.KIND_WATER)):
        t[MATERIAL_IDS[name]] = kind
    t.setflags(write=False)
    return t


_KIND = _kinds()
#: unblurred shadows: compose reads the block samples itself instead of a spread pass (the
#: same image; tests/render/test_kernels.py compares both)
_SPREAD_IN_COMPOSE = True
#: id(scene) -> (weak reference to the scene, ids of its objects, face tangents)
_TANGENTS: dict[int, tuple] = {}


def face_tangents(scene) -> np.ndarray:
    """(n_static_faces, 2) float32 unit horizontal tangent of every static face of
    ``scene``, in the RayScene's face order (objects in order): the orientation of roof
    tiles, standing seams, paving joints and asphalt patches.

    A pitched face (normal more than ~1 degree off vertical, walls included) takes its
    normal's horizontal direction (down the slope); a flat face takes the direction of its
    longest edge on its object's flat outline (an edge no other flat face of the object
    shares): the run of a sidewalk or road strip, the side of a flat roof. Flat faces with
    no outline edge take their longest edge."""
    objs = scene.objects
    nfs = [o.n_triangles for o in objs]
    if not objs or sum(nfs) == 0:
        return np.zeros((0, 2), np.float32)
    tri = np.concatenate([np.asarray(o.vertices, np.float64)[np.asarray(o.faces)]
                          for o in objs])  # (m, 3, 3)
    obj = np.repeat(np.arange(len(objs), dtype=np.int64), nfs)
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    nl = np.linalg.norm(nrm, axis=1)
    hl = np.linalg.norm(nrm[:, :2], axis=1)
    out = np.zeros((len(tri), 2), np.float64)
    out[:, 0] = 1.0
    pitched = hl > 0.02 * np.maximum(nl, 1e-30)
    out[pitched] = nrm[pitched, :2] / hl[pitched, None]
    flat = np.flatnonzero(~pitched & (nl > 0))
    if len(flat):
        a = tri[flat]
        b = np.roll(a, -1, axis=1)  # edges (a0 a1), (a1 a2), (a2 a0)
        q1 = np.round(a * 1000.0).astype(np.int64)  # 1 mm keys
        q2 = np.round(b * 1000.0).astype(np.int64)
        swap = (q1[..., 0] > q2[..., 0]) | ((q1[..., 0] == q2[..., 0]) & (
            (q1[..., 1] > q2[..., 1]) | ((q1[..., 1] == q2[..., 1]) & (q1[..., 2] > q2[..., 2]))))
        lo = np.where(swap[..., None], q2, q1)
        hi = np.where(swap[..., None], q1, q2)
        key = np.broadcast_to(obj[flat, None], swap.shape).astype(np.uint64)
        mult = np.uint64(0x9E3779B97F4A7C15)
        for part in (lo[..., 0], lo[..., 1], lo[..., 2], hi[..., 0], hi[..., 1], hi[..., 2]):
            key = (key * mult) ^ part.astype(np.uint64)
            key ^= key >> np.uint64(29)
        _, inv, cnt = np.unique(key.reshape(-1), return_inverse=True, return_counts=True)
        outline = (cnt[inv] == 1).reshape(-1, 3)
        e = (b - a)[..., :2]
        ln = np.linalg.norm(e, axis=2)
        score = ln + np.where(outline, 1e6, 0.0)  # an outline edge first, then length
        k = np.argmax(score, axis=1)
        ev = e[np.arange(len(flat)), k]
        el = np.maximum(ln[np.arange(len(flat)), k], 1e-12)
        out[flat] = ev / el[:, None]
    return out.astype(np.float32)


def _tex_hash_seed(texture_seed: int) -> int:
    """uint64 seed of the material patterns' cell hashes for a texture seed."""
    ss = np.random.SeedSequence([int(texture_seed), 0x4D41])
    return int(ss.generate_state(1, np.uint64)[0])


def _face_tangents_cached(rayscene) -> np.ndarray:
    """:func:`face_tangents` of the RayScene's static scene, computed once per scene (an
    export builds a fresh RayScene for every placement group of the same scene): kept while
    the scene lives and holds the same objects."""
    scene = rayscene.scene
    key = tuple(map(id, scene.objects))
    hit = _TANGENTS.get(id(scene))
    if hit is not None and hit[0]() is scene and hit[1] == key:
        return hit[2]
    t = face_tangents(scene)
    t.setflags(write=False)
    for k in [k for k, v in _TANGENTS.items() if v[0]() is None]:  # scenes gone
        del _TANGENTS[k]
    _TANGENTS[id(scene)] = (weakref.ref(scene), key, t)
    return t

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


def _crown_gaps(srays: np.ndarray, tiles: np.ndarray) -> np.ndarray:
    """(k,) float32 sun visibility through tree crowns for shadow rays blocked by trees
    only: sun flecks where a 0.5 m leaf-cluster noise field (taken at the point the ray
    reaches 6 m higher, so the pattern moves with the sun like the crown's gaps) is high;
    about a third of a crown's shadow gets some light, a tenth of it strongly."""
    d = srays[:, 3:6].astype(np.float64)
    k = 6.0 / np.maximum(d[:, 2], 0.05)
    x = srays[:, 0] + k * d[:, 0]
    y = srays[:, 1] + k * d[:, 1]
    t = tiles[0]
    qx, qy = x * 2.0 + 41.0, y * 2.0 + 23.0
    x0, y0 = np.floor(qx), np.floor(qy)
    fx, fy = qx - x0, qy - y0
    i0, j0 = x0.astype(np.int64) & 255, y0.astype(np.int64) & 255
    i1, j1 = (i0 + 1) & 255, (j0 + 1) & 255
    n = ((t[j0, i0] * (1 - fx) + t[j0, i1] * fx) * (1 - fy)
         + (t[j1, i0] * (1 - fx) + t[j1, i1] * fx) * fy)
    return np.clip((n - 0.4) * 0.9, 0.0, 0.85).astype(np.float32)


def _wet_reflections(rayscene, buffers, face_mat, face_alb, gains, L, sun_col, sky_col,
                     e_sun: float, e_sky: float) -> np.ndarray:
    """(n, 3) float32 radiance seen in the mirror direction from wet road surfaces
    (materials that wetness glosses: asphalt, markings, concrete, paving), one traced ray per
    2 x 2 block copied to the block's wet pixels; -1 elsewhere (the shader then uses the
    sky). Reflected surfaces are lit by the sun (no shadow test) and the sky; rays that
    leave the scene see the sky."""
    h, w = buffers.height_px, buffers.width_px
    face = buffers.face.reshape(h, w)
    fm = face_mat[np.maximum(face, 0)]
    wetm = (face >= 0) & (_WETK[fm] > 0.5)
    out = np.full((h * w, 3), -1.0, np.float32)
    sr, sc = np.nonzero(wetm[::2, ::2])
    if len(sr) == 0:
        return out
    idx = (2 * sr) * w + 2 * sc
    rays = buffers.rays[idx]
    d = rays[:, 3:6] / np.linalg.norm(rays[:, 3:6], axis=1, keepdims=True)
    nrm = buffers.normal[idx]
    p = rays[:, :3] + buffers.t[idx, None] * rays[:, 3:6] + _PEEL * nrm
    r = d - 2.0 * np.sum(d * nrm, axis=1, keepdims=True) * nrm
    hits = rayscene.cast_rays(np.concatenate([p, r], axis=1).astype(np.float32))
    col = np.empty((len(idx), 3), np.float32)
    miss = hits.face < 0
    col[miss] = sky_col * np.float32(1.2 * e_sky)
    hf = hits.face[~miss]
    if len(hf):
        alb = face_alb[hf] * gains[face_mat[hf]]
        hn = hits.normal[~miss]
        hn = hn * np.where(np.sum(hn * r[~miss], axis=1, keepdims=True) > 0, -1.0, 1.0)
        ndl = np.clip(hn @ L, 0.0, None)[:, None]
        col[~miss] = alb * (e_sun * ndl * sun_col + e_sky * (0.55 + 0.45 * hn[:, 2:3]) * sky_col)
    grid = np.full((-(-h // 2), -(-w // 2), 3), -1.0, np.float32)
    grid[sr, sc] = col
    full = np.repeat(np.repeat(grid, 2, axis=0), 2, axis=1)[:h, :w].reshape(-1, 3)
    keep = wetm.reshape(-1) & (full[:, 0] >= 0)
    out[keep] = full[keep]
    return out


def _disk_vectors(L: np.ndarray, radius_deg: float) -> np.ndarray:
    """(2, 3) float32 vectors perpendicular to L spanning the sun's disk (length
    tan(radius)); zeros for a point sun."""
    if radius_deg <= 0:
        return np.zeros((2, 3), np.float32)
    up = np.array([0.0, 0.0, 1.0]) if abs(L[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(L, up)
    u /= np.linalg.norm(u)
    v = np.cross(L, u)
    k = math.tan(math.radians(radius_deg))
    return (np.stack([u, v]) * k).astype(np.float32)


def _haze_colour(tint: float, e_sky: float) -> np.ndarray:
    """Veil radiance: tint -1 = blue-grey (clean air, Rayleigh), +1 = warm grey-brown
    (smog, dust), through neutral grey."""
    blue = np.array([0.56, 0.64, 0.78])
    grey = np.array([0.66, 0.67, 0.68])
    warm = np.array([0.74, 0.68, 0.58])
    c = grey + (tint * (warm - grey) if tint > 0 else -tint * (blue - grey))
    return (c * (0.8 + 0.4 * e_sky)).astype(np.float32)


def _light(factors, oc):
    """The frame's light: sun and sky colours, their irradiances and the haze veil's colour."""
    elev = math.radians(factors["sun_elevation_deg"])
    warm = max(0.0, 1.0 - elev / math.radians(45.0))
    sun_col = np.array([1.0, 0.96 - 0.05 * warm, 0.90 - 0.12 * warm], np.float32)
    sky_col = np.array([0.60, 0.68, 0.85], np.float32)  # blue sky light: shadows turn blue
    if factors.get("sun_rgb") is not None:  # domain randomisation
        sun_col = np.asarray(factors["sun_rgb"], np.float32)
        sky_col = np.asarray(factors["sky_rgb"], np.float32)
    sky_col = sky_col + np.float32(oc) * (np.array([0.85, 0.86, 0.88], np.float32) - sky_col)
    e_sun = np.float32(1.15 * (1.0 - 0.85 * oc))
    # sky light (diffuse share of the irradiance: turbidity, bounce light from the
    # surroundings); a clear-sky shadow keeps ~25 % (x1) to ~45 % (x2) of the sunlit level
    e_sky = np.float32((0.30 + 0.45 * oc) * float(factors.get("sky_light", 1.0)))
    veil = _haze_colour(float(factors.get("haze_tint", 0.0)), float(e_sky))
    return sun_col, sky_col, e_sun, e_sky, veil


def _shadow_pass(rayscene, buffers, factors, has_lit, own, ndl, src, L, tiles, textured, nearest,
                 step, oc, pseed, mark):
    """Sun visibility ``lit`` per pixel (shadow rays at sun-disk samples, dappled light through
    crowns, spread over each block and blurred into a penumbra) and its ``lit_step`` (0:
    every pixel's value; k: only the block samples', read by :func:`._kernels.compose`)."""
    h, w = buffers.height_px, buffers.width_px
    n = h * w
    lit = np.ones(n if has_lit else 1, np.float32)
    lit_step = 0  # 0: lit holds every pixel's value; k: only the own pixels' (K.compose)
    if has_lit:
        disk = _disk_vectors(L.astype(np.float64), float(factors.get("sun_radius_deg", 0.0)))
        idx, srays = K.gather_shadow_rays(own, buffers.rays, buffers.t, buffers.normal, L,
                                          np.float32(_PEEL), disk, np.uint64(pseed ^ 0x5D15C))
        occ = rayscene.test_occlusions(srays) if len(idx) else np.zeros(0, bool)
        vis = np.where(occ, np.float32(0.0), np.float32(1.0)).astype(np.float32)
        if textured and occ.any():  # dappled light through crowns: blocked by trees only?
            blocked = np.flatnonzero(occ)
            solid = rayscene.test_occlusions(srays[blocked], ignore=("tree",))
            leafy = blocked[~solid]
            if len(leafy):
                vis[leafy] = _crown_gaps(srays[leafy], tiles)
        mark("shadow_rays")
        sig = (0.5 + 6.0 * oc) if oc > 0.02 else (0.6 if disk.any() else 0.0)
        if sig <= 0 and _SPREAD_IN_COMPOSE:  # nothing blurs lit: compose reads the samples
            K.scatter_values(idx, vis, lit)
            lit_step = step
        elif nearest:
            K.spread_shadow_nearest(h, w, step, own, ndl, src, idx, vis, lit)
        else:
            K.spread_shadow(h, w, step, own, ndl, idx, vis, lit)
        if sig > 0:  # sun-disk samples: a smooth penumbra; overcast: a wide, soft edge
            lit = cv2.GaussianBlur(lit.reshape(h, w), (0, 0), sig).reshape(-1)
        mark("shadow_spread")
    return lit, lit_step


def _ao_pass(rayscene, camera, buffers, ao_cfg, pseed, mark):
    """Ambient occlusion per pixel (rays cast per block where something rises nearby,
    spread over each surface); a (1,) array of ones without ``ao_cfg``."""
    has_ao = bool(ao_cfg)
    h, w = buffers.height_px, buffers.width_px
    n = h * w
    ao = np.ones(n if has_ao else 1, np.float32)
    if has_ao:
        ao_step, n_dirs = int(ao_cfg["step_px"]), int(ao_cfg["rays"])
        radius = float(ao_cfg["radius_m"])
        bh, bw = -(-h // ao_step), -(-w // ao_step)
        # only blocks with something rising > 0.15 m above their sample within the radius
        # (seen in the image) can be occluded: the others get 1 without casting
        zmax, zs, hit = K.ao_blocks(h, w, ao_step, buffers.rays, buffers.t, buffers.face)
        d = buffers.depth[::16, ::16]
        d = d[d > 0]
        px_m = float(np.median(d)) / float(camera.K[0][0]) if len(d) else 0.1
        kr = int(min(math.ceil(radius / max(px_m * ao_step, 1e-3)), 32))
        zn = cv2.dilate(zmax.reshape(bh, bw), np.ones((2 * kr + 1, 2 * kr + 1), np.uint8))
        need = hit & (zn.reshape(-1) - zs > np.float32(0.15))
        blocks, arays = K.gather_ao_rays(h, w, ao_step, buffers.rays, buffers.t,
                                         buffers.normal, buffers.face, need, n_dirs,
                                         np.float32(_PEEL), np.uint64(pseed ^ 0xA0))
        aocc = (rayscene.test_occlusions(arays, tfar=radius)
                if len(blocks) else np.zeros(0, bool))
        low = np.where(hit, np.float32(1.0), np.float32(-1.0)).astype(np.float32)
        if len(blocks):
            low[blocks] = 1.0 - aocc.reshape(-1, n_dirs).mean(axis=1)
        K.spread_ao(h, w, ao_step, low, buffers.semantic.reshape(-1),
                    buffers.depth.reshape(-1), ao)
        mark("ambient_occlusion")
    return ao


def camera_gains(factors) -> np.ndarray:
    """White balance and tint as RGB gains, (3,) float64 scaled to unit luma."""
    wb = float(factors["white_balance"])  # log(R gain / B gain)
    tint = float(factors.get("tint", 0.0))  # log G gain
    gains = np.array([math.exp(wb / 2), math.exp(tint), math.exp(-wb / 2)])
    return gains / float(_LUMA @ gains)


def exposure(factors, metered) -> tuple[float, float, float]:
    """The tone curve's (gain, power, shoulder): auto exposure solved from ``metered()`` (the
    sensor's luma, softened by the frame's optical blur, every 4th pixel, (n,) float64), or the
    fixed exposure. Adds ``exposure_gain`` and ``tone_power`` to ``factors``. Every backend's
    camera pass calls this; only the metering differs (host or device)."""
    shoulder = float(factors.get("tone_shoulder", 0.25))
    if factors.get("exposure_mode", "fixed") == "auto":
        gain, power = solve_tone(metered(), float(factors["key_gray"]),
                                 float(factors["target_gray_sd"]), shoulder)
    else:
        gain, power = float(factors["exposure"]), 1.0 / 2.2
    factors["exposure_gain"] = float(gain)
    factors["tone_power"] = float(power)
    return gain, power, shoulder


def _camera_pass(lin, factors, h, w):
    """The camera: white balance and tint, auto (metered) or fixed exposure, saturation, the
    tone curve, a panchromatic frame; (H, W, 3) uint8. Adds ``exposure_gain`` and
    ``tone_power`` to ``factors``."""
    gains = camera_gains(factors)

    def metered():
        # meter what the sensor records: the luma softened by the frame's optical blur
        # (metering sharp pixels overestimated the final gray sd by ~2.5 on average)
        y = cv2.transform(lin, (_LUMA * gains).reshape(1, 3).astype(np.float32))
        if factors["blur_sigma_px"] > 0.05:
            y = cv2.GaussianBlur(y, (0, 0), float(factors["blur_sigma_px"]))
        return y[::4, ::4].reshape(-1).astype(np.float64)

    gain, power, shoulder = exposure(factors, metered)
    rgb = np.empty((h, w, 3), np.uint8)
    K.tone(lin, (gains * gain).astype(np.float32),
           np.float32(factors.get("saturation", 1.0)), tone_lut(shoulder, power), rgb)
    if factors.get("grayscale"):  # a panchromatic product (like several DOTA images)
        g = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        rgb = np.ascontiguousarray(np.repeat(g[..., None], 3, axis=2))
    return rgb


def _sensor_pass(rgb, factors, pseed):
    """The sensor: chromatic blur and noise growing with brightness."""
    sig = factors["blur_sigma_px"]
    ca = float(factors.get("chromatic_blur", 0.0))
    if sig > 0.05:
        if ca > 0.01:  # lateral colour: red and blue a little softer than green
            chans = [cv2.GaussianBlur(ch, (0, 0), sig * f)
                     for ch, f in zip(cv2.split(rgb), (1.0 + ca, 1.0, 1.0 + 1.5 * ca))]
            rgb = cv2.merge(chans)  # split / merge: the same bytes as numpy slices and stack
        else:
            rgb = cv2.GaussianBlur(rgb, (0, 0), sig)
    ns = factors["noise_sigma"]
    shot = float(factors.get("shot_noise", 0.0))
    if ns > 0 or shot > 0:
        K.add_noise(rgb, np.uint64(pseed ^ 0x4E015E), np.float32(ns * 255.0),
                    np.float32(shot * 255.0), _normal_quantiles())
    return rgb


def shade(rayscene, camera, buffers, factors: dict, rng: np.random.Generator | None = None,
          timings: dict | None = None, shadow_step: int | None = None,
          before_compose=None) -> np.ndarray:
    """Shaded RGB (H, W, 3) uint8 for the primary hits in ``buffers`` under ``factors``
    (from :func:`sample_factors`; the per-pixel randomness comes from
    ``factors["pixel_seed"]``, so ``rng`` is not used and kept for compatibility).

    Stages: surface (sun cosine) -> shadow rays (sun-disk samples) -> ambient-occlusion
    rays -> compose (linear radiance) -> tone (auto exposure, white balance, saturation,
    tone curve) -> sensor (chromatic blur, noise by brightness, JPEG).
    Adds the metered ``exposure_gain`` and ``tone_power`` to ``factors``.

    timings : optional dict that receives seconds per shading stage (for benchmarks).
    shadow_step : overrides ``factors["shadow_step"]``. 1 = one shadow ray per pixel; k =
                  one per k x k block plus every pixel that differs from its block's first
                  pixel (another label, or a depth jump over 0.2 m), so object edges stay
                  exact and only shadow edges inside one surface are coarser.
    before_compose : optional callable, called once when the ray-casting stages are done
                  (before compose); :func:`.frame.render_frame` starts visibility there,
                  so it runs beside the less parallel stages that follow.
    """
    tick = [time.perf_counter()]

    def mark(name):
        if timings is not None:
            now = time.perf_counter()
            timings[name] = timings.get(name, 0.0) + now - tick[0]
            tick[0] = now

    h, w = buffers.height_px, buffers.width_px
    n = h * w
    if shadow_step is None:
        shadow_step = factors.get("shadow_step", 2)
    step = max(1, int(shadow_step))
    pseed = int(factors.get("pixel_seed", 0))
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
    nearest = factors.get("shadow_edges", "cast") == "nearest" and step > 1
    src = np.empty(n if nearest else 1, np.uint8)  # nearest: the corner sample each copies
    mark("setup")
    K.surface(h, w, buffers.rays, buffers.t, buffers.face, buffers.normal,
              buffers.semantic.reshape(-1), buffers.depth.reshape(-1), face_mat, tiles, textured,
              L, _FOLIAGE, step, nearest, ndl, own, src)
    mark("surface")

    has_lit = bool(factors.get("shadows", True))
    lit, lit_step = _shadow_pass(rayscene, buffers, factors, has_lit, own, ndl, src, L, tiles,
                                 textured, nearest, step, oc, pseed, mark)

    ao_cfg = factors.get("ambient_occlusion")
    has_ao = bool(ao_cfg)
    ao = _ao_pass(rayscene, camera, buffers, ao_cfg, pseed, mark)

    sun_col, sky_col, e_sun, e_sky, veil = _light(factors, oc)
    alt = max(float(camera.altitude_m), 1.0)
    gains_m = material_gains(factors)
    has_refl = bool(factors.get("wet_reflections", False)) and float(wet) > 0
    refl = (_wet_reflections(rayscene, buffers, face_mat, face_alb, gains_m, L, sun_col,
                             sky_col, float(e_sun), float(e_sky))
            if has_refl else np.zeros((1, 3), np.float32))
    if has_refl:
        mark("wet_reflections")
    if before_compose is not None:
        before_compose()
    lin = np.empty((h, w, 3), np.float32)
    K.compose(h, w, buffers.rays, buffers.t, buffers.face, buffers.normal,
              buffers.depth.reshape(-1), ndl, lit, has_lit, own, src, lit_step, nearest, ao,
              has_ao, face_mat, face_alb,
              gains_m, tiles, textured, _FINE, _COARSE, _DRY, _WETK, _SPEC,
              _SHINE, _F0, wet, L, sun_col, sky_col, (sky_col * np.float32(0.25)).astype(np.float32), veil, e_sun, e_sky,
              np.float32(1.0 - 0.9 * oc), np.float32(factors["haze"]), np.float32(1.0 / alt),
              np.float32(factors.get("vignetting", 0.0)),
              np.float32(factors.get("road_wear", 0.0)), _WEAR_IDS, refl, has_refl, _KIND,
              _face_tangents_cached(rayscene), np.float32(1.0 / float(camera.K[0][0])),
              np.uint64(_tex_hash_seed(int(factors["texture_seed"]) if textured else 0)),
              np.float32(0.72 * (1.0 - oc)), lin)
    mark("compose")

    rgb = _camera_pass(lin, factors, h, w)
    mark("tone")

    rgb = _sensor_pass(rgb, factors, pseed)
    mark("sensor")
    q = factors.get("jpeg_quality")
    if q:
        ok, enc = cv2.imencode(".jpg", rgb[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, int(q)])
        if ok:
            rgb = np.ascontiguousarray(cv2.imdecode(enc, cv2.IMREAD_COLOR)[..., ::-1])
    mark("jpeg")
    return np.ascontiguousarray(rgb)
