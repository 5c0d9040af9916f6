"""Realism geometry of the procedural scenes: clumped crowns and species, roof coverings and
roof details, tyre tracks (issue 15)."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
import trimesh

from aerial_synth.errors import SceneError
from aerial_synth.scene.model import MATERIAL_IDS
from aerial_synth.scene.procedural import generate
from aerial_synth.scene.procedural.markings import lane_centres, road_tracks
from aerial_synth.scene.procedural.roads import Road
from aerial_synth.scene.procedural.roofs import ROOF_MATERIALS, roof_parts
from aerial_synth.scene.procedural.trees import (
    N_TEMPLATES,
    SPECIES,
    crown_template,
    species_weights,
    tree_objects,
)


def _small(**extra):
    spec = {"generator": "city_park", "seed": 5, "size_m": [120, 120],
            "roads": [{"name": "a", "points": [[-60, 0], [60, 0]], "width_m": 8},
                      {"name": "b", "points": [[0, -60], [0, 60]], "width_m": 7}],
            "buildings": {"count": 6, "width_m": [8, 30], "depth_m": [8, 30], "height_m": [4, 20]},
            "trees": {"park": {"count": 60}}}
    spec.update(extra)
    return spec


# ------------------------------------------------------------------------------- trees
def _pieces(v, f):
    return trimesh.Trimesh(v, f, process=False).split(only_watertight=False)


@pytest.mark.parametrize("species", ["broadleaf", "spreading", "columnar"])
def test_crowns_are_several_overlapping_clumps(species):
    for i in range(N_TEMPLATES):
        v, f = crown_template(species, i)
        parts = _pieces(v, f)
        assert len(parts) >= 3, (species, i, len(parts))  # k > 1 ellipsoid clumps
        for p in parts:
            assert p.is_watertight and p.volume > 0
        # the clumps overlap: their xy discs are not disjoint (one lumpy crown, not a cluster)
        discs = [shapely.Point(*p.centroid[:2]).buffer(np.ptp(p.vertices[:, 0]) / 2) for p in parts]
        assert shapely.union_all(discs).geom_type == "Polygon", (species, i)
        assert np.all(np.hypot(v[:, 0], v[:, 1]) <= 1 + 1e-9)
        assert v[:, 2].min() == pytest.approx(0.0) and v[:, 2].max() == pytest.approx(1.0)
    # templates differ from each other (jittered)
    a, b = crown_template(species, 0)[0], crown_template(species, 1)[0]
    assert a.shape != b.shape or not np.allclose(a, b)


def test_conifers_are_stacked_cones_narrower_at_the_top():
    for i in range(N_TEMPLATES):
        v, f = crown_template("conifer", i)
        parts = _pieces(v, f)
        assert 2 <= len(parts) <= 4
        for p in parts:
            assert p.is_watertight and p.volume > 0
        r = np.hypot(v[:, 0], v[:, 1])
        # the widest point of each tier shrinks going up, and the top is a point
        tiers = sorted(parts, key=lambda p: p.vertices[:, 2].min())
        widths = [np.hypot(p.vertices[:, 0], p.vertices[:, 1]).max() for p in tiers]
        assert all(a > b for a, b in zip(widths, widths[1:])), widths
        top = v[:, 2] > 0.75
        assert r[top].max() < 0.6 * r.max()
        assert r[np.argmax(v[:, 2])] < 0.1


def test_tree_objects_scale_templates_and_group_by_species():
    trees = np.array([[0, 0, 4.0, 12.0, SPECIES.index("broadleaf"), 0.31, 0.1],
                      [20, 0, 4.0, 12.0, SPECIES.index("conifer"), 0.77, 0.9]])
    objs = tree_objects(trees)
    names = [o.name for o in objs]
    assert names[-1] == "trunks" and objs[-1].label == "trunk"
    crowns = {o.name: o for o in objs if o.label == "tree"}
    assert len(crowns) == 2
    broad = next(o for n, o in crowns.items() if "broadleaf" in n)
    con = next(o for n, o in crowns.items() if "conifer" in n)
    assert broad.vertices[:, 2].max() == pytest.approx(12.0)
    assert np.hypot(broad.vertices[:, 0], broad.vertices[:, 1]).max() == pytest.approx(4.0)
    assert np.hypot(con.vertices[:, 0] - 20, con.vertices[:, 1]).max() == pytest.approx(0.6 * 4.0)
    assert np.mean(con.color) < np.mean(broad.color)  # darker needles
    # trunks reach into the crown, never above it
    tv = objs[-1].vertices
    for x0, o in ((0, broad), (20, con)):
        top = tv[np.abs(tv[:, 0] - x0) < 1.0, 2].max()
        assert o.vertices[:, 2].min() < top < o.vertices[:, 2].max()


def test_species_mix_from_the_spec_and_its_errors():
    only_con = generate(_small(tree_species={"conifer": 1.0}))
    names = {o.name for o in only_con.objects if o.label == "tree"}
    assert names and all("conifer" in n for n in names)
    mixed = generate(_small())  # the generator's default mix: broadleaf and conifers
    kinds = {n.split("_")[2] for n in (o.name for o in mixed.objects if o.label == "tree")}
    assert {"broadleaf", "conifer"} <= kinds
    sec = generate(_small(trees={"park": {"count": 40, "species": {"columnar": 1}}}))
    assert all("columnar" in o.name for o in sec.objects if o.label == "tree")
    with pytest.raises(SceneError, match="tree_species: unknown species 'palm'"):
        generate(_small(tree_species={"palm": 1.0}))
    with pytest.raises(SceneError, match=r"trees.park.species.conifer: expected a weight >= 0"):
        generate(_small(trees={"park": {"count": 4, "species": {"conifer": -1}}}))
    with pytest.raises(SceneError, match="positive sum"):
        species_weights({"conifer": 0})


def test_trunks_stay_clear_of_roads():
    sc = generate(_small())
    road = sc.truth.road_area
    tv = next(o for o in sc.objects if o.name == "trunks").vertices
    assert not shapely.contains_xy(road, tv[:, 0], tv[:, 1]).any()


# ------------------------------------------------------------------------------- roofs
def _buildings(n=60, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        w, d = rng.uniform(6, 45, 2)
        h = rng.uniform(3.5, 25)
        poly = shapely.affinity.rotate(shapely.box(-w / 2, -d / 2, w / 2, d / 2), rng.uniform(0, 180))
        out.append((shapely.affinity.translate(poly, *rng.uniform(-100, 100, 2)), h))
    return out


def test_roofs_get_a_covering_and_details_stay_on_the_roof():
    seen, pitched = set(), 0
    for k, (poly, h) in enumerate(_buildings()):
        rp = roof_parts(poly, h, np.random.default_rng(k))
        assert rp.material in ROOF_MATERIALS
        seen.add(rp.material)
        v = rp.body[0]
        assert v[:, 2].min() == 0.0 and v[:, 2].max() == pytest.approx(rp.ridge_z)
        assert rp.ridge_z <= h + 1e-9
        if rp.pitched:
            pitched += 1
            assert rp.material == "roof_tiles" and rp.roof_z < rp.ridge_z
        grown = poly.buffer(1e-6)
        for mat, dv, df in rp.details:
            assert mat in MATERIAL_IDS
            assert shapely.contains_xy(grown, dv[:, 0], dv[:, 1]).all(), (k, mat)
            assert dv[:, 2].min() >= rp.roof_z - 0.05, (k, mat)  # on the roof, not in the walls
            assert dv[:, 2].max() > rp.roof_z
            tm = trimesh.Trimesh(dv, df, process=False)
            assert tm.is_watertight and tm.volume > 0
    assert seen == set(ROOF_MATERIALS)
    assert pitched > 0


def test_flat_roofs_have_parapets_and_details():
    poly = shapely.box(0, 0, 40, 25)
    n_det = []
    for k in range(20):
        rp = roof_parts(poly, 18.0, np.random.default_rng(k), {"roof_gravel": 1.0})
        assert rp.material == "roof_gravel" and not rp.pitched
        parapet = rp.details[0]
        assert parapet[0] == "concrete"
        pv = parapet[1]
        # a ring along the edge: on the outline, and nothing in the middle
        assert shapely.contains_xy(poly.buffer(1e-6).difference(poly.buffer(-0.4)), pv[:, 0], pv[:, 1]).all()
        n_det.append(len(rp.details) - 1)
    assert max(n_det) >= 3


def test_scene_buildings_carry_roof_materials_and_detail_objects():
    sc = generate(_small())
    mats = {o.material for o in sc.objects if o.name.startswith("building_")}
    assert mats and mats <= set(ROOF_MATERIALS)
    det = [o for o in sc.objects if o.name.startswith("roof_details_")]
    assert det and all(o.label == "building" for o in det)
    plain = generate(_small(roofs={"enabled": False}))
    assert not [o for o in plain.objects if o.name.startswith("roof_details_")]
    assert {o.material for o in plain.objects if o.name.startswith("building_")} == {"roof"}
    with pytest.raises(SceneError, match="roofs.materials: unknown key"):
        generate(_small(roofs={"materials": {"thatch": 1}}))


# ------------------------------------------------------------------------------- tracks
def test_lane_centres():
    from shapely.geometry import LineString

    line = LineString([(0, 0), (100, 0)])
    assert lane_centres(Road("a", line, 8.0)) == [2.0, -2.0]
    assert lane_centres(Road("a", line, 14.0, lanes=2)) == [1.75, 5.25, -1.75, -5.25]
    assert lane_centres(Road("a", line, 4.0, lanes=0)) == [0.0]
    one = lane_centres(Road("a", line, 13.75, oneway=True, lanes=3, shoulder_left_m=0.75))
    np.testing.assert_allclose(one, [4.375, 0.875, -2.625])


def test_tracks_are_two_strips_per_lane_with_gaps_at_junctions():
    from shapely.geometry import LineString

    r = Road("a", LineString([(-50, 0), (50, 0)]), 8.0)
    cross = LineString([(0, -50), (0, 50)]).buffer(3.5, cap_style="flat")
    t = road_tracks(r, cross, {})
    # away from the junction: 4 strips of 0.6 m centred at +-2 +- 0.9
    ys = np.linspace(-4, 4, 801)
    hit = shapely.contains_xy(t, np.full_like(ys, -20.0), ys)
    runs = np.flatnonzero(np.diff(hit.astype(int)) == 1)
    assert len(runs) == 4
    for c in (-2.9, -1.1, 1.1, 2.9):
        assert shapely.contains_xy(t, -20.0, c) and not shapely.contains_xy(t, -20.0, c + 0.35)
    assert t.area == pytest.approx(4 * 0.6 * (100 - 2 * (3.5 + 2.0)), rel=0.01)
    assert not t.intersects(cross.buffer(1.99))  # a gap at the junction


def test_scene_tracks_lie_on_the_road_a_few_mm_up():
    sc = generate(_small())
    road = sc.truth.road_area
    tracks = [o for o in sc.objects if o.material == "track"]
    assert len(tracks) == 2 and all(o.label == "road" for o in tracks)
    for o in tracks:
        v = o.vertices
        assert shapely.contains_xy(road.buffer(1e-6), v[:, 0], v[:, 1]).all()
        assert np.all(v[:, 2] - 0.05 > 0) and np.all(v[:, 2] - 0.05 <= 0.006)  # at most 6 mm
    off = generate(_small(tracks={"enabled": False}))
    assert not [o for o in off.objects if o.material == "track"]


# ------------------------------------------------------------------------------ determinism
@pytest.mark.parametrize("gen", ["city_park", "city"])
def test_same_seed_same_vertices(gen):
    spec = _small() if gen == "city_park" else {
        "generator": "city", "seed": 4, "size_km": 0.4, "window_m": [-100, -100, 100, 100]}
    a, b = generate(spec), generate(spec)
    assert a.vertex_hash() == b.vertex_hash()
    assert generate(spec, seed=9).vertex_hash() != a.vertex_hash()
    assert any(o.material == "track" for o in a.objects)
    assert any(o.name.startswith("roof_details_") for o in a.objects)


def test_glb_export_keeps_roofs_tracks_and_species(tmp_path):
    import collections

    from aerial_synth.scene import load_scene
    from aerial_synth.scene.io import export_glb

    a = generate(_small())
    b = load_scene(export_glb(a, tmp_path / "s.glb"))
    key = lambda sc: collections.Counter((o.label, o.material, o.n_triangles) for o in sc.objects)  # noqa: E731
    assert key(a) == key(b)
    assert {"roof_gravel", "track"} <= {o.material for o in b.objects}


def test_osm_roof_covering_from_tags():
    from aerial_synth.scene.procedural.roofs import covering_from_tags

    assert covering_from_tags({"building": "house"}) == "roof_tiles"
    assert covering_from_tags({"building": "warehouse"}) == "roof_metal"
    assert covering_from_tags({"building": "apartments"}) == "roof_gravel"
    assert covering_from_tags({"building": "yes"}) == "roof_gravel"
    assert covering_from_tags({"building": "house", "roof:material": "metal"}) == "roof_metal"
    assert covering_from_tags({"building": "industrial", "roof:material": "Gravel"}) == "roof_gravel"
    assert covering_from_tags({"building": "industrial", "roof:material": "straw"}) == "roof_metal"


def test_two_way_roads_with_several_lanes_get_lane_lines():
    from shapely.geometry import LineString

    from aerial_synth.scene.procedural.markings import road_markings

    line = LineString([(-50, 0), (50, 0)])
    m2 = road_markings(Road("a", line, 14.0, lanes=2), None, {})
    m1 = road_markings(Road("a", line, 14.0, lanes=1), None, {})
    xs = np.linspace(-45, 45, 901)
    for y in (3.5, -3.5):  # between lane 1 and 2 of each direction: dashes
        on = shapely.contains_xy(m2, xs, np.full_like(xs, y))
        assert 0.2 < on.mean() < 0.5
        assert not shapely.contains_xy(m1, xs, np.full_like(xs, y)).any()
    # the tracks of the lanes stay clear of the lane lines
    t = road_tracks(Road("a", line, 14.0, lanes=2), None, {})
    assert not t.intersects(m2)
