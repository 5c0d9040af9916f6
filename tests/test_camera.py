import math

import numpy as np
import pytest

from aerial_synth.camera import Camera, CameraConfig, grid_poses, sample_pose_targeted
from aerial_synth.errors import CameraError
from aerial_synth.placement.model import PlacedVehicle, Placement


def _placement(n=5):
    vs = [
        PlacedVehicle(id=i + 1, model="sedan", color="white", cls="small-vehicle", length_m=4.5,
                      width_m=1.8, height_m=1.5, x_m=10.0 * i, y_m=-3.0 * i, z_m=0.5,
                      heading_rad=0.3 * i)
        for i in range(n)
    ]
    return Placement(scene="t", scenario="manual", seed=0, vehicles=vs)


def test_defaults_match_method():
    cfg = CameraConfig()
    assert cfg.f_px == pytest.approx(500.0)
    assert cfg.nadir_gsd_m == pytest.approx(0.12)
    assert cfg.fov_x_deg == pytest.approx(91.36, abs=0.01)
    assert CameraConfig(fov_deg=cfg.fov_x_deg).f_px == pytest.approx(500.0)
    assert CameraConfig(focal_px=500).nadir_gsd_m == pytest.approx(0.12)


@pytest.mark.parametrize(
    "kw",
    [
        {"altitude_m": 0},
        {"altitude_m": -5},
        {"altitude_m": float("nan")},
        {"width_px": 0},
        {"height_px": 16385},
        {"width_px": 10.5},
        {"gsd_m": 0.12, "fov_deg": 90},
        {"gsd_m": 0.12, "focal_px": 500},
        {"focal_px": 500, "fov_deg": 90},
        {"fov_deg": 180},
        {"gsd_m": 0},
        {"max_tilt_deg": 89},
        {"max_tilt_deg": -1},
    ],
)
def test_bad_config(kw):
    with pytest.raises(CameraError):
        CameraConfig(**kw)


def test_look_at_refuses_steep_tilt():
    with pytest.raises(CameraError):
        Camera.look_at_ground(CameraConfig(), (0, 0, 0), tilt_deg=89)


def test_ground_square_spans_83_px_at_nadir():
    cam = Camera.look_at_ground(CameraConfig(), (3.0, -7.0, 0.0), yaw_deg=0.0)
    sq = np.array([[3, -7, 0], [13, -7, 0], [13, 3, 0], [3, 3, 0]], float)
    uv = cam.project(sq)
    span = uv.max(axis=0) - uv.min(axis=0)
    assert span == pytest.approx([10 / 0.12, 10 / 0.12], abs=1.0)
    # image orientation at yaw 0: east is right, north is up
    assert uv[1, 0] > uv[0, 0] and uv[2, 1] < uv[1, 1]


def test_project_target_is_image_centre_and_round_trip():
    rng = np.random.default_rng(3)
    cfg = CameraConfig(width_px=800, height_px=600)
    for _ in range(20):
        cam = sample_pose_targeted(cfg, _placement(), rng)
        uv = cam.project(np.array([cam.target_xyz]))[0]
        assert uv == pytest.approx([400.0, 300.0], abs=1e-6)
        # altitude above the target
        assert cam.center[2] - cam.target_xyz[2] == pytest.approx(60.0)
        # pixel_directions inverts project
        pts = rng.uniform(-30, 30, (10, 3)) + np.array(cam.target_xyz)
        uv = cam.project(pts)
        d = cam.pixel_directions(uv)
        v = pts - cam.center
        cos = (d * v).sum(1) / np.linalg.norm(d, axis=1) / np.linalg.norm(v, axis=1)
        assert np.all(cos > 1 - 1e-12)
        back = Camera.from_dict(cam.to_dict())
        assert np.array_equal(back.project(pts), cam.project(pts))


def test_tilt_and_yaw_ranges_over_1000_samples():
    rng = np.random.default_rng(0)
    cfg = CameraConfig()
    pl = _placement()
    tilts, yaws, axis_tilts = [], [], []
    for _ in range(1000):
        cam = sample_pose_targeted(cfg, pl, rng)
        tilts.append(cam.tilt_deg)
        yaws.append(cam.yaw_deg)
        z = cam.R[:, 2]
        axis_tilts.append(math.degrees(math.acos(-z[2])))
        assert np.allclose(cam.R.T @ cam.R, np.eye(3), atol=1e-12)
        assert np.linalg.det(cam.R) == pytest.approx(1.0)
    tilts, yaws = np.array(tilts), np.array(yaws)
    assert tilts.min() >= -15 and tilts.max() <= 15
    assert tilts.min() < -14 and tilts.max() > 14
    assert yaws.min() >= 0 and yaws.max() < 360 and yaws.min() < 5 and yaws.max() > 355
    assert np.allclose(axis_tilts, np.abs(tilts), atol=1e-6)
    assert max(axis_tilts) <= 15 + 1e-9


def test_targeted_needs_vehicles():
    with pytest.raises(CameraError):
        sample_pose_targeted(CameraConfig(), _placement(0), np.random.default_rng(0))


def test_grid_covers_bounds_with_overlap():
    cfg = CameraConfig(width_px=100, height_px=100)  # 12 m tiles
    cams = grid_poses(cfg, [[0, 0], [50, 30]], overlap=0.25)
    xs = sorted({round(c.target_xyz[0], 6) for c in cams})
    ys = sorted({round(c.target_xyz[1], 6) for c in cams})
    assert np.allclose(np.diff(xs), 9.0) and np.allclose(np.diff(ys), 9.0)
    assert xs[0] - 6 <= 0 and xs[-1] + 6 >= 50 and ys[0] - 6 <= 0 and ys[-1] + 6 >= 30
    assert all(c.tilt_deg == 0 for c in cams)
    with pytest.raises(CameraError):
        grid_poses(cfg, [[0, 0], [50, 30]], overlap=1.0)
