"""Placement geometry on hand-built layouts (see layouts.py)."""

import json
import warnings

import numpy as np
import pytest
import shapely

from aerial_synth.errors import AerialSynthError, PlacementError
from aerial_synth.placement import place, validate_placement
from aerial_synth.placement.traffic import PlacementWarning
from aerial_synth.scene.raycast import RayScene
from aerial_synth.vehicles import load_catalog

from . import layouts


@pytest.fixture(scope="module")
def catalog():
    return load_catalog()


def _run(scene, catalog, scenario="jam", seed=0, **kw):
    rs = RayScene(scene)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PlacementWarning)
        p = place(rs, scenario, seed=seed, catalog=catalog, **kw)
    return rs, p, validate_placement(rs, p, scene.truth)


def _footprints(p, shrink=0.0):
    return shapely.polygons(np.array([v.corners_xy(-shrink) for v in p.vehicles]))


def _right_edge_offset(p, truth):
    """Distance from each vehicle centre to the road edge on its right (straight road y=±4)."""
    return shapely.distance(shapely.points([[v.x_m, v.y_m] for v in p.vehicles]), truth.road_area.boundary)


def test_straight_road_offset_and_heading(catalog):
    scene = layouts.straight()
    rs, p, rep = _run(scene, catalog, n_lines=6)
    assert len(p.vehicles) >= 40
    off = _right_edge_offset(p, scene.truth)
    assert np.max(np.abs(off - 1.75)) < 0.05
    assert np.nanmax(rep.heading_error_deg) < 2.0
    # right-hand traffic: eastbound (heading ~0) in the south lane y<0, westbound north
    for v in p.vehicles:
        east = np.cos(v.heading_rad) > 0
        assert (v.y_m < 0) == east
    assert rep.overlaps == 0


def test_left_hand_traffic_mirrors_the_lanes(catalog):
    scene = layouts.straight()
    _, p, rep = _run(scene, catalog, n_lines=4, overrides={"traffic": "left"})
    assert len(p.vehicles) >= 20
    for v in p.vehicles:
        assert (v.y_m > 0) == (np.cos(v.heading_rad) > 0)


def test_lane_offset_is_configurable(catalog):
    scene = layouts.straight(width=10.0)
    _, p, _ = _run(scene, catalog, n_lines=4, overrides={"lane_offset_m": 2.5})
    off = _right_edge_offset(p, scene.truth)
    assert np.max(np.abs(off - 2.5)) < 0.05


@pytest.mark.parametrize("layout", [layouts.bend90, layouts.ring])
def test_curves_follow_the_tangent(catalog, layout):
    scene = layout()
    rs, p, rep = _run(scene, catalog, n_lines=8, overrides={"double_lane_probability": 1.0})
    assert len(p.vehicles) >= 30
    assert np.nanmax(rep.heading_error_deg) < 5.0
    assert rep.overlaps == 0


def test_t_junction_lines_never_leave_the_road(catalog):
    scene = layouts.t_junction()
    rs, p, rep = _run(scene, catalog, n_lines=12, overrides={"double_lane_probability": 1.0})
    assert len(p.vehicles) >= 15
    road = scene.truth.road_area.buffer(1e-6)
    assert all(shapely.within(_footprints(p), road))
    assert rep.corners_drivable == 1.0 and rep.footprint_drivable == 1.0


def test_lines_stop_at_road_ends():
    """On a dead-end road (x from 0 to 300, flat caps) every line that stops for a geometric
    reason stops at a road end: no vehicle past the end, its last vehicle within one maximum
    spacing + half a length of the end it drives towards, and the reason recorded as road_end."""
    length = 300.0
    scene = layouts.dead_end(length=length)
    rs = RayScene(scene)
    catalog = load_catalog()
    d_max = 23.5  # jam's d_max
    ended_at_end = 0
    for seed in range(4):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", PlacementWarning)
            p = place(rs, "jam", seed=seed, catalog=catalog, n_lines=2,
                      overrides={"vehicles_per_line": {"mean": 500, "sd": 0}, "double_lane_probability": 1.0})
        xs = np.array([v.corners_xy()[:, 0] for v in p.vehicles])
        assert xs.max() <= length + 1e-6 and xs.min() >= -1e-6  # nobody past either end
        by_line = {}
        for v in p.vehicles:
            by_line.setdefault((v.line_id, v.lane), []).append(v)
        for line_id, lane, reason, n in p.stats["line_table"]:
            vs = by_line[(line_id, lane)]
            assert len(vs) == n
            assert reason in ("road_end", "blocked"), reason  # nothing else can stop a line here
            if reason != "road_end":
                continue
            last = vs[-1]
            east = np.cos(last.heading_rad) > 0
            to_end = (length - last.x_m) if east else last.x_m
            assert 0 < to_end <= d_max + last.length_m / 2, (to_end, reason)
            ended_at_end += 1
    assert ended_at_end >= 4  # the test saw real road ends, not just blocked lines


def test_dead_end_stops_before_the_end(catalog):
    scene = layouts.dead_end(length=150.0)
    _, p, _ = _run(scene, catalog, n_lines=10)
    xs = np.array([c[:, 0] for c in (v.corners_xy() for v in p.vehicles)])
    assert xs.max() <= 150.0 + 1e-6 and xs.min() >= 0.0 - 1e-6


def test_road_found_through_an_overhanging_crown(catalog):
    scene = layouts.crown_over_road()
    rs = RayScene(scene)
    under = [o for o in scene.objects if o.label == "tree"]
    # the crown really hides the road from a plain trace
    assert rs.trace_down(np.array([[0.0, 2.25]]), ignore=()).labels == ["tree"]
    assert rs.trace_down(np.array([[0.0, 2.25]])).labels == ["road"]
    _, p, rep = _run(scene, catalog, n_lines=6)
    crowns = shapely.union_all([shapely.MultiPoint(o.vertices[:, :2]).convex_hull for o in under])
    covered = shapely.intersects(_footprints(p), crowns)
    assert covered.sum() >= 5  # vehicles stand on road under crowns
    assert np.nanmax(rep.heading_error_deg) < 2.0


def test_no_truck_on_a_road_too_narrow_for_it(catalog):
    scene = layouts.narrow(width=2.8)
    _, p, rep = _run(scene, catalog, scenario="jam", n_lines=30,
                     overrides={"double_lane_probability": 0.0})
    assert len(p.vehicles) >= 3  # cars fit
    assert all(v.cls == "small-vehicle" for v in p.vehicles)
    assert all(v.width_m <= 2.0 for v in p.vehicles)
    assert all(shapely.within(_footprints(p), scene.truth.road_area.buffer(1e-6)))
    # trucks were tried and refused (the catalog samples them ~10 % of the time)
    _, p2, _ = _run(layouts.straight(), catalog, n_lines=30)
    assert any(v.cls == "large-vehicle" for v in p2.vehicles)


def test_same_seed_same_placement_json(catalog):
    scene = layouts.t_junction()
    a = _run(scene, catalog, seed=3, n_lines=5)[1].to_json()
    b = _run(scene, catalog, seed=3, n_lines=5)[1].to_json()
    c = _run(scene, catalog, seed=4, n_lines=5)[1].to_json()
    assert a == b
    assert a != c
    d = json.loads(a)
    assert d["seed"] == 3 and d["scenario"] == "jam"
    v = d["vehicles"][0]
    for key in ("id", "model", "color", "cls", "length_m", "width_m", "height_m", "x_m", "y_m",
                "z_m", "heading_rad", "line_id", "lane", "direction", "spacing_m"):
        assert key in v
    assert [v["id"] for v in d["vehicles"]] == list(range(1, len(d["vehicles"]) + 1))


def test_random_scenario_random_headings(catalog):
    scene = layouts.ring(radius=60, width=12)
    _, p, rep = _run(scene, catalog, scenario="random", n_vehicles=60)
    assert len(p.vehicles) == 60
    assert rep.overlaps == 0 and rep.corners_drivable == 1.0
    assert np.nanmedian(rep.heading_error_deg) > 20  # not aligned with the road
    assert all(v.line_id == -1 and v.direction == "random" for v in p.vehicles)


def test_more_vehicles_than_the_road_holds(catalog):
    scene = layouts.dead_end(length=80.0)
    rs = RayScene(scene)
    with pytest.warns(PlacementWarning, match="held"):
        p = place(rs, "jam", seed=0, n_vehicles=5000, catalog=catalog)
    assert 5 <= len(p.vehicles) < 40
    assert p.stats["shortfall"] == 5000 - len(p.vehicles)


def test_no_road_found_is_an_error(catalog):
    rs = RayScene(layouts.hidden_road())
    with pytest.raises(PlacementError, match="found no road"):
        place(rs, "jam", seed=0, catalog=catalog, n_lines=1)


def test_min_center_distance_rule(catalog):
    scene = layouts.straight()
    _, p, _ = _run(scene, catalog, n_lines=6, overrides={"min_center_distance_m": 12.0,
                                                            "spacing": {"mean_m": 14.0}})
    xy = np.array([[v.x_m, v.y_m] for v in p.vehicles])
    d = np.linalg.norm(xy[:, None] - xy[None], axis=-1) + np.eye(len(xy)) * 1e9
    assert d.min() >= 12.0


def test_gap_is_kept(catalog):
    scene = layouts.straight()
    _, p, rep = _run(scene, catalog, n_lines=6, overrides={"gap_m": 1.0})
    polys = _footprints(p)
    tree = shapely.STRtree(polys)
    a, b = tree.query(polys, predicate="dwithin", distance=0.999)
    assert not np.any(a != b)
    assert rep.gap_violations == 0
    # grown by gap/2 per side (corners_xy(gap_m)), no two footprints overlap
    grown = shapely.polygons(np.array([v.corners_xy(1.0) for v in p.vehicles]))
    a, b = shapely.STRtree(grown).query(grown, predicate="intersects")
    pairs = a < b
    assert np.all(shapely.area(shapely.intersection(grown[a[pairs]], grown[b[pairs]])) < 1e-9)


@pytest.mark.parametrize(
    "kw, message",
    [
        ({"n_vehicles": float("nan")}, "--vehicles: expected a positive integer, got nan"),
        ({"n_vehicles": 0}, "--vehicles: expected a positive integer, got 0"),
        ({"n_vehicles": "abc"}, "--vehicles: expected a positive integer, got 'abc'"),
        ({"n_lines": -2}, "--lines: expected a positive integer, got -2"),
        ({"seed": -1}, "--seed: expected a non-negative integer, got -1"),
        ({"seed": 1.5}, "--seed: expected a non-negative integer, got 1.5"),
        ({"overrides": {"gap_m": float("nan")}}, "--set gap_m: expected a finite number >= 0 and <= 10, got nan"),
    ],
)
def test_place_api_refuses_bad_counts_and_seeds(catalog, kw, message):
    rs = RayScene(layouts.straight(length=60.0))
    with pytest.raises(AerialSynthError) as exc:
        place(rs, "jam", catalog=catalog, **kw)
    assert str(exc.value) == message
