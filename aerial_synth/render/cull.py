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
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["vehicles_for_views"]

#: extra angle for mirror rays off sloped or cambered roads, degrees
_SLOPE_DEG = 10.0
#: no culling past these angles (the reaches grow without bound)
_MAX_VIEW_DEG = 80.0
_MIN_SUN_DEG = 3.0
#: slack for mesh parts past the nominal box (mirrors) and float error, metres
_SLACK_M = 1.0


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
    elev = float(render_config.sun_elevation_deg[0]) - float(render_config.sun_radius_deg[1])
    if elev < _MIN_SUN_DEG:
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
    reach = (float(render_config.ao_radius_m) + _SLACK_M
             + max(dz / math.tan(math.radians(elev)), dz * math.tan(math.radians(mirror_deg))))
    area = shapely.union_all(outlines)
    xy = np.array([[float(v.x_m), float(v.y_m)] for v in vehicles])
    radius = np.array([0.5 * math.hypot(float(v.length_m), float(v.width_m)) for v in vehicles])
    near = shapely.dwithin(area, shapely.points(xy), reach + radius)
    return [v for v, k in zip(vehicles, near) if k]
