from __future__ import annotations

import numpy as np
import pytest

from aerial_synth.errors import SceneError
from aerial_synth.scene import export_glb, load_scene
from aerial_synth.scene.io import load_rules

from .conftest import quad_yup, write_glb


def _park_glb(path):
    road = quad_yup(-50, 50, -5, 5)
    grass = quad_yup(-50, 50, 5, 30)
    T = np.eye(4)
    T[:3, 3] = [0.0, 0.0, -100.0]  # glTF -z = world +y: moves the node 100 m north
    return write_glb(
        path,
        [
            ("Street_Main", *road, None),
            ("Grass_North", *grass, None),
            ("Grass_Far", *grass, T),
            ("Kiosk", *quad_yup(20, 24, 10, 14, 3.0), None),
            ("Thing_7", *quad_yup(-30, -28, 10, 12, 1.0), None),
        ],
    )


def test_round_trip_with_rules(tmp_path):
    glb = _park_glb(tmp_path / "park.glb")
    rules = tmp_path / "rules.yaml"
    rules.write_text(
        "rules:\n"
        "  - {match: 'kiosk*', label: building, material: wall, color: [0.5, 0.4, 0.3]}\n"
        "  - {match: 're:^thing_\\d+$', label: pole}\n"
    )
    a = load_scene(glb, labels=rules)
    assert {o.name: o.label for o in a.objects} == {
        "Street_Main": "road",
        "Grass_North": "ground",
        "Grass_Far": "ground",
        "Kiosk": "building",
        "Thing_7": "pole",
    }
    assert a.meta["n_unmatched"] == 0
    kiosk = next(o for o in a.objects if o.name == "Kiosk")
    assert kiosk.material == "wall" and kiosk.color == pytest.approx((0.5, 0.4, 0.3))
    out = export_glb(a, tmp_path / "again.glb")
    b = load_scene(out)  # default rules only: labels travel in the names
    assert [(o.name, o.label, o.material) for o in a.objects] == [
        (o.name, o.label, o.material) for o in b.objects
    ]
    for oa, ob in zip(a.objects, b.objects):
        assert np.array_equal(oa.vertices, ob.vertices)
        assert np.array_equal(oa.faces, ob.faces)
        assert oa.color == pytest.approx(ob.color, abs=1e-7)
    assert a.vertex_hash() == b.vertex_hash()


def test_node_transform_and_y_up(tmp_path):
    # one triangle in glTF (y-up): (1, 2, 3), (4, 2, 3), (1, 2, -5); node translated by (10, 0, 0)
    v = np.array([[1.0, 2.0, 3.0], [4.0, 2.0, 3.0], [1.0, 2.0, -5.0]])
    T = np.eye(4)
    T[:3, 3] = [10.0, 0.0, 0.0]
    glb = write_glb(tmp_path / "tri.glb", [("road_tri", v, [[0, 1, 2]], T)])
    s = load_scene(glb)
    got = s.objects[0].vertices
    want = np.array([[11.0, -3.0, 2.0], [14.0, -3.0, 2.0], [11.0, 5.0, 2.0]])  # (x, -z, y)
    np.testing.assert_allclose(got, want, atol=1e-6)
    np.testing.assert_array_equal(s.objects[0].faces, [[0, 1, 2]])
    # still counter-clockwise seen from above (normal +z)
    n = np.cross(got[1] - got[0], got[2] - got[0])
    assert n[2] > 0


def test_default_rules_case_insensitive():
    r = load_rules(None)
    cases = {
        "ROAD_1": "road", "Street.003": "road", "asphalt": "road", "Building_A": "building",
        "house7": "building", "Tree_oak": "tree", "CROWN": "tree", "trunk_3": "trunk",
        "Grass": "ground", "terrain_lod0": "ground", "Lake": "water", "Sidewalk_N": "sidewalk",
        "Parking_lot": "parking", "lane_dash": "lane_marking", "Marking_stop": "lane_marking",
        "Lamp_post": "pole", "pole": "pole", "road__x": "road", "water__road": "water",
    }
    for name, label in cases.items():
        rule = r.label_for(name)
        assert rule is not None and rule.label == label, name
    assert r.label_for("bench_01") is None


def test_unmatched_are_unknown_obstacles(tmp_path):
    glb = _park_glb(tmp_path / "p.glb")
    s = load_scene(glb)
    assert s.meta["n_unmatched"] == 2
    assert sorted(s.meta["unmatched"]) == ["Kiosk", "Thing_7"]
    assert {o.label for o in s.objects if o.name in ("Kiosk", "Thing_7")} == {"unknown"}
    assert "unknown" in s.label_config.obstacles


def test_sidecar_rules_and_units(tmp_path):
    glb = _park_glb(tmp_path / "city.glb")
    (tmp_path / "city.labels.yaml").write_text(
        "units: cm\nrules: {'kiosk': building, 'thing_*': pole}\n"
        "label_config: {ignore: [tree, pole]}\n"
    )
    s = load_scene(glb)
    assert s.meta["n_unmatched"] == 0
    road = next(o for o in s.objects if o.label == "road")
    assert road.vertices[:, 0].max() == pytest.approx(0.5)  # 50 units of 1 cm
    assert s.label_config.ignore == frozenset({"tree", "pole"})


def test_obj_and_ply_are_z_up(tmp_path):
    import trimesh

    v = np.array([[0.0, 0.0, 1.0], [2.0, 0.0, 1.0], [0.0, 3.0, 1.0]])
    m = trimesh.Trimesh(v, [[0, 1, 2]], process=False)
    ply = tmp_path / "road_patch.ply"
    ply.write_bytes(m.export(file_type="ply"))
    s = load_scene(ply)
    assert s.objects[0].label == "road"
    np.testing.assert_allclose(s.objects[0].vertices, v)
    obj = tmp_path / "scene.obj"
    obj.write_text(
        "o road_a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
        "o house_b\nv 5 5 0\nv 6 5 0\nv 5 6 3\nf 4 5 6\n"
    )
    s = load_scene(obj)
    labels = {o.name: o.label for o in s.objects}
    assert labels == {"road_a": "road", "house_b": "building"}
    house = next(o for o in s.objects if o.name == "house_b")
    np.testing.assert_allclose(house.vertices, [[5, 5, 0], [6, 5, 0], [5, 6, 3]])


def test_no_road_error_names_file(tmp_path):
    glb = write_glb(tmp_path / "meadow.glb", [("grass", *quad_yup(0, 1, 0, 1), None)])
    with pytest.raises(SceneError, match="meadow.glb.*no 'road'"):
        load_scene(glb)


def test_bundled_name_and_unknown_name():
    from aerial_synth.scene import list_scenes

    assert {"city_park", "suburb", "highway"} <= set(list_scenes())
    with pytest.raises(SceneError, match="not a bundled scene"):
        load_scene("no_such_scene")


def test_import_is_light():
    import subprocess
    import sys

    code = (
        "import sys, aerial_synth.scene, aerial_synth.scene.cli; "
        "bad = [m for m in ('open3d', 'trimesh', 'shapely', 'cv2') if m in sys.modules]; "
        "print(bad); sys.exit(1 if bad else 0)"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
