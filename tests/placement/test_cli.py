"""``aerial-synth place`` end to end on small scenes, and its bad-input handling."""

import json

import pytest

from aerial_synth.cli import main
from aerial_synth.scene.io import export_glb

from . import layouts


@pytest.fixture(scope="module")
def straight_glb(tmp_path_factory):
    p = tmp_path_factory.mktemp("scenes") / "straight.glb"
    export_glb(layouts.straight(length=200.0), p)
    return p


def _one_error_line(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(("aerial-synth: error:", "aerial-synth place: ")), err[0]
    return err[0]


def test_place_writes_json_png_and_summary(straight_glb, tmp_path, capsys):
    out = tmp_path / "out"
    rc = main(["place", "--scenario", "jam", "--scene", str(straight_glb), "--seed", "2",
               "--lines", "4", "--out", str(out)])
    assert rc == 0
    d = json.loads((out / "placement.json").read_text())
    assert d["scenario"] == "jam" and d["seed"] == 2 and len(d["vehicles"]) > 10
    assert d["parameters"]["spacing"]["mean_m"] == 10.4
    assert (out / "placement.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = capsys.readouterr().out
    assert "vehicles" in text and "spacing m: mean" in text and "overlaps 0" in text
    # the same seed again: byte-identical placement.json
    out2 = tmp_path / "out2"
    assert main(["place", "--scenario", "jam", "--scene", str(straight_glb), "--seed", "2",
                 "--lines", "4", "--out", str(out2), "--no-png"]) == 0
    assert (out / "placement.json").read_bytes() == (out2 / "placement.json").read_bytes()


def test_overrides_from_the_cli(straight_glb, tmp_path):
    out = tmp_path / "o"
    assert main(["place", "--scenario", "normal", "--scene", str(straight_glb), "--lines", "2",
                 "--set", "spacing.mean_m=20", "--set", "double_lane_probability=0",
                 "--traffic", "left", "--out", str(out), "--no-png"]) == 0
    d = json.loads((out / "placement.json").read_text())
    assert d["parameters"]["spacing"]["mean_m"] == 20
    assert d["parameters"]["traffic"] == "left"
    assert all(v["lane"] == 0 for v in d["vehicles"])


@pytest.mark.parametrize(
    "extra, needle",
    [
        (["--scenario", "gridlock"], "unknown scenario 'gridlock'"),
        (["--set", "spacing.min_m=30"], "d_min"),
        (["--set", "spacing.sd_m=-0.5"], "sd_m"),
        (["--set", "spacing"], "KEY=VALUE"),
        (["--vehicles", "0"], "--vehicles"),
    ],
)
def test_bad_input_one_line_exit_2(straight_glb, tmp_path, capsys, extra, needle):
    out = tmp_path / "bad"
    args = ["place", "--scene", str(straight_glb), "--out", str(out), "--no-png"]
    if "--scenario" not in extra:
        args += ["--scenario", "jam"]
    rc = main(args + extra)
    assert rc == 2
    assert needle in _one_error_line(capsys)
    assert not out.exists()


def test_scene_whose_traces_find_no_road(tmp_path, capsys):
    glb = tmp_path / "hidden.glb"
    export_glb(layouts.hidden_road(), glb)
    out = tmp_path / "o"
    rc = main(["place", "--scenario", "jam", "--scene", str(glb), "--out", str(out)])
    assert rc == 2
    line = _one_error_line(capsys)
    assert "found no road" in line and "hidden" in line
    assert not out.exists()


def test_too_many_vehicles_places_what_fits_and_warns(tmp_path, capsys):
    glb = tmp_path / "short.glb"
    export_glb(layouts.dead_end(length=60.0), glb)
    out = tmp_path / "o"
    rc = main(["place", "--scenario", "jam", "--scene", str(glb), "--vehicles", "3000",
               "--out", str(out), "--no-png"])
    assert rc == 0
    cap = capsys.readouterr()
    assert "warning" in cap.err and "3000" in cap.err
    d = json.loads((out / "placement.json").read_text())
    assert 0 < len(d["vehicles"]) < 30
    assert d["stats"]["shortfall"] == 3000 - len(d["vehicles"])
