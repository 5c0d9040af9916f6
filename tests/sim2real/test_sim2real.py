"""sim2real without torch: bad input (one line, exit 2, nothing written), the missing extra,
tiles mapped back to the original frame, the rotated-NMS merge, prediction files."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from aerial_synth.cli import main
from aerial_synth.evaluate.ap import Detections, pairwise_iou
from aerial_synth.evaluate.evaluation import read_task1_folder
from aerial_synth.evaluate.scoring import ScoringOptions, score
from aerial_synth.sim2real import ultra
from aerial_synth.sim2real.config import Sim2RealError, inspect_synthetic, parse_arm, parse_arms
from aerial_synth.sim2real.pipeline import write_task1
from aerial_synth.sim2real.real import (
    merge_tiles,
    plan_image,
    read_real,
    rotated_nms,
    tile_to_original,
)
from aerial_synth.sim2real.report import ARM_FIELDS, REPORT_FIELDS, summary_text

from ..helpers import REPO
from .conftest import box, rect, write_real, write_synthetic

# -- the optional extra ------------------------------------------------------------------------


def test_without_ultralytics_one_line_and_exit_2(tmp_path):
    syn = write_synthetic(tmp_path / "syn")
    real = write_real(tmp_path / "real", "a", [box(10, 10, 30, 20)])
    out = tmp_path / "out"
    code = ("import sys; sys.modules['ultralytics'] = None; from aerial_synth.cli import main; "
            f"sys.exit(main(['sim2real', '--synthetic', {str(syn)!r}, '--real', {str(real)!r}, "
            f"'--out', {str(out)!r}]))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                       cwd=REPO)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "pip install 'aerial-synth[train]'" in lines[0]
    assert "missing: ultralytics" in lines[0]
    assert not out.exists()


def test_missing_packages_is_read_without_importing(monkeypatch):
    monkeypatch.setitem(sys.modules, "ultralytics", None)
    assert "ultralytics" in ultra.missing_packages()
    with pytest.raises(Sim2RealError, match=r"pip install 'aerial-synth\[train\]'"):
        ultra.require_train_extra()


# -- bad input ----------------------------------------------------------------------------------


@pytest.fixture
def extra_present(monkeypatch):
    """Pretend the [train] extra is installed: every check before training still runs."""
    monkeypatch.setattr(ultra, "require_train_extra", lambda: None)


def _run(capsys, *args):
    rc = main(["sim2real", *map(str, args)])
    return rc, capsys.readouterr().err.strip().splitlines()


def test_real_without_gsd_header_names_the_file(tmp_path, capsys, extra_present):
    syn = write_synthetic(tmp_path / "syn", gsd=0.25)
    real = write_real(tmp_path / "real", "nogsd", [box(10, 10, 30, 20)], header=False)
    out = tmp_path / "out"
    rc, err = _run(capsys, "--synthetic", syn, "--real", real, "--out", out)
    assert rc == 2 and len(err) == 1
    assert "nogsd.txt" in err[0] and "gsd:" in err[0] and "--real-gsd" in err[0]
    assert not out.exists()


def test_native_scale_needs_no_gsd_and_keeps_pixels(tmp_path, capsys, extra_present):
    """--real-scale native plans the real images at their own pixels (no gsd: header needed);
    arm,native plans both; a bad value is one line and exit 2."""
    from aerial_synth.sim2real.config import Sim2RealConfig
    from aerial_synth.sim2real.pipeline import check_inputs

    syn = write_synthetic(tmp_path / "syn", gsd=0.25)
    real = write_real(tmp_path / "real", "nogsd", [box(10, 10, 30, 20)], header=False)
    cfg = Sim2RealConfig(arms=parse_arms([str(syn)]), real=real, out=tmp_path / "o", epochs=1,
                         real_scale=("native",))
    plans = check_inputs(cfg)[4]
    assert list(plans) == [None] and plans[None][0].scale == (1.0, 1.0)
    assert plans[None][0].scaled_wh == plans[None][0].size_wh
    cfg = Sim2RealConfig(arms=parse_arms([str(syn)]), real=real, out=tmp_path / "o", epochs=1,
                         real_scale="arm,native", real_gsd=0.125)
    plans = check_inputs(cfg)[4]
    assert list(plans) == [None, 0.25]
    assert plans[0.25][0].scale == (0.5, 0.5) and plans[None][0].scale == (1.0, 1.0)
    rc, err = _run(capsys, "--synthetic", syn, "--real", real, "--out", tmp_path / "o2",
                   "--real-scale", "arm,nat")
    assert rc == 2 and len(err) == 1 and "--real-scale" in err[0] and "'arm,nat'" in err[0]
    assert not (tmp_path / "o2").exists()


def test_real_image_without_labels(tmp_path, capsys, extra_present):
    syn = write_synthetic(tmp_path / "syn")
    real = write_real(tmp_path / "real", "a", [box(10, 10, 30, 20)])
    (real / "images" / "unlabelled.png").write_bytes((real / "images" / "a.png").read_bytes())
    out = tmp_path / "out"
    rc, err = _run(capsys, "--synthetic", syn, "--real", real, "--out", out)
    assert rc == 2 and len(err) == 1
    assert "unlabelled.png has no label file" in err[0]
    assert not out.exists()


def test_synthetic_without_yolo_obb(tmp_path, capsys, extra_present):
    syn = tmp_path / "syn"
    (syn / "dota" / "train" / "labelTxt").mkdir(parents=True)
    real = write_real(tmp_path / "real", "a", [box(10, 10, 30, 20)])
    out = tmp_path / "out"
    rc, err = _run(capsys, "--synthetic", f"x={syn}", "--real", real, "--out", out)
    assert rc == 2 and len(err) == 1
    assert "expected a YOLO-OBB dataset" in err[0] and "--format yolo-obb" in err[0]
    assert not out.exists()


def test_arm_name_given_twice(tmp_path, capsys, extra_present):
    a, b = write_synthetic(tmp_path / "a"), write_synthetic(tmp_path / "b")
    real = write_real(tmp_path / "real", "r", [box(10, 10, 30, 20)])
    out = tmp_path / "out"
    rc, err = _run(capsys, "--synthetic", f"same={a}", "--synthetic", f"same={b}", "--real", real, "--out", out)
    assert rc == 2 and len(err) == 1 and "arm name 'same' given twice" in err[0]
    assert not out.exists()


@pytest.mark.parametrize("extra, msg", [
    (["--model", "yolo11n-obb.pt"], "--model: expected a model yaml"),
    (["--weights", "nowhere.pt"], "--weights nowhere.pt: no such file"),
    (["--overlap", "700"], "--overlap: expected 0 <= overlap < --tile"),
    (["--imgsz", "100"], "--imgsz: expected a multiple of 32"),
    (["--ignore-border", "nogroup=4"], "no group 'nogroup'"),
])
def test_other_bad_options(tmp_path, capsys, extra_present, extra, msg):
    syn = write_synthetic(tmp_path / "syn")
    real = write_real(tmp_path / "real", "r", [box(10, 10, 30, 20)])
    out = tmp_path / "out"
    rc, err = _run(capsys, "--synthetic", syn, "--real", real, "--out", out, *extra)
    assert rc == 2 and len(err) == 1 and msg in err[0], err
    assert not out.exists()


def test_synthetic_image_without_label_and_gsd_from_metadata(tmp_path):
    syn = write_synthetic(tmp_path / "syn", manifest=False)
    s = inspect_synthetic(syn, "--synthetic x=")
    assert (s.n_train, s.n_val, s.names, s.gsd_m) == (2, 1, ("small-vehicle", "large-vehicle"), None)
    (syn / "manifest.json").write_text('{"parameters": {"gsd_m": null}}')
    (syn / "meta").mkdir()
    for i, g in enumerate((0.1, 0.1, 0.3)):
        (syn / "meta" / f"{i}.json").write_text(f'{{"gsd_m": {g}}}')
    assert inspect_synthetic(syn, "--synthetic x=").gsd_m == pytest.approx(0.1)
    (syn / "yolo-obb" / "labels" / "train" / "train0.txt").unlink()
    with pytest.raises(Sim2RealError, match="train0.png has no label file"):
        inspect_synthetic(syn, "--synthetic x=")


def test_arm_parsing(tmp_path):
    assert parse_arm(f"traffic={tmp_path}/a,{tmp_path}/b").dirs == (tmp_path / "a", tmp_path / "b")
    assert parse_arm(str(tmp_path / "exp1")).name == "exp1"
    assert [a.name for a in parse_arms(["x=1", "y=2"])] == ["x", "y"]
    with pytest.raises(Sim2RealError, match="at least one"):
        parse_arms([])


# -- tiles back to the original frame, merged without duplicates ----------------------------------


def test_tile_to_original_inverts_scale_and_offset():
    xy = rect(40.0, 30.0, 12, 5, 20)[None]
    scale, tile = (1.25, 1.25), (96, 64, 128, 128)
    in_tile = xy * scale - (96, 64)
    assert np.allclose(tile_to_original(in_tile, tile, scale), xy)


def test_rotated_nms_by_hand():
    a = box(0, 0, 10, 10)
    shifted = box(2, 0, 12, 10)          # IoU 80 / 120 = 0.667 with a
    edge = box(6, 0, 16, 10)             # IoU 40 / 160 = 0.25 with a
    xy = np.stack([a, shifted, edge, a])
    keep = rotated_nms(xy, [0.9, 0.95, 0.5, 0.8], ["car", "car", "car", "truck"], 0.3)
    # by score: shifted (kept), a (IoU 0.667 > 0.3: dropped), truck a (other class: kept),
    # edge (IoU with shifted 60 / 140 = 0.43: dropped)
    assert keep.tolist() == [1, 3]
    keep = rotated_nms(xy[[0, 2]], [0.9, 0.5], ["car", "car"], 0.3)
    assert keep.tolist() == [0, 1]        # 0.25 is not above 0.3
    assert rotated_nms(np.zeros((0, 4, 2)), [], [], 0.3).tolist() == []


def _perfect_tile_predictions(r, truth_xy):
    """What a perfect detector sees in each tile: every truth box wholly inside the tile, in
    tile pixels, score by position (deterministic)."""
    out = []
    scaled = truth_xy * np.asarray(r.scale)
    for (x, y, w, h) in r.tiles:
        inside = (scaled[..., 0].min(1) >= x) & (scaled[..., 0].max(1) <= x + w) & \
                 (scaled[..., 1].min(1) >= y) & (scaled[..., 1].max(1) <= y + h)
        xy = scaled[inside] - (x, y)
        sc = 0.5 + 0.4 * np.linspace(1, 0, len(truth_xy))[inside]
        out.append((xy, sc, ["small-vehicle"] * int(inside.sum())))
    return out


def test_perfect_predictions_through_tiles_score_ap_one(tmp_path):
    # 300 x 200 px at 0.15 m, rescaled to 0.12 m (375 x 250), tiles of 128 with 48 overlap:
    # boxes in tile overlaps are predicted by several tiles and must come back once each
    boxes = [box(70, 70, 86, 78), rect(150, 100, 14, 6, 30), box(250, 20, 262, 30),
             rect(30, 170, 16, 7, -60), box(100, 90, 116, 97)]
    real = write_real(tmp_path / "real", "img", boxes, size=(300, 200), gsd=0.15)
    items = read_real(real, ("small-vehicle", "large-vehicle"))
    r = plan_image(items[0], 0.12, None, 128, 48)
    assert r.scaled_wh == (375, 250) and r.scale == (1.25, 1.25)
    # the devkit's origins: every 128 - 48 = 80 px, the last tile flush with the edge
    assert sorted({t[0] for t in r.tiles}) == [0, 80, 160, 240, 247]
    assert sorted({t[1] for t in r.tiles}) == [0, 80, 122] and len(r.tiles) == 15
    truth = items[0].polygons_xy_px
    per_tile = _perfect_tile_predictions(r, truth)
    assert sum(len(p[1]) for p in per_tile) > len(boxes)  # duplicates across tiles
    xy, sc, cl = merge_tiles(r, per_tile, 0.3)
    assert len(xy) == len(boxes)
    iou = pairwise_iou(xy, truth)
    assert np.allclose(iou.max(1), 1.0) and sorted(iou.argmax(1).tolist()) == list(range(len(boxes)))
    # written as task-1 files and read back as `aerial-synth eval` does: AP 1.0
    write_task1(tmp_path / "pred", ["img"] * len(xy), xy, sc, cl, ["small-vehicle", "large-vehicle"])
    assert (tmp_path / "pred" / "Task1_large-vehicle.txt").read_text() == ""
    dets = read_task1_folder(tmp_path / "pred", {"img": 0})
    res = score(items, dets, ScoringOptions.from_text("vehicle"))
    assert res.overall.ap["vehicle"] == pytest.approx(1.0)
    rc = main(["eval", "--gt", str(real), "--pred", str(tmp_path / "pred"), "--merge-classes", "vehicle"])
    assert rc == 0
    # without the merge the duplicates from overlapping tiles are false positives
    xy2 = np.concatenate([tile_to_original(p[0], t, r.scale) for t, p in zip(r.tiles, per_tile)])
    sc2 = np.concatenate([p[1] for p in per_tile])
    cl2 = ["small-vehicle"] * len(sc2)
    assert len(xy2) > len(boxes)
    res2 = score(items, Detections(np.zeros(len(sc2), np.int64), cl2, sc2, xy2),
                 ScoringOptions.from_text("vehicle"))
    c = res2.overall.per_threshold[0.5]["vehicle"]
    assert c.tp == len(boxes) and c.fp == len(xy2) - len(boxes)


def test_real_classes_must_meet_the_truth(tmp_path):
    real = write_real(tmp_path / "real", "img", [box(10, 10, 30, 20)], ["car"])
    with pytest.raises(Sim2RealError, match="no truth box of the classes small-vehicle,large-vehicle .found car"):
        read_real(real, ("small-vehicle", "large-vehicle"))
    assert read_real(real, ("car",))[0].classes == ["car"]


def test_plan_needs_a_gsd_to_rescale(tmp_path):
    real = write_real(tmp_path / "real", "img", [box(10, 10, 30, 20)], header=False)
    g = read_real(real, None)[0]
    with pytest.raises(Sim2RealError, match="--real-gsd"):
        plan_image(g, 0.12, None, 128, 32)
    r = plan_image(g, 0.12, 0.24, 128, 32)
    assert r.scaled_wh == (600, 400)
    r = plan_image(g, None, None, 128, 32)
    assert r.scale == (1.0, 1.0)


# -- the report text -------------------------------------------------------------------------------


def test_summary_text_lists_every_arm_and_group():
    arm = {k: None for k in ARM_FIELDS}
    arm.update(name="traffic", training_images=10, epochs=3, seconds=12.5, synthetic_val_map50=0.5,
               real_ap50=0.25, real_recall=0.5,
               real={"per_group": {"minsk": {"ap50": 0.3, "recall": 0.6}, "vedai": {"ap50": None, "recall": 0.0}}})
    native = {"ap50": 0.0625, "recall": 0.25,
              "real": {"per_group": {"minsk": {"ap50": 0.5, "recall": 0.75}, "vedai": {"ap50": None, "recall": 0.0}}}}
    arm["real_by_scale"] = {"arm": {"ap50": 0.25, "recall": 0.5, "real": arm["real"]}, "native": native}
    report = {k: None for k in REPORT_FIELDS}
    report.update(parameters={"real_scale": ["arm", "native"]},
                  arms=[arm, dict(arm, name="random", real_ap50=0.125)],
                  device={"name": "CPU: test", "used": "cpu"},
                  versions={"aerial_synth": "0", "ultralytics": "8.4.190", "torch": "2"},
                  real={"dir": "r", "images": 3, "vehicles": 9}, scoring={"iou_type_by_group": {}})
    text = summary_text(report)
    assert "traffic" in text and "random" in text and "0.125" in text
    assert "minsk" in text and "0.300/0.60" in text and "-/0.00" in text
    head, native_part = text.split("--real-scale native")
    assert "--real-scale arm" in head and "0.062" not in head
    assert native_part.count("0.062") == 2 and native_part.count("0.500/0.75") == 2


def test_real_scale_option():
    from aerial_synth.sim2real.config import parse_real_scale

    assert parse_real_scale("arm") == ("arm",)
    assert parse_real_scale("native,arm") == ("native", "arm")
    for bad in ("", "arm,arm", "gsd", "arm,"):
        with pytest.raises(Sim2RealError, match="--real-scale"):
            parse_real_scale(bad)
    from aerial_synth.sim2real.config import Sim2RealConfig

    arms = parse_arms(["x=d"])
    assert Sim2RealConfig(arms=arms, real="r", out="o", epochs=1, real_scale=["native", "arm"]).real_scale == (
        "native", "arm")
    for bad in (5, None, ["arm", 1]):
        with pytest.raises(Sim2RealError, match="--real-scale"):
            Sim2RealConfig(arms=arms, real="r", out="o", epochs=1, real_scale=bad)
