"""Hand-built road layouts for placement tests: road polygons from centre lines, grass
around them, and the truth (validation only; placement never reads it)."""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import LineString, Point, box

from aerial_synth.scene.build import ellipsoid, polygon_object
from aerial_synth.scene.model import RoadTruth, Scene, SceneObject, SceneTruth

ROAD_Z = 0.05


def make_scene(name, roads, margin=30.0, extra=(), cap_style="flat"):
    """roads: list of (LineString, width_m). Returns a Scene with road + ground + extras."""
    polys = [line.buffer(w / 2, cap_style=cap_style, join_style="round", quad_segs=32) for line, w in roads]
    area = shapely.union_all(polys)
    minx, miny, maxx, maxy = area.bounds
    ground = box(minx - margin, miny - margin, maxx + margin, maxy + margin).difference(area)
    objs = [polygon_object("road", "road", area, ROAD_Z), polygon_object("grass", "ground", ground, 0.0)]
    objs += list(extra)
    truth = SceneTruth(road_area=area, roads=tuple(RoadTruth(line, w) for line, w in roads))
    return Scene(name, objs, truth=truth)


def straight(length=300.0, width=8.0):
    return make_scene("straight", [(LineString([(-length / 2, 0), (length / 2, 0)]), width)])


def bend90(width=8.0, radius=25.0, arm=120.0):
    """An L: east along y=0, a quarter circle of ``radius``, then north."""
    a = np.linspace(-np.pi / 2, 0, 40)
    arc = np.column_stack([radius * np.cos(a), radius + radius * np.sin(a)])
    pts = np.vstack([[-arm, 0.0], arc, [radius, radius + arm]])
    return make_scene("bend90", [(LineString(pts), width)])


def ring(radius=45.0, width=8.0):
    a = np.linspace(0, 2 * np.pi, 361)
    return make_scene("ring", [(LineString(np.column_stack([radius * np.cos(a), radius * np.sin(a)])), width)])


def t_junction(width=8.0):
    main = LineString([(-120, 0), (120, 0)])
    stem = LineString([(0, 0), (0, -120)])
    return make_scene("t_junction", [(main, width), (stem, width)])


def dead_end(width=7.0, length=150.0):
    return make_scene("dead_end", [(LineString([(0, 0), (length, 0)]), width)])


def crown_over_road(width=8.0):
    """A straight road with big crowns whose centres are over the road's edge."""
    crowns = []
    for i, x in enumerate(np.arange(-100, 101, 20.0)):
        v, f = ellipsoid((x, width / 2 + 0.5, 7.0), (4.5, 4.5, 2.5), subdivisions=2)
        crowns.append(SceneObject(f"tree_crown_{i}", "tree", v, f))
    return make_scene("crowns", [(LineString([(-150, 0), (150, 0)]), width)], extra=crowns)


def narrow(width=2.8, length=200.0):
    return make_scene("narrow", [(LineString([(-length / 2, 0), (length / 2, 0)]), width)])


def hidden_road():
    """A road triangle of 1 mm^2: random traces never find it."""
    g = polygon_object("grass", "ground", box(-50, -50, 50, 50), 0.0)
    r = polygon_object("road", "road", Point(0, 0).buffer(0.0006, quad_segs=2), 0.05)
    return Scene("hidden", [g, r])
