"""aerial-synth eval end to end: DOTA task-1 and YOLO-OBB predictions, the report, bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from aerial_synth.cli import main
from aerial_synth.evaluate.evaluation import run_eval
from aerial_synth.evaluate.labels import image_size
from aerial_synth.formats import dota

from .conftest import make_dota, rect, write_dota_image


def task1_from_gt(gt_dir, pred_dir, drop=(), shift=0.0):
    """Task1_<class>.txt files that repeat the ground truth (minus ``drop`` image names)."""
    pred_dir.mkdir(parents=True, exist_ok=True)
    files = {}
    k = 0
    for p in sorted((gt_dir / "labelTxt").glob("*.txt")):
        lab = dota.read_labels(p)
        polys, cls = lab.polygons_xy_px, lab.classes
        if p.stem in drop:
            continue
        for poly, c in zip(polys, cls):
            k += 1
            xy = " ".join(f"{v + shift:.3f}" for v in poly.reshape(-1))
            files.setdefault(c, []).append(f"{p.stem} {1.0 - 0.001 * k:.4f} {xy}")
    for c, lines in files.items():
        (pred_dir / f"Task1_{c}.txt").write_text("\n".join(lines) + "\n")
    return pred_dir


def test_task1_predictions_end_to_end(tmp_path, capsys):
    gt = make_dota(tmp_path / "gt", 5, per_image=4)
    pred = task1_from_gt(gt, tmp_path / "pred")
    out = tmp_path / "report"
    assert main(["eval", "--gt", str(gt), "--pred", str(pred), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "mAP" in text and "1.0000" in text
    data = json.loads((out / "eval.json").read_text())
    assert data["map"] == 1.0 and data["metric"] == "voc07" and data["n_images"] == 5
    assert set(data["ap"]) == {"small-vehicle", "large-vehicle"}
    assert sorted(p.name for p in out.iterdir()) == [
        "eval.json", "pr_large-vehicle.png", "pr_small-vehicle.png", "summary.txt"]
    # drop the predictions of one image: recall falls to the share of boxes left
    pred2 = task1_from_gt(gt, tmp_path / "pred2", drop={"img000"})
    res = run_eval(gt, pred2, metric="all-point")
    n_all = sum(r.n_gt for r in res.per_threshold[0.5].values())
    n_tp = sum(r.tp for r in res.per_threshold[0.5].values())
    assert n_all == 20 and n_tp == 16
    # coco: a 1 px shift of 20 x 9 boxes costs IoU at the high thresholds only
    pred3 = task1_from_gt(gt, tmp_path / "pred3", shift=1.0)
    coco = run_eval(gt, pred3, metric="coco").to_dict()
    assert coco["map50"] == 1.0 and coco["map"] < 1.0


def test_yolo_obb_predictions_use_image_sizes(tmp_path):
    gt = tmp_path / "gt"
    boxes = [rect(50, 40, 24, 10, 30), rect(150, 100, 30, 14, -50)]
    write_dota_image(gt, "a", boxes, ["small-vehicle", "large-vehicle"], size=(240, 180))
    assert image_size(gt / "images" / "a.png") == (240, 180)
    pred = tmp_path / "predict" / "labels"
    pred.mkdir(parents=True)
    lines = []
    for k, (b, conf) in enumerate(zip(boxes, (0.9, 0.8))):
        q = (b / (240, 180)).reshape(-1)
        lines.append(f"{k} " + " ".join(f"{v:.6f}" for v in q) + f" {conf}")
    lines.append("0 " + " ".join(f"{v:.6f}" for v in (rect(200, 20, 20, 9) / (240, 180)).reshape(-1)) + " 0.95")
    (pred / "a.txt").write_text("\n".join(lines) + "\n")
    res = run_eval(gt, tmp_path / "predict", metric="all-point", names="small-vehicle,large-vehicle")
    # small-vehicle: a false positive above the true positive -> precision 1/2 at recall 1
    assert res.ap["small-vehicle"] == pytest.approx(0.5)
    assert res.ap["large-vehicle"] == pytest.approx(1.0)
    yaml = tmp_path / "data.yaml"
    yaml.write_text("names:\n  0: small vehicle\n  1: large vehicle\n")  # spaces -> hyphens
    res2 = run_eval(gt, tmp_path / "predict", metric="all-point", names=str(yaml))
    assert res2.ap == res.ap


def test_devkit_style_gt_without_header_and_difficult_two(tmp_path):
    gt = tmp_path / "gt"
    write_dota_image(gt, "a", [rect(40, 40, 20, 9), rect(120, 40, 20, 9)], difficult=[0, 2], header=False)
    pred = tmp_path / "pred"
    pred.mkdir()
    (pred / "Task1_small-vehicle.txt").write_text(
        "a 0.9 " + " ".join(f"{v:.2f}" for v in rect(40, 40, 20, 9).reshape(-1)) + "\n")
    res = run_eval(gt, pred)
    r = res.per_threshold[0.5]["small-vehicle"]
    assert (r.n_gt, r.n_difficult, r.tp) == (1, 1, 1)


def _run(capsys, argv):
    rc = main(argv)
    err = capsys.readouterr().err
    return rc, err


@pytest.fixture
def case(tmp_path):
    gt = make_dota(tmp_path / "gt", 3)
    pred = task1_from_gt(gt, tmp_path / "pred")
    return tmp_path, gt, pred


def test_bad_input_one_line_exit_2_nothing_written(case, capsys):
    tmp, gt, pred = case
    out = tmp / "report"
    base = ["eval", "--gt", str(gt), "--pred", str(pred), "--out", str(out)]

    def refused(argv, *needles):
        rc, err = _run(capsys, argv)
        assert rc == 2, err
        assert err.count("\n") == 1, err
        for n in needles:
            assert n in err, err
        assert not out.exists()

    # a prediction naming an image that is not in the ground truth
    f = pred / "Task1_small-vehicle.txt"
    good = f.read_text()
    f.write_text(good + "nosuch 0.5 0 0 10 0 10 5 0 5\n")
    n = good.count("\n") + 1
    refused(base, f"Task1_small-vehicle.txt:{n}: image 'nosuch' is not in the ground truth")
    # malformed lines: file and line number named
    f.write_text(good + "img000 0.5 0 0 10 0 10 5\n")
    refused(base, f"Task1_small-vehicle.txt:{n}: expected 'image score x1 y1", "got 8 fields")
    f.write_text(good + "img000 high 0 0 10 0 10 5 0 5\n")
    refused(base, f"Task1_small-vehicle.txt:{n}: expected score as a finite number, got 'high'")
    f.write_text(good + "img000 0.5 0 0 10 0 nan 5 0 5\n")
    refused(base, f"Task1_small-vehicle.txt:{n}: expected coordinate 5 as a finite number")
    f.write_text(good)
    g = gt / "labelTxt" / "img001.txt"
    gtext = g.read_text()
    g.write_text(gtext + "1 2 3 4 5 6 small-vehicle 0\n")
    refused(base, f"img001.txt:{gtext.count(chr(10)) + 1}: expected 'x1 y1 x2 y2 x3 y3 x4 y4 category")
    g.write_text(gtext + "1 2 3 4 5 6 7 8 small-vehicle yes\n")
    refused(base, "expected difficult as an integer (0 or 1), got 'yes'")
    g.write_text(gtext.replace("gsd:0.12", "gsd:abc"))
    refused(base, "img001.txt:2: expected gsd as a number, got 'abc'")
    g.write_text(gtext)
    # an empty ground-truth folder
    empty = tmp / "empty" / "labelTxt"
    empty.mkdir(parents=True)
    refused(["eval", "--gt", str(empty), "--pred", str(pred), "--out", str(out)],
            "no label files (*.txt) found")
    # missing folders, a file where a folder belongs
    refused(["eval", "--gt", str(tmp / "nope"), "--pred", str(pred), "--out", str(out)], "--gt", "no such folder")
    refused(["eval", "--gt", str(gt), "--pred", str(tmp / "nope"), "--out", str(out)], "--pred", "no such folder")
    refused(["eval", "--gt", str(g), "--pred", str(pred), "--out", str(out)], "expected a folder, found a file")
    # --out inside an input, --out a file
    refused(["eval", "--gt", str(gt), "--pred", str(pred), "--out", str(pred / "r")], "inside the input folder --pred")
    refused(["eval", "--gt", str(gt), "--pred", str(pred), "--out", str(gt / "labelTxt" / "img000.txt")],
            "expected a folder, found a file")
    # bad options
    refused(base + ["--iou", "1.5"], "--iou: expected a finite number >= 0 and < 1, got '1.5'")
    refused(base + ["--metric", "map"], "--metric: expected one of voc07, all-point, coco, got 'map'")
    # YOLO-OBB predictions without names, with a class index out of range
    yp = tmp / "ypred"
    yp.mkdir()
    (yp / "img000.txt").write_text("5 0.1 0.1 0.2 0.1 0.2 0.2 0.1 0.2 0.9\n")
    refused(["eval", "--gt", str(gt), "--pred", str(yp), "--out", str(out)], "--names")
    refused(["eval", "--gt", str(gt), "--pred", str(yp), "--names", "a,b", "--out", str(out)],
            "img000.txt:1: expected a class index in 0..1 (--names), got 5")
    (yp / "img000.txt").write_text("0 0.1 0.1 0.2 0.1 0.2 0.2 0.1 0.2\n")
    refused(["eval", "--gt", str(gt), "--pred", str(yp), "--names", "a,b", "--out", str(out)],
            "img000.txt:1: expected 'cls x1 y1 x2 y2 x3 y3 x4 y4 conf' (10 fields), got 9")
    (yp / "img000.txt").unlink()
    (yp / "zzz.txt").write_text("0 0.1 0.1 0.2 0.1 0.2 0.2 0.1 0.2 0.9\n")
    refused(["eval", "--gt", str(gt), "--pred", str(yp), "--names", "a,b", "--out", str(out)],
            "zzz.txt: image 'zzz' is not in the ground truth")
    # a working run still works and writes
    rc, err = _run(capsys, base)
    assert rc == 0 and (out / "eval.json").is_file()


def test_ten_thousand_boxes_match_themselves(tmp_path):
    """Sanity (not a timing): 200 images x 50 boxes evaluate and match themselves."""
    from aerial_synth.evaluate.ap import Detections, evaluate
    from aerial_synth.formats.labels import ImageLabels

    rng = np.random.default_rng(0)
    gt, rows = [], []
    for i in range(200):
        xy = np.stack([rect(*rng.uniform(20, 1000, 2), 20, 9, rng.uniform(0, 180)) for _ in range(50)])
        gt.append(ImageLabels(f"i{i}", xy, ["car"] * 50, np.zeros(50, bool)))
        rows.append(xy)
    d = Detections(np.repeat(np.arange(200), 50), ["car"] * 10000, rng.random(10000), np.concatenate(rows))
    res = evaluate(gt, d, metric="all-point")
    r = res.per_threshold[0.5]["car"]
    # overlapping random boxes can steal each other's best match; nearly all still match
    assert r.tp + r.fp == 10000 and r.tp > 9900


@pytest.mark.parametrize("cmd", ["eval", "mix", "stats"])
@pytest.mark.parametrize("out_kind", ["device", "below-a-file", "a-file"])
def test_hostile_outputs_for_every_command(case, capsys, cmd, out_kind):
    tmp, gt, pred = case
    afile = tmp / "afile"
    afile.write_text("x")
    out = {"device": "/dev/null", "below-a-file": str(afile / "out"), "a-file": str(afile)}[out_kind]
    argv = {
        "eval": ["eval", "--gt", str(gt), "--pred", str(pred)],
        "mix": ["mix", "--real", str(gt), "--synthetic", str(gt), "--real-images", "1"],
        "stats": ["stats", str(gt)],
    }[cmd] + ["--out", out]
    before = sorted(p.name for p in tmp.iterdir())
    rc, err = _run(capsys, argv)
    assert rc == 2 and err.count("\n") == 1 and "--out" in err, err
    assert sorted(p.name for p in tmp.iterdir()) == before and afile.read_text() == "x"
