"""Georeferenced scenes: recentring on load, CRS, export round trip, and the issue-10 check
that a UTM-shifted city_park places and renders exactly like the unshifted one."""

from __future__ import annotations

import functools
import json
import warnings

import numpy as np
import pytest

from aerial_synth.errors import SceneError
from aerial_synth.scene import RayScene, export_glb, load_scene
from aerial_synth.scene.georef import FAR_M, SceneWarning, choose_origin
from aerial_synth.scene.io import _zup_to_yup

from .conftest import quad_yup, write_glb

SHIFT = np.array([500_000.0, 5_300_000.0, 0.0])  # UTM-like false easting / northing


def _node_translation_glb(src, dst, shift_zup):
    """Copy a glb, giving every mesh node the float64 translation ``shift_zup`` (z-up m)."""
    import trimesh

    ts = trimesh.load(str(src), force="scene", process=False, maintain_order=True)
    T = np.eye(4)
    T[:3, 3] = _zup_to_yup(np.asarray(shift_zup, float)[None])[0]
    for node in ts.graph.nodes_geometry:
        ts.graph.update(frame_to=node, matrix=T)
    dst.write_bytes(ts.export(file_type="glb"))
    return dst


def _write_obj(scene, path, shift):
    """The scene as OBJ text with every coordinate + shift, 9 decimals (full precision)."""
    lines, base = [], 1
    for o in scene.objects:
        lines.append(f"o {o.label}__{o.name}")
        v = o.vertices + shift
        lines += [f"v {x:.9f} {y:.9f} {z:.9f}" for x, y, z in v]
        lines += [f"f {a + base} {b + base} {c + base}" for a, b, c in o.faces]
        base += len(v)
    path.write_text("\n".join(lines) + "\n")
    return path


@functools.lru_cache(maxsize=None)
def _city_park_files(tmp):
    """(unshifted glb, shifted glb, unshifted obj, shifted obj) of city_park in folder tmp."""
    from pathlib import Path

    tmp = Path(tmp)
    proc = load_scene("city_park")
    glb = export_glb(proc, tmp / "city_park.glb")
    shifted = _node_translation_glb(glb, tmp / "city_park_utm.glb", SHIFT)
    obj = _write_obj(proc, tmp / "city_park.obj", np.zeros(3))
    obj_shifted = _write_obj(proc, tmp / "city_park_utm.obj", SHIFT)
    return glb, shifted, obj, obj_shifted


@pytest.fixture(scope="module")
def city_park_files(tmp_path_factory):
    return _city_park_files(str(tmp_path_factory.mktemp("georef")))


# ------------------------------------------------------------------------------ the rule
def test_choose_origin_rule():
    assert choose_origin([-250, -250, 0], [250, 250, 20]) == (0.0, 0.0, 0.0)
    assert choose_origin([-FAR_M, 0, 0], [FAR_M, 1, 1]) == (0.0, 0.0, 0.0)  # 10 km: unchanged
    o = choose_origin([499_750, 5_299_750, 0], [500_250, 5_300_250, 20])
    assert o == (500_000.0, 5_300_000.0, 0.0)
    # centre rounded to the 1 km grid (halves up), each axis on its own
    assert choose_origin([12_000, -5, 300], [13_000, 5, 400]) == (13_000.0, 0.0, 0.0)
    assert choose_origin([-20_600, 0, 0], [-20_400, 1, 1])[0] == -20_000.0  # -20.5 km: half up
    # a shift by whole kilometres gives back the unshifted local bounds exactly
    lo, hi = np.array([-243.7, -251.2, 0.0]), np.array([249.1, 238.4, 17.0])
    for shift in ([500_000, 5_300_000, 0], [-123_000, 77_000, 0], [0, 0, 42_000]):
        o = np.array(choose_origin(lo + shift, hi + shift))
        assert np.array_equal(o, np.array(shift, float))


def test_scene_near_zero_is_unchanged(tmp_path):
    glb = write_glb(tmp_path / "s.glb", [("road", *quad_yup(-20, 20, -4, 4), None)])
    sc = load_scene(glb)
    assert sc.origin == (0.0, 0.0, 0.0) and sc.crs is None
    assert np.allclose(sc.bounds(), [[-20, -4, 0], [20, 4, 0]])


def test_node_translation_is_applied_in_float64_and_recentred(tmp_path):
    t = np.eye(4)
    t[:3, 3] = [512_345.678901, 0.0, -5_312_345.123456]  # y-up: world y = -z
    glb = write_glb(tmp_path / "utm.glb", [("road", *quad_yup(-20, 20, -4, 4), t)])
    sc = load_scene(glb)
    assert sc.origin == (512_000.0, 5_312_000.0, 0.0)
    b = sc.bounds()
    # local = original - origin, with the fractional metres intact (float64 all the way)
    assert np.allclose(b[0], [345.678901 - 20, 345.123456 - 4, 0], atol=1e-6)
    assert np.allclose(b[1], [345.678901 + 20, 345.123456 + 4, 0], atol=1e-6)
    orig = sc.to_original(b)
    assert np.allclose(orig[0, :2], [512_325.678901, 5_312_341.123456], atol=1e-6)


def test_float32_vertices_far_from_origin_warn(tmp_path):
    v, f = quad_yup(500_000 - 20, 500_000 + 20, 5_300_000 - 4, 5_300_000 + 4)
    glb = write_glb(tmp_path / "baked.glb", [("road", v, f, None)])
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        sc = load_scene(glb)
    msgs = [str(x.message) for x in w if issubclass(x.category, SceneWarning)]
    assert len(msgs) == 1 and "\n" not in msgs[0]
    assert "baked.glb" in msgs[0] and "float32" in msgs[0] and "0.5 m" in msgs[0]
    assert sc.origin == (500_000.0, 5_300_000.0, 0.0)
    # the translation form does not warn
    t = np.eye(4)
    t[:3, 3] = [500_000, 0, -5_300_000]
    ok = write_glb(tmp_path / "ok.glb", [("road", *quad_yup(-20, 20, -4, 4), t)])
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        load_scene(ok)
    assert not [x for x in w if issubclass(x.category, SceneWarning)]


# ------------------------------------------------------------------------------ CRS
def test_crs_from_labels_sidecar_and_gltf_extras(tmp_path):
    import trimesh

    t = np.eye(4)
    t[:3, 3] = [500_000, 0, -5_300_000]
    glb = write_glb(tmp_path / "city.glb", [("road", *quad_yup(-20, 20, -4, 4), t)])
    (tmp_path / "city.labels.yaml").write_text("crs: EPSG:32632\n")
    assert load_scene(glb).crs == "EPSG:32632"
    bad = tmp_path / "bad.yaml"
    bad.write_text("crs: EPSG:999999999\n")
    with pytest.raises(SceneError, match=r"bad\.yaml: crs: expected a CRS .*EPSG:999999999"):
        load_scene(glb, labels=bad)
    # glTF scene extras {"crs": ...} as other tools write it
    ts = trimesh.load(str(glb), force="scene", process=False)
    ts.metadata["crs"] = "EPSG:25833"
    other = tmp_path / "other.glb"
    other.write_bytes(ts.export(file_type="glb"))
    assert load_scene(other).crs == "EPSG:25833"
    # the labels file wins over the file's extras
    (tmp_path / "other.labels.yaml").write_text("crs: EPSG:32633\n")
    assert load_scene(other).crs == "EPSG:32633"


# ------------------------------------------------------------------------------ export
def test_export_round_trip_keeps_local_vertices_origin_and_crs(tmp_path):
    t = np.eye(4)
    t[:3, 3] = [512_345.678901, 123.25, -5_312_345.123456]
    glb = write_glb(tmp_path / "utm.glb", [("road", *quad_yup(-20, 20, -4, 4), t),
                                           ("grass", *quad_yup(-20, 20, 4, 30), t)])
    (tmp_path / "utm.labels.yaml").write_text("crs: EPSG:32632\n")
    a = load_scene(glb)
    out = export_glb(a, tmp_path / "again.glb")
    b = load_scene(out)
    assert b.origin == a.origin and b.crs == "EPSG:32632"
    # local vertices go to the file as float32 (glTF) and come back exactly so; the offset
    # never touches them
    for oa, ob in zip(a.objects, b.objects):
        assert np.array_equal(ob.vertices, oa.vertices.astype(np.float32).astype(np.float64))
    c = load_scene(export_glb(b, tmp_path / "third.glb"))
    assert c.vertex_hash() == b.vertex_hash() and c.origin == b.origin  # bit-identical
    # other tools see the original frame: node translation = origin (y-up), float64 JSON
    data = out.read_bytes()
    n = int.from_bytes(data[12:16], "little")
    tree = json.loads(data[20 : 20 + n])
    ox, oy, oz = a.origin
    for node in tree["nodes"]:
        if "mesh" in node:
            assert node["matrix"][12:15] == [ox, oz, -oy]
    assert tree["scenes"][0]["extras"]["aerial_synth"] == {"origin": [ox, oy, oz], "crs": "EPSG:32632"}
    # a procedural scene (origin 0, no CRS) writes neither
    p = export_glb(load_scene("city_park"), tmp_path / "cp.glb")
    d2 = p.read_bytes()
    t2 = json.loads(d2[20 : 20 + int.from_bytes(d2[12:16], "little")])
    assert "extras" not in t2["scenes"][0]
    assert all("matrix" not in nd or nd["matrix"][12:15] == [0, 0, 0] for nd in t2["nodes"])


# ------------------------------------------------------------------------------ issue 10
def _place(scene, n, seed=5):
    from aerial_synth.placement import place

    rs = RayScene(scene)
    return rs, place(rs, "jam", n_vehicles=n, seed=seed)


def _compare_placements(pa, pb, origin_b, shift):
    va, vb = pa.vehicles, pb.vehicles
    assert len(va) == len(vb) > 0
    xa = np.array([[v.x_m, v.y_m, v.z_m] for v in va])
    xb = np.array([[v.x_m, v.y_m, v.z_m] for v in vb])
    # original frame of the shifted scene minus the shift == the unshifted positions
    back = (xb + np.asarray(origin_b)) - shift
    assert np.abs(back - xa).max() < 0.01
    ha = np.degrees([v.heading_rad for v in va])
    hb = np.degrees([v.heading_rad for v in vb])
    dh = (hb - ha + 180.0) % 360.0 - 180.0
    assert np.abs(dh).max() < 0.01
    # headings are not snapped to multiples of 90 degrees (the float32 symptom)
    snapped = np.isclose(np.mod(ha, 90.0), 0.0, atol=1e-3) | np.isclose(np.mod(ha, 90.0), 90.0, atol=1e-3)
    assert snapped.mean() < 0.05


def test_shifted_glb_loads_to_the_same_local_scene(city_park_files):
    glb, shifted, _, _ = city_park_files
    a, b = load_scene(glb), load_scene(shifted)
    assert a.origin == (0.0, 0.0, 0.0)
    assert b.origin == (500_000.0, 5_300_000.0, 0.0)
    assert b.vertex_hash() == a.vertex_hash()


def test_shifted_glb_places_and_renders_like_the_unshifted(city_park_files):
    from aerial_synth.camera import Camera, CameraConfig
    from aerial_synth.render import RenderConfig, render_frame
    from aerial_synth.render.world import add_placement

    glb, shifted, _, _ = city_park_files
    a, b = load_scene(glb), load_scene(shifted)
    rs_a, pa = _place(a, 150)
    rs_b, pb = _place(b, 150)
    _compare_placements(pa, pb, b.origin, SHIFT)
    add_placement(rs_a, pa, simple_boxes=True)
    add_placement(rs_b, pb, simple_boxes=True)
    cfg = CameraConfig(width_px=384, height_px=384, gsd_m=0.15)
    # aim at the vehicle with the most neighbours within 20 m (whatever the scene's layout)
    xy = np.array([[u.x_m, u.y_m] for u in pa.vehicles])
    near = (np.linalg.norm(xy[:, None] - xy[None], axis=-1) < 20.0).sum(axis=1)
    v = pa.vehicles[int(np.argmax(near))]
    cam = Camera.look_at_ground(cfg, (v.x_m, v.y_m, 0.0), yaw_deg=30.0, tilt_deg=20.0)
    quick = RenderConfig(jpeg_probability=0.0)
    fa = render_frame(rs_a, cam, pa, np.random.default_rng(1), quick)
    fb = render_frame(rs_b, cam, pb, np.random.default_rng(1), quick)
    assert len(np.unique(fa.instance)) > 3  # vehicles in view
    assert np.array_equal(fa.instance, fb.instance)
    assert np.array_equal(fa.semantic, fb.semantic)


def test_shifted_obj_places_like_the_unshifted(city_park_files):
    _, _, obj, obj_shifted = city_park_files
    a, b = load_scene(obj), load_scene(obj_shifted)
    assert b.origin == (500_000.0, 5_300_000.0, 0.0)
    d = max(np.abs(x.vertices - y.vertices).max() for x, y in zip(a.objects, b.objects))
    assert d < 1e-6  # text coordinates keep full precision
    _, pa = _place(a, 150)
    _, pb = _place(b, 150)
    _compare_placements(pa, pb, b.origin, SHIFT)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["glb", "obj"])
def test_shifted_city_park_1000_vehicles(city_park_files, kind):
    glb, shifted, obj, obj_shifted = city_park_files
    a, b = (load_scene(glb), load_scene(shifted)) if kind == "glb" else (
        load_scene(obj), load_scene(obj_shifted))
    _, pa = _place(a, 1000)
    _, pb = _place(b, 1000)
    assert len(pa.vehicles) == 1000
    _compare_placements(pa, pb, b.origin, SHIFT)


def test_ascii_ply_keeps_full_precision(tmp_path):
    """An ASCII PLY (one object, named after the file, z-up) with UTM-sized text coordinates
    recentres with its fractional millimetres intact."""
    x0, y0 = 512_345.6789, 5_312_345.4321
    v = np.array([[x0, y0, 1.5], [x0 + 40, y0, 1.5], [x0 + 40, y0 + 8, 1.5], [x0, y0 + 8, 1.5]])
    head = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty double x\nproperty double y\n"
            "property double z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n")
    body = "".join(f"{a:.4f} {b:.4f} {c:.4f}\n" for a, b, c in v) + "3 0 1 2\n3 0 2 3\n"
    ply = tmp_path / "road_utm.ply"
    ply.write_text(head + body)
    sc = load_scene(ply)
    assert sc.origin == (512_000.0, 5_312_000.0, 0.0)
    (o,) = sc.objects
    assert o.label == "road"
    assert np.allclose(o.vertices, v - np.array(sc.origin), atol=1e-9, rtol=0)
    assert np.allclose(sc.to_original(o.vertices), v, atol=1e-9, rtol=0)


def test_cli_export_reports_and_keeps_the_georeference(cli_main, capsys, tmp_path):
    t = np.eye(4)
    t[:3, 3] = [500_000, 0, -5_300_000]
    glb = write_glb(tmp_path / "utm.glb", [("road", *quad_yup(-20, 20, -4, 4), t)])
    (tmp_path / "utm.labels.yaml").write_text("crs: EPSG:32632\n")
    out = tmp_path / "again.glb"
    assert cli_main(["scene", "export", str(glb), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "; local frame origin (500000, 5300000, 0) m in EPSG:32632" in text
    back = load_scene(out)
    assert back.origin == (500_000.0, 5_300_000.0, 0.0) and back.crs == "EPSG:32632"
    assert np.allclose(back.bounds(), [[-20, -4, 0], [20, 4, 0]])
