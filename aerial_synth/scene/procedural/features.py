"""Features shared by the generators: roads from spec entries, lakes, random buildings."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from ...errors import SceneError
from .builder import Builder
from .roads import Road, chaikin, road_polygon, wiggle


def spec_roads(b: Builder, items, default_width):
    """Roads from explicit spec entries (points in metres; wiggle; T-junction snapping)."""
    import shapely
    from shapely.geometry import LineString

    by_name: dict[str, Any] = {}
    for k, it in enumerate(items):
        name = str(it.get("name", f"r{k}"))
        pts = np.asarray(it["points"], float)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
            raise SceneError(f"road {name!r}: points must be a list of >= 2 [x, y] pairs")
        pts = wiggle(pts, float(it.get("wiggle_m", 0.0)), b.rng)
        for end, key in ((0, "start_on"), (-1, "end_on")):
            other = it.get(key)
            if other is not None:
                if other not in by_name:
                    raise SceneError(f"road {name!r}: {key} names unknown earlier road {other!r}")
                ol = by_name[other]
                p = ol.interpolate(ol.project(shapely.Point(pts[end])))
                pts[end] = (p.x, p.y)
        pts = chaikin(pts, int(it.get("smooth", 3)))
        line = LineString(pts)
        by_name[name] = line
        b.roads.append(
            Road(
                name=name,
                line=line,
                width_m=float(it.get("width_m", default_width)),
                oneway=bool(it.get("oneway", False)),
                lanes=int(it.get("lanes", 1)),
                sidewalk_m=float(it.get("sidewalk_m", 0.0)),
                dead_end=bool(it.get("dead_end", False)),
                centre=str(it.get("centre", "dashed")),
            )
        )
        if road_polygon(b.roads[-1]).intersection(b.box).area < 1.0:
            x1, y1 = b.box.bounds[2:]
            raise SceneError(
                f"roads[{k}] ({name!r}): expected a road that crosses the scene (x in "
                f"[{-x1:g}, {x1:g}] m, y in [{-y1:g}, {y1:g}] m by its size_m), got one with no "
                f"surface inside it"
            )


def lake(b: Builder, spec: Mapping):
    import shapely

    c = np.asarray(spec["center"], float)
    rx, ry = (float(v) for v in spec["radii_m"])
    n = 48
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    k = b.rng.uniform(0.85, 1.15, n)
    k = np.convolve(np.r_[k[-2:], k, k[:2]], np.ones(5) / 5, mode="valid")
    poly = shapely.Polygon(np.column_stack([c[0] + rx * k * np.cos(a), c[1] + ry * k * np.sin(a)]))
    poly = poly.buffer(0).difference(b.road_area().buffer(float(spec.get("road_clear_m", 8.0))))
    if not poly.is_empty:
        b.water.append(poly)


def random_buildings(b: Builder, spec: Mapping, region=None):
    import shapely
    from shapely import affinity

    n = int(spec.get("count", 0))
    if n <= 0:
        return
    region = region if region is not None else b.box
    minx, miny, maxx, maxy = region.bounds
    wr, dr, hr = spec.get("width_m", [10, 25]), spec.get("depth_m", [8, 18]), spec.get(
        "height_m", [4, 15]
    )
    clearance = float(spec.get("clearance_m", 4.0))
    placed, tries = 0, 0
    while placed < n and tries < 60 * n:
        tries += 1
        x, y = b.rng.uniform(minx, maxx), b.rng.uniform(miny, maxy)
        w, d, h = b.rng.uniform(*wr), b.rng.uniform(*dr), b.rng.uniform(*hr)
        ang = b.rng.uniform(0, 180)
        poly = affinity.rotate(shapely.box(x - w / 2, y - d / 2, x + w / 2, y + d / 2), ang)
        if not region.contains(poly):
            continue
        if b.try_building(poly, h, clearance):
            placed += 1


