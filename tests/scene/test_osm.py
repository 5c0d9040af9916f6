"""Scenes from OpenStreetMap extracts: reading, roads and junctions, direction hints and
placement, buildings/trees/water/parking, georeference, GLB round trip.

Every OSM file is written here from the hand-written town of ``osm_town.py`` (nodes, ways,
relations); nothing is downloaded.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from aerial_synth.errors import SceneError

from .osm_town import bbox_lonlat, make_town, to_lonlat

shapely = pytest.importorskip("shapely")
pyproj = pytest.importorskip("pyproj")
pytest.importorskip("osmium")

CRS = "EPSG:32633"  # the UTM zone of the town (13.4 E, 52.5 N)

#: widths the docs promise for the town's roads (docs/osm.md), metres
EXPECTED_WIDTH = {
    "Main Street": 2 * 3.0,       # residential, lanes=2 x 3.0 m
    "Oneway Lane": 6.0,           # width=6
    "Dual East": 2 * 3.5,         # primary, lanes=2 x 3.5 m
    "Dual West": 2 * 3.5,
    "Ring": 7.0,                  # width=7
    "Spur": 6.5,                  # residential default, two-way
    "Avenue": 3 * 3.5,            # primary, lanes=3 x 3.5 m
    None: 5.0,                    # the parking driveway: service default, two-way
}


@pytest.fixture(scope="module")
def town():
    return make_town()


@pytest.fixture(scope="module")
def files(town, tmp_path_factory):
    d = tmp_path_factory.mktemp("osm")
    return {
        "osm": town.write(d / "town.osm"),
        "bz2": town.write(d / "town.osm.bz2"),
        "pbf": town.write(d / "town.osm.pbf"),
        "dir": d,
    }


@pytest.fixture(scope="module")
def scene(files):
    from aerial_synth.scene.osm import build_osm_scene

    return build_osm_scene(files["osm"])


@pytest.fixture(scope="module")
def rs(scene):
    from aerial_synth.scene.raycast import RayScene

    return RayScene(scene)


def local(scene, pts_m):
    """Hand-written town metres -> the scene's local frame, projected independently."""
    tr = pyproj.Transformer.from_crs("EPSG:4326", scene.crs, always_xy=True)
    ll = np.array([to_lonlat(x, y) for x, y in pts_m])
    x, y = tr.transform(ll[:, 0], ll[:, 1])
    return np.column_stack([np.asarray(x) - scene.origin[0], np.asarray(y) - scene.origin[1]])


def labels_at(rs, xy):
    from aerial_synth.scene.model import LABELS

    tr = rs.trace_down(np.asarray(xy, float).reshape(-1, 2), ignore=())
    return [LABELS[i] for i in tr.label_id]


# ---------------------------------------------------------------------------- reading
def test_reads_xml_bz2_and_pbf_alike(files, scene):
    from aerial_synth.scene.osm import build_osm_scene

    bb = bbox_lonlat()
    a = build_osm_scene(files["osm"], bbox=bb)
    b = build_osm_scene(files["bz2"], bbox=bb)
    c = build_osm_scene(files["pbf"], bbox=bb)
    assert a.vertex_hash() == b.vertex_hash() == c.vertex_hash()
    # the XML file's <bounds> is the default bbox
    assert scene.meta["bbox"] == pytest.approx(list(bb), abs=1e-7)
    assert scene.crs == CRS
    assert scene.name == "town"


def test_small_bbox_keeps_only_what_falls_in_it(files):
    from aerial_synth.scene.osm import build_osm_scene

    lo = to_lonlat(100, 60)
    hi = to_lonlat(200, 160)
    s = build_osm_scene(files["pbf"], bbox=(lo[0], lo[1], hi[0], hi[1]))
    b = s.bounds()
    assert np.all(b[1, :2] - b[0, :2] < 105)  # 100 m box (+ grid convergence)
    names = {r.name for r in s.truth.roads}
    assert names == {"Ring", "Spur"}
    assert s.meta["osm"]["buildings"] == 0


def test_multipolygons_courtyard_and_lake_island(scene, rs):
    xy = local(scene, [(25, 85), (5, 65), (-20, -70), (-20, -90), (-20, -50 + 1)])
    lab = labels_at(rs, xy)
    assert lab[0] == "ground"          # courtyard: a hole in the building
    assert lab[1] == "building"
    assert lab[2] == "ground"          # island: a hole in the lake
    assert lab[3] == "water"
    assert lab[4] == "water"


# ---------------------------------------------------------------------------- roads
def _independent_road_area(town, scene):
    """Union of the centre lines buffered by the documented widths, built with shapely and
    pyproj from the hand-written ways, clipped to the projected bbox."""
    polys = []
    for ids, tags in town.ways.values():
        if tags.get("highway") not in ("residential", "primary", "service"):
            continue
        pts = local(scene, [town.nodes[i][:2] for i in ids])
        polys.append(shapely.LineString(pts).buffer(EXPECTED_WIDTH[tags.get("name")] / 2))
    ring = shapely.segmentize(shapely.box(*bbox_lonlat()), 1e-4)
    tr = pyproj.Transformer.from_crs("EPSG:4326", scene.crs, always_xy=True)
    clip = shapely.transform(ring, lambda c: np.column_stack(tr.transform(c[:, 0], c[:, 1]))
                             - np.asarray(scene.origin[:2]))
    return shapely.intersection(shapely.union_all(polys), clip)


def test_drivable_area_equals_buffered_centre_lines(town, scene):
    ref = _independent_road_area(town, scene)
    got = scene.truth.road_area
    assert abs(got.area - ref.area) / ref.area < 0.02
    assert shapely.symmetric_difference(got, ref).area / ref.area < 0.02
    # the road mesh covers exactly the truth polygon
    road = next(o for o in scene.objects if o.label == "road")
    v, f = road.vertices, road.faces
    a, b, c = v[f[:, 0], :2], v[f[:, 1], :2], v[f[:, 2], :2]
    tri = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    assert tri.sum() == pytest.approx(got.area, rel=1e-6)
    assert np.allclose(v[:, 2], 0.0)


def test_junctions_crack_free(scene, rs):
    area = scene.truth.road_area
    parts = list(shapely.get_parts(area))
    # the street network is one piece; each carriageway of the dual road is its own piece
    assert len(parts) == 3
    holes = [shapely.Polygon(r) for p in parts for r in p.interiors]
    assert len(holes) == 1  # only the roundabout's island
    island = holes[0]
    assert island.area == pytest.approx(math.pi * (28 - 3.5) ** 2, rel=0.03)
    # every crossing and T-junction is road right up to its corners (no sliver)
    for x, y in [(-100, 0), (150, 0), (240, 0), (150, 82), (-100, 50)]:
        c = local(scene, [(x, y)])[0]
        ang = np.linspace(0, 2 * np.pi, 24, endpoint=False)
        ring = c + 2.5 * np.stack([np.cos(ang), np.sin(ang)], 1)
        assert set(labels_at(rs, np.vstack([c, ring]))) <= {"road", "lane_marking"}, (x, y)


def test_footways_are_sidewalk_not_drivable(scene, rs):
    xy = local(scene, [(30, -7)])
    assert labels_at(rs, xy) == ["sidewalk"]
    assert "sidewalk" not in scene.label_config.drivable


def test_lane_markings(scene, rs):
    marks = next(o for o in scene.objects if o.label == "lane_marking")
    # on the road surface only
    pts = shapely.points(marks.vertices[:, :2])
    assert shapely.covers(scene.truth.road_area.buffer(1e-6), pts).all()
    assert np.allclose(marks.vertices[:, 2], 0.01)

    def hits(points, y_off=0.0):
        xy = local(scene, points)
        return sum(lab == "lane_marking" for lab in labels_at(rs, xy))

    # dashed centre line on two-way Main Street, 3 m of every 9 m
    along = [(x, 0.0) for x in np.arange(-60, 100, 0.5)]
    assert 0.25 < hits(along) / len(along) < 0.45
    # none off the centre line of the two-lane two-way street
    assert hits([(x, 1.5) for x in np.arange(-60, 100, 0.5)]) == 0
    # the lanes=3 avenue: two lane dividers 3.5 m either side of its centre line
    for dx in (-1.75, 1.75):
        assert hits([(240 + dx, y) for y in np.arange(-250, -120, 0.5)]) > 60
    assert hits([(240.0, y) for y in np.arange(-250, -120, 0.5)]) == 0
    # cleared in junctions
    c = local(scene, [(-100, 0)])[0]
    near = shapely.Point(c).buffer(3.0)
    assert not shapely.intersects(near, shapely.MultiPoint(marks.vertices[:, :2]))


# ---------------------------------------------------------------------------- hints
def test_direction_hints_from_tags(scene):
    from aerial_synth.scene.hints import road_hints

    h = road_hints(scene)
    assert h is not None and len(h) == 8
    pts = local(scene, [(-100, 100), (-30, 0), (50, -150), (50, -128), (178, 110), (240, 50),
                        (150, 40), (0, 250)])
    d = h.direction_at(pts)
    # the scene frame is UTM grid north, a degree or two off true north here
    def close(v, w, tol=3.0):
        return np.degrees(np.arccos(np.clip(np.dot(v, w), -1, 1))) < tol
    assert close(d[0], [0, 1])          # oneway=yes, northbound
    assert np.isnan(d[1]).all()          # two-way main street
    assert close(d[2], [1, 0])          # dual carriageway, eastbound
    assert close(d[3], [-1, 0])         # and westbound
    assert close(d[4], [0, 1], 10)      # roundabout (24-gon): counter-clockwise at its east side
    assert close(d[5], [0, -1])         # motorway-like avenue drawn north to south
    assert np.isnan(d[6]).all()          # two-way spur
    assert np.isnan(d[7]).all()          # off every road
    lanes = h.lanes_at(pts[[0, 1, 5]])
    assert lanes.tolist() == [[-1, 0], [1, 1], [3, 0]]


def test_oneway_minus_one_reverses_and_motorway_implies_oneway():
    from aerial_synth.scene.osm.tags import road_params

    p = road_params({"highway": "residential", "oneway": "-1"})
    assert p.oneway and p.reverse
    p = road_params({"highway": "motorway"})
    assert p.oneway and not p.reverse
    assert not road_params({"highway": "motorway", "oneway": "no"}).oneway
    p = road_params({"highway": "tertiary", "lanes": "3", "lanes:forward": "2"})
    assert (p.lanes_forward, p.lanes_backward, p.width_m) == (2, 1, 9.0)
    p = road_params({"highway": "secondary", "width": "8.5 m", "lanes": "2"})
    assert p.width_m == 8.5 and p.width_source == "width"
    assert road_params({"highway": "primary", "oneway": "yes"}).width_m == 7.0


# ---------------------------------------------------------------------------- placement
def _road_of(scene, v, junction_m: float = 4.0):
    """The one road a vehicle stands on, or None inside or near a junction (within
    ``junction_m`` of another road's carriageway)."""
    p = shapely.Point(v.x_m, v.y_m)
    d = [r.centerline.distance(p) - r.width_m / 2 for r in scene.truth.roads]
    inside = [k for k, x in enumerate(d) if x <= 0]
    near = [k for k, x in enumerate(d) if x <= junction_m]
    return scene.truth.roads[inside[0]] if len(inside) == 1 and len(near) == 1 else None


def _deviation_deg(road, v):
    line = road.centerline
    s = line.project(shapely.Point(v.x_m, v.y_m))
    a = line.interpolate(max(s - 0.5, 0.0))
    b = line.interpolate(min(s + 0.5, line.length))
    t = math.atan2(b.y - a.y, b.x - a.x)
    return abs(math.degrees(math.remainder(v.heading_rad - t, 2 * math.pi)))


@pytest.mark.parametrize("scenario,kw", [("jam", {"n_vehicles": 160}), ("normal", {}),
                                         ("sparse", {})])
def test_placement_on_osm_scene(scene, rs, scenario, kw):
    from aerial_synth.placement.footprints import validate_placement
    from aerial_synth.placement.traffic import place

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        p = place(rs, scenario, seed=3, **kw)
    assert len(p.vehicles) > 60
    rep = validate_placement(rs, p, scene.truth).summary()
    assert rep["overlaps"] == 0
    assert rep["corners_drivable"] == 1.0
    assert rep["footprint_on_road_min"] == 1.0
    along = {}
    for v in p.vehicles:
        road = _road_of(scene, v, junction_m=0.0)
        if road is None:
            continue  # in a junction (inside two carriageways)
        along.setdefault(road.name, []).append(_deviation_deg(road, v))
    for name in ("Oneway Lane", "Dual East", "Dual West", "Avenue"):
        dev = np.array(along[name])
        assert (dev <= 10).all(), (name, dev.max())  # 100 % along the way
    main = np.array(along["Main Street"])
    assert (main <= 10).sum() >= 5 and (main >= 170).sum() >= 5  # both directions
    assert ((main <= 10) | (main >= 170)).all()
    ring = np.array(along.get("Ring", []))
    assert (ring <= 10).all()  # counter-clockwise only
    # no opposite lanes on one-way roads: every opposite-lane vehicle is on a two-way road
    for v in p.vehicles:
        road = _road_of(scene, v)
        if v.lane == 1 and road is not None:
            assert not road.oneway, road.name


def test_roundabout_gets_the_legal_direction_only(files):
    """A scene cut around the roundabout: every vehicle on the ring drives counter-clockwise."""
    from aerial_synth.placement.traffic import place
    from aerial_synth.scene.osm import build_osm_scene
    from aerial_synth.scene.raycast import RayScene

    lo, hi = to_lonlat(100, 50), to_lonlat(200, 160)
    s = build_osm_scene(files["osm"], bbox=(lo[0], lo[1], hi[0], hi[1]))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        p = place(RayScene(s), "jam", seed=5, n_vehicles=40)
    c = local(s, [(150, 110)])[0]
    on_ring = 0
    for v in p.vehicles:
        r = np.hypot(v.x_m - c[0], v.y_m - c[1])
        if not (24.5 <= r <= 31.5):
            continue
        on_ring += 1
        ccw = math.atan2(v.y_m - c[1], v.x_m - c[0]) + math.pi / 2
        assert abs(math.degrees(math.remainder(v.heading_rad - ccw, 2 * math.pi))) <= 10
    assert on_ring >= 8


def test_lanes_feed_multilane(scene, rs):
    """multilane offers 3 lanes per direction: the lanes=3 avenue fills all three, the
    1 + 1 lane main street only its own lane per direction."""
    from aerial_synth.placement.traffic import place

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        p = place(rs, "multilane", seed=2, n_lines=40)
    avenue = next(r for r in scene.truth.roads if r.name == "Avenue")
    main = next(r for r in scene.truth.roads if r.name == "Main Street")
    lanes_used = set()
    for v in p.vehicles:
        road = _road_of(scene, v)
        if road is avenue:
            # distance from the right-hand edge: half the width + the offset to the left
            lanes_used.add(int((avenue.width_m / 2 + _left_offset(avenue, v)) // 3.5))
        if road is main:
            dev = _deviation_deg(main, v)
            assert dev <= 10 or dev >= 170
            # in its own half: right of the centre line, whichever way it drives
            side = _left_offset(main, v) * (1 if dev <= 10 else -1)
            assert side < -0.5
    assert lanes_used == {0, 1, 2}


def _left_offset(road, v):
    """Signed distance of a vehicle left of the road's centre line (line direction)."""
    line = road.centerline
    pt = shapely.Point(v.x_m, v.y_m)
    s = line.project(pt)
    a, b = line.interpolate(max(s - 0.5, 0)), line.interpolate(min(s + 0.5, line.length))
    t = np.array([b.x - a.x, b.y - a.y])
    t /= np.linalg.norm(t)
    q = line.interpolate(s)
    return float(t[0] * (v.y_m - q.y) - t[1] * (v.x_m - q.x))


# ---------------------------------------------------------------------------- the rest
def test_buildings_heights_from_tags(scene, rs):
    roofs = [o for o in scene.objects if o.name.startswith("building_roofs_")]
    assert {o.material for o in roofs} <= {"roof_gravel", "roof_tiles", "roof_metal"}
    assert len({o.material for o in roofs}) == len(roofs)
    heights = set(np.round(np.unique(np.concatenate([o.vertices[:, 2] for o in roofs])), 3))
    # levels x 3 m (5 and 4 levels), house default, height tag
    assert heights == {15.0, 12.0, 7.0, 12.5}
    xy = local(scene, [(-40, 32), (-47, -32), (80, 35), (10, 70)])
    tr = rs.trace_down(xy, ignore=())
    assert tr.z.tolist() == pytest.approx([15.0, 7.0, 12.5, 12.0], abs=1e-3)


def test_trees_rows_parking_water(scene, rs):
    trunks = next(o for o in scene.objects if o.label == "trunk")
    crowns = next(o for o in scene.objects if o.label == "tree")
    n_trees = scene.meta["osm"]["trees"]
    assert n_trees == 3 + 13  # three tree nodes; a 100 m row every 8 m
    assert len(crowns.vertices) % n_trees == 0
    per = crowns.vertices.reshape(n_trees, -1, 3)
    c = local(scene, [(-200, 200)])[0]
    k = np.argmin(np.linalg.norm(per[:, :, :2].mean(1) - c, axis=1))
    width = per[k, :, 0].max() - per[k, :, 0].min()
    assert width == pytest.approx(9.0, rel=0.05)  # diameter_crown=9
    assert per[k, :, 2].max() == pytest.approx(14.0, abs=0.05)  # height=14
    assert len(trunks.faces)
    lab = labels_at(rs, local(scene, [(-170, 60), (-20, -90), (-200, 250)]))
    assert lab[0] == "parking"
    assert lab[1] == "water"
    assert lab[2] in ("ground", "tree")
    assert scene.truth.parking_area is not None
    assert scene.truth.parking_area.area == pytest.approx(80 * 60, rel=0.02)


def test_ground_plane_under_everything(scene, rs):
    ground = next(o for o in scene.objects if o.name == "ground")
    assert np.allclose(ground.vertices[:, 2], -0.10)
    b = scene.bounds()
    xy = np.random.default_rng(0).uniform(b[0, :2] + 5, b[1, :2] - 5, (500, 2))
    tr = rs.trace_down(xy, ignore=())
    inside = shapely.contains_xy(shapely.MultiPoint(ground.vertices[:, :2]).convex_hull,
                                 xy[:, 0], xy[:, 1])
    assert np.isfinite(tr.z[inside]).all()


# ---------------------------------------------------------------------------- georeference
def test_georeference_and_lonlat_round_trip(scene, rs):
    from aerial_synth.placement.traffic import place

    assert scene.crs == CRS
    o = np.asarray(scene.origin)
    # origin = the projected bbox centre (rounded to metres)
    tr = pyproj.Transformer.from_crs("EPSG:4326", CRS, always_xy=True)
    bb = bbox_lonlat()
    cx, cy = tr.transform((bb[0] + bb[2]) / 2, (bb[1] + bb[3]) / 2)
    assert abs(o[0] - cx) <= 0.5 and abs(o[1] - cy) <= 0.5 and o[2] == 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        p = place(rs, "sparse", seed=1, n_vehicles=40)
    from aerial_synth.placement.model import Placement

    back = Placement.from_json(p.to_json())  # through the JSON text (9 decimals)
    lon = np.array([v.lon_deg for v in back.vehicles])
    lat = np.array([v.lat_deg for v in back.vehicles])
    x, y = tr.transform(lon, lat)
    xy = np.column_stack([x, y]) - o[:2]
    ref = np.array([[v.x_m, v.y_m] for v in p.vehicles])
    assert np.abs(xy - ref).max() < 0.01
    assert p.georeference["crs"] == CRS


def test_crs_option(files):
    from aerial_synth.scene.osm import build_osm_scene

    s = build_osm_scene(files["osm"], crs="EPSG:25833")
    assert s.crs == "EPSG:25833"
    tr = pyproj.Transformer.from_crs("EPSG:4326", "EPSG:25833", always_xy=True)
    x, y = tr.transform(*to_lonlat(-100, 0))
    hit = np.array([x, y]) - np.asarray(s.origin[:2])
    assert s.truth.road_area.distance(shapely.Point(hit)) == 0.0


# ---------------------------------------------------------------------------- glTF
def test_glb_round_trip_keeps_labels_and_hints(scene, tmp_path):
    from aerial_synth.scene.hints import road_hints
    from aerial_synth.scene.io import export_glb, load_scene

    out = export_glb(scene, tmp_path / "town.glb")
    back = load_scene(out)
    assert {(o.name, o.label) for o in back.objects} == {(o.name, o.label) for o in scene.objects}
    assert back.crs == scene.crs and back.origin == pytest.approx(scene.origin)
    assert back.meta["attribution"] == "© OpenStreetMap contributors"
    h0, h1 = road_hints(scene), road_hints(back)
    assert h1 is not None and len(h1) == len(h0)
    for a, b in zip(h0.roads, h1.roads):
        assert np.allclose(a.coords_xy, b.coords_xy, atol=1e-3)
        assert (a.oneway, a.lanes_forward, a.lanes_backward, a.width_m) == \
            (b.oneway, b.lanes_forward, b.lanes_backward, b.width_m)
    pts = np.random.default_rng(1).uniform(-250, 250, (4000, 2))
    d0, d1 = h0.direction_at(pts), h1.direction_at(pts)
    assert np.isfinite(d0[:, 0]).sum() > 50
    same = np.isclose(d0, d1, atol=1e-4, equal_nan=True).all(axis=1)
    assert same.all(), pts[~same]


def test_hints_shift_with_the_frame():
    from aerial_synth.scene.hints import HintRoad, RoadHints, meta_from_extras

    h = RoadHints([HintRoad(np.array([[0.0, 0.0], [10.0, 0.0]]), 4.0, True, 1, 0)])
    d = h.to_dict()
    d["origin"] = [100.0, 0.0, 0.0]
    got = meta_from_extras({"aerial_synth_road_hints": d}, (90.0, 0.0, 0.0), "x")["road_hints"]
    assert got.roads[0].coords_xy[0].tolist() == [10.0, 0.0]
    with pytest.raises(SceneError, match="expected a mapping"):
        RoadHints.from_dict([1, 2], "glb")


# ---------------------------------------------------------------------------- odd data
def test_oneway_minus_one_and_missing_nodes(tmp_path):
    """oneway=-1 runs against the node order; a way with a node missing from the extract is
    built from the nodes that are there; a multipolygon with a missing member is skipped."""
    from aerial_synth.scene.hints import road_hints
    from aerial_synth.scene.osm import build_osm_scene

    from .osm_town import Town

    t = Town()
    t.way([(-150, 0), (0, 0), (150, 0)], {"highway": "residential", "oneway": "-1"})
    w = t.way([(0, -150), (0, -50), (0, 150)], {"highway": "tertiary", "name": "Cut"})
    t.ways[w][0].insert(2, 99999)  # a node the extract does not hold
    a = t.way([(50, 50), (90, 50), (90, 90), (50, 90)], {}, close=True)
    t.relation([("w", a, "outer"), ("w", 88888, "inner")],
               {"type": "multipolygon", "building": "yes"})
    s = build_osm_scene(t.write(tmp_path / "odd.osm"))
    h = road_hints(s)
    d = h.direction_at(local(s, [(-100, 0), (0, 100)]))
    assert d[0, 0] < -0.99  # westbound: against the node order
    assert np.isnan(d[1]).all()
    cut = next(r for r in s.truth.roads if r.name == "Cut")
    assert cut.centerline.length == pytest.approx(300, rel=0.02)


def test_left_hand_traffic_keeps_legal_directions(scene, rs):
    from aerial_synth.placement.footprints import validate_placement
    from aerial_synth.placement.traffic import place

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        p = place(rs, "normal", seed=3, overrides={"traffic": "left"})
    rep = validate_placement(rs, p, scene.truth, traffic="left").summary()
    assert rep["overlaps"] == 0 and rep["corners_drivable"] == 1.0
    for v in p.vehicles:
        road = _road_of(scene, v, junction_m=0.0)
        if road is None:
            continue
        dev = _deviation_deg(road, v)
        if road.oneway:
            assert dev <= 10, road.name
        elif _road_of(scene, v) is road:  # two-way, away from junctions: keeps left
            assert dev <= 10 or dev >= 170, (road.name, dev, v.x_m, v.y_m)
            side = _left_offset(road, v) * (1 if dev <= 10 else -1)
            assert side > -0.25, road.name


def test_tyre_tracks_lie_on_the_roads_a_few_mm_up(scene, rs):
    tracks = [o for o in scene.objects if o.material == "track"]
    assert len(tracks) == 1 and tracks[0].label == "road" and tracks[0].name == "tyre_tracks"
    v = tracks[0].vertices
    road = scene.truth.road_area
    assert shapely.contains_xy(road.buffer(1e-6), v[:, 0], v[:, 1]).all()
    assert np.all(v[:, 2] == pytest.approx(0.005))
    # traced from above, a share of the road surface is track, all of it drivable
    minx, miny, maxx, maxy = road.bounds
    pts = np.random.default_rng(0).uniform((minx, miny), (maxx, maxy), (20000, 2))
    pts = pts[shapely.contains_xy(road, pts[:, 0], pts[:, 1])]
    tr = rs.trace_down(pts, ignore=())
    on = tr.is_label({"road"})
    assert 0.05 < np.mean(np.abs(tr.z[on] - 0.005) < 1e-6) < 0.6
