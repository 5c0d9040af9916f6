"""Footprints: one meaning of gap_m, and the whole footprint on drivable surface."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import shapely
from shapely.geometry import LineString, Polygon

from aerial_synth.placement import (
    PlacedVehicle,
    Placement,
    place,
    traffic_engine,
    validate_placement,
)
from aerial_synth.placement import traffic as traffic_mod
from aerial_synth.placement.footprints import FootprintIndex, footprint_points, footprint_samples
from aerial_synth.placement.traffic import PlacementWarning
from aerial_synth.scene.build import polygon_object, prism
from aerial_synth.scene.model import LABEL_IDS, Scene, SceneObject
from aerial_synth.scene.raycast import RayScene
from aerial_synth.vehicles import load_catalog

from . import layouts

L, W = 4.5, 1.8


# ----------------------------------------------------------------------------- gap_m


@pytest.mark.parametrize("gap", [0.0, 0.5, 1.0, 2.25])
@pytest.mark.parametrize("heading", [0.0, np.pi / 2, np.radians(37.0)])
def test_footprints_exactly_gap_apart_are_accepted_closer_refused(gap, heading):
    """gap_m is the clearance between two footprints: behind each other (along the heading)
    and side by side, exactly gap_m apart is fine, 1 cm less is refused."""
    fwd = np.array([np.cos(heading), np.sin(heading)])
    left = np.array([-np.sin(heading), np.cos(heading)])
    for direction, size in ((fwd, L), (left, W)):
        for dist, ok in ((gap, True), (gap + 0.01, True), (gap - 0.01, False)):
            if dist < 0:
                continue
            idx = FootprintIndex(gap)
            idx.add(idx.polygon(0.0, 0.0, heading, L, W), (0.0, 0.0))
            c = direction * (size + dist)
            poly = idx.polygon(c[0], c[1], heading, L, W)
            assert abs(shapely.distance(poly, idx._polys[0]) - dist) < 1e-9
            assert idx.collides(poly, c) == (not ok), (gap, dist, heading)


def test_gap_rule_is_the_same_in_the_tree_and_in_the_recent_list():
    gap = 0.5
    idx = FootprintIndex(gap, rebuild_every=4)
    for i in range(8):  # 8 vehicles in a row, exactly gap apart: the tree holds them all
        x = i * (L + gap)
        p = idx.polygon(x, 0.0, 0.0, L, W)
        assert not idx.collides(p, (x, 0.0))
        idx.add(p, (x, 0.0))
    assert idx._tree is not None and idx._tree_n == 8
    x = 3 * (L + gap) + 0.2  # overlaps vehicles 3 and 4's clearances
    assert idx.collides(idx.polygon(x, 0.0, 0.0, L, W), (x, 0.0))
    assert idx.collides(idx.polygon(0.0, W + gap - 0.01, 0.0, L, W))
    assert not idx.collides(idx.polygon(0.0, W + gap, 0.0, L, W))


def test_corners_xy_grows_by_half_the_gap_per_side():
    v = PlacedVehicle(id=1, model="m", color="c", cls="small-vehicle", length_m=L, width_m=W,
                      height_m=1.5, x_m=0.0, y_m=0.0, z_m=0.0, heading_rad=0.0)
    c = v.corners_xy(1.0)
    assert np.allclose(c.max(axis=0), [L / 2 + 0.5, W / 2 + 0.5])
    # two vehicles exactly gap apart: their grown rectangles touch and do not overlap
    u = PlacedVehicle(**{**v.__dict__, "id": 2, "x_m": L + 1.0})
    a, b = shapely.Polygon(v.corners_xy(1.0)), shapely.Polygon(u.corners_xy(1.0))
    assert shapely.intersects(a, b) and shapely.area(shapely.intersection(a, b)) < 1e-12


# ----------------------------------------------------- the whole footprint on drivable


def _poke_scene(apexes, road_len=120.0, width=8.0):
    """A straight road along x (y in [-4, 4]); square buildings turned 45 degrees stand south
    of it, each with its top corner poking 1.4 m into the road at an apex (x, -2.6)."""
    buildings, objs = [], []
    for i, ax in enumerate(apexes):
        apex_y = -width / 2 + 1.4
        half = 6.0  # half-diagonal of the square
        sq = Polygon([(ax, apex_y), (ax + half, apex_y - half), (ax, apex_y - 2 * half),
                      (ax - half, apex_y - half)])
        buildings.append(sq)
        v, f = prism(sq, 0.0, 9.0)
        objs.append(SceneObject(f"building_{i}", "building", v, f))
    scene = layouts.make_scene("pokes", [(LineString([(-road_len / 2, 0), (road_len / 2, 0)]), width)],
                               extra=objs)
    # the truth's road area excludes the buildings (a map would not call them road)
    blocked = shapely.union_all(buildings)
    scene.truth = type(scene.truth)(road_area=scene.truth.road_area.difference(blocked),
                                    roads=scene.truth.roads)
    return scene, blocked


def _vehicle(x, y, heading=0.0, vid=1):
    return PlacedVehicle(id=vid, model="m", color="c", cls="small-vehicle", length_m=L, width_m=W,
                         height_m=1.5, x_m=x, y_m=y, z_m=0.05, heading_rad=heading)


def test_validator_refuses_a_body_crossed_by_a_building_corner_between_the_corners():
    # apex at x = 1: the vehicle (x in [-2.25, 2.25], y in [-3.15, -1.35]) has its corners,
    # centre and edge midpoints on road, but the building's corner is inside its body
    scene, blocked = _poke_scene([1.0])
    rs = RayScene(scene)
    v = _vehicle(0.0, -4.0 + 1.75)
    body = shapely.Polygon(v.corners_xy())
    assert shapely.area(shapely.intersection(body, blocked)) > 0.2  # really crossed
    # what the old check traced (4 corners + centre) and the edge midpoints: all road
    first9 = footprint_samples(v.x_m, v.y_m, v.heading_rad, L, W)[0, :9]
    assert set(rs.trace_down(first9).labels) <= {"road"}
    clean = _vehicle(-20.0, -4.0 + 1.75, vid=2)
    p = Placement("pokes", "jam", 0, vehicles=[v, clean])
    for truth in (None, scene.truth):  # traced samples alone, and with the truth polygon
        rep = validate_placement(rs, p, truth)
        assert rep.corners_drivable == 1.0  # the old figure said all is well
        assert rep.footprint_ok.tolist() == [False, True]
        assert rep.footprint_drivable == 0.5
        assert rep.summary()["footprint_drivable"] == 0.5
        assert rep.summary()["footprint_off_drivable"] == 1
    rep = validate_placement(rs, p, scene.truth)
    assert rep.area_drivable[0] < 0.99 and rep.area_drivable[1] == pytest.approx(1.0)


def test_placement_refuses_a_footprint_a_building_corner_pokes_into(monkeypatch):
    """Jam traffic along a road with building corners poking into the lane every 9 m: no
    placed body may touch a building. With only corners + centre traced (the old check) the
    same run does place vehicles across building corners, so this test can fail."""
    apexes = np.arange(-50.0, 51.0, 9.0) + 0.3
    scene, blocked = _poke_scene(apexes)
    rs = RayScene(scene)
    cat = load_catalog()

    def run():
        hits, n = 0, 0
        for seed in range(3):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", PlacementWarning)
                p = place(rs, "jam", seed=seed, catalog=cat, n_lines=8,
                          overrides={"double_lane_probability": 0.0})
            bodies = shapely.polygons(np.array([v.corners_xy() for v in p.vehicles]))
            inter = shapely.area(shapely.intersection(bodies, blocked))
            hits += int((inter > 1e-6).sum())
            n += len(p.vehicles)
            if seed == 0:
                rep = validate_placement(rs, p, scene.truth)
        return hits, n, rep

    hits, n, rep = run()
    assert n >= 20  # the south lane is mostly unusable, the north lane is free
    assert hits == 0
    assert rep.footprint_drivable == 1.0

    def corners_only(x, y, h, length, width, **kw):
        pts, owner, start, count = footprint_points(x, y, h, length, width, **kw)
        keep = (start[:, None] + np.arange(5)).ravel()
        return pts[keep], owner[keep], np.arange(len(start)) * 5, np.full(len(start), 5)

    monkeypatch.setattr(traffic_engine, "footprint_points", corners_only)
    hits_old, _, rep_old = run()
    assert hits_old > 0  # the old check accepted bodies crossed by a building corner
    assert rep_old.footprint_drivable < 1.0


def test_footprint_samples_cover_edges_densely():
    pts = footprint_samples([0.0], [0.0], [0.3], [12.0], [2.5])[0]
    c, s = np.cos(-0.3), np.sin(-0.3)
    local = pts @ np.array([[c, s], [-s, c]])  # rotate back into the vehicle frame
    assert np.allclose(local[:4], [[6, 1.25], [6, -1.25], [-6, -1.25], [-6, 1.25]])
    assert np.allclose(local[4], [0, 0])
    on_edge = np.isclose(np.abs(local[:, 1]), 1.25)
    xs = np.sort(local[on_edge & (local[:, 1] > 0), 0])
    assert xs[0] == pytest.approx(-6) and xs[-1] == pytest.approx(6)
    assert np.diff(xs).max() <= 0.1 + 1e-9
    assert (np.abs(local) <= [6 + 1e-9, 1.25 + 1e-9]).all()


def test_footprint_points_follow_each_vehicle_size():
    x, y, h = np.array([0.0, 50.0, 100.0]), np.zeros(3), np.array([0.0, 1.0, 2.0])
    ln, wd = np.array([4.5, 12.0, 4.5]), np.array([1.8, 2.5, 1.8])
    pts, owner, start, count = footprint_points(x, y, h, ln, wd)
    assert count[0] == count[2] < count[1]  # a truck needs more samples than a car
    assert owner.tolist() == [0] * count[0] + [1] * count[1] + [2] * count[2]
    assert start.tolist() == [0, count[0], count[0] + count[1]]
    for i in range(3):
        block = pts[start[i]:start[i] + count[i]]
        assert np.allclose(block[4], [x[i], y[i]])  # sample 4 is the centre
        same = footprint_samples(x[i], y[i], h[i], ln[i], wd[i])[0]
        assert np.array_equal(block, same)
        poly = shapely.Polygon(PlacedVehicle(1, "m", "c", "x", ln[i], wd[i], 1.0, x[i], y[i], 0.0,
                                             h[i]).corners_xy())
        assert shapely.covers(poly.buffer(1e-9), shapely.points(block)).all()


def test_drivable_ids_include_parking():
    rs = RayScene(layouts.straight())
    assert LABEL_IDS["parking"] in traffic_engine.Prober(rs, traffic_mod.load_scenario("jam").probe).drivable_ids


# ------------------------------------------------------------- cracks between road polygons


def _crack_scene(road_len=160.0, width=8.0):
    """A straight road along x made of pieces that leave 0.3 m gaps (cracks) with grass
    below: cracks right across the road every 20 m, and 2 m slits along both lane centres
    (y = +-2) between them, as where two mapped road polygons meet. A car centred on a
    slit has all of its outline on road; only its interior meets the gap."""
    cracks = [shapely.box(x - 0.15, -width / 2, x + 0.15, width / 2)
              for x in np.arange(-road_len / 2 + 10, road_len / 2 - 5, 20.0)]
    cracks += [shapely.box(x, y - 0.15, x + 2.0, y + 0.15)
               for x in np.arange(-road_len / 2 + 14, road_len / 2 - 10, 5.0) for y in (-2.0, 2.0)]
    gap = shapely.union_all(cracks)
    base = layouts.make_scene("cracks", [(LineString([(-road_len / 2, 0), (road_len / 2, 0)]), width)])
    road_area = base.truth.road_area.difference(gap)
    ground = shapely.box(*base.bounds()[:, :2].T.ravel()[[0, 2, 1, 3]]).difference(road_area)
    objs = [polygon_object("road", "road", road_area, layouts.ROAD_Z),
            polygon_object("grass", "ground", ground, 0.0)]
    truth = type(base.truth)(road_area=road_area, roads=base.truth.roads)
    return Scene("cracks", objs, truth=truth), gap


def test_no_footprint_straddles_a_crack(monkeypatch):
    """Jam and normal traffic on a road with 0.3 m cracks: no placed body covers any part of
    a crack, and the validator agrees. With the interior traced every 1 m (before issue 36)
    the same runs do put bodies over the slits, and the validator misses them: this test
    can fail."""
    scene, gap = _crack_scene()
    rs = RayScene(scene)
    cat = load_catalog()

    def run():
        hits, n, missed = 0, 0, 0
        for scenario, seed in (("jam", 0), ("jam", 1), ("normal", 2)):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", PlacementWarning)
                p = place(rs, scenario, seed=seed, catalog=cat, n_lines=8,
                          overrides={"double_lane_probability": 0.0})
            bodies = shapely.polygons(np.array([v.corners_xy() for v in p.vehicles]))
            on_gap = shapely.area(shapely.intersection(bodies, gap)) > 1e-6
            hits += int(on_gap.sum())
            n += len(p.vehicles)
            rep = validate_placement(rs, p)  # traced samples only, no truth
            missed += int((on_gap & rep.footprint_ok).sum())
        return hits, n, missed

    hits, n, missed = run()
    assert n >= 20
    assert hits == 0 and missed == 0

    coarse = footprint_points.__defaults__[:-1] + (1.0,)  # the interior every 1 m
    monkeypatch.setattr(footprint_points, "__defaults__", coarse)
    hits_old, _, missed_old = run()
    assert hits_old > 0 and missed_old == hits_old


def test_validator_traces_the_interior_every_tenth_of_a_metre():
    """A car whose outline is all road but whose interior covers a 0.3 m x 2 m slit."""
    scene, gap = _crack_scene()
    rs = RayScene(scene)
    slit = next(g for g in shapely.get_parts(gap) if shapely.bounds(g)[3] - shapely.bounds(g)[1] < 1)
    (x0, y0, x1, y1) = shapely.bounds(slit)
    v = _vehicle(x0 - 0.1, (y0 + y1) / 2)  # the slit under its front half, off the centre
    assert shapely.contains(shapely.Polygon(v.corners_xy()), slit)
    outline = footprint_points(v.x_m, v.y_m, v.heading_rad, L, W, inner_step_m=1e9)[0]
    assert set(rs.trace_down(outline).labels) == {"road"}  # the outline alone sees no gap
    rep = validate_placement(rs, Placement("cracks", "jam", 0, vehicles=[v]))
    assert rep.footprint_ok.tolist() == [False]
    pts = footprint_samples(0.0, 0.0, 0.0, L, W)[0]
    inner = pts[np.abs(pts).max(axis=1) < 0.8]
    xs, ys = np.unique(inner[:, 0]), np.unique(inner[:, 1])
    assert np.diff(xs).max() <= 0.1 + 1e-9 and np.diff(ys).max() <= 0.1 + 1e-9
