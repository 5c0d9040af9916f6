"""The scoring options of eval (merged classes, HBB IoU, ignored border, groups), each
against a hand computation, and the eval command with them."""

from __future__ import annotations

import json

import numpy as np
import pytest

from aerial_synth.cli import main
from aerial_synth.errors import EvaluationError
from aerial_synth.evaluate.ap import Detections, pairwise_iou
from aerial_synth.evaluate.labels import ImageLabels
from aerial_synth.evaluate.scoring import (
    ScoringOptions,
    hbb_hull,
    image_groups,
    is_axis_aligned,
    parse_ignore_border,
    parse_merge_classes,
    read_gt,
    score,
)

from .conftest import rect, write_dota_image


def box(x0, y0, x1, y1):
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)


def labels(name, boxes, classes, difficult=None, size=(100, 100), group=None):
    g = ImageLabels(name, np.asarray(boxes, float).reshape(-1, 4, 2), list(classes),
                    np.zeros(len(classes), bool) if difficult is None else np.asarray(difficult, bool),
                    size_wh=size)
    if group:
        g.extra["group"] = group
    return g


def dets(rows):
    """rows: (image index, class, score, (4,2) corners)."""
    return Detections(np.array([r[0] for r in rows], np.int64), [r[1] for r in rows],
                      np.array([r[2] for r in rows], float),
                      np.array([r[3] for r in rows], float).reshape(-1, 4, 2))


def agn(res, group=None):
    r = res.overall if group is None else res.groups[group]
    return next(iter(r.per_threshold[r.iou_thresholds[0]].values()))


# -- merged classes ------------------------------------------------------------------------------


def test_merged_classes_make_swapped_labels_right():
    gt = [labels("a", [box(10, 10, 30, 20), box(50, 50, 70, 60)], ["small-vehicle", "large-vehicle"])]
    d = dets([(0, "large-vehicle", 0.9, box(10, 10, 30, 20)), (0, "small-vehicle", 0.8, box(50, 50, 70, 60))])
    per_class = score(gt, d, ScoringOptions())
    assert per_class.overall.ap == {"large-vehicle": 0.0, "small-vehicle": 0.0}
    merged = score(gt, d, ScoringOptions.from_text("vehicle"))
    assert merged.overall.classes == ["vehicle"]
    assert merged.overall.ap["vehicle"] == pytest.approx(1.0)
    c = agn(merged)
    assert (c.n_gt, c.n_det, c.tp, c.fp) == (2, 2, 2, 0)


def test_merged_classes_with_members_drop_the_others():
    gt = [labels("a", [box(10, 10, 30, 20), box(50, 50, 70, 60)], ["small-vehicle", "plane"])]
    d = dets([(0, "small-vehicle", 0.9, box(10, 10, 30, 20)), (0, "plane", 0.8, box(50, 50, 70, 60)),
              (0, "ship", 0.95, box(0, 80, 10, 90))])
    res = score(gt, d, ScoringOptions.from_text("vehicle=small-vehicle,large-vehicle"))
    c = agn(res)
    assert (c.n_gt, c.n_det, c.tp, c.fp) == (1, 1, 1, 0)
    assert res.overall.ap["vehicle"] == pytest.approx(1.0)


@pytest.mark.parametrize("text", ["", "=a", "veh=", "two words"])
def test_merge_classes_refuses_bad_text(text):
    with pytest.raises(EvaluationError, match="--merge-classes"):
        parse_merge_classes(text)


# -- HBB IoU -------------------------------------------------------------------------------------


def test_hbb_hull_and_axis_aligned():
    diamond = np.array([[0, 5], [5, 0], [10, 5], [5, 10]], float)
    assert hbb_hull(diamond)[0].tolist() == [[0, 0], [10, 0], [10, 10], [0, 10]]
    assert is_axis_aligned([box(1, 2, 3, 4), box(3, 4, 1, 2)[::-1]])
    assert not is_axis_aligned([diamond])
    assert is_axis_aligned(np.zeros((0, 4, 2)))


def test_hbb_iou_of_a_diamond_is_one_where_obb_is_one_half():
    gt = [labels("a", [box(0, 0, 10, 10)], ["car"])]
    diamond = np.array([[0, 5], [5, 0], [10, 5], [5, 10]], float)
    # oriented: the diamond covers half the square, IoU 50 / 100 = 0.5, not > 0.5
    assert pairwise_iou(diamond[None], box(0, 0, 10, 10)[None])[0, 0] == pytest.approx(0.5)
    d = dets([(0, "car", 0.9, diamond)])
    assert score(gt, d, ScoringOptions(iou_type="obb")).overall.ap["car"] == 0.0
    assert score(gt, d, ScoringOptions(iou_type="hbb")).overall.ap["car"] == pytest.approx(1.0)


@pytest.mark.parametrize("iou, ap", [(0.33, 1.0), (0.34, 0.0)])
def test_hbb_iou_matches_a_hand_computation(iou, ap):
    # a thin rotated box whose hull is [5, 15] x [0, 10]: with the truth [0, 10] x [0, 10]
    # the hulls share 5 x 10 = 50 of 100 + 100 - 50 = 150 -> IoU 1/3
    gt = [labels("a", [box(0, 0, 10, 10)], ["car"])]
    thin = np.array([[5, 0.5], [5.5, 0], [15, 9.5], [14.5, 10]], float)
    assert hbb_hull(thin)[0].tolist() == [[5, 0], [15, 0], [15, 10], [5, 10]]
    res = score(gt, dets([(0, "car", 0.9, thin)]), ScoringOptions(iou_type="hbb"), iou=iou)
    assert res.overall.ap["car"] == pytest.approx(ap)


def test_auto_iou_type_is_chosen_per_group():
    gt = [labels("a", [box(0, 0, 10, 10)], ["car"], group="aligned"),
          labels("b", [rect(50, 50, 20, 8, 30)], ["car"], group="oriented")]
    res = score(gt, dets([]), ScoringOptions(iou_type="auto"))
    assert res.iou_type == {"aligned": "hbb", "oriented": "obb"}


# -- border ----------------------------------------------------------------------------------------


def test_ignore_border_by_centre():
    # 100 x 100 image, border 10 px: the truth centred at x = 5 becomes difficult; the detection
    # on it is removed (centre at x = 5), so it is neither TP nor FP; the middle one is a TP;
    # a false positive centred at y = 95 is removed too.
    gt = [labels("a", [box(0, 45, 10, 55), box(40, 40, 60, 60)], ["car", "car"])]
    d = dets([(0, "car", 0.9, box(0, 45, 10, 55)), (0, "car", 0.8, box(40, 40, 60, 60)),
              (0, "car", 0.7, box(80, 90, 90, 100))])
    plain = agn(score(gt, d, ScoringOptions()))
    assert (plain.n_gt, plain.tp, plain.fp) == (2, 2, 1)
    c = agn(score(gt, d, ScoringOptions.from_text(border=["10"])))
    assert (c.n_gt, c.n_difficult, c.n_det, c.tp, c.fp) == (1, 1, 1, 1, 0)
    assert c.ap == pytest.approx(1.0)
    # a centre exactly 10 px from the border is kept (strictly less than PX is ignored)
    c = agn(score(gt, dets([(0, "car", 0.9, box(5, 45, 15, 55))]), ScoringOptions.from_text(border=["10"])))
    assert c.n_det == 1


def test_ignore_border_per_group_and_errors():
    gt = [labels("a", [box(0, 45, 10, 55)], ["car"], group="minsk"),
          labels("b", [box(0, 45, 10, 55)], ["car"], group="dota")]
    d = dets([(0, "car", 0.9, box(0, 45, 10, 55)), (1, "car", 0.9, box(0, 45, 10, 55))])
    res = score(gt, d, ScoringOptions.from_text(border=["minsk=10"]))
    assert res.border_px == {"dota": 0.0, "minsk": 10.0}
    assert (agn(res, "minsk").n_gt, agn(res, "minsk").n_det) == (0, 0)
    assert (agn(res, "dota").n_gt, agn(res, "dota").tp) == (1, 1)
    with pytest.raises(EvaluationError, match="no group 'nope'"):
        score(gt, d, ScoringOptions.from_text(border=["nope=3"]))
    for bad in (["-1"], ["x"], ["=4"], ["5", "5"]):
        with pytest.raises(EvaluationError, match="--ignore-border"):
            parse_ignore_border(bad)


# -- groups ----------------------------------------------------------------------------------------


def test_groups_by_regex_and_their_ap():
    gt = [labels("P0001__a", [box(0, 0, 20, 10)], ["car"]), labels("P0002__b", [box(0, 0, 20, 10)], ["car"]),
          labels("minsk_1", [box(30, 30, 50, 40)], ["car"])]
    assert image_groups(gt, r"^(P\d+)") == ["P0001", "P0002", "(other)"]
    assert image_groups(gt, r"minsk") == ["(other)", "(other)", "minsk"]
    d = dets([(0, "car", 0.9, box(0, 0, 20, 10)), (2, "car", 0.9, box(60, 60, 80, 70))])
    res = score(gt, d, ScoringOptions(group=r"^(P)|minsk"))
    assert sorted(res.groups) == ["P", "minsk"]
    # P: 2 truths, one found -> VOC07 AP = 6/11 (recall 0.5 at precision 1)
    assert res.groups["P"].ap["car"] == pytest.approx(6 / 11)
    assert res.groups["minsk"].ap["car"] == 0.0
    with pytest.raises(EvaluationError, match="--group"):
        ScoringOptions(group="(")


# -- the command -------------------------------------------------------------------------------------


def _collection(tmp_path):
    root = tmp_path / "real"
    write_dota_image(root / "minsk", "f1", [box(0, 40, 20, 60), box(50, 50, 80, 70)], ["small-vehicle"] * 2,
                     size=(100, 100))
    write_dota_image(root / "vedai", "t1", [rect(60, 60, 30, 12, 35)], ["large-vehicle"], size=(120, 120))
    return root


def test_eval_command_with_a_collection_and_options(tmp_path, capsys):
    root = _collection(tmp_path)
    pred = tmp_path / "pred"
    pred.mkdir()
    # minsk: an oriented prediction on the middle car whose hull is the truth, one on the border
    # car; vedai: the truth itself
    mid = np.array([[50, 60], [65, 50], [80, 60], [65, 70]], float)
    t = rect(60, 60, 30, 12, 35)
    lines = [f"minsk/f1 0.9 {' '.join(f'{v:g}' for v in mid.ravel())}",
             f"minsk/f1 0.8 {' '.join(f'{v:g}' for v in box(0, 40, 20, 60).ravel())}",
             f"vedai/t1 0.7 {' '.join(f'{v:.4f}' for v in t.ravel())}"]
    (pred / "Task1_small-vehicle.txt").write_text("\n".join(lines) + "\n")
    out = tmp_path / "rep"
    rc = main(["eval", "--gt", str(root), "--pred", str(pred), "--merge-classes", "vehicle",
               "--iou-type", "auto", "--ignore-border", "minsk=25", "--out", str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "minsk" in text and "vedai" in text
    data = json.loads((out / "eval.json").read_text())
    assert data["iou_type_by_group"] == {"minsk": "hbb", "vedai": "obb"}
    assert data["overall"]["ap"] == {"vehicle": 1.0}
    g = data["groups"]["minsk"]["per_threshold"]["0.50"]["vehicle"]
    assert (g["n_gt"], g["n_difficult"], g["n_det"], g["tp"], g["fp"]) == (1, 1, 1, 1, 0)
    # without the options, per class and oriented: the minsk diamond is no match
    rc = main(["eval", "--gt", str(root), "--pred", str(pred), "--iou-type", "obb"])
    assert rc == 0
    assert read_gt(root)[0].name == "minsk/f1"


@pytest.mark.parametrize("args, msg", [
    (["--iou-type", "rbox"], "--iou-type: expected one of obb, hbb, auto"),
    (["--ignore-border", "minsk=-3"], "--ignore-border: expected PX or GROUP=PX"),
    (["--ignore-border", "nowhere=3"], "no group 'nowhere'"),
    (["--merge-classes", "=x"], "--merge-classes: expected NAME"),
    (["--group", "("], "--group: expected a regular expression"),
])
def test_eval_command_refuses_bad_options(tmp_path, capsys, args, msg):
    root = _collection(tmp_path)
    pred = tmp_path / "pred"
    pred.mkdir()
    (pred / "Task1_small-vehicle.txt").write_text("minsk/f1 0.9 0 0 1 0 1 1 0 1\n")
    rc = main(["eval", "--gt", str(root), "--pred", str(pred), *args])
    err = capsys.readouterr().err
    assert rc == 2
    assert msg in err and len(err.strip().splitlines()) == 1
