"""Parked vehicles: lots (suburb, depot, OSM, synthetic), occupancy, kerbs, mixed, bad input."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import shapely

from aerial_synth.errors import AerialSynthError, ConfigError, SceneError
from aerial_synth.placement import Placement, place
from aerial_synth.placement.parking import STICK_OUT_M, find_lots, parking_report
from aerial_synth.placement.parking_config import ParkingConfig
from aerial_synth.scene import RayScene, load_scene
from aerial_synth.scene.build import polygon_object
from aerial_synth.scene.model import LABEL_IDS, Scene
from aerial_synth.scene.parking_layout import LotLayout, layout_bays, lot_frame

LOT_IDS = [LABEL_IDS["parking"], LABEL_IDS["parking_marking"]]


def _footprint_samples(v, n_l=9, n_w=5):
    f = np.linspace(-0.5, 0.5, n_l) * (v.length_m - 0.01)
    g = np.linspace(-0.5, 0.5, n_w) * (v.width_m - 0.01)
    gu, gv = np.meshgrid(f, g)
    c, s = math.cos(v.heading_rad), math.sin(v.heading_rad)
    return np.stack([v.x_m + c * gu.ravel() - s * gv.ravel(), v.y_m + s * gu.ravel() + c * gv.ravel()], 1)


def _assert_lot_invariants(rs, placement, lots):
    parked = [v for v in placement.vehicles if v.state == "parked"]
    assert parked
    # every footprint wholly on the lot (parking or its painted lines): 45 traces each
    lab = rs.trace_labels(np.concatenate([_footprint_samples(v) for v in parked])).reshape(len(parked), -1)
    assert np.isin(lab, LOT_IDS).all()
    # no overlaps
    polys = shapely.polygons(np.array([v.corners_xy() for v in parked]))
    a, b = shapely.STRtree(polys).query(polys, predicate="intersects")
    k = a < b
    assert (shapely.area(shapely.intersection(polys[a[k]], polys[b[k]])) < 1e-9).all()
    by_id = {lt.id: lt for lt in lots}
    for v in parked:
        bays = by_id[v.lot].bays
        # heading within 3 degrees of the bay axis (perpendicular: across the row; angled: the
        # bay angle), either way round (nose-in / back-in)
        d = math.degrees(abs(math.remainder(v.heading_rad - bays.axis_rad[v.bay], math.pi)))
        assert d < 3.0
        # never more than 0.2 m out of the bay, so never in the aisle
        bay = shapely.Polygon(bays.corners()[v.bay]).buffer(STICK_OUT_M + 1e-6, join_style="mitre")
        assert bay.contains(shapely.Polygon(v.corners_xy()))
    rep = parking_report(placement, lots)
    assert rep["overlaps"] == 0 and rep["in_bay_fraction"] == 1.0 and rep["alignment_deg"]["max"] < 3.0


@pytest.fixture(scope="module")
def suburb_rs():
    return RayScene(load_scene("suburb"))


def test_suburb_lots_found_by_traces(suburb_rs):
    lots = find_lots(suburb_rs)
    assert len(lots) == 2  # driveways and entrances are no lots
    hints = suburb_rs.scene.hints.lots
    for lt, h in zip(sorted(lots, key=lambda x: -x.frame.cy), hints):
        assert lt.layout_source == "scene"
        assert len(lt.bays) == h.bays and lt.dropped_bays == 0
    # the traced rectangle (before the hint) is within 5 cm of the true one
    lots_default = find_lots(RayScene(Scene(suburb_rs.scene.name, suburb_rs.scene.objects)))
    truth = sorted((lt.frame for lt in lots_default), key=lambda f: -f.cy)
    for f, (cx, cy, L, S) in zip(truth, [(120, 120, 55, 50), (-120, -200, 50, 45)]):
        assert abs(f.cx - cx) < 0.05 and abs(f.cy - cy) < 0.05
        assert abs(f.long_m - L) < 0.1 and abs(f.short_m - S) < 0.1
        assert abs(math.remainder(f.u_rad, math.pi)) < math.radians(0.5)


def test_suburb_parking(suburb_rs):
    p = place(suburb_rs, "parking", seed=4)
    lots = find_lots(suburb_rs, ParkingConfig())
    _assert_lot_invariants(suburb_rs, p, lots)
    assert {v.state for v in p.vehicles} == {"parked"}
    dirs = {v.direction for v in p.vehicles}
    assert dirs == {"nose-in", "back-in"}
    assert all(v.cls == "small-vehicle" for v in p.vehicles)
    # jitter is there (not every car on the bay centre line), and small
    rep = parking_report(p, lots)
    assert 0.3 < rep["alignment_deg"]["mean"] < 2.5
    # JSON round trip is exact, state / lot / bay included
    q = Placement.from_json(p.to_json())
    assert q.to_json() == p.to_json()
    assert [(v.state, v.lot, v.kerb, v.bay) for v in q.vehicles] == [(v.state, v.lot, v.kerb, v.bay)
                                                                      for v in p.vehicles]


def test_parked_vehicles_draw_trim_options(suburb_rs):
    """Parked cars get the catalog's trim options (roof racks, sunroofs, ...) as traffic
    does: base size kept, option models resolvable, deterministic, and at the catalog rates."""
    from aerial_synth.vehicles import load_catalog

    cat = load_catalog()
    a = place(suburb_rs, "parking", seed=11)
    b = place(suburb_rs, "parking", seed=11)
    assert a.to_json() == b.to_json()
    dressed = [v for v in a.vehicles if "+" in v.model]
    assert dressed, "no parked vehicle drew an option"
    for v in dressed:
        m, base = cat.model(v.model), cat.model(v.model.split("+")[0])
        assert (v.length_m, v.width_m) == (base.length_m, base.width_m)
        assert v.height_m == pytest.approx(m.height_m) and m.height_m >= base.height_m
    # the share of dressed cars is the catalog's rate for the models drawn (binomial, 4 sd)
    rates = [sum(cat.options_of(cat.model(v.model.split("+")[0])).values()) for v in a.vehicles]
    mean, sd = sum(rates), math.sqrt(sum(r * (1 - r) for r in rates))
    assert abs(len(dressed) - mean) <= 4 * sd + 1


def test_depot_takes_buses_and_trailers():
    rs = RayScene(load_scene("depot"))
    p = place(rs, "parking", seed=2, overrides={"parking": {"occupancy_mean": 0.9}})
    lots = find_lots(rs)
    _assert_lot_invariants(rs, p, lots)
    models = {v.model for v in p.vehicles}
    assert {"city_bus", "semi_trailer"} <= models
    assert all(v.cls == "large-vehicle" for v in p.vehicles)
    # parked semis stand straight in their bay (no jitter)
    for v in p.vehicles:
        if v.model == "semi_trailer":
            bays = lots[v.lot].bays
            assert abs(math.remainder(v.heading_rad - bays.axis_rad[v.bay], math.pi)) < 1e-9
    # trailers only in the 18 m truck bays, buses fit the 14 m bays
    for v in p.vehicles:
        assert v.length_m <= lots[v.lot].bays.length_m + STICK_OUT_M


def _lots_scene(n=50, size=(27.0, 24.0), rot_deg=0.0, seed=0, pitch=40.0):
    """A synthetic scene: one road and n small rectangular lots (no markings, no hints)."""
    rng = np.random.default_rng(seed)
    objs = []
    polys = []
    cols = 10
    for i in range(n):
        cx, cy = (i % cols) * pitch, (i // cols) * pitch + 30.0
        w, h = size[0] + rng.uniform(0, 6), size[1] + rng.uniform(0, 4)
        box = shapely.affinity.rotate(shapely.box(cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2),
                                      rot_deg + rng.uniform(-20, 20), origin=(cx, cy))
        polys.append(box)
    objs.append(polygon_object("parking", "parking", shapely.union_all(polys), 0.05))
    road = shapely.box(-20, -10, cols * pitch, -2)
    objs.append(polygon_object("road_0", "road", road, 0.05))
    ground = shapely.box(-pitch, -15, (cols + 1) * pitch, (n // cols + 2) * pitch).difference(
        shapely.union_all(polys)).difference(road)
    objs.append(polygon_object("ground", "ground", ground, 0.0))
    return Scene("lots", objs), polys


def test_occupancy_matches_the_target_over_50_lots():
    scene, polys = _lots_scene()
    rs = RayScene(scene)
    target = 0.6
    p = place(rs, "parking", seed=7, overrides={"parking": {"occupancy_mean": target,
                                                            "occupancy_concentration": 10.0}})
    lots = p.stats["lots"]
    assert len(lots) == 50
    occ = np.array([lt["filled"] / lt["bays"] for lt in lots])
    assert abs(occ.mean() - target) < 0.05
    assert occ.std() > 0.05  # drawn per lot, not one figure for all
    # every lot got its default layout; rows parallel to its minimum rotated rectangle
    for lt in lots:
        assert lt["layout_source"] == "default"
        poly = min(polys, key=lambda q: q.centroid.distance(shapely.Point(lt["center_xy"])))
        assert poly.centroid.distance(shapely.Point(lt["center_xy"])) < 0.05
        fr = lot_frame(poly)
        assert abs(math.remainder(math.radians(lt["row_deg"]) - fr.u_rad, math.pi)) < math.radians(0.5)
    _assert_lot_invariants(rs, p, find_lots(rs))


def test_angled_and_parallel_layouts_from_the_scenario():
    scene, _ = _lots_scene(n=6, size=(40.0, 30.0), pitch=70.0)
    rs = RayScene(scene)
    for angle in (60, 45, 0):
        p = place(rs, "parking", seed=1, overrides={"parking": {
            "occupancy_mean": 1.0, "layout": {"angle_deg": angle, "bay_length_m": 5.5 if angle else 6.0}}})
        lots = find_lots(rs, ParkingConfig(layout={"angle_deg": angle, "bay_length_m": 5.5 if angle else 6.0}))
        _assert_lot_invariants(rs, p, lots)
        if angle:
            assert {v.direction for v in p.vehicles} == {"nose-in"}  # no back-in into angled bays


def test_osm_lot():
    """An amenity=parking area of an OSM extract (rotated, no markings) gets the default
    layout: rows along its minimum rotated rectangle, 2.5 x 5.0 m bays, 6 m aisles."""
    from aerial_synth.scene.osm import build_osm_scene
    from tests.scene.osm_town import Town

    t = Town()
    t.way([(-150, 0), (150, 0)], {"highway": "residential", "name": "Main"})
    a = math.radians(30.0)
    c, s = math.cos(a), math.sin(a)
    corners = [(x * c - y * s + 20, x * s + y * c + 60) for x, y in
               ((-35, -20), (35, -20), (35, 20), (-35, 20))]
    t.way(corners, {"amenity": "parking", "parking": "surface"}, close=True)
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as d:
        path = t.write(Path(d) / "lot.osm")
        scene = build_osm_scene(path)
    rs = RayScene(scene)
    lots = find_lots(rs)
    assert len(lots) == 1
    lt = lots[0]
    assert lt.layout_source == "default"
    # against the lot polygon as projected (UTM grid convergence turns it by ~1.3 degrees)
    true = lot_frame(scene.truth.parking_area)
    assert abs(math.degrees(math.remainder(true.u_rad - a, math.pi))) < 2.0
    # (the projected polygon is a slightly sheared rectangle: 0.3 m on its sides)
    assert abs(lt.frame.long_m - true.long_m) < 0.3 and abs(lt.frame.short_m - true.short_m) < 0.3
    assert abs(lt.frame.cx - true.cx) < 0.1 and abs(lt.frame.cy - true.cy) < 0.1
    assert abs(math.degrees(math.remainder(lt.frame.u_rad - true.u_rad, math.pi))) < 0.2
    expected = layout_bays(lt.frame, LotLayout())
    assert len(lt.bays) == len(expected) > 60
    p = place(rs, "parking", seed=3)
    _assert_lot_invariants(rs, p, lots)


def test_kerb_parking_keeps_junctions_and_driveways_free(suburb_rs):
    p = place(suburb_rs, "street-parking", seed=5)
    parked = [v for v in p.vehicles if v.state == "parked"]
    assert len(parked) > 150 and all(v.kerb >= 0 and v.lot == -1 for v in parked)
    truth = suburb_rs.scene.truth
    fps = shapely.polygons(np.array([v.corners_xy() for v in parked]))
    # wholly on the road, never on sidewalk or kerb
    lab = suburb_rs.trace_labels(np.concatenate([_footprint_samples(v) for v in parked]))
    assert np.isin(lab, [LABEL_IDS["road"], LABEL_IDS["lane_marking"]]).all()
    # junction corners: the crossing street is at least 5 m away (0.5 m trace sampling)
    roads = {r.name: r for r in truth.roads}
    for v, fp in zip(parked, fps):
        own = min(roads.values(), key=lambda r: r.centerline.distance(shapely.Point(v.x_m, v.y_m)))
        for r in roads.values():
            if r is own:
                continue
            carriageway = r.centerline.buffer(r.width_m / 2, cap_style="flat").difference(
                own.centerline.buffer(own.width_m / 2 + 0.01, cap_style="flat"))
            assert fp.distance(carriageway) >= 4.5, (v.id, r.name)
    # driveways (parking beside the road) are kept free
    drive = truth.parking_area
    assert shapely.distance(drive, fps).min() > 1.0
    # parallel to the kerb, facing the traffic direction of their side
    rep = p.stats
    assert rep["kerb_bays_kept_free"] > 0 and rep["kerbs"] > 20


def test_mixed_moving_vehicles_pass_the_traffic_checks(suburb_rs):
    from aerial_synth.placement import validate_placement

    p = place(suburb_rs, "mixed", seed=6, n_lines=15)
    moving = [v for v in p.vehicles if v.state == "moving"]
    parked = [v for v in p.vehicles if v.state == "parked"]
    assert moving and parked
    assert {v.lot >= 0 for v in parked} == {True, False}  # lots and kerbs
    assert sorted(v.id for v in p.vehicles) == list(range(1, len(p.vehicles) + 1))
    sub = Placement(p.scene, p.scenario, p.seed, p.parameters, moving)
    rep = validate_placement(suburb_rs, sub, truth=suburb_rs.scene.truth)
    assert rep.overlaps == 0 and rep.corners_drivable == 1.0
    assert rep.footprint_drivable == 1.0
    assert np.nanmax(rep.heading_error_deg) < 15.0
    # nothing overlaps anything, moving or parked
    polys = shapely.polygons(np.array([v.corners_xy() for v in p.vehicles]))
    a, b = shapely.STRtree(polys).query(polys, predicate="intersects")
    assert not (a < b).any()
    json.loads(p.to_json())


@pytest.mark.parametrize("override, words", [
    ({"occupancy_mean": 1.5}, "parking.occupancy_mean: expected a finite number >= 0 and <= 1, got 1.5"),
    ({"occupancy_mean": -0.1}, "parking.occupancy_mean"),
    ({"mix": {"tank": 1.0}}, "parking.mix.tank: unknown class or model"),
    ({"depot_mix": {"bus": 1.0}}, "parking.depot_mix.bus: unknown class or model"),
    ({"layout": {"angle_deg": 30}}, "parking.layout.angle_deg"),
    ({"kerb_sides": "middle"}, "parking.kerb_sides"),
    ({"colour": 1}, "parking.colour: unknown key"),
])
def test_bad_parking_input_is_one_line(suburb_rs, override, words):
    with pytest.raises(AerialSynthError) as e:
        place(suburb_rs, "parking", seed=1, overrides={"parking": override})
    msg = str(e.value)
    assert "\n" not in msg and words in msg
    assert isinstance(e.value, ConfigError)


def test_bay_larger_than_a_scene_lot_is_refused():
    from aerial_synth.scene.procedural import generate

    spec = {"name": "t", "generator": "depot", "seed": 1, "size_m": [240, 200],
            "yards": [{"center": [0, 20], "size_m": [40, 30], "layout": {"bay_length_m": 18.0, "aisle_m": 20.0}}]}
    with pytest.raises(SceneError) as e:
        generate(spec, source="t.yaml")
    assert "\n" not in str(e.value) and "yards[0].layout" in str(e.value)


@pytest.mark.parametrize("name", ["suburb", "depot"])
def test_bays_read_from_the_markings_without_hints(name):
    """A scene without lot hints (as after a glTF round trip): the layout is read from the
    painted lines and the bays coincide with the hinted ones within 1 cm."""
    s = load_scene(name)
    bare = find_lots(RayScene(Scene(s.name, s.objects)))
    hinted = find_lots(RayScene(s))
    assert len(bare) == len(hinted) == len(s.hints.lots)
    for a, b in zip(sorted(bare, key=lambda x: x.frame.cx), sorted(hinted, key=lambda x: x.frame.cx)):
        assert a.layout_source == "markings" and b.layout_source == "scene"
        assert (a.layout.bay_width_m, a.layout.bay_length_m, a.layout.angle_deg) == (
            b.layout.bay_width_m, b.layout.bay_length_m, b.layout.angle_deg)
        assert len(a.bays) == len(b.bays)
        assert np.abs(a.bays.centre_xy - b.bays.centre_xy).max() < 0.01


@pytest.mark.parametrize("angle, tol_m", [(60, 0.25), (45, 0.25), (0, 0.01)])
def test_angled_and_parallel_bays_read_from_the_markings(angle, tol_m):
    from aerial_synth.scene.procedural import generate

    spec = {"name": "t", "generator": "depot", "seed": 1, "size_m": [240, 200], "trees": {"count": 0},
            "yards": [{"center": [-62, -20], "size_m": [80, 60], "rotation_deg": 20,
                       "layout": {"angle_deg": angle, "bay_length_m": 5.0 if angle else 6.0}}]}
    s = generate(spec)
    a, = find_lots(RayScene(Scene(s.name, s.objects)))
    b, = find_lots(RayScene(s))
    assert a.layout_source == "markings" and a.layout.angle_deg == angle
    assert len(a.bays) == len(b.bays)
    assert np.abs(a.bays.centre_xy - b.bays.centre_xy).max() < tol_m
    d = np.abs(np.angle(np.exp(1j * (a.bays.axis_rad - b.bays.axis_rad))))
    assert np.degrees(d).max() < 0.5


def test_osm_parking_spaces_are_the_bays():
    """Where the extract maps amenity=parking_space polygons inside a lot, those are the
    bays (not the generated layout)."""
    import tempfile
    from pathlib import Path

    from aerial_synth.scene.osm import build_osm_scene
    from tests.scene.osm_town import Town

    t = Town()
    t.way([(-150, 0), (150, 0)], {"highway": "residential"})
    t.way([(-20, 20), (30, 20), (30, 50), (-20, 50)], {"amenity": "parking"}, close=True)
    n = 8
    for k in range(n):  # one row of 2.6 x 5.2 m spaces along the lot's north side
        x0 = -10 + 2.6 * k
        t.way([(x0, 44.5), (x0 + 2.6, 44.5), (x0 + 2.6, 49.7), (x0, 49.7)],
              {"amenity": "parking_space"}, close=True)
    with tempfile.TemporaryDirectory() as d:
        scene = build_osm_scene(t.write(Path(d) / "spaces.osm"))
    assert len(scene.hints.spaces) == n
    rs = RayScene(scene)
    lt, = find_lots(rs)
    assert lt.layout_source == "osm-spaces" and len(lt.bays) == n
    assert abs(lt.bays.width_m - 2.6) < 0.05 and abs(lt.bays.length_m - 5.2) < 0.05
    cents = np.array([np.mean(r, axis=0) for r in scene.hints.spaces])
    d = np.linalg.norm(lt.bays.centre_xy[:, None, :] - cents[None, :, :], axis=2).min(axis=1)
    assert d.max() < 0.01
    p = place(rs, "parking", seed=2, overrides={"parking": {"occupancy_mean": 1.0}})
    assert len(p.vehicles) == n  # every space filled, nothing else
    _assert_lot_invariants(rs, p, [lt])


def test_osm_kerb_parking_tags_are_obeyed():
    """parking:left|right|both (and parking:lane:*) of a way decide which kerbs take parked
    cars; untagged ways follow the scenario."""
    import tempfile
    from pathlib import Path

    from aerial_synth.scene.osm import build_osm_scene
    from tests.scene.osm_town import Town

    t = Town()
    t.way([(-150, 0), (150, 0)], {"highway": "residential", "width": "8",
                                  "parking:left": "no", "parking:right": "lane"})
    t.way([(-150, 80), (150, 80)], {"highway": "residential", "width": "8", "parking:lane:both": "no_parking"})
    t.way([(-150, -80), (150, -80)], {"highway": "residential", "width": "8"})
    with tempfile.TemporaryDirectory() as d:
        scene = build_osm_scene(t.write(Path(d) / "kerbs.osm"))
    kp = scene.hints.kerbs
    assert sorted((r.left, r.right) for r in kp) == [(False, False), (False, True)]
    rs = RayScene(scene)
    p = place(rs, "street-parking", seed=4, overrides={"parking": {"occupancy_mean": 1.0}})
    # each parked car: the road it stands on and its side (the truth centre lines run in the
    # ways' node order, west to east; UTM turns them by ~1.3 degrees)
    roads = sorted(scene.truth.roads, key=lambda r: float(np.mean(r.centerline.xy[1])))
    count = {}
    for v in p.vehicles:
        pt = shapely.Point(v.x_m, v.y_m)
        k = int(np.argmin([r.centerline.distance(pt) for r in roads]))
        line = roads[k].centerline
        s0 = line.project(pt)
        a = np.asarray(line.interpolate(max(s0 - 0.5, 0)).coords[0])
        b = np.asarray(line.interpolate(min(s0 + 0.5, line.length)).coords[0])
        c = np.asarray(line.interpolate(s0).coords[0])
        left = (b - a)[0] * (v.y_m - c[1]) - (b - a)[1] * (v.x_m - c[0]) > 0
        key = (("south", "mid", "north")[k], "left" if left else "right")
        count[key] = count.get(key, 0) + 1
    assert not any(k[0] == "north" for k in count)      # parking:lane:both=no_parking
    assert ("mid", "left") not in count                  # parking:left=no
    assert count.get(("mid", "right"), 0) > 10           # parking:right=lane
    assert count.get(("south", "left"), 0) > 10 and count.get(("south", "right"), 0) > 10  # untagged
