"""Frame buffers and visibility on hand-built worlds (nadir geometry checks)."""

import numpy as np
import pytest
import shapely

from aerial_synth.camera import Camera, CameraConfig
from aerial_synth.render import RenderConfig, render_frame
from aerial_synth.render.buffers import cast_buffers
from aerial_synth.render.visibility import compute_visibility
from aerial_synth.scene import build
from aerial_synth.scene.model import LABEL_IDS, Scene
from aerial_synth.scene.raycast import RayScene

from .worlds import make_scene, make_world

CFG = CameraConfig()
SMALL = CameraConfig(width_px=256, height_px=256, gsd_m=0.12)
QUICK = RenderConfig(jpeg_probability=0.0)


def _nadir(target, cfg=CFG, yaw=0.0):
    return Camera.look_at_ground(cfg, target, yaw_deg=yaw)


def test_ten_metre_square_spans_83_px_in_the_buffers():
    objs = [
        build.polygon_object("g", "ground", shapely.box(-50, -50, 50, 50).difference(
            shapely.box(0, 0, 10, 10)), 0.0),
        build.polygon_object("p", "parking", shapely.box(0, 0, 10, 10), 0.0),
    ]
    rs = RayScene(Scene("sq", objs))
    cam = _nadir((5.0, 5.0, 0.0), SMALL)
    buf = cast_buffers(rs, cam)
    rows, cols = np.nonzero(buf.semantic == LABEL_IDS["parking"])
    assert cols.max() - cols.min() + 1 == pytest.approx(10 / 0.12, abs=1.0)
    assert rows.max() - rows.min() + 1 == pytest.approx(10 / 0.12, abs=1.0)


def test_depth_at_centre_is_altitude_minus_ground_height():
    rs = RayScene(make_scene(plateau_z=2.5, building=False))
    cam = _nadir((0.0, 23.0, 0.0), SMALL)  # camera at z = 60 above a 2.5 m plateau
    buf = cast_buffers(rs, cam)
    h, w = buf.depth.shape
    centre = buf.depth[h // 2 - 1 : h // 2 + 1, w // 2 - 1 : w // 2 + 1]
    assert np.allclose(centre, 60.0 - 2.5, atol=0.01)
    assert buf.depth.dtype == np.float32


@pytest.mark.parametrize("offset", [(0.0, 0.0), (6.0, -4.0), (-15.0, 9.0)])
def test_projected_centre_matches_mask_centroid(offset):
    x, y = 0.0 + offset[0], -2.0 + offset[1]
    rs, pl = make_world([(5, x, y, 0.7, 4.5, 1.8, 1.5)], building=False)
    cam = _nadir((0.0, -2.0, 0.0))
    f = render_frame(rs, cam, pl, np.random.default_rng(0), QUICK)
    rows, cols = np.nonzero(f.instance == 5)
    centroid = np.array([cols.mean() + 0.5, rows.mean() + 0.5])
    uv = cam.project(np.array([[x, y, 0.75]]))[0]
    assert np.abs(centroid - uv).max() < 1.0
    v = f.visibility[5]
    assert v.visible_fraction == pytest.approx(1.0, abs=0.01) and not v.truncated


def test_crown_lowers_visible_fraction():
    spec = [(3, 8.0, 2.0, 0.0, 4.5, 1.8, 1.5)]
    cam = _nadir((8.0, 2.0, 0.0), SMALL)
    rs, pl = make_world(spec, building=False)
    free = render_frame(rs, cam, pl, np.random.default_rng(0), QUICK).visibility[3]
    assert free.visible_fraction > 0.99 and free.amodal_px > 300
    rs, pl = make_world(spec, building=False, crown_at=(9.5, 2.5))
    hidden = render_frame(rs, cam, pl, np.random.default_rng(0), QUICK).visibility[3]
    assert hidden.visible_fraction < 0.7
    assert hidden.amodal_px == free.amodal_px  # amodal ignores the crown
    assert hidden.amodal_bbox_xyxy == free.amodal_bbox_xyxy


def test_vehicle_behind_vehicle_keeps_amodal_silhouette():
    # a tall truck and a car side by side, seen 15 deg off nadir so the truck hides the car
    spec = [(1, 0.0, 0.0, 0.0, 9.0, 2.5, 3.5), (2, 0.0, 2.9, 0.0, 4.5, 1.8, 1.4)]
    rs, pl = make_world(spec, building=False)
    cam = Camera.look_at_ground(SMALL, (0.0, 0.0, 0.0), tilt_deg=15.0, tilt_axis_deg=0.0)
    f = render_frame(rs, cam, pl, np.random.default_rng(0), QUICK)
    car = f.visibility[2]
    alone_rs, alone_pl = make_world(spec[1:], building=False)
    alone = render_frame(alone_rs, cam, alone_pl, np.random.default_rng(0), QUICK).visibility[2]
    assert car.visible_fraction < 0.95
    assert car.amodal_px == alone.amodal_px
    mask, (x0, y0) = f.amodal_mask(2)
    m2, o2 = alone_rs and render_frame(alone_rs, cam, alone_pl, np.random.default_rng(0), QUICK).amodal_mask(2)
    assert (x0, y0) == o2 and np.array_equal(mask, m2)


def test_truncation_at_the_border():
    rs, pl = make_world([(9, 0.0, -2.0, 0.0, 4.5, 1.8, 1.5)], building=False)
    # put the vehicle's centre on the left border
    cam = _nadir((15.36, -2.0, 0.0), SMALL)
    f = render_frame(rs, cam, pl, np.random.default_rng(0), QUICK)
    v = f.visibility[9]
    assert v.truncated and 0.35 < v.truncated_fraction < 0.65
    assert v.amodal_bbox_xyxy[0] == 0
    assert v.amodal_bbox_full_xyxy[0] < 0
    assert v.visible_px == v.amodal_px
    mask, (x0, y0) = f.amodal_mask(9)
    assert x0 == 0 and mask.sum() == v.amodal_px
    # a vehicle fully outside is not reported
    cam = _nadir((40.0, -2.0, 0.0), SMALL)
    assert 9 not in render_frame(rs, cam, pl, np.random.default_rng(0), QUICK).visibility


def test_instance_ids_are_placement_ids_and_semantics_agree(street_world):
    rs, pl = street_world
    rng = np.random.default_rng(1)
    cam = Camera.look_at_ground(CFG, (2.0, 0.0, 0.0), yaw_deg=33.0, tilt_deg=12.0,
                                tilt_axis_deg=70.0)
    f = render_frame(rs, cam, pl, rng, QUICK)
    ids = set(np.unique(f.instance).tolist()) - {0}
    assert ids and ids <= {v.id for v in pl.vehicles}
    assert 70000 in ids  # no 256 / 65536 limit in the buffer
    assert f.instance.dtype == np.uint32 and f.semantic.dtype == np.uint8
    assert np.array_equal(f.instance > 0, f.semantic == LABEL_IDS["vehicle"])
    assert set(f.visibility) >= ids
    for vid, v in f.visibility.items():
        assert 0 <= v.visible_fraction <= 1
        assert v.visible_px == int((f.instance == vid).sum())
        mask, (x0, y0) = f.amodal_mask(vid)
        assert mask.sum() == v.amodal_px
        # visible pixels lie inside the amodal silhouette
        rows, cols = np.nonzero(f.instance == vid)
        assert mask[rows - y0, cols - x0].all()
    assert f.rgb.shape == (1024, 1024, 3) and f.rgb.dtype == np.uint8


def test_same_seed_gives_identical_buffers(street_world):
    rs, pl = street_world
    cam = Camera.look_at_ground(SMALL, (0.0, 0.0, 0.0), yaw_deg=10.0, tilt_deg=5.0)
    cfg = RenderConfig(jpeg_probability=1.0, wet_probability=0.5, overcast_probability=0.5)
    a = render_frame(rs, cam, pl, np.random.default_rng(42), cfg)
    rs2, pl2 = make_world([(v.id, v.x_m, v.y_m, v.heading_rad, v.length_m, v.width_m, v.height_m)
                           for v in pl.vehicles])
    b = render_frame(rs2, cam, pl2, np.random.default_rng(42), cfg)
    for name in ("instance", "semantic", "depth", "rgb"):
        assert getattr(a, name).tobytes() == getattr(b, name).tobytes(), name
    assert a.to_meta() == b.to_meta()
    c = render_frame(rs, cam, pl, np.random.default_rng(43), cfg)
    assert c.rgb.tobytes() != a.rgb.tobytes()


def test_shadows_darken_the_road_north_of_the_building():
    rs, pl = make_world([], building=True)
    cam = _nadir((27.5, 16.0, 0.0), SMALL)
    cfg = RenderConfig(sun_azimuth_deg=(180, 180), sun_elevation_deg=(45, 45), haze=(0, 0),
                       overcast_probability=0, wet_probability=0, jpeg_probability=0,
                       noise_sigma=(0, 0), texture=False, vignetting=(0, 0),
                       exposure_mode="fixed", ambient_occlusion=False, grayscale_probability=0,
                       shot_noise=(0, 0))
    f = render_frame(rs, cam, pl, np.random.default_rng(0), cfg)
    # sun in the south: the 9 m house (x 20..35, y 10..22) shades grass up to y = 31
    north = cam.project(np.array([[27.5, 26.0, 0.0]]))[0].astype(int)
    far = cam.project(np.array([[39.0, 26.0, 0.0]]))[0].astype(int)
    assert (0 <= north).all() and (north < 256).all() and (0 <= far).all() and (far < 256).all()
    assert f.rgb[north[1], north[0]].mean() < 0.75 * f.rgb[far[1], far[0]].mean()
    no = render_frame(rs, cam, pl, np.random.default_rng(0), RenderConfig(**{
        **cfg.to_dict(), "shadows": False}))
    assert no.rgb[north[1], north[0]].mean() == pytest.approx(f.rgb[far[1], far[0]].mean(), abs=3)


def test_visibility_without_vehicles():
    rs = RayScene(make_scene())
    cam = _nadir((0.0, 0.0, 0.0), SMALL)
    buf = cast_buffers(rs, cam)
    vis, masks = compute_visibility(rs, cam, buf.instance, [])
    assert vis == {} and masks.crop(1)[0].shape == (0, 0)
