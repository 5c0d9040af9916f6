"""Scene CLI: happy paths and one-line errors with exit status 2."""

from __future__ import annotations

import pytest

from .conftest import quad_yup, write_glb


def _one_error_line(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("aerial-synth: error: ")
    return err[0]


def test_list(cli_main, capsys):
    assert cli_main(["scene", "list"]) == 0
    out = capsys.readouterr().out
    assert "city_park" in out and "highway" in out and "suburb" in out
    # every bundled spec is listed with its generator and size: none reads as invalid
    # (city_dense_2km, sized by size_km, used to read "(unreadable spec)")
    from aerial_synth.scene import list_scenes

    lines = out.splitlines()
    assert len(lines) == len(list_scenes())
    assert not [ln for ln in lines if "invalid" in ln or "unreadable" in ln], out
    dense = next(ln for ln in lines if ln.startswith("city_dense_2km "))
    assert "city, 2000 m x 2000 m, seed 11" in dense


def test_show_and_export(cli_main, tmp_path, capsys):
    glb = write_glb(
        tmp_path / "small.glb",
        [("road", *quad_yup(-20, 20, -4, 4), None), ("grass", *quad_yup(-20, 20, 4, 20), None)],
    )
    png = tmp_path / "map.png"
    assert cli_main(["scene", "show", str(glb), "--out", str(png), "--m-per-px", "0.25"]) == 0
    import cv2

    img = cv2.imread(str(png))
    assert img.shape == (96, 160, 3)
    out = tmp_path / "again.glb"
    assert cli_main(["scene", "export", str(glb), "--out", str(out)]) == 0
    assert out.stat().st_size > 0
    assert not list(tmp_path.glob(".*.tmp"))


def _bad_cases(tmp_path):
    corrupt = tmp_path / "corrupt.glb"
    corrupt.write_bytes(b"glTF\x02\x00\x00\x00garbage-not-a-real-glb" * 3)
    unsupported = tmp_path / "scene.fbx"
    unsupported.write_bytes(b"x")
    good = write_glb(tmp_path / "ok.glb", [("road", *quad_yup(0, 10, 0, 10), None)])
    broken_rules = tmp_path / "broken.yaml"
    broken_rules.write_text("rules: [ {match: road*, label: road\n  - oops: [\n")
    no_road = write_glb(tmp_path / "meadow.glb", [("grass", *quad_yup(0, 10, 0, 10), None)])
    return {
        "missing": (["scene", "show", str(tmp_path / "nope.glb")], "nope.glb"),
        "unsupported": (["scene", "show", str(unsupported)], "scene.fbx"),
        "corrupt": (["scene", "show", str(corrupt)], "corrupt.glb"),
        "broken_yaml": (["scene", "show", str(good), "--labels", str(broken_rules)], "broken.yaml"),
        "no_road": (["scene", "show", str(no_road)], "meadow.glb"),
        "unknown_name": (["scene", "show", "atlantis"], "atlantis"),
        "bad_label": (["scene", "export", str(good), "--labels", str(tmp_path / "lab.yaml")], "lab.yaml"),
    }


@pytest.mark.parametrize(
    "case",
    ["missing", "unsupported", "corrupt", "broken_yaml", "no_road", "unknown_name", "bad_label"],
)
def test_bad_input_exit_2_one_line(cli_main, tmp_path, capsys, case):
    (tmp_path / "lab.yaml").write_text("rules: [{match: 'road*', label: highway_lane}]\n")
    argv, must_name = _bad_cases(tmp_path)[case]
    out = tmp_path / ("x.glb" if argv[1] == "export" else "x.png")
    assert cli_main(argv + ["--out", str(out)]) == 2
    line = _one_error_line(capsys)
    assert must_name in line, line
    assert not out.exists()
