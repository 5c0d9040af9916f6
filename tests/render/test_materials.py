"""Material patterns (issue 15): roof coverings, asphalt patches, tyre tracks, paving joints,
grass patch layer, water ripples (:mod:`aerial_synth.render._materials`).

Every pattern is seeded by the texture seed, deterministic for any thread count, oriented
by the face tangent, and never touches labels."""

import math

import numba
import numpy as np
import pytest
import shapely

from aerial_synth.camera import Camera, CameraConfig
from aerial_synth.placement.model import Placement
from aerial_synth.render import RenderConfig, render_frame
from aerial_synth.render import _materials as M
from aerial_synth.render.buffers import cast_buffers
from aerial_synth.render.shading import face_tangents
from aerial_synth.scene import build
from aerial_synth.scene.model import MATERIAL_IDS, MATERIALS, Scene, SceneObject
from aerial_synth.scene.raycast import RayScene

from .worlds import with_threads

# every factor but the textures fixed, so differences have one cause
PLAIN = dict(sun_azimuth_deg=(200, 200), sun_elevation_deg=(40, 40), haze=(0, 0),
             overcast_probability=0, wet_probability=0, jpeg_probability=0,
             noise_sigma=(0, 0), shot_noise=(0, 0), blur_sigma_px=(0, 0), vignetting=(0, 0),
             grayscale_probability=0, exposure_mode="fixed", exposure=(1, 1),
             white_balance=(0, 0), tint=(0, 0), saturation=(1, 1), shadows=False,
             ambient_occlusion=False, road_wear=(1, 1))
EMPTY = Placement(scene="t", scenario="manual", seed=0, vehicles=[])


def _roof_plane(angle_deg, material, size=30.0, pitch_deg=25.0, z0=3.0):
    """One pitched roof face (a square, rising towards local -x) turned by angle_deg about
    the origin: its downslope direction is (cos a, sin a)."""
    a = math.radians(angle_deg)
    c, s = math.cos(a), math.sin(a)
    k = math.tan(math.radians(pitch_deg))
    h = size / 2
    loc = np.array([[-h, -h], [h, -h], [h, h], [-h, h]])
    z = z0 + k * (h - loc[:, 0])
    v = np.column_stack([c * loc[:, 0] - s * loc[:, 1], s * loc[:, 0] + c * loc[:, 1], z])
    return SceneObject(f"roof_{material}", "building", v, np.array([[0, 1, 2], [0, 2, 3]]),
                       material=material)


def material_scene() -> Scene:
    """Every new material on a small plot: road with tracks, sidewalk, concrete lot,
    gravel, tiled and metal roofs, grass, soil and water."""
    ground = shapely.box(-40, -40, 40, 40).difference(shapely.box(-40, -5, 40, 5))
    ground = ground.difference(shapely.box(-35, -30, -20, -12))
    objs = [
        build.polygon_object("grass", "ground", ground.difference(shapely.box(0, -40, 40, -6)),
                             0.0),
        build.polygon_object("soil", "ground", ground.intersection(shapely.box(0, -40, 40, -6))
                             .difference(shapely.box(20, -25, 35, -8)), 0.0, material="soil"),
        build.polygon_object("road", "road", shapely.box(-40, -5, 40, 5), 0.0),
        build.polygon_object("track", "road", shapely.box(-40, -2.9, 40, -2.3), 0.004,
                             material="track"),
        build.polygon_object("walk", "sidewalk", shapely.box(-40, 5, 40, 7.5), 0.12),
        build.polygon_object("lot", "parking", shapely.box(20, -25, 35, -8), 0.05,
                             material="concrete"),
        build.polygon_object("pond", "water", shapely.box(-35, -30, -20, -12), 0.0),
    ]
    for name, (x, y) in (("roof_tiles", (-20, 20)), ("roof_metal", (0, 20))):
        o = _roof_plane(0.0, name, size=12.0)
        objs.append(SceneObject(o.name, o.label, o.vertices + [x, y, 0], o.faces,
                                material=name))
    v, f = build.prism(shapely.box(14, 12, 28, 28), 0.0, 6.0)
    objs.append(SceneObject("flat", "building", v, f, material="roof_gravel"))
    return Scene("materials", objs)


@pytest.fixture(scope="module")
def world():
    rs = RayScene(material_scene())
    cam = Camera.look_at_ground(CameraConfig(width_px=320, height_px=320, gsd_m=0.25),
                                (0.0, 0.0, 0.0))
    return rs, cam


def _gray(rgb):
    return rgb.astype(np.float64) @ [0.299, 0.587, 0.114]


def test_material_patterns_are_seeded_and_thread_independent(world):
    rs, cam = world
    cfg = RenderConfig(**PLAIN)
    a = with_threads(1, lambda: render_frame(rs, cam, EMPTY, np.random.default_rng(2), cfg))
    b = with_threads(2, lambda: render_frame(rs, cam, EMPTY, np.random.default_rng(2), cfg))
    assert a.rgb.tobytes() == b.rgb.tobytes()
    c = render_frame(rs, cam, EMPTY, np.random.default_rng(2), cfg)
    assert c.rgb.tobytes() == a.rgb.tobytes()
    # another texture seed: other patterns, same labels
    d = render_frame(rs, cam, EMPTY, np.random.default_rng(2),
                     RenderConfig(**PLAIN, texture_seed=7))
    assert d.instance.tobytes() == a.instance.tobytes()
    assert d.depth.tobytes() == a.depth.tobytes()
    buf = cast_buffers(rs, cam)
    mats = rs.face_material[np.where(buf.face >= 0, buf.face, 0)].reshape(a.semantic.shape)
    for name in ("roof_gravel", "roof_tiles", "roof_metal", "track", "concrete", "paving",
                 "asphalt", "water", "soil"):
        sel = mats == MATERIAL_IDS[name]
        assert sel.sum() > 100, name
        assert (a.rgb[sel] != d.rgb[sel]).any(), name  # seeded by texture_seed
    # the patterns are real texture: every roof covering varies across its face
    for name in ("roof_gravel", "roof_tiles", "roof_metal"):
        assert _gray(a.rgb)[mats == MATERIAL_IDS[name]].std() > 3.0, name


def test_textured_materials_differ_from_untextured(world):
    rs, cam = world
    on = render_frame(rs, cam, EMPTY, np.random.default_rng(0), RenderConfig(**PLAIN))
    off = render_frame(rs, cam, EMPTY, np.random.default_rng(0),
                       RenderConfig(**PLAIN, texture=False))
    buf = cast_buffers(rs, cam)
    mats = rs.face_material[np.where(buf.face >= 0, buf.face, 0)].reshape(on.semantic.shape)
    up = buf.normal[:, 2].reshape(mats.shape) > 0.3  # roofs, not the walls below them
    for name in ("roof_gravel", "roof_tiles", "roof_metal"):
        sel = (mats == MATERIAL_IDS[name]) & up
        g_off = _gray(off.rgb)[sel]
        assert g_off.std() < 1.0, name  # flat without texture
        assert _gray(on.rgb)[sel].std() > 2 * g_off.std() + 1.0, name
    # tyre tracks are darker than the asphalt beside them
    trk = mats == MATERIAL_IDS["track"]
    asp = (mats == MATERIAL_IDS["asphalt"])
    assert np.median(_gray(on.rgb)[trk]) < np.median(_gray(on.rgb)[asp]) - 3


def _dominant_angle(gray):
    """Direction (degrees mod 180, world frame: x east, y north) of the strongest
    periodic pattern of an image patch (peak of its windowed power spectrum)."""
    g = gray - gray.mean()
    n = g.shape[0]
    win = np.outer(np.hanning(n), np.hanning(n))
    p = np.abs(np.fft.fftshift(np.fft.fft2(g * win))) ** 2
    cy = cx = n // 2
    yy, xx = np.mgrid[:n, :n]
    p[(yy - cy) ** 2 + (xx - cx) ** 2 < 16] = 0  # drop the lowest frequencies
    r, c = np.unravel_index(np.argmax(p), p.shape)
    fx, fy = c - cx, -(r - cy)  # image rows run south: world y = -row
    return math.degrees(math.atan2(fy, fx)) % 180.0


@pytest.mark.parametrize("material", ["roof_tiles", "roof_metal"])
def test_roof_pattern_turns_with_the_face(material):
    cam = Camera.look_at_ground(CameraConfig(width_px=160, height_px=160, gsd_m=0.04),
                                (0.0, 0.0, 0.0))
    angles = {}
    for turn in (0.0, 30.0):
        rs = RayScene(Scene("roof", [_roof_plane(turn, material)]))
        fr = render_frame(rs, cam, EMPTY, np.random.default_rng(0),
                          RenderConfig(**{**PLAIN, "sun_elevation_deg": (90, 90)}))
        assert (fr.semantic > 0).all()
        angles[turn] = _dominant_angle(_gray(fr.rgb))
    d = (angles[30.0] - angles[0.0]) % 180.0
    assert abs(d - 30.0) < 4.0, angles
    # tile courses repeat down the slope (pattern direction = the downslope tangent);
    # standing seams repeat across it
    expect = 0.0 if material == "roof_tiles" else 90.0
    assert min(abs(angles[0.0] - expect), 180 - abs(angles[0.0] - expect)) < 4.0, angles


def test_face_tangents_follow_slopes_and_outlines():
    strip = shapely.affinity.rotate(shapely.box(-30, -1.25, 30, 1.25), 37.0, origin=(0, 0))
    objs = [build.polygon_object("walk", "sidewalk", strip, 0.1),
            _roof_plane(120.0, "roof_tiles")]
    t = face_tangents(Scene("t", objs))
    n_flat = objs[0].n_triangles
    assert t.shape == (n_flat + 2, 2) and t.dtype == np.float32
    assert np.allclose(np.linalg.norm(t, axis=1), 1.0, atol=1e-5)
    # flat strip: along the strip (sign free)
    ang = np.degrees(np.arctan2(t[:n_flat, 1], t[:n_flat, 0])) % 180.0
    assert np.allclose(ang, 37.0, atol=0.5), ang
    # pitched face: down the slope
    assert np.allclose(t[n_flat:], [math.cos(math.radians(120)), math.sin(math.radians(120))],
                       atol=1e-5)


def test_line_cover_is_the_exact_box_filter():
    cover = numba.njit(lambda x, fp, p, w: M.line_cover(np.float32(x), np.float32(fp),
                                                        np.float32(p), np.float32(w)))
    rng = np.random.default_rng(0)
    for _ in range(200):
        x, fp = rng.uniform(-5, 5), rng.uniform(0.01, 0.5)
        p, w = rng.uniform(0.3, 2.0), rng.uniform(0.005, 0.1)
        s = np.linspace(x - fp / 2, x + fp / 2, 20001)
        brute = ((s % p) < w).mean()
        assert cover(x, fp, p, w) == pytest.approx(brute, abs=2e-3)


def test_paving_joints_darken_the_pixels_on_joint_lines():
    walk = build.polygon_object("walk", "sidewalk", shapely.box(-30, -30, 30, 30), 0.0)
    rs = RayScene(Scene("walk", [walk]))
    cam = Camera.look_at_ground(CameraConfig(width_px=384, height_px=384, gsd_m=0.12),
                                (0.3, 0.2, 0.0))
    fr = render_frame(rs, cam, EMPTY, np.random.default_rng(0),
                      RenderConfig(**{**PLAIN, "sun_elevation_deg": (90, 90)}))
    buf = cast_buffers(rs, cam)
    p = buf.rays[:, :3] + buf.t[:, None] * buf.rays[:, 3:6]
    t = face_tangents(rs.scene)
    tx, ty = t[buf.face, 0], t[buf.face, 1]
    u = p[:, 0] * tx + p[:, 1] * ty
    v = p[:, 1] * tx - p[:, 0] * ty
    slab = M.PAVING_SLAB_M

    def dist(x):  # distance to the nearest joint line
        return np.abs((x + slab / 2) % slab - slab / 2)

    d = np.minimum(dist(u), dist(v)).reshape(fr.semantic.shape)
    g = _gray(fr.rgb)
    on = d < 0.03  # the joint runs through the pixel (0.12 m wide)
    off = d > 0.2
    assert on.sum() > 500 and off.sum() > 10000
    assert g[on].mean() < g[off].mean() - 6.0
    # partial-pixel darkening, not black lines
    assert np.median(g[on]) > 0.6 * np.median(g[off])


def test_randomised_textures_cover_the_new_materials(world):
    rs, cam = world
    a = render_frame(rs, cam, EMPTY, np.random.default_rng(4),
                     RenderConfig(**PLAIN, randomise="textures"))
    b = render_frame(rs, cam, EMPTY, np.random.default_rng(4), RenderConfig(**PLAIN))
    assert len(a.factors["material_rgb_gain"]) == len(MATERIALS)
    assert a.instance.tobytes() == b.instance.tobytes()
    assert a.semantic.tobytes() == b.semantic.tobytes()
    buf = cast_buffers(rs, cam)
    mats = rs.face_material[np.where(buf.face >= 0, buf.face, 0)].reshape(a.semantic.shape)
    for name in ("roof_gravel", "roof_tiles", "roof_metal", "track"):
        sel = mats == MATERIAL_IDS[name]
        assert np.abs(a.rgb[sel].astype(int) - b.rgb[sel].astype(int)).mean() > 2, name


def test_kernels_record_the_materials_source():
    """compose inlines _materials' helpers but numba's disk cache checks only
    _kernels.py: its MATERIALS_SHA must name the current _materials.py, so an edit there
    cannot leave stale compiled code behind."""
    import hashlib
    from pathlib import Path

    from aerial_synth.render import _kernels as K

    digest = hashlib.sha256(Path(M.__file__).read_bytes()).hexdigest()[:16]
    assert K.MATERIALS_SHA == digest
