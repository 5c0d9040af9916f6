"""The fast paths of a frame give the same labels as the plain ones.

- ``cast_buffers`` maps Embree's answer in one compiled pass: the same faces, labels,
  instance ids, depths and normals as :meth:`RayScene.cast_rays` on the same rays.
- ``compute_visibility(..., depth=...)`` skips the vehicles-only rays of pixels that the
  primary hit settles: the same visibility records and amodal masks as casting every
  pixel, on worlds with unoccluded vehicles, vehicles under a crown and a vehicle behind
  another (tilted view), and it casts fewer rays.
"""

import numpy as np
import pytest

from aerial_synth.camera import Camera, CameraConfig
from aerial_synth.render.buffers import cast_buffers
from aerial_synth.render.visibility import VEHICLES_ONLY, compute_visibility

from .worlds import MIXED_SPECS, make_world

SMALL = CameraConfig(width_px=256, height_px=256, gsd_m=0.12)

SPECS = MIXED_SPECS


def _counting(rs):
    """Wrap rs.cast_rays to count the rays of vehicles-only casts."""
    seen = []
    orig = rs.cast_rays

    def spy(rays, ignore=()):
        if frozenset(ignore) == VEHICLES_ONLY:
            seen.append(len(rays))
        return orig(rays, ignore=ignore)

    rs.cast_rays = spy
    return seen


CAMERAS = [
    dict(),
    dict(tilt_deg=15.0, tilt_axis_deg=0.0),
    dict(tilt_deg=30.0, tilt_axis_deg=110.0),
    dict(yaw_deg=35.0, tilt_deg=8.0, tilt_axis_deg=250.0),
]


@pytest.mark.parametrize("pose", CAMERAS)
def test_skipping_settled_pixels_gives_the_same_visibility_and_amodal_masks(pose):
    rs, pl = make_world(SPECS, building=True, crown_at=(8.5, -1.0))
    cam = Camera.look_at_ground(SMALL, (1.0, 1.0, 0.0), **pose)
    buf = cast_buffers(rs, cam)
    seen = _counting(rs)
    full, full_masks = compute_visibility(rs, cam, buf.instance, pl.vehicles)
    n_full = sum(seen)
    seen.clear()
    fast, fast_masks = compute_visibility(rs, cam, buf.instance, pl.vehicles, depth=buf.depth)
    n_fast = sum(seen)
    assert len(full) >= 5
    fractions = [v.visible_fraction for v in full.values()]
    assert min(fractions) < 0.95 and max(fractions) == 1.0  # occluded and free vehicles
    assert fast == full  # every field of every record
    for k in ("ids", "rows", "cols"):
        np.testing.assert_array_equal(getattr(fast_masks, k), getattr(full_masks, k))
    for vid in full:
        m1, o1 = full_masks.crop(vid)
        m2, o2 = fast_masks.crop(vid)
        assert o1 == o2 and np.array_equal(m1, m2)
    assert n_fast < 0.5 * n_full  # most union pixels are settled by the primary hit


def test_fully_visible_vehicles_need_almost_no_vehicles_only_rays():
    # free cars far apart on an open road, nadir: every union pixel is settled but for the
    # few whose ground hit lies within the 1 cm tolerance of a car's box
    specs = [(1, -8.0, 0.0, 0.0, 4.5, 1.8, 1.5), (2, 6.0, 1.0, 0.5, 4.5, 1.8, 1.5)]
    rs, pl = make_world(specs, building=False)
    cam = Camera.look_at_ground(SMALL, (0.0, 0.0, 0.0))
    buf = cast_buffers(rs, cam)
    seen = _counting(rs)
    fast, _ = compute_visibility(rs, cam, buf.instance, pl.vehicles, depth=buf.depth)
    n_fast = sum(seen)
    seen.clear()
    full, _ = compute_visibility(rs, cam, buf.instance, pl.vehicles)
    assert sum(seen) > 1000 and n_fast <= 0.01 * sum(seen)
    assert fast == full and all(v.visible_fraction == 1.0 for v in fast.values())


def test_a_hidden_vehicle_is_still_cast():
    # the crown hides the car: its pixels cannot be settled by the primary hit
    rs, pl = make_world([(3, 8.0, 2.0, 0.0, 4.5, 1.8, 1.5)], building=False,
                        crown_at=(9.5, 2.5))
    cam = Camera.look_at_ground(SMALL, (8.0, 2.0, 0.0))
    buf = cast_buffers(rs, cam)
    seen = _counting(rs)
    fast, _ = compute_visibility(rs, cam, buf.instance, pl.vehicles, depth=buf.depth)
    assert sum(seen) > 100
    seen.clear()
    full, _ = compute_visibility(rs, cam, buf.instance, pl.vehicles)
    assert fast == full and fast[3].visible_fraction < 0.7


@pytest.mark.parametrize("pose", CAMERAS[:2])
def test_fused_buffers_equal_the_mapped_cast(pose):
    # the Embree primary (the z-buffer's agreement with it: tests/render/test_raster.py)
    rs, pl = make_world(SPECS, building=True, crown_at=(8.5, -1.0))
    cam = Camera.look_at_ground(SMALL, (1.0, 1.0, 0.0), **pose)
    buf = cast_buffers(rs, cam, method="embree")
    hits = rs.cast_rays(cam.pixel_rays())
    np.testing.assert_array_equal(buf.face, hits.face)
    np.testing.assert_array_equal(buf.t, hits.t)
    np.testing.assert_array_equal(buf.semantic.ravel(), hits.label_id.astype(np.uint8))
    np.testing.assert_array_equal(buf.instance.ravel(), hits.instance_id.astype(np.uint32))
    np.testing.assert_array_equal(buf.depth.ravel(), np.where(hits.hit, hits.t, 0))
    n = hits.normal * np.where(np.sum(hits.normal * cam.pixel_rays()[:, 3:], axis=1) > 0,
                               -1, 1)[:, None].astype(np.float32)
    # crown (foliage) hits carry the interpolated shading normal (render/smooth.py)
    from aerial_synth.render.smooth import smooth_shading_normals

    rays = cam.pixel_rays().astype(np.float32)
    uv = rs._cast_raw(rays)["primitive_uvs"]
    smooth_shading_normals(rs, hits.face, uv, rays, n)
    np.testing.assert_array_equal(buf.normal, n)
    assert set(np.unique(buf.instance)) >= {1, 2, 3}
    assert buf.face.min() == -1 or (buf.face >= 0).all()


def test_fast_preset_leaves_out_the_costly_factors():
    from aerial_synth.render import RenderConfig

    fast, full = RenderConfig.preset("fast"), RenderConfig.preset("full")
    assert not fast.ambient_occlusion and not fast.soft_shadows and fast.shadow_step == 4
    assert not fast.texture and not fast.wet_reflections  # moved out for the 1.5x budget
    assert full.ambient_occlusion and full.soft_shadows and full.texture
    assert full.wet_reflections and full.shadow_step == 3


def test_vehicles_crossing_the_camera_plane_are_bounded_and_give_the_same_result():
    from aerial_synth.render.visibility import _corners

    # 75 degrees off nadir: the camera stands ~223 m south of its target; cars ~16 m
    # further south straddle its image plane (their bounds are clipped, not dropped)
    extra = [(20 + k, -3.0 + 3 * k, -239.0 + 1.5 * (k % 3), 0.3 * k, 4.5, 1.8, 1.5)
             for k in range(6)]
    rs, pl = make_world(SPECS + extra, building=True, crown_at=(8.5, -1.0))
    cam = Camera.look_at_ground(SMALL, (1.0, 1.0, 0.0), tilt_deg=75.0, tilt_axis_deg=0.0)
    ids, b = rs._vehicle_bounds()
    z = cam.to_camera(_corners(b).reshape(-1, 3)).reshape(len(ids), 8, 3)[..., 2]
    assert ((z > 0).any(axis=1) & (z <= 0).any(axis=1)).sum() >= 2
    buf = cast_buffers(rs, cam)
    full, full_masks = compute_visibility(rs, cam, buf.instance, pl.vehicles)
    fast, fast_masks = compute_visibility(rs, cam, buf.instance, pl.vehicles, depth=buf.depth)
    assert len(full) >= 5 and fast == full
    for k in ("ids", "rows", "cols"):
        np.testing.assert_array_equal(getattr(fast_masks, k), getattr(full_masks, k))
