"""Oriented-box AP: hand-built cases with exact values, and random cases against an
independent per-pair reference written the way the DOTA devkit's voc_eval is."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon

from aerial_synth.evaluate.ap import (
    Detections,
    all_point_ap,
    candidate_pairs,
    evaluate,
    pairwise_iou,
    voc07_ap,
)
from aerial_synth.formats.labels import ImageLabels


def rect(cx, cy, w, h, angle_deg=0.0):
    """Four corners (4, 2) of a w x h rectangle centred at (cx, cy), rotated."""
    a = np.deg2rad(angle_deg)
    c, s = np.cos(a), np.sin(a)
    pts = np.array([[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [-w / 2, h / 2]])
    return pts @ np.array([[c, s], [-s, c]]) + (cx, cy)


def gt_image(name, boxes, classes=None, difficult=None):
    boxes = np.asarray(boxes, float).reshape(-1, 4, 2)
    n = len(boxes)
    return ImageLabels(name, boxes, list(classes or ["car"] * n),
                       np.asarray(difficult if difficult is not None else [False] * n, bool))


def dets(rows):
    """rows: (image index, class, score, corners)."""
    if not rows:
        return Detections(np.zeros(0, int), [], np.zeros(0), np.zeros((0, 4, 2)))
    return Detections(np.array([r[0] for r in rows]), [r[1] for r in rows],
                      np.array([r[2] for r in rows], float), np.array([r[3] for r in rows], float))


# -- reference: per-detection loop over shapely polygons, devkit semantics ------------------


def _fan(p):
    """Signed triangles (origin, p_i, p_i+1) of a ring oriented to a non-negative area:
    summed, their indicators give the winding number at every point."""
    p = [tuple(map(float, v)) for v in p]
    area = sum(p[i][0] * p[(i + 1) % 4][1] - p[(i + 1) % 4][0] * p[i][1] for i in range(4)) / 2
    if area < 0:
        p = p[::-1]
    out = []
    for i in range(4):
        a, b = p[i], p[(i + 1) % 4]
        cross = a[0] * b[1] - b[0] * a[1]
        if cross != 0:
            out.append((1.0 if cross > 0 else -1.0, Polygon([(0.0, 0.0), a, b])))
    return out, abs(area)


def ref_iou(p, q):
    """The devkit's polygon IoU written plainly: intersection = the sum of signed
    intersections of the two fans' triangles (any corner order, bow ties included)."""
    fa, area_a = _fan(p)
    fb, area_b = _fan(q)
    inter = sum(sa * sb * ta.intersection(tb).area for sa, ta in fa for sb, tb in fb)
    union = area_a + area_b - inter
    return inter / union if union != 0 else 0.0


def ref_voc_eval(gt, det, classname, ovthresh, use_07):
    recs = {}
    npos = 0
    for i, g in enumerate(gt):
        sel = [k for k, c in enumerate(g.classes) if c == classname]
        diff = [bool(g.difficult[k]) for k in sel]
        recs[i] = {"bbox": [g.polygons_xy_px[k] for k in sel], "difficult": diff, "det": [False] * len(sel)}
        npos += sum(not d for d in diff)
    rows = [(det.image[k], det.scores[k], det.polygons_xy_px[k]) for k in range(len(det))
            if det.classes[k] == classname]
    order = sorted(range(len(rows)), key=lambda k: -rows[k][1])
    tp = np.zeros(len(rows))
    fp = np.zeros(len(rows))
    for d, k in enumerate(order):
        img, _, bb = rows[k]
        R = recs[img]
        ovmax, jmax = -np.inf, -1
        for j, g in enumerate(R["bbox"]):
            o = ref_iou(g, bb)
            if o > ovmax:
                ovmax, jmax = o, j
        if ovmax > ovthresh:
            if not R["difficult"][jmax]:
                if not R["det"][jmax]:
                    tp[d] = 1
                    R["det"][jmax] = True
                else:
                    fp[d] = 1
        else:
            fp[d] = 1
    fp, tp = np.cumsum(fp), np.cumsum(tp)
    rec = tp / float(npos)
    prec = tp / np.maximum(tp + fp, np.finfo(np.float64).eps)
    if use_07:
        ap = 0.0
        for t in np.arange(0.0, 1.1, 0.1):
            p = 0 if np.sum(rec >= t) == 0 else np.max(prec[rec >= t])
            ap += p / 11.0
        return ap
    mrec = np.concatenate(([0.0], rec, [1.0]))
    mpre = np.concatenate(([0.0], prec, [0.0]))
    for i in range(mpre.size - 1, 0, -1):
        mpre[i - 1] = max(mpre[i - 1], mpre[i])
    i = np.where(mrec[1:] != mrec[:-1])[0]
    return float(np.sum((mrec[i + 1] - mrec[i]) * mpre[i + 1]))


# -- hand-built cases --------------------------------------------------------------------------


@pytest.mark.parametrize("metric", ["voc07", "all-point", "coco"])
def test_perfect_predictions_give_ap_one(metric):
    boxes = [rect(50, 50, 20, 10, 30), rect(120, 80, 30, 12, -60), rect(200, 40, 18, 8, 90)]
    gt = [gt_image("a", boxes), gt_image("b", boxes[:2])]
    d = dets([(0, "car", 0.9, b) for b in boxes] + [(1, "car", 0.8, b) for b in boxes[:2]])
    res = evaluate(gt, d, metric=metric)
    assert res.ap["car"] == pytest.approx(1.0, abs=1e-12)  # 11 x 1/11 sums to 1 + 2e-16
    assert res.map == pytest.approx(1.0, abs=1e-12)
    r = res.per_threshold[res.iou_thresholds[0]]["car"]
    assert (r.tp, r.fp, r.n_gt) == (5, 0, 5)


def test_false_positive_above_every_true_positive_lowers_ap_exactly():
    n = 4
    boxes = [rect(40 * i + 20, 30, 20, 10) for i in range(n)]
    gt = [gt_image("a", boxes)]
    rows = [(0, "car", 0.5 - 0.01 * i, b) for i, b in enumerate(boxes)]
    rows.append((0, "car", 0.99, rect(500, 500, 20, 10)))  # matches nothing, top score
    res_all = evaluate(gt, dets(rows), metric="all-point")
    # precision at recall k/n is k/(k+1), rising with k, so the envelope is n/(n+1) at every
    # recall: the false positive lowers AP from 1 by exactly 1/(n+1)
    prec = np.array([k / (k + 1) for k in range(1, n + 1)])
    expected = max(prec)
    assert 1.0 - res_all.ap["car"] == pytest.approx(1 / (n + 1), abs=1e-12)
    assert res_all.ap["car"] == pytest.approx(expected, abs=1e-12)
    res07 = evaluate(gt, dets(rows), metric="voc07")
    # 11-point: the max precision at recall >= t is n/(n+1) for every t (precision rises)
    assert res07.ap["car"] == pytest.approx(n / (n + 1), abs=1e-12)
    r = res07.per_threshold[0.5]["car"]
    assert (r.tp, r.fp) == (n, 1)


def test_missed_object_caps_recall():
    boxes = [rect(20, 20, 20, 10), rect(80, 20, 20, 10), rect(140, 20, 20, 10), rect(200, 20, 20, 10)]
    gt = [gt_image("a", boxes)]
    d = dets([(0, "car", 0.9 - 0.1 * i, b) for i, b in enumerate(boxes[:3])])
    res = evaluate(gt, d, metric="all-point")
    r = res.per_threshold[0.5]["car"]
    assert r.recall[-1] == 0.75
    assert res.ap["car"] == pytest.approx(0.75, abs=1e-12)
    # 11-point: thresholds 0.8, 0.9, 1.0 are above the reached recall
    assert evaluate(gt, d, metric="voc07").ap["car"] == pytest.approx(8 / 11, abs=1e-12)


def test_difficult_objects_are_ignored():
    easy = rect(20, 20, 20, 10)
    hard = rect(100, 20, 20, 10)
    gt = [gt_image("a", [easy, hard], difficult=[False, True])]
    # a detection on the difficult box scores highest: neither TP nor FP
    d = dets([(0, "car", 0.95, hard), (0, "car", 0.9, easy)])
    res = evaluate(gt, d, metric="all-point")
    r = res.per_threshold[0.5]["car"]
    assert (r.n_gt, r.n_difficult, r.tp, r.fp, r.ignored) == (1, 1, 1, 0, 1)
    assert res.ap["car"] == 1.0
    # missing the difficult box costs nothing either
    assert evaluate(gt, dets([(0, "car", 0.9, easy)]), metric="all-point").ap["car"] == 1.0


def test_one_prediction_over_two_boxes_counts_once():
    a = rect(50, 50, 20, 10)
    b = rect(60, 50, 20, 10)  # IoU(a, b) = 1/3
    gt = [gt_image("x", [a, b])]
    mid = rect(55, 50, 20, 10)  # IoU 15/25 = 0.6 with both
    res = evaluate(gt, dets([(0, "car", 0.9, mid)]), metric="all-point")
    r = res.per_threshold[0.5]["car"]
    assert (r.tp, r.fp, r.n_gt) == (1, 0, 2)
    assert r.recall[-1] == 0.5
    # a second copy of the same prediction is a false positive (its best box is taken)
    res2 = evaluate(gt, dets([(0, "car", 0.9, mid), (0, "car", 0.8, mid)]), metric="all-point")
    r2 = res2.per_threshold[0.5]["car"]
    assert (r2.tp, r2.fp) == (1, 1)
    assert res2.ap["car"] == pytest.approx(0.5, abs=1e-12)


def test_threshold_is_strict_and_classes_do_not_match_each_other():
    a = rect(50, 50, 20, 10)
    b = rect(50 + 20 / 3, 50, 20, 10)  # overlap 40/3 x 10 over union 80/3 x 10: IoU exactly 0.5
    assert pairwise_iou([a], [b])[0, 0] == pytest.approx(0.5, abs=1e-12)
    gt = [gt_image("x", [a])]
    r = evaluate(gt, dets([(0, "car", 0.9, rect(50 + 20 / 3 + 1e-6, 50, 20, 10))]), iou_threshold=0.5)
    assert r.per_threshold[0.5]["car"].tp == 0  # IoU just under 0.5
    res = evaluate(gt, dets([(0, "truck", 0.9, a)]))
    assert res.ap == {"car": 0.0, "truck": None}  # truck has no ground truth: left out of mAP
    assert res.map == 0.0


def test_rotated_iou_table_matches_shapely_polygons():
    rng = np.random.default_rng(3)
    A = [rect(*rng.uniform(0, 60, 2), *rng.uniform(5, 40, 2), rng.uniform(0, 180)) for _ in range(7)]
    B = [rect(*rng.uniform(0, 60, 2), *rng.uniform(5, 40, 2), rng.uniform(0, 180)) for _ in range(5)]
    table = pairwise_iou(A, B)
    assert table.shape == (7, 5)
    for i, p in enumerate(A):
        for j, q in enumerate(B):
            inter = Polygon(p).intersection(Polygon(q)).area
            assert table[i, j] == pytest.approx(inter / (Polygon(p).area + Polygon(q).area - inter), abs=1e-12)
    assert (table > 0).sum() > 5  # the case exercises overlaps
    # a 45-degree square over an axis-aligned one: intersection is an octagon, IoU known
    s = rect(0, 0, 2, 2)
    d = rect(0, 0, 2, 2, 45)
    oct_area = 8 * (np.sqrt(2) - 1)
    assert pairwise_iou([s], [d])[0, 0] == pytest.approx(oct_area / (8 - oct_area), abs=1e-12)
    # any corner order of a simple quad is the same shape
    assert pairwise_iou([s[::-1]], [s])[0, 0] == pytest.approx(1.0)
    # a bow tie counts its lobes with opposite winding, as the devkit's polyiou: this one's
    # two halves cancel inside the square (IoU 0); a lopsided one keeps its bigger lobe
    bow = s[[0, 2, 1, 3]]
    assert not shapely.is_valid(shapely.polygons(bow))
    assert pairwise_iou([bow], [s])[0, 0] == pytest.approx(0.0, abs=1e-12)
    lop = np.array([[0, 0], [4, 4], [4, 0], [0, 1]], float)
    big = rect(2, 2, 4, 4)
    assert pairwise_iou([lop], [big])[0, 0] == pytest.approx(ref_iou(lop, big), abs=1e-12)
    assert pairwise_iou([lop], [big])[0, 0] > 0.2


def test_ap_functions_on_known_curves():
    rec = np.array([0.5, 0.5, 1.0])
    prec = np.array([1.0, 0.5, 2 / 3])
    assert all_point_ap(rec, prec) == pytest.approx(0.5 * 1.0 + 0.5 * 2 / 3)
    assert voc07_ap(rec, prec) == pytest.approx((6 * 1.0 + 5 * 2 / 3) / 11)


# -- random cases against the reference -------------------------------------------------------


def random_case(rng, n_img=6, n_cls=2):
    gt, rows = [], []
    for i in range(n_img):
        k = int(rng.integers(0, 9))
        boxes = [rect(*rng.uniform(0, 200, 2), *rng.uniform(8, 40, 2), rng.uniform(0, 180)) for _ in range(k)]
        cls = [f"c{int(rng.integers(0, n_cls))}" for _ in range(k)]
        diff = rng.random(k) < 0.2
        gt.append(gt_image(f"img{i}", boxes, cls, diff))
        for b, c in zip(boxes, cls):
            if rng.random() < 0.8:  # a jittered detection, sometimes a bow tie
                jit = b + rng.normal(0, 3, (4, 2))
                if rng.random() < 0.1:
                    jit = jit[[0, 2, 1, 3]]
                rows.append((i, c, float(rng.random()), jit))
            if rng.random() < 0.3:  # a duplicate
                rows.append((i, c, float(rng.random()), b + rng.normal(0, 6, (4, 2))))
        for _ in range(int(rng.integers(0, 4))):  # clutter, sometimes the wrong class
            rows.append((i, f"c{int(rng.integers(0, n_cls))}", float(rng.random()),
                         rect(*rng.uniform(0, 200, 2), *rng.uniform(8, 40, 2), rng.uniform(0, 180))))
    return gt, dets(rows)


@pytest.mark.parametrize("seed", range(12))
def test_agrees_with_reference_on_random_cases(seed):
    rng = np.random.default_rng(seed)
    gt, d = random_case(rng)
    for metric, use07 in (("voc07", True), ("all-point", False)):
        for thr in (0.3, 0.5, 0.7):
            res = evaluate(gt, d, iou_threshold=thr, metric=metric)
            for c in res.classes:
                if res.ap[c] is None:
                    continue
                assert res.ap[c] == pytest.approx(ref_voc_eval(gt, d, c, thr, use07), abs=1e-4)
    if seed % 3:
        return  # the ten-threshold comparison on a third of the cases keeps the suite fast
    coco = evaluate(gt, d, metric="coco")
    for c in coco.classes:
        if coco.ap[c] is None:
            continue
        ref = np.mean([ref_voc_eval(gt, d, c, t, False) for t in np.arange(0.5, 0.951, 0.05)])
        assert coco.ap[c] == pytest.approx(ref, abs=1e-4)


# -- properties ---------------------------------------------------------------------------------

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

box_params = st.tuples(st.floats(0, 100), st.floats(0, 100), st.floats(2, 50), st.floats(2, 50),
                       st.floats(0, 180))


@settings(max_examples=60, deadline=None)
@given(a=box_params, b=box_params, k=st.integers(0, 3), rev=st.booleans())
def test_iou_properties(a, b, k, rev):
    A, B = rect(*a), rect(*b)
    iou = pairwise_iou([A], [B])[0, 0]
    assert 0.0 <= iou <= 1.0 + 1e-12
    assert pairwise_iou([B], [A])[0, 0] == pytest.approx(iou, abs=1e-9)  # symmetric
    B2 = np.roll(B, k, axis=0)
    if rev:
        B2 = B2[::-1]
    assert pairwise_iou([A], [B2])[0, 0] == pytest.approx(iou, abs=1e-9)  # any corner order
    assert pairwise_iou([A], [A])[0, 0] == pytest.approx(1.0)
    assert iou == pytest.approx(ref_iou(A, B), abs=1e-9)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_ap_does_not_depend_on_detection_or_image_order(seed):
    rng = np.random.default_rng(seed)
    gt, d = random_case(rng, n_img=4)
    base = evaluate(gt, d, metric="all-point")
    perm = rng.permutation(len(d))
    d2 = Detections(d.image[perm], [d.classes[i] for i in perm], d.scores[perm], d.polygons_xy_px[perm])
    assert evaluate(gt, d2, metric="all-point").ap == base.ap
    order = rng.permutation(len(gt))
    inv = np.argsort(order)
    d3 = Detections(inv[d.image], d.classes, d.scores, d.polygons_xy_px)
    res3 = evaluate([gt[i] for i in order], d3, metric="all-point")
    for c, v in base.ap.items():
        assert (v is None and res3.ap[c] is None) or res3.ap[c] == pytest.approx(v, abs=1e-12)


def test_one_absurd_box_does_not_hide_the_others():
    boxes = [rect(50, 50, 20, 10), rect(120, 80, 30, 12, 40)]
    n = 200  # enough image keys that key x stride would overflow with 1e300 coordinates
    gt = [gt_image(f"i{k}", boxes) for k in range(n)]
    rows = [(k, "car", 0.5, b) for k in range(n) for b in boxes]
    rows.append((0, "car", 0.9, np.array([[1e300, 1], [1e300, 5], [-1e300, 5], [-1e300, 1]])))
    d = dets(rows)
    r = evaluate(gt, d, metric="all-point").per_threshold[0.5]["car"]
    assert (r.tp, r.fp) == (2 * n, 1)
    # and the candidate search pairs each box with its own copy only (plus the absurd one)
    gxy = np.concatenate([g.polygons_xy_px for g in gt])
    gimg = np.repeat(np.arange(n), 2)
    di, gj = candidate_pairs(d.polygons_xy_px, d.image, gxy, gimg)
    assert len(di) <= 2 * n + 4
