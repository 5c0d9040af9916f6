"""Slow end-to-end checks on a synthetic grid city written as PBF (tools/bench_osm.py's
generator): a bbox cut of a larger file, full jam / normal / sparse runs, every vehicle on
a one-way street driving its way."""

from __future__ import annotations

import importlib.util
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("osmium")
pytest.importorskip("pyproj")
shapely = pytest.importorskip("shapely")

pytestmark = pytest.mark.slow


def _bench():
    path = Path(__file__).resolve().parents[2] / "tools" / "bench_osm.py"
    spec = importlib.util.spec_from_file_location("bench_osm", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def city(tmp_path_factory):
    from aerial_synth.scene.osm import build_osm_scene
    from aerial_synth.scene.raycast import RayScene

    b = _bench()
    f = tmp_path_factory.mktemp("grid") / "grid.osm.pbf"
    b.write_grid_city(f, 20, 20, real_like=True, side=4, footways=True)
    s = build_osm_scene(f, bbox=b.bbox_of(300, 300, 1100, 1100))
    return s, RayScene(s)


@pytest.mark.parametrize("scenario", ["jam", "normal", "sparse"])
def test_grid_city_directions(city, scenario):
    from aerial_synth.placement.footprints import validate_placement
    from aerial_synth.placement.traffic import place

    s, rs = city
    b = s.bounds()
    assert np.all(b[1, :2] - b[0, :2] < 840)  # only the 800 m bbox (turned by grid convergence)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        p = place(rs, scenario, seed=7)
    rep = validate_placement(rs, p, s.truth).summary()
    assert rep["overlaps"] == 0 and rep["corners_drivable"] == 1.0
    n_one = 0
    carriageways = shapely.buffer(np.array([r.centerline for r in s.truth.roads], dtype=object),
                                  np.array([r.width_m / 2 for r in s.truth.roads]))
    tree = shapely.STRtree(carriageways)
    for v in p.vehicles:
        pt = shapely.Point(v.x_m, v.y_m)
        # a vehicle whose footprint reaches into a second carriageway stands in a junction
        fp = shapely.Polygon(v.corners_xy())
        touched = tree.query(fp, predicate="intersects")
        inside = [s.truth.roads[k] for k in touched
                  if s.truth.roads[k].centerline.distance(pt) <= s.truth.roads[k].width_m / 2]
        if len(touched) != 1 or len(inside) != 1 or not inside[0].oneway:
            continue
        line = inside[0].centerline
        d = line.project(pt)
        a, c = line.interpolate(max(d - 0.5, 0)), line.interpolate(min(d + 0.5, line.length))
        t = math.atan2(c.y - a.y, c.x - a.x)
        assert abs(math.degrees(math.remainder(v.heading_rad - t, 2 * math.pi))) <= 10
        n_one += 1
    assert n_one > 20
