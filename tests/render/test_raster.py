"""The z-buffer primary (render/raster.py) answers what one Embree ray per pixel answers.

- On a world of roads, a building, a crown (smooth normals), a trunk and vehicles, seen
  nadir, tilted and turned, both methods give the same face at all but a few edge pixels,
  the same labels, depths to float32 round-off and the same normals (smooth ones too).
- A pixel centre is inside a triangle iff the exact ray test says so (a square's coverage
  equals the analytic set of centres).
- Watertight: a ground of 20,000 jittered triangles has no hole in the raster's answer.
- Triangles reaching behind the camera (a huge ground, a horizon in view), misses (sky),
  exact ties (two coplanar triangles: the lower face wins) and the thread count.
"""

from __future__ import annotations

import numpy as np
import pytest

from aerial_synth.camera import Camera, CameraConfig
from aerial_synth.render.buffers import cast_buffers
from aerial_synth.scene.model import LABEL_IDS, Scene, SceneObject
from aerial_synth.scene.raycast import RayScene

from .worlds import MIXED_SPECS, make_world, with_threads

SMALL = CameraConfig(width_px=320, height_px=256, gsd_m=0.1)
SPECS = MIXED_SPECS
POSES = [
    dict(),
    dict(yaw_deg=33.0, tilt_deg=15.0, tilt_axis_deg=70.0),
    dict(yaw_deg=200.0, tilt_deg=35.0, tilt_axis_deg=250.0),
]


def _both(rs, cam):
    return cast_buffers(rs, cam, method="raster"), cast_buffers(rs, cam, method="embree")


@pytest.mark.parametrize("pose", POSES)
def test_raster_agrees_with_the_embree_cast(pose):
    rs, _ = make_world(SPECS, building=True, crown_at=(8.5, -1.0))
    cam = Camera.look_at_ground(SMALL, (3.0, 1.0, 0.0), **pose)
    r, e = _both(rs, cam)
    n = cam.height_px * cam.width_px
    same = r.face == e.face
    assert same.mean() > 0.998, (n - same.sum())
    assert (r.semantic != e.semantic).sum() <= 0.0005 * n
    assert (r.instance != e.instance).sum() <= 0.0005 * n
    assert set(np.unique(r.instance)) >= {1, 2, 3, 4, 5}
    hit = same & (e.face >= 0)
    assert hit.sum() > 0.99 * n
    np.testing.assert_allclose(r.t[hit], e.t[hit], rtol=2e-5, atol=1e-4)
    np.testing.assert_array_equal(r.depth.ravel()[hit], r.t[hit])
    np.testing.assert_allclose(r.normal[hit], e.normal[hit], atol=2e-3)
    np.testing.assert_array_equal(r.rays, e.rays)
    # the crown's normals are the interpolated (smooth) ones: they vary across one face
    crown = hit & (rs.face_label[np.maximum(e.face, 0)] == LABEL_IDS["tree"])
    assert crown.sum() > 100
    faces, counts = np.unique(r.face[crown], return_counts=True)
    on = r.face == faces[np.argmax(counts)]
    assert np.ptp(r.normal[on], axis=0).max() > 1e-3
    # camera-facing unit normals
    d = np.sum(r.normal[hit] * r.rays[hit, 3:], axis=1)
    assert (d <= 1e-6).all()
    np.testing.assert_allclose(np.linalg.norm(r.normal[hit], axis=1), 1.0, atol=1e-5)


def _flat(name, label, v, f):
    return SceneObject(name, label, np.asarray(v, np.float64), np.asarray(f, np.int64))


def test_coverage_is_the_set_of_pixel_centres_inside():
    # a 3.07 x 3.09 m square at z = 0 under a nadir camera: covered iff the ray through the
    # pixel centre meets the square; nothing else in the scene
    x0, x1, y0, y1 = -1.33, 1.74, -1.71, 1.38
    sq = _flat("sq", "road", [[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0]],
               [[0, 1, 2], [0, 2, 3]])
    rs = RayScene(Scene("sq", [sq]))
    cam = Camera.look_at_ground(CameraConfig(width_px=64, height_px=48, gsd_m=0.1), (0.0, 0.0, 0.0))
    r, e = _both(rs, cam)
    rays = cam.pixel_rays().astype(np.float64)
    t = -rays[:, 2] / rays[:, 5]
    p = rays[:, :3] + t[:, None] * rays[:, 3:]
    inside = (p[:, 0] >= x0) & (p[:, 0] <= x1) & (p[:, 1] >= y0) & (p[:, 1] <= y1)
    assert inside.sum() > 500 and (~inside).sum() > 500
    np.testing.assert_array_equal(r.face >= 0, inside)
    np.testing.assert_array_equal(r.face, e.face)
    assert np.isinf(r.t[r.face < 0]).all() and (r.depth.ravel()[r.face < 0] == 0).all()
    assert (r.semantic.ravel()[r.face < 0] == 0).all()
    np.testing.assert_allclose(r.t[r.face >= 0], 60.0, rtol=1e-6)


def _jittered_ground(n=100, size=100.0, seed=0):
    rng = np.random.default_rng(seed)
    g = np.linspace(-size / 2, size / 2, n + 1)
    x, y = np.meshgrid(g, g)
    step = size / n
    jx = rng.uniform(-0.3, 0.3, x.shape) * step
    jy = rng.uniform(-0.3, 0.3, y.shape) * step
    jx[:, [0, -1]] = 0
    jy[[0, -1], :] = 0
    z = rng.uniform(-0.05, 0.05, x.shape)
    v = np.stack([x + jx, y + jy, z], axis=-1).reshape(-1, 3)
    i = np.arange((n + 1) * (n + 1)).reshape(n + 1, n + 1)
    a, b, c, d = i[:-1, :-1], i[:-1, 1:], i[1:, 1:], i[1:, :-1]
    f = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                        np.stack([a, c, d], -1).reshape(-1, 3)])
    return v, f


@pytest.mark.parametrize("pose", POSES)
def test_a_closed_ground_has_no_holes(pose):
    v, f = _jittered_ground()
    rs = RayScene(Scene("grid", [_flat("g", "ground", v, f)]))
    assert len(f) == 20_000
    cam = Camera.look_at_ground(CameraConfig(width_px=400, height_px=300, gsd_m=0.1),
                                (2.0, -3.0, 0.0), **pose)
    r = cast_buffers(rs, cam, method="raster")
    rays = cam.pixel_rays().astype(np.float64)
    p = rays[:, :3] - (rays[:, 2] / rays[:, 5])[:, None] * rays[:, 3:]  # on z = 0
    on = (np.abs(p[:, :2]) < 49.0).all(axis=1)  # inside the ground, away from its rim
    assert on.mean() > 0.5
    assert (r.face[on] >= 0).all()  # every such centre hits the ground: watertight
    e = cast_buffers(rs, cam, method="embree")
    assert (r.face == e.face).mean() > 0.999


def test_pixel_centres_exactly_on_shared_edges_are_covered():
    # vertical strips whose shared edges pass exactly through every other column of pixel
    # centres (a nadir camera 60 m up: the centre of column c sees x = 60 * x_c, computed
    # exactly): those centres lie on an edge of two triangles and must hit one of them
    from aerial_synth.render.raster import image_coords

    cfg = CameraConfig(width_px=64, height_px=48, gsd_m=0.125)
    cam = Camera.look_at_ground(cfg, (0.0, 0.0, 0.0))
    assert cam.center.tolist() == [0.0, 0.0, 60.0] and np.array_equal(np.abs(cam.R), np.eye(3))
    xs, _ = image_coords(cam)
    edges = np.concatenate([[-5.0], 60.0 * xs[1:-1:2].astype(np.float64), [5.0]])
    v, f = [], []
    for k in range(len(edges) - 1):
        a, b = edges[k], edges[k + 1]
        i = len(v)
        v += [[a, -4.0, 0.0], [b, -4.0, 0.0], [b, 4.0, 0.0], [a, 4.0, 0.0]]
        f += [[i, i + 1, i + 2], [i, i + 2, i + 3]] if k % 2 else [[i + 1, i + 2, i + 3],
                                                                   [i + 1, i + 3, i]]
    rs = RayScene(Scene("strips", [_flat("g", "ground", v, f)]))
    r = cast_buffers(rs, cam, method="raster")
    assert (r.face >= 0).all()


def test_triangles_behind_the_camera_horizon_and_sky():
    # a 20 km ground of two triangles (corners far behind the camera) and a steep view that
    # sees the horizon: the sky misses, everything else hits the ground as Embree says
    s = 10_000.0
    ground = _flat("g", "ground", [[-s, -s, 0], [s, -s, 0], [s, s, 0], [-s, s, 0]],
                   [[0, 1, 2], [0, 2, 3]])
    wall = _flat("w", "building", [[30, -40, 0], [30, 40, 0], [30, 40, 25], [30, -40, 25]],
                 [[0, 1, 2], [0, 2, 3]])
    rs = RayScene(Scene("far", [ground, wall]))
    cfg = CameraConfig(width_px=200, height_px=160, gsd_m=0.5)
    for pose in (dict(), dict(tilt_deg=80.0, tilt_axis_deg=0.0),
                 dict(tilt_deg=80.0, tilt_axis_deg=180.0, yaw_deg=45.0)):
        cam = Camera.look_at_ground(cfg, (0.0, 0.0, 0.0), **pose)
        r, e = _both(rs, cam)
        assert (r.face == e.face).mean() > 0.995
        assert ((r.face < 0) == (e.face < 0)).mean() > 0.995
    assert (r.face < 0).any() and (r.face >= 0).any()  # the last view sees sky and ground


def test_an_exact_tie_goes_to_the_lower_face_and_threads_do_not_matter():
    # the same square twice: every pixel ties exactly, the face order decides
    v = [[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]]
    a = _flat("a", "road", v, [[0, 1, 2], [0, 2, 3]])
    b = _flat("b", "parking", v, [[0, 1, 2], [0, 2, 3]])
    rs = RayScene(Scene("tie", [a, b]))
    cam = Camera.look_at_ground(CameraConfig(width_px=96, height_px=80, gsd_m=0.05), (0.3, 0.1, 0.0),
                                yaw_deg=20.0, tilt_deg=10.0, tilt_axis_deg=30.0)
    r1 = with_threads(1, lambda: cast_buffers(rs, cam, method="raster"))
    r2 = with_threads(2, lambda: cast_buffers(rs, cam, method="raster"))
    hit = r1.face >= 0
    assert hit.sum() > 1000 and (r1.face[hit] < 2).all()  # object "a" (faces 0, 1) wins
    for k in ("face", "t", "normal", "semantic", "instance", "depth"):
        assert getattr(r1, k).tobytes() == getattr(r2, k).tobytes(), k


def test_big_world_is_the_same_on_one_and_two_threads():
    rs, _ = make_world(SPECS, building=True, crown_at=(8.5, -1.0))
    cam = Camera.look_at_ground(SMALL, (3.0, 1.0, 0.0), **POSES[1])
    r1 = with_threads(1, lambda: cast_buffers(rs, cam, method="raster"))
    r2 = with_threads(2, lambda: cast_buffers(rs, cam, method="raster"))
    for k in ("face", "t", "normal", "semantic", "instance", "depth"):
        assert getattr(r1, k).tobytes() == getattr(r2, k).tobytes(), k


def test_unknown_method_is_refused():
    rs, _ = make_world(SPECS[:1], building=False)
    cam = Camera.look_at_ground(SMALL, (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="raster"):
        cast_buffers(rs, cam, method="optix")


@pytest.mark.parametrize("size", [(1, 1), (1, 7), (3, 1), (2048, 3)])
def test_odd_image_sizes_agree_with_the_cast(size):
    rs, _ = make_world(SPECS[:2], building=True)
    cam = Camera.look_at_ground(CameraConfig(width_px=size[0], height_px=size[1], gsd_m=0.1),
                                (0.0, 0.0, 0.0), tilt_deg=10.0)
    r, e = _both(rs, cam)
    assert r.instance.shape == (size[1], size[0])
    np.testing.assert_array_equal(r.face, e.face)


def test_an_empty_scene_and_a_degenerate_triangle_are_all_misses():
    cam = Camera.look_at_ground(CameraConfig(width_px=16, height_px=8, gsd_m=0.1), (0.0, 0.0, 0.0))
    line = _flat("d", "road", [[0, 0, 0], [1, 1, 0], [2, 2, 0]], [[0, 1, 2]])  # zero area
    for scene in (Scene("empty", []), Scene("degenerate", [line])):
        r = cast_buffers(RayScene(scene), cam, method="raster")
        assert (r.face == -1).all() and np.isinf(r.t).all() and (r.depth == 0).all()
        assert (r.semantic == 0).all() and (r.instance == 0).all()
