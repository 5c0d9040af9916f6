"""Realism factors (issue 15): camera (auto exposure, white balance, tone, noise by
brightness), light (ambient occlusion, sun-disk shadows), materials, domain randomisation.

Labels must never depend on shading; every factor is seeded and recorded."""

import json

import numpy as np
import pytest

from aerial_synth.camera import Camera, CameraConfig
from aerial_synth.errors import ConfigError
from aerial_synth.render import RenderConfig, render_frame
from aerial_synth.render import _kernels as K
from aerial_synth.render.config import PRESETS, sample_factors
from aerial_synth.render.shading import _normal_quantiles
from aerial_synth.render.tone import solve_tone, tone_lut

from .worlds import make_world, with_threads

SMALL = CameraConfig(width_px=256, height_px=256, gsd_m=0.12)
SPEC = [(1, 0.0, -2.0, 0.3, 4.5, 1.8, 1.5), (2, 7.0, 2.0, 0.0, 9.0, 2.5, 3.5),
        (3, -7.0, -2.0, 3.0, 4.2, 1.8, 1.4)]
# everything but the factor under test fixed, so a difference has one cause
PLAIN = dict(sun_azimuth_deg=(200, 200), sun_elevation_deg=(40, 40), haze=(0, 0),
             overcast_probability=0, wet_probability=0, jpeg_probability=0,
             noise_sigma=(0, 0), shot_noise=(0, 0), blur_sigma_px=(0, 0), vignetting=(0, 0),
             grayscale_probability=0, exposure_mode="fixed", exposure=(1, 1),
             white_balance=(0, 0), tint=(0, 0), saturation=(1, 1), texture=False)


@pytest.fixture(scope="module")
def world():
    rs, pl = make_world(SPEC, crown_at=(3.0, 4.0))
    cam = Camera.look_at_ground(SMALL, (1.0, 0.0, 0.0), yaw_deg=25.0, tilt_deg=7.0)
    return rs, pl, cam


def test_labels_do_not_depend_on_shading(world):
    rs, pl, cam = world
    configs = [RenderConfig(), RenderConfig.preset("fast"), RenderConfig(shadows=False),
               RenderConfig(randomise="textures"), RenderConfig(**PLAIN),
               RenderConfig(ambient_occlusion=False, soft_shadows=False, texture=False)]
    frames = [render_frame(rs, cam, pl, np.random.default_rng(5), c) for c in configs]
    ref = frames[0]
    assert len(ref.visibility) == 3
    for f in frames[1:]:
        for name in ("instance", "semantic", "depth"):
            assert getattr(f, name).tobytes() == getattr(ref, name).tobytes(), name
        assert [v.to_dict() for v in f.visibility.values()] == [
            v.to_dict() for v in ref.visibility.values()]
    # ... while the pictures do differ
    assert len({f.rgb.tobytes() for f in frames}) == len(frames)


def test_full_frame_is_identical_for_any_thread_count_and_records_every_factor(world):
    rs, pl, cam = world
    cfg = RenderConfig(jpeg_probability=1.0, haze=(0.2, 0.2), wet_probability=1.0)
    a = with_threads(1, lambda: render_frame(rs, cam, pl, np.random.default_rng(9), cfg))
    b = with_threads(2, lambda: render_frame(rs, cam, pl, np.random.default_rng(9), cfg))
    assert a.rgb.tobytes() == b.rgb.tobytes()
    assert a.to_meta() == b.to_meta()
    f = a.factors
    for key in ("key_gray", "target_gray_sd", "exposure_gain", "tone_power", "tone_shoulder",
                "white_balance", "tint", "saturation", "grayscale", "chromatic_blur",
                "noise_sigma", "shot_noise", "jpeg_quality", "vignetting", "sun_radius_deg",
                "haze", "haze_tint", "asphalt_albedo", "ground_albedo", "concrete_albedo",
                "ambient_occlusion", "pixel_seed", "randomise", "vegetation_dryness",
                "sky_light"):
        assert key in f, key
    json.dumps(a.to_meta())  # JSON-ready
    c = render_frame(rs, cam, pl, np.random.default_rng(10), cfg)
    assert c.rgb.tobytes() != a.rgb.tobytes() and c.factors["pixel_seed"] != f["pixel_seed"]


def test_auto_exposure_reaches_the_drawn_key_gray(world):
    rs, pl, cam = world
    for key, sd in ((60.0, 18.0), (120.0, 35.0), (170.0, 40.0)):
        cfg = RenderConfig(**{**PLAIN, "exposure_mode": "auto", "key_gray": (key, key),
                              "contrast_cv": (sd / key, sd / key)})
        f = render_frame(rs, cam, pl, np.random.default_rng(0), cfg)
        gray = f.rgb.astype(float) @ [0.299, 0.587, 0.114]
        assert gray.mean() == pytest.approx(key, abs=4.0)
        assert f.factors["exposure_gain"] > 0 and 0.3 <= f.factors["tone_power"] <= 1.6


def test_solve_tone_hits_mean_and_sd():
    rng = np.random.default_rng(0)
    luma = np.exp(rng.normal(-2.0, 0.8, 50_000))
    for key, sd in ((50.0, 15.0), (110.0, 38.0), (180.0, 45.0)):
        gain, power = solve_tone(luma, key, sd, shoulder=0.3)
        x = np.clip(gain * luma, 0, 1)
        g = 255 * (x * 1.3 / (1 + 0.3 * x)) ** power
        assert g.mean() == pytest.approx(key, abs=1.0)
        assert g.std() == pytest.approx(sd, rel=0.05)
    # an sd out of reach: the power stops at its bound, the mean still fits
    gain, power = solve_tone(luma, 100.0, 200.0, shoulder=0.0)
    assert power == pytest.approx(1.6)
    assert solve_tone(np.zeros(10), 100.0, 30.0, 0.0) == (1.0, pytest.approx(1 / 2.2))


def test_tone_kernel_matches_numpy():
    rng = np.random.default_rng(1)
    lin = rng.uniform(0, 1.5, (40, 50, 3)).astype(np.float32)
    gains = np.array([1.2, 0.9, 0.7], np.float32)
    lut = tone_lut(0.3, 0.5)
    out = np.empty((40, 50, 3), np.uint8)
    K.tone(lin, gains, np.float32(0.6), lut, out)
    c = lin.astype(np.float64) * gains
    y = c @ [0.299, 0.587, 0.114]
    c = y[..., None] + 0.6 * (c - y[..., None])
    idx = np.clip(np.floor(c * 4096), 0, len(lut) - 1).astype(int)
    assert np.abs(out.astype(int) - lut[idx].astype(int)).max() <= 1


def test_noise_grows_with_brightness():
    q = _normal_quantiles()
    dark = np.full((200, 200, 3), 30, np.uint8)
    bright = np.full((200, 200, 3), 220, np.uint8)
    K.add_noise(dark, np.uint64(3), np.float32(1.0), np.float32(12.0), q)
    K.add_noise(bright, np.uint64(3), np.float32(1.0), np.float32(12.0), q)
    sd_dark, sd_bright = dark[..., 1].std(), bright[..., 1].std()
    assert sd_bright > 2.0 * sd_dark
    assert sd_bright == pytest.approx(np.sqrt(1 + 144 * 220 / 255), rel=0.1)


def test_ambient_occlusion_darkens_the_ground_beside_a_vehicle():
    rs, pl = make_world([(1, 0.0, -2.0, 0.0, 4.5, 1.8, 1.5)], building=False)
    cam = Camera.look_at_ground(SMALL, (0.0, -2.0, 0.0))
    # sun straight above: no cast shadow beside the car, only occlusion of the sky
    base = {**PLAIN, "sun_elevation_deg": (90, 90), "shadows": False}
    on = render_frame(rs, cam, pl, np.random.default_rng(0),
                      RenderConfig(**base, ambient_occlusion=True, ao_rays=16, ao_step=2))
    off = render_frame(rs, cam, pl, np.random.default_rng(0),
                       RenderConfig(**base, ambient_occlusion=False))
    near = cam.project(np.array([[0.0, -2.0 - 1.2, 0.0]]))[0].astype(int)  # 0.3 m off its side
    far = cam.project(np.array([[0.0, -2.0 - 3.8, 0.0]]))[0].astype(int)  # road, 2.9 m off
    g_on, g_off = on.rgb.astype(int).sum(2), off.rgb.astype(int).sum(2)
    assert g_on[near[1], near[0]] < g_off[near[1], near[0]] - 6
    assert abs(g_on[far[1], far[0]] - g_off[far[1], far[0]]) <= 3
    assert on.factors["ambient_occlusion"] == {"step_px": 2, "rays": 16, "radius_m": 2.0}
    assert off.factors["ambient_occlusion"] is None


def test_sun_disk_sampling_gives_a_penumbra():
    rs, pl = make_world([], building=True)
    cam = Camera.look_at_ground(SMALL, (27.5, 24.0, 0.0))
    base = {**PLAIN, "sun_azimuth_deg": (180, 180), "sun_elevation_deg": (45, 45),
            "ambient_occlusion": False, "shadow_step": 1}
    hard = render_frame(rs, cam, pl, np.random.default_rng(0),
                        RenderConfig(**base, soft_shadows=False))
    soft = render_frame(rs, cam, pl, np.random.default_rng(0),
                        RenderConfig(**base, sun_radius_deg=(3.0, 3.0)))
    # the house's shadow edge on the grass (y = 31 m), across x = 24 .. 31 m: grey levels
    # between shadow and light only when soft
    ys = np.linspace(24.0, 38.0, 200)
    pts = np.stack([np.full(200, 27.5), ys, np.zeros(200)], 1)
    uv = cam.project(pts).astype(int)
    shade_lv = hard.rgb[uv[0, 1], uv[0, 0], 1].astype(int)
    lit_lv = hard.rgb[uv[-1, 1], uv[-1, 0], 1].astype(int)
    assert lit_lv > shade_lv + 30

    def mid(img):
        r0, r1 = sorted((uv[0, 1], uv[-1, 1]))
        c0 = uv[0, 0]
        g = img[r0:r1, c0 - 25 : c0 + 25, 1].astype(int)
        lo, hi = shade_lv + 0.15 * (lit_lv - shade_lv), shade_lv + 0.85 * (lit_lv - shade_lv)
        return ((g > lo) & (g < hi)).sum()

    assert mid(soft.rgb) > 3 * max(mid(hard.rgb), 10)
    assert hard.factors["sun_radius_deg"] == 0.0 and soft.factors["sun_radius_deg"] == 3.0


def test_randomised_textures_change_colours_not_labels(world):
    rs, pl, cam = world
    a = render_frame(rs, cam, pl, np.random.default_rng(2), RenderConfig(**PLAIN))
    b = render_frame(rs, cam, pl, np.random.default_rng(2),
                     RenderConfig(**PLAIN, randomise="textures"))
    assert a.instance.tobytes() == b.instance.tobytes()
    assert np.abs(a.rgb.astype(int) - b.rgb.astype(int)).mean() > 10
    gains = np.asarray(b.factors["material_rgb_gain"])
    assert gains.shape[1] == 3 and (gains > 0).all() and gains.std() > 0.2
    assert "material_rgb_gain" not in a.factors


def test_presets_and_bad_config():
    assert set(PRESETS) == {"full", "fast"}
    fast = RenderConfig.preset("fast")
    assert not fast.ambient_occlusion and not fast.soft_shadows and fast.shadow_step == 4
    assert fast.shadow_edges == "nearest" and RenderConfig().shadow_edges == "cast"
    assert RenderConfig.preset("full") == RenderConfig()
    assert RenderConfig.preset("fast", shadows=False).shadows is False
    for kw, needle in [({"key_gray": (200, 100)}, "key_gray"),
                       ({"key_gray": (0, 100)}, "key_gray"),
                       ({"saturation": "a lot"}, "saturation"),
                       ({"grayscale_probability": 1.5}, "grayscale_probability"),
                       ({"randomise": "colours"}, "randomise"),
                       ({"shadow_edges": "guess"}, "shadow_edges"),
                       ({"exposure_mode": "manual"}, "exposure_mode"),
                       ({"ao_rays": 0}, "ao_rays"),
                       ({"ambient_occlusion": "yes"}, "ambient_occlusion")]:
        with pytest.raises(ConfigError) as e:
            RenderConfig(**kw)
        msg = str(e.value)
        assert needle in msg and "\n" not in msg, msg
    with pytest.raises(ConfigError, match="preset"):
        RenderConfig.preset("ultra")
    with pytest.raises(ConfigError, match="unknown"):
        RenderConfig.from_mapping({"sharpness": 2})


def test_factor_draws_are_seeded():
    cfg = RenderConfig(randomise="textures")
    a = sample_factors(cfg, np.random.default_rng(np.random.SeedSequence([4, 1])))
    b = sample_factors(cfg, np.random.default_rng(np.random.SeedSequence([4, 1])))
    c = sample_factors(cfg, np.random.default_rng(np.random.SeedSequence([4, 2])))
    assert a == b and a != c
    # the key grays of many frames span the real spread (48-185 per docs/rendering.md)
    keys = [sample_factors(RenderConfig(), np.random.default_rng(i))["key_gray"]
            for i in range(200)]
    assert min(keys) < 60 and max(keys) > 170


def test_road_wear_darkens_parts_of_the_asphalt_only():
    from aerial_synth.scene.model import LABEL_IDS

    rs, pl = make_world([], building=False)
    cam = Camera.look_at_ground(CameraConfig(width_px=512, height_px=128, gsd_m=0.12),
                                (0.0, 0.0, 0.0))
    base = {**PLAIN, "texture": True, "shadows": False, "ambient_occlusion": False}
    worn = render_frame(rs, cam, pl, np.random.default_rng(0),
                        RenderConfig(**base, road_wear=(1, 1)))
    new = render_frame(rs, cam, pl, np.random.default_rng(0),
                       RenderConfig(**base, road_wear=(0, 0)))
    road = worn.semantic == LABEL_IDS["road"]
    a, b = worn.rgb[..., 1][road].astype(int), new.rgb[..., 1][road].astype(int)
    assert (a < b - 8).mean() > 0.01  # cracks, patches, stains
    assert (a == b).mean() > 0.3  # most of the surface untouched
    assert worn.factors["road_wear"] == 1.0 and new.factors["road_wear"] == 0.0


def test_crown_gaps_let_some_sun_through_deterministically():
    from aerial_synth.render.shading import _crown_gaps, _noise_tiles

    rng = np.random.default_rng(0)
    rays = np.zeros((5000, 6), np.float32)
    rays[:, :2] = rng.uniform(-50, 50, (5000, 2))
    rays[:, 3:] = [0.3, 0.2, 0.93]
    v = _crown_gaps(rays, _noise_tiles(0))
    assert v.dtype == np.float32 and v.shape == (5000,)
    assert 0.0 <= v.min() and v.max() <= 0.85
    assert 0.2 < (v > 0).mean() < 0.5 and 0.05 < v.mean() < 0.3
    assert np.array_equal(v, _crown_gaps(rays.copy(), _noise_tiles(0)))


def test_wet_roads_mirror_the_scene_not_only_the_sky(world):
    rs, pl, cam = world  # tilted view, a crown and vehicles beside the road
    base = {**PLAIN, "wet_probability": 1.0, "wet": (1.0, 1.0), "texture": True}
    on = render_frame(rs, cam, pl, np.random.default_rng(1), RenderConfig(**base))
    off = render_frame(rs, cam, pl, np.random.default_rng(1),
                       RenderConfig(**base, wet_reflections=False))
    dry = render_frame(rs, cam, pl, np.random.default_rng(1),
                       RenderConfig(**{**base, "wet_probability": 0.0}))
    assert on.instance.tobytes() == off.instance.tobytes() == dry.instance.tobytes()
    assert on.depth.tobytes() == off.depth.tobytes()
    from aerial_synth.scene.model import LABEL_IDS

    road = on.semantic == LABEL_IDS["road"]
    diff = np.abs(on.rgb.astype(int) - off.rgb.astype(int)).max(axis=2)
    assert (diff[road] > 3).mean() > 0.005  # some road pixels show a reflected object
    assert (diff[~road & (on.semantic != LABEL_IDS["lane_marking"])] == 0).all()
    assert on.factors["wet_reflections"] and not off.factors["wet_reflections"]
    # frames that are not wet never trace mirror rays
    assert "rgb_wet_reflections" not in dry.timings_s


def test_auto_contrast_meets_the_target_after_the_optical_blur(world):
    """The camera meters the blurred luma, so the recorded gray sd is the drawn target even
    though the sensor blur removes fine texture after the tone curve."""
    rs, pl, cam = world
    for sig in (0.0, 0.9):
        cfg = RenderConfig(**{**PLAIN, "exposure_mode": "auto", "key_gray": (110, 110),
                              "contrast_cv": (0.3, 0.3), "texture": True,
                              "blur_sigma_px": (sig, sig)})
        f = render_frame(rs, cam, pl, np.random.default_rng(0), cfg)
        gray = f.rgb.astype(float) @ [0.299, 0.587, 0.114]
        assert gray.std() == pytest.approx(f.factors["target_gray_sd"], abs=1.2), sig
        assert gray.mean() == pytest.approx(110.0, abs=3.0)


def _solve_tone_reference(luma, key_gray, target_sd, shoulder, power_range=(0.3, 1.6)):
    """The numpy formulation the compiled solver replaced (same bisections)."""
    import math

    def curve(v, p):
        v = np.clip(v, 0.0, 1.0)
        return (v * (1.0 + shoulder) / (1.0 + shoulder * v)) ** p

    y = luma[np.isfinite(luma) & (luma > 1e-6)]
    ly = np.log(y)
    lo, hi = float(ly.min()), float(ly.max()) + 1e-6
    cnt, edges = np.histogram(ly, bins=256, range=(lo, hi))
    yc = np.exp(0.5 * (edges[1:] + edges[:-1]))
    wts = cnt / cnt.sum()

    def stats(lg, p):
        g = 255.0 * curve(math.exp(lg) * yc, p)
        m = float(wts @ g)
        return m, math.sqrt(max(float(wts @ (g * g)) - m * m, 0.0))

    def gain_for(p):
        a, b = -lo - 12.0, -lo + 12.0
        for _ in range(22):
            mid = 0.5 * (a + b)
            a, b = (mid, b) if stats(mid, p)[0] < key_gray else (a, mid)
        return 0.5 * (a + b)

    plo, phi = power_range
    if stats(gain_for(phi), phi)[1] <= target_sd:
        p = phi
    elif stats(gain_for(plo), plo)[1] >= target_sd:
        p = plo
    else:
        a, b = math.log(plo), math.log(phi)
        for _ in range(12):
            mid = 0.5 * (a + b)
            a, b = (mid, b) if stats(gain_for(math.exp(mid)), math.exp(mid))[1] < target_sd else (a, mid)
        p = math.exp(0.5 * (a + b))
    return math.exp(gain_for(p)), p


@pytest.mark.parametrize("key, sd, shoulder", [(110.0, 35.0, 0.3), (60.0, 15.0, 0.0),
                                               (170.0, 48.0, 0.5), (100.0, 200.0, 0.2)])
def test_compiled_tone_solver_equals_the_numpy_formulation(key, sd, shoulder):
    rng = np.random.default_rng(7)
    luma = np.exp(rng.normal(-2.0, 1.0, 60_000)) * rng.uniform(0.5, 1.5, 60_000)
    g, p = solve_tone(luma, key, sd, shoulder)
    g0, p0 = _solve_tone_reference(luma, key, sd, shoulder)
    assert p == pytest.approx(p0, rel=1e-9, abs=1e-12)
    assert g == pytest.approx(g0, rel=1e-6)
