"""``aerial-synth place`` with the parking scenarios: output and bad input (one line, exit 2,
nothing written)."""

from __future__ import annotations

import json

import pytest

from aerial_synth.cli import main


def _one_error_line(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("aerial-synth: error:"), err[0]
    return err[0]


@pytest.fixture(scope="module")
def small_lot_spec(tmp_path_factory):
    """A small suburb (2 x 2 blocks) with one lot: quick to build."""
    p = tmp_path_factory.mktemp("spec") / "small.yaml"
    p.write_text(
        "name: small\ngenerator: suburb\nseed: 2\nsize_m: [200, 200]\n"
        "grid: {blocks_x: 2, blocks_y: 2, street_width_m: 7.5, sidewalk_m: 2.0, jitter_m: 0}\n"
        "parking_lots:\n  - {center: [50, 50], size_m: [40, 36], layout: {angle_deg: 60}}\n"
        "houses: {driveway_prob: 0.5}\n", encoding="utf-8")
    return p


def test_place_parking_writes_parked_vehicles(small_lot_spec, tmp_path, capsys):
    out = tmp_path / "o"
    rc = main(["place", "--scene", str(small_lot_spec), "--scenario", "parking", "--seed", "1",
               "--no-png", "--out", str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "parked" in text and "in bay 100.0 %" in text and "overlaps 0" in text
    d = json.loads((out / "placement.json").read_text())
    vs = d["vehicles"]
    assert vs and {v["state"] for v in vs} == {"parked"}
    assert all(v["lot"] == 0 and v["kerb"] == -1 and v["bay"] >= 0 for v in vs)
    assert d["stats"]["lots"][0]["layout_source"] == "scene"
    assert d["stats"]["parking_validation"]["in_bay_fraction"] == 1.0


@pytest.mark.parametrize("args, words", [
    (["--set", "parking.occupancy_mean=1.5"], "--set parking.occupancy_mean: expected a finite number >= 0"),
    (["--set", "parking.occupancy_mean=-0.2"], "--set parking.occupancy_mean"),
    (["--set", "parking.mix.tank=1"], "parking.mix.tank: unknown class or model"),
    (["--set", "parking.layout.angle_deg=30"], "parking.layout.angle_deg: expected one of 90, 60, 45, 0"),
])
def test_bad_parking_input_one_line_exit_2(small_lot_spec, tmp_path, capsys, args, words):
    out = tmp_path / "o"
    rc = main(["place", "--scene", str(small_lot_spec), "--scenario", "parking", "--no-png",
               "--out", str(out)] + args)
    assert rc == 2
    assert words in _one_error_line(capsys)
    assert not (out / "placement.json").exists()


def test_bay_larger_than_its_lot_one_line_exit_2(tmp_path, capsys):
    spec = tmp_path / "bad.yaml"
    spec.write_text("name: bad\ngenerator: suburb\nseed: 1\nsize_m: [200, 200]\n"
                    "grid: {blocks_x: 2, blocks_y: 2}\n"
                    "parking_lots:\n  - {center: [50, 50], size_m: [12, 8]}\n", encoding="utf-8")
    out = tmp_path / "o"
    rc = main(["place", "--scene", str(spec), "--scenario", "parking", "--no-png", "--out", str(out)])
    assert rc == 2
    line = _one_error_line(capsys)
    assert "parking_lots[0].layout" in line and "needs a lot of at least 14.5 x 11.0 m, got 12 x 8 m" in line
    assert not (out / "placement.json").exists()
