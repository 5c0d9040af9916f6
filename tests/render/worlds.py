"""Hand-built test worlds for the renderer (no bundled scenes needed)."""

from __future__ import annotations

import numpy as np
import shapely

from aerial_synth.placement.model import PlacedVehicle, Placement
from aerial_synth.scene import build
from aerial_synth.scene.model import Scene, SceneObject
from aerial_synth.scene.raycast import RayScene

# a truck beside a car (the truck hides part of the car when tilted), a car under a crown
# (with ``crown_at=(8.5, -1.0)``), free cars, two cars nose to tail (boxes overlap with a
# 2 px margin) and one near the border of a 256 px view of (1, 1)
MIXED_SPECS = [
    (1, 0.0, 0.0, 0.0, 9.0, 2.5, 3.5),
    (2, 0.0, 2.9, 0.0, 4.5, 1.8, 1.4),
    (3, 8.0, -2.0, 0.4, 4.5, 1.8, 1.5),
    (4, -9.0, -1.5, 2.0, 4.2, 1.8, 1.45),
    (5, -9.0, 3.2, 2.0, 4.2, 1.8, 1.45),
    (6, 14.5, 2.0, 1.2, 4.5, 1.8, 1.5),
    (7, 6.0, 6.0, 0.0, 4.5, 1.8, 1.5),
]


def make_scene(crown_at=None, plateau_z=None, building=True) -> Scene:
    objs = [
        build.polygon_object("grass", "ground", shapely.box(-100, -100, 100, 100).difference(
            shapely.box(-100, -4, 100, 4)), 0.0),
        build.polygon_object("road", "road", shapely.box(-100, -4, 100, 4), 0.0),
        build.polygon_object("mark", "lane_marking", shapely.box(-100, -0.06, 100, 0.06), 0.005),
    ]
    if plateau_z is not None:
        v, f = build.prism(shapely.box(-3, 20, 3, 26), 0.0, plateau_z)
        objs.append(SceneObject("plateau", "ground", v, f))
    if building:
        v, f = build.prism(shapely.box(20, 10, 35, 22), 0.0, 9.0)
        objs.append(SceneObject("house", "building", v, f))
    if crown_at is not None:
        v, f = build.ellipsoid((crown_at[0], crown_at[1], 7.0), (3.0, 3.0, 2.0), 2)
        objs.append(SceneObject("crown", "tree", v, f))
        v, f = build.cylinder(crown_at, 0.25, 0.0, 5.5)
        objs.append(SceneObject("trunk", "trunk", v, f))
    return Scene("test", objs)


def make_placement(specs) -> Placement:
    """specs: [(id, x, y, heading_rad, length, width, height), ...]"""
    vs = [
        PlacedVehicle(id=i, model="sedan", color="white",
                      cls="large-vehicle" if ln > 6 else "small-vehicle",
                      length_m=ln, width_m=wd, height_m=ht, x_m=x, y_m=y, z_m=0.0,
                      heading_rad=hd % (2 * np.pi))
        for i, x, y, hd, ln, wd, ht in specs
    ]
    return Placement(scene="test", scenario="manual", seed=0, vehicles=vs)


def make_world(specs, **scene_kw):
    from aerial_synth.render.world import add_placement

    rs = RayScene(make_scene(**scene_kw))
    pl = make_placement(specs)
    add_placement(rs, pl, simple_boxes=True)
    return rs, pl


def with_threads(n, fn):
    """fn() with numba's thread count set to n (at most the configured maximum)."""
    import numba

    old = numba.get_num_threads()
    numba.set_num_threads(min(n, numba.config.NUMBA_NUM_THREADS))
    try:
        return fn()
    finally:
        numba.set_num_threads(old)
