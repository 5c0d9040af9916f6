"""A render task loads only the tiles its footprint touches, and sees what the whole world
shows there."""

import dataclasses
import warnings

import numpy as np

from aerial_synth.camera import CameraConfig, sample_pose_targeted
from aerial_synth.placement import place
from aerial_synth.render import add_placement, render_frame
from aerial_synth.scene.raycast import RayScene
from aerial_synth.scene.tiles import TiledWorld


def window_for_camera(world, grid, placement, camera, ground_z=0.0, pad_m=30.0):
    """The RayScene of the tiles the camera's ground footprint touches, with the vehicles of
    ``placement`` that stand in that window (ids kept), as a tiled render task builds it."""
    scene, tiles = world.scene_for_xy(grid, camera.ground_footprint_xy(ground_z), pad_m)
    b = scene.bounds()
    lo, hi = b[0, :2], b[1, :2]
    vs = [v for v in placement.vehicles
          if lo[0] - v.length_m <= v.x_m <= hi[0] + v.length_m and lo[1] - v.length_m <= v.y_m <= hi[1] + v.length_m]
    sub = dataclasses.replace(placement, vehicles=vs)
    rs = RayScene(scene)
    add_placement(rs, sub, simple_boxes=True)
    return rs, sub, tiles


def test_frame_from_touched_tiles_equals_whole_world(small_city_spec, small_city_scene):
    world = TiledWorld.from_spec(small_city_spec)
    grid = world.grid(125.0, 30.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pl = place(RayScene(small_city_scene), "jam", seed=2, n_vehicles=150)
    cam_cfg = CameraConfig(altitude_m=40.0, width_px=96, height_px=96, max_tilt_deg=10.0)
    full = RayScene(small_city_scene)
    add_placement(full, pl, simple_boxes=True)
    compared = 0
    for k in range(3):
        cam = sample_pose_targeted(cam_cfg, pl, np.random.default_rng(k), within_xy=world.bounds)
        rs, sub, tiles = window_for_camera(world, grid, pl, cam, ground_z=0.05)
        assert 1 <= len(tiles) <= 4 < len(grid)  # only the touched tiles, not the world
        a = render_frame(full, cam, pl, np.random.default_rng(9))
        b = render_frame(rs, cam, sub, np.random.default_rng(9))
        np.testing.assert_array_equal(a.instance, b.instance)
        assert (a.semantic == b.semantic).mean() > 0.999
        assert len(np.unique(a.instance)) > 1
        compared += 1
    assert compared == 3
