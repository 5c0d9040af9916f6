"""Which placed vehicles can show in a set of views: the rest need not be built at all.

An export renders the 10 (``images_per_placement``) images of a placement group from one
RayScene. Its Embree scenes (the full one, one without tree crowns for shadow rays, one of
vehicles only for amodal masks) and the vehicle meshes are built once per group, and their
cost grows with the number of vehicle triangles (~380 per car), most of which no camera of
the group sees. :func:`vehicles_for_views` keeps the vehicles that can touch a pixel of
one of the views, directly or through a secondary ray:

* seen: inside the view frustum between the lowest surface and the highest vehicle roof
  (the convex hull of the image corners projected onto both heights);
* a shadow: the sun is at least ``sun_elevation_deg[0] - sun_radius_deg[1]`` high, so a
  roof ``dz`` above the lowest surface shades at most ``dz / tan(elevation)`` away;
* a mirror image (wet roads): a reflected ray leaves the ground at the angle the camera
  ray arrived at (plus a margin for sloped roads) and reaches a roof ``dz`` up within
  ``dz * tan(angle)``;
* ambient occlusion: ``ao_radius_m``.

Each vehicle is kept if its footprint circle comes within that reach of the frustum's
outline. Where a bound does not hold (the sun or a corner ray near the horizon) every
vehicle is kept.

:func:`secondary_reach_m` is that reach for anything ``dz`` tall: the tiled export
(:mod:`aerial_synth.dataset.tiled`) sizes its render window and its vehicle area with it.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["lowest_sun_deg", "secondary_reach_m", "vehicles_for_views"]

#: extra angle for mirror rays off sloped or cambered roads, degrees
_SLOPE_DEG = 10.0
#: no culling past these angles (the reaches grow without bound)
_MAX_VIEW_DEG = 80.0
_MIN_SUN_DEG = 3.0
#: slack for mesh parts past the nominal box (mirrors) and float error, metres
_SLACK_M = 1.0


def lowest_sun_deg(render_config) -> float:
    """The lowest sun (degrees) a frame of ``render_config`` can cast a shadow ray towards:
    the lowest elevation less the largest sun-disk radius."""
    return float(render_config.sun_elevation_deg[0]) - float(render_config.sun_radius_deg[1])


def _mirror_possible(rc) -> bool:
    return bool(rc.wet_reflections) and float(rc.wet_probability) > 0 and float(rc.wet[1]) > 0


def secondary_reach_m(dz: float, render_config, view_deg: float, *, slope_deg: float = _SLOPE_DEG,
                      enabled_only: bool = False, oblique: bool = True) -> float:
    """How far (xy metres) past the area a view sees something ``dz`` metres tall (above the
    lowest surface) can still put a pixel into it: its shadow (``dz / tan(sun)`` at the
    lowest sun, :func:`lowest_sun_deg`), its mirror image in a wet road (a reflected ray
    rises at the camera ray's angle off the vertical, at most ``view_deg``, plus
    ``slope_deg`` for sloped roads: ``dz * tan(view_deg + slope_deg)``), or its ambient
    occlusion (``ao_radius_m``), plus 1 m of slack.

    ``oblique``: also count the view's own reach ``dz * tan(view_deg)`` (something tall
    seen obliquely past the area's outline on the ground; never more than the mirror
    term). Leave it out where the area already holds every point the views see between
    the lowest surface and ``dz`` (the cull's frustum outline; the ground footprint of a
    camera whose nadir lies in it). ``enabled_only``: count only what ``render_config``
    renders (no AO term without ``ambient_occlusion``, no shadow term without ``shadows``,
    no mirror term without wet reflections). The cull counts everything (so its vehicle
    sets stay as they were).

    ``inf`` where no bound holds: a counted sun under 3 deg, or a ray at or past the
    horizon. (:func:`vehicles_for_views` also stops culling past an 80 deg mirror angle.)"""
    rc = render_config
    shadows = not enabled_only or bool(rc.shadows)
    mirror = not enabled_only or _mirror_possible(rc)
    ao = not enabled_only or bool(rc.ambient_occlusion)
    elev = lowest_sun_deg(rc)
    ang = view_deg + slope_deg if mirror else view_deg
    if (shadows and elev < _MIN_SUN_DEG) or ang >= 90.0:
        return math.inf
    dz = max(float(dz), 0.0)
    far = dz * math.tan(math.radians(ang)) if (mirror or oblique) else 0.0
    if shadows:
        far = max(dz / math.tan(math.radians(elev)), far)
    return (float(rc.ao_radius_m) if ao else 0.0) + _SLACK_M + far


def vehicles_for_views(vehicles, cameras, render_config, z_low: float) -> list:
    """The vehicles of ``vehicles`` (PlacedVehicle, in order) that can show in any view of
    ``cameras``; ``z_low`` is the lowest surface of the scene (metres). Rendering the views
    with only these vehicles gives the same labels, depth and visibility as with all of them,
    and the same RGB but for a few shadow or AO samples that Embree's (non-robust)
    traversal of a different tree can decide otherwise for grazing rays."""
    vehicles = list(vehicles)
    cameras = list(cameras)
    if not vehicles or not cameras:
        return vehicles
    top = max(float(v.z_m) + float(v.height_m) for v in vehicles)
    lo = min(float(z_low), min(float(v.z_m) for v in vehicles))
    dz = max(top - lo, 0.0)
    if lowest_sun_deg(render_config) < _MIN_SUN_DEG:
        return vehicles
    import shapely

    outlines, view_deg = [], 0.0
    for cam in cameras:
        corners = np.array([[0, 0], [cam.width_px, 0], [cam.width_px, cam.height_px],
                            [0, cam.height_px]], float)
        d = cam.pixel_directions(corners)
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        if (d[:, 2] >= 0).any():
            return vehicles
        view_deg = max(view_deg, float(np.degrees(np.arccos(np.clip(-d[:, 2], -1.0, 1.0))).max()))
        pts = np.concatenate([cam.ground_footprint_xy(lo), cam.ground_footprint_xy(top)])
        outlines.append(shapely.MultiPoint(pts).convex_hull)
    mirror_deg = view_deg + _SLOPE_DEG
    if mirror_deg > _MAX_VIEW_DEG:
        return vehicles
    reach = secondary_reach_m(dz, render_config, view_deg)
    area = shapely.union_all(outlines)
    xy = np.array([[float(v.x_m), float(v.y_m)] for v in vehicles])
    radius = np.array([0.5 * math.hypot(float(v.length_m), float(v.width_m)) for v in vehicles])
    near = shapely.dwithin(area, shapely.points(xy), reach + radius)
    return [v for v, k in zip(vehicles, near) if k]
