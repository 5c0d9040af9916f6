"""``aerial-synth place`` end to end on small scenes, and its bad-input handling."""

import json
import os

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
    assert "footprint on drivable 100.0 %" in text
    assert d["stats"]["validation"]["footprint_drivable"] == 1.0
    # the versions that produced it, read from the installed distributions
    import numpy
    import shapely

    from aerial_synth import __version__

    v = d["versions"]
    assert v["aerial-synth"] == __version__ and v["numpy"] == numpy.__version__
    assert v["shapely"] == shapely.__version__
    assert set(v) >= {"open3d", "opencv-python-headless", "trimesh"}
    assert d["georeference"] == {"origin": [0.0, 0.0, 0.0], "crs": None}
    assert all(v["x_orig_m"] == v["x_m"] and v["y_orig_m"] == v["y_m"] for v in d["vehicles"])
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


BAD_INPUTS = [
    (["--scenario", "gridlock"], "unknown scenario 'gridlock': expected one of jam, mixed, multilane, normal"),
    (["--set", "spacing.min_m=30"], "--set spacing: d_min (30 m) must not exceed d_max (23.5 m)"),
    (["--set", "spacing.sd_m=-0.5"], "--set spacing.sd_m: expected a finite number > 0, got -0.5"),
    (["--set", "spacing"], "--set 'spacing': expected KEY=VALUE"),
    (["--set", "spacing.mean_m=abc"], "--set spacing.mean_m: expected a finite number > 0, got 'abc'"),
    (["--set", "spacing.mean_m=nan"], "--set spacing.mean_m: expected a finite number > 0, got 'nan'"),
    (["--set", "spacing.mean_m=inf"], "--set spacing.mean_m: expected a finite number > 0, got 'inf'"),
    (["--set", "spacing.bogus_m=1"], "--set spacing.bogus_m: unknown key; expected one of skewness, "
                                     "mean_m, sd_m, min_m, max_m, floor_m"),
    (["--set", "spacing=[1,2]"], "--set spacing: expected a mapping of key: value, got [1, 2]"),
    (["--set", "vehicles_per_line.mean=-3"], "--set vehicles_per_line.mean: expected a finite number > 0"),
    (["--set", "gap_m=.nan"], "--set gap_m: expected a finite number >= 0 and <= 10, got nan"),
    (["--vehicles", "0"], "--vehicles: expected an integer >= 1 and <= 10000000, got '0'"),
    (["--vehicles", "-5"], "--vehicles: expected an integer >= 1"),
    (["--vehicles", "1e3"], "--vehicles: expected an integer >= 1"),
    (["--lines", "0"], "--lines: expected an integer >= 1 and <= 1000000, got '0'"),
    (["--seed", "-1"], "--seed: expected a non-negative integer, got '-1'"),
    (["--seed", "1.5"], "--seed: expected a non-negative integer, got '1.5'"),
    (["--seed", "abc"], "--seed: expected a non-negative integer, got 'abc'"),
    (["--gap", "nan"], "--gap: expected a finite number >= 0 and <= 10, got 'nan'"),
    (["--gap", "-0.5"], "--gap: expected a finite number >= 0 and <= 10, got '-0.5'"),
    (["--gap", "11"], "--gap: expected a finite number >= 0 and <= 10, got '11'"),
    (["--lane-offset", "0"], "--lane-offset: expected a finite number > 0 and <= 50, got '0'"),
    (["--lane-offset", "inf"], "--lane-offset: expected a finite number > 0 and <= 50, got 'inf'"),
    (["--lane-offset", "x"], "--lane-offset: expected a finite number > 0 and <= 50, got 'x'"),
    (["--m-per-px", "0"], "--m-per-px: expected a finite number >= 0.01 and <= 100, got '0'"),
    (["--m-per-px", "nan"], "--m-per-px: expected a finite number >= 0.01 and <= 100, got 'nan'"),
    (["--m-per-px", "0.01"], "--m-per-px: expected at least 0.0"),  # 200 m scene: 2e4 px
    (["--traffic", "middle"], "--traffic: expected one of right, left, got 'middle'"),
    (["--vehicles", "5", "--lines", "2"], "not allowed with argument"),
]


@pytest.mark.parametrize("extra, needle", BAD_INPUTS, ids=[" ".join(b[0]) for b in BAD_INPUTS])
def test_bad_input_one_line_exit_2(straight_glb, tmp_path, capsys, extra, needle):
    out = tmp_path / "bad"
    args = ["place", "--scene", str(straight_glb), "--out", str(out)]
    if "--m-per-px" not in extra:
        args += ["--no-png"]
    if "--scenario" not in extra:
        args += ["--scenario", "jam"]
    rc = main(args + extra)
    assert rc == 2
    assert needle in _one_error_line(capsys)
    assert not out.exists()


def _fifo(path):
    os.mkfifo(path)
    return path


def _chardev(path):
    import stat

    try:
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 3))  # a private /dev/null twin
    except (PermissionError, OSError):
        pytest.skip("mknod of a character device is not allowed here")
    return path


@pytest.mark.parametrize(
    "make, needle",
    [
        (lambda d: (d / "afile").write_text("keep") and d / "afile", "expected a folder, found a file"),
        (lambda d: (d / "afile").write_text("keep") and d / "afile" / "sub", "found a file"),
        (lambda d: _fifo(d / "fifo"), "expected a folder, found a FIFO"),
        (lambda d: _chardev(d / "null"), "expected a folder, found a character device"),
    ],
    ids=["file", "below-a-file", "fifo", "chardev"],
)
def test_out_that_is_not_a_folder_is_refused_before_any_work(straight_glb, tmp_path, capsys, make, needle):
    target = make(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    rc = main(["place", "--scene", str(straight_glb), "--out", str(target), "--lines", "1"])
    assert rc == 2
    line = _one_error_line(capsys)
    assert line.startswith(f"aerial-synth: error: --out {target}: ") and needle in line
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    if (tmp_path / "afile").exists():
        assert (tmp_path / "afile").read_text() == "keep"


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write into a read-only folder")
def test_read_only_out_is_refused(straight_glb, tmp_path, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        rc = main(["place", "--scene", str(straight_glb), "--out", str(ro / "x"), "--lines", "1"])
        assert rc == 2
        assert "not writable" in _one_error_line(capsys)
        assert list(ro.iterdir()) == []
    finally:
        ro.chmod(0o755)


def test_failed_run_leaves_an_existing_output_as_it_was(straight_glb, tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["place", "--scene", str(straight_glb), "--lines", "2", "--out", str(out), "--no-png"]) == 0
    before = (out / "placement.json").read_bytes()
    capsys.readouterr()
    rc = main(["place", "--scene", str(straight_glb), "--out", str(out), "--set", "gap_m=.nan"])
    assert rc == 2
    _one_error_line(capsys)
    assert sorted(p.name for p in out.iterdir()) == ["placement.json"]
    assert (out / "placement.json").read_bytes() == before


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
