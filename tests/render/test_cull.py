"""render.cull: the vehicles a group's cameras can see, in view, in a shadow or a mirror."""

from __future__ import annotations

import math

import numpy as np

from aerial_synth.camera import Camera, CameraConfig
from aerial_synth.render import RenderConfig, add_placement, render_frame
from aerial_synth.render.cull import vehicles_for_views
from aerial_synth.scene.raycast import RayScene

from .worlds import make_placement, make_scene

CFG = CameraConfig(altitude_m=30.0, width_px=256, height_px=256)  # 30.7 m square footprint


def _cam(x=0.0, y=0.0, tilt=0.0):
    return Camera.look_at_ground(CFG, (x, y, 0.0), yaw_deg=0.0, tilt_deg=tilt)


def _kept(vehicles, cams, **render):
    return {v.id for v in vehicles_for_views(vehicles, cams, RenderConfig(**render), z_low=0.0)}


def test_reach_follows_the_sun_and_the_view():
    half = 0.5 * CFG.width_px * CFG.nadir_gsd_m
    # cars on the road (y = -2) ever further past the footprint's right edge
    specs = [(k + 1, half + d, -2.0, 0.0, 4.5, 1.8, 1.5) for k, d in enumerate((0.0, 3, 6, 12, 24, 48))]
    pl = make_placement(specs)
    cam = [_cam()]
    high = _kept(pl.vehicles, cam, sun_elevation_deg=(60.0, 70.0), sun_radius_deg=(0.0, 0.0))
    low = _kept(pl.vehicles, cam, sun_elevation_deg=(10.0, 70.0), sun_radius_deg=(0.0, 0.0))
    # the one at the edge always shows; 48 m out, nothing of it can reach the view
    assert 1 in high and 6 not in high
    # a lower sun throws longer shadows: a superset
    assert high <= low and len(low) > len(high)
    # the bounds: 1.5 m roofs, a 10 deg sun -> 8.5 m shadows; mirror rays at the corner angle
    corner = math.degrees(math.atan(math.hypot(half, half) / 30.0))
    reach = 2.0 + 1.0 + max(1.5 / math.tan(math.radians(10.0)),
                            1.5 * math.tan(math.radians(corner + 10.0)))
    for v in pl.vehicles:
        d = v.x_m - half - 0.5 * math.hypot(v.length_m, v.width_m)
        assert (v.id in low) == (d <= reach + 1e-6), (v.id, d, reach)
    # a sun near the horizon (no bound on shadows): every vehicle
    assert _kept(pl.vehicles, cam, sun_elevation_deg=(2.0, 70.0)) == {v.id for v in pl.vehicles}
    # no cameras, no vehicles: nothing to decide
    assert vehicles_for_views([], cam, RenderConfig(), 0.0) == []
    assert len(vehicles_for_views(pl.vehicles, [], RenderConfig(), 0.0)) == len(pl.vehicles)


def test_views_union_and_tilt():
    specs = [(1, 0.0, -2.0, 0.0, 4.5, 1.8, 1.5), (2, 80.0, -2.0, 0.0, 4.5, 1.8, 1.5),
             (3, -80.0, -2.0, 0.0, 4.5, 1.8, 1.5)]
    pl = make_placement(specs)
    r = dict(sun_elevation_deg=(40.0, 70.0), sun_radius_deg=(0.0, 1.0))
    assert _kept(pl.vehicles, [_cam()], **r) == {1}
    assert _kept(pl.vehicles, [_cam(), _cam(x=80.0)], **r) == {1, 2}  # any camera's view
    # a tilted camera looks further: its footprint reaches past the nadir one's
    assert _kept(pl.vehicles, [_cam(x=50.0, tilt=40.0)], **r) >= _kept(pl.vehicles, [_cam(x=50.0)], **r)


def test_a_shadow_from_outside_the_view_is_kept():
    """A truck just outside the footprint whose shadow falls into the view: it changes the
    image, and the cull keeps it; a car far away changes nothing and goes."""
    half = 0.5 * CFG.width_px * CFG.nadir_gsd_m
    truck = (5, half + 12.5, -2.0, 0.0, 9.0, 2.5, 4.0)  # its near end 8 m out
    far = (6, half + 60.0, -2.0, 0.0, 4.5, 1.8, 1.5)
    scene = make_scene(building=False)
    cam = _cam()
    # the sun low in the east (azimuth 90): the truck's shadow points west, into the view
    rcfg = RenderConfig.preset("full", sun_azimuth_deg=(90.0, 90.0), sun_elevation_deg=(20.0, 20.0),
                               overcast_probability=0.0, wet_probability=0.0,
                               jpeg_probability=0.0, sun_radius_deg=(0.3, 0.3))

    def rgb(specs):
        rs = RayScene(scene)
        add_placement(rs, make_placement(specs), simple_boxes=True)
        fr = render_frame(rs, cam, make_placement(specs), np.random.default_rng(1), config=rcfg)
        return fr.rgb.astype(int)

    with_truck, without = rgb([truck, far]), rgb([far])
    shaded = np.abs(with_truck - without).max(axis=2) > 8
    assert shaded.sum() > 100  # the truck's shadow is in the image
    kept = _kept(make_placement([truck, far]).vehicles, [cam], sun_elevation_deg=(20.0, 20.0),
                 sun_radius_deg=(0.3, 0.3))
    assert kept == {5}


def test_face_tangents_once_per_scene():
    """The shader's face tangents are computed once per scene (an export builds a RayScene
    per placement group), again when the scene's objects change."""
    from aerial_synth.render.shading import _face_tangents_cached, face_tangents
    from aerial_synth.scene import build
    from aerial_synth.scene.model import SceneObject

    scene = make_scene()
    t1 = _face_tangents_cached(RayScene(scene))
    assert _face_tangents_cached(RayScene(scene)) is t1
    assert np.array_equal(t1, face_tangents(scene)) and not t1.flags.writeable
    import shapely

    v, f = build.prism(shapely.box(-30, 10, -20, 18), 0.0, 6.0)
    scene.objects.append(SceneObject("shed", "building", v, f))
    rs = RayScene(scene)
    t2 = _face_tangents_cached(rs)
    assert t2 is not t1 and len(t2) == len(rs._static_faces) == len(t1) + len(f)
