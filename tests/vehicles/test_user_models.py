"""User meshes (glTF/GLB/OBJ) and bad catalog input through the CLI."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
import yaml

from aerial_synth.errors import AssetError
from aerial_synth.scene.model import MATERIAL_IDS
from aerial_synth.vehicles import build_mesh, load_catalog

COLORS = [{"name": "red", "rgb": [0.6, 0.05, 0.05], "weight": 1.0}]


def _box(extents, centre, material, rgba):
    b = trimesh.creation.box(extents=extents)
    b.apply_translation(centre)
    b.visual = trimesh.visual.TextureVisuals(
        material=trimesh.visual.material.PBRMaterial(name=material, baseColorFactor=rgba)
    )
    return b


def _write_yup_zforward_glb(path: Path, scale: float = 1.0) -> None:
    """A 4.2 x 1.8 x 1.5 m car-ish model in glTF-like axes: y up, forward = -z, width on x.
    The windscreen block sits toward -z (the front). Units: metres / scale."""
    s = 1.0 / scale
    scene = trimesh.Scene()
    scene.add_geometry(_box([1.8 * s, 1.0 * s, 4.2 * s], [0, 0.5 * s, 0], "CarPaint",
                            [200, 200, 200, 255]), node_name="body")
    scene.add_geometry(_box([1.4 * s, 0.5 * s, 0.6 * s], [0, 1.25 * s, -0.6 * s], "Glass",
                            [10, 10, 20, 255]), node_name="windscreen")
    path.write_bytes(scene.export(file_type="glb"))


def _catalog(tmp_path: Path, models, colors=COLORS, name="catalog.yaml") -> Path:
    p = tmp_path / name
    p.write_text(yaml.safe_dump({"models": models, "colors": colors}))
    return p


def _mesh_entry(**kw):
    e = {"name": "my_car", "mesh": "my_car.glb", "forward": "-z", "up": "+y",
         "class": "small-vehicle", "paint_material": "CarPaint", "weight": 1.0}
    e.update(kw)
    return e


@pytest.mark.parametrize("scale", [1.0, 0.01])
def test_yup_minus_z_forward_glb_loads_into_vehicle_frame(tmp_path, scale):
    _write_yup_zforward_glb(tmp_path / "my_car.glb", scale=scale)
    cat = load_catalog(_catalog(tmp_path, [_mesh_entry(scale=scale)]))
    m = cat.model("my_car")
    np.testing.assert_allclose(m.size_m, (4.2, 1.8, 1.5), rtol=1e-5)
    assert m.source == "mesh:my_car.glb" and not m.is_procedural
    mesh = build_mesh(m, cat.color("red"))
    lo, hi = mesh.bounds
    np.testing.assert_allclose(hi - lo, (4.2, 1.8, 1.5), rtol=1e-5)
    np.testing.assert_allclose([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]], 0, atol=1e-6)
    glass = mesh.face_material == MATERIAL_IDS["glass"]
    paint = mesh.face_material == MATERIAL_IDS["paint"]
    assert glass.any() and paint.any()
    ws = mesh.vertices[mesh.faces[glass]].reshape(-1, 3).mean(axis=0)
    assert ws[0] > 0.3 and ws[2] > 1.0  # the front block came out at +x, on top
    assert np.allclose(mesh.face_albedo[paint], (0.6, 0.05, 0.05), atol=1e-6)
    # a proper rotation keeps the winding: the box's signed volume stays positive
    assert trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).volume > 0


def test_obj_in_a_subfolder(tmp_path):
    (tmp_path / "meshes").mkdir()
    box = trimesh.creation.box(extents=[5.0, 2.0, 2.2])  # already +x forward, z up
    box.export(tmp_path / "meshes" / "van.obj")
    entry = _mesh_entry(mesh="meshes/van.obj", forward="+x", up="+z", paint_material="")
    cat = load_catalog(_catalog(tmp_path, [entry]))
    np.testing.assert_allclose(cat.model("my_car").size_m, (5.0, 2.0, 2.2), rtol=1e-6)


def test_unknown_paint_material_lists_the_materials(tmp_path):
    _write_yup_zforward_glb(tmp_path / "my_car.glb")
    with pytest.raises(AssetError, match="CarPaint"):
        load_catalog(_catalog(tmp_path, [_mesh_entry(paint_material="Body")]))


# --------------------------------------------------------------------------- bad input
GOOD = {"name": "car", "body": "sedan", "class": "small-vehicle", "length_m": 4.5,
        "width_m": 1.8, "height_m": 1.45, "weight": 1.0}


def _with(**kw):
    e = dict(GOOD)
    e.update(kw)
    return e


BAD_CASES = {
    "zero length": ([_with(length_m=0)], "length_m"),
    "negative width": ([_with(width_m=-1.8)], "width_m"),
    "string height": ([_with(height_m="tall")], "height_m"),
    "unknown class": ([_with(**{"class": "car"})], "class"),
    "negative weight": ([_with(weight=-0.5)], "weight"),
    "unknown body": ([_with(body="tank")], "body"),
    "missing mesh file": ([_mesh_entry(mesh="nowhere.glb")], "not found"),
    "escaping mesh path": ([_mesh_entry(mesh="../outside.glb")], "escapes"),
    "absolute mesh path": ([_mesh_entry(mesh="/etc/passwd.glb")], "absolute"),
    "mesh with a size": ([_mesh_entry(length_m=4.0)], "mesh bounds"),
    "bad forward axis": ([_mesh_entry(forward="front")], "forward"),
    "duplicate names": ([GOOD, GOOD], "twice"),
}


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bad_catalog_exits_2_with_one_line(tmp_path, capsys, cli_main, case):
    models, needle = BAD_CASES[case]
    sub = tmp_path / "assets"
    sub.mkdir()
    _write_yup_zforward_glb(tmp_path / "outside.glb")  # exists, but outside the folder
    _write_yup_zforward_glb(sub / "my_car.glb")
    cat = _catalog(sub, models)
    for argv in (["assets", "list", "--catalog", str(cat)],
                 ["assets", "preview", "--catalog", str(cat), "--out", str(tmp_path / "s.png")]):
        rc = cli_main(argv)
        err = capsys.readouterr().err
        assert rc == 2, (case, err)
        lines = err.strip().splitlines()
        assert len(lines) == 1, err
        assert "catalog.yaml" in lines[0] and needle in lines[0], lines[0]
    assert not (tmp_path / "s.png").exists()


@pytest.mark.parametrize(
    "colors, needle",
    [
        ([{"name": "red", "rgb": [0.6, 0.05, 0.05], "weight": -1}], "weight"),
        ([{"name": "red", "rgb": [255, 0, 0]}], "rgb"),
        ([], "colors"),
    ],
)
def test_bad_colours_exit_2(tmp_path, capsys, cli_main, colors, needle):
    cat = _catalog(tmp_path, [GOOD], colors=colors)
    assert cli_main(["assets", "list", "--catalog", str(cat)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0]


def test_missing_catalog_and_bad_yaml_exit_2(tmp_path, capsys, cli_main):
    assert cli_main(["assets", "list", "--catalog", str(tmp_path / "none.yaml")]) == 2
    bad = tmp_path / "bad.yaml"
    bad.write_text("models: [\n  - {name: a\n")
    assert cli_main(["assets", "list", "--catalog", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all("error" in e for e in err)


def test_list_prints_the_table(capsys, cli_main):
    assert cli_main(["assets", "list"]) == 0
    out = capsys.readouterr().out
    for name in ("hatchback", "campervan", "box_truck_large", "large-vehicle", "length_m"):
        assert name in out


def test_preview_writes_a_png_of_every_variant(tmp_path, capsys, cli_main):
    import cv2

    _write_yup_zforward_glb(tmp_path / "my_car.glb")
    cat = _catalog(tmp_path, [GOOD, _mesh_entry()],
                   colors=COLORS + [{"name": "white", "rgb": [0.8, 0.8, 0.8], "weight": 2}])
    out = tmp_path / "sheet.png"
    assert cli_main(["assets", "preview", "--catalog", str(cat), "--out", str(out),
                     "--gsd", "0.08"]) == 0
    img = cv2.imread(str(out))
    assert img is not None and img.shape[0] > 50 and img.shape[1] > 100
    assert "4 variants" in capsys.readouterr().out
    assert not list(tmp_path.glob(".sheet.png.*"))  # no temp file left behind
