"""Oriented-box average precision, as the DOTA devkit's task-1 evaluation computes it.

Semantics (``dota_evaluation_task1.py``, ``voc_eval``), re-implemented and vectorised:

- per class, detections sorted by score, highest first (ties keep file order);
- each detection's overlap is the largest polygon IoU with a ground-truth box of the same
  image and class (the first such box on ties); a detection is a true positive when that IoU
  is **strictly** greater than the threshold and the box is not difficult and not already
  taken by a higher-scoring detection; it is ignored (neither TP nor FP) when the box is
  difficult; otherwise it is a false positive. The devkit only looks at the best box: a
  detection whose best box is taken is a false positive even if another box also overlaps;
- recall = TP / non-difficult ground truth, precision = TP / max(TP + FP, eps);
- VOC07 11-point AP (thresholds ``numpy.arange(0, 1.1, 0.1)`` as in the devkit), all-point
  AP (area under the precision envelope), and COCO-style: the mean of all-point AP over
  IoU 0.50:0.05:0.95.

IoU: shapely 2 array functions over candidate pairs (boxes whose axis-aligned extents meet,
found with one STRtree query); no Python loop over pairs. Boxes are taken as the devkit's
``polyiou`` takes them: any corner order of a simple quadrilateral is the same shape; a
self-intersecting one (a "bow tie") counts its two lobes with opposite signs, the
intersection being the integral of the product of winding numbers (see :class:`Quads`).
IoU is 0 where the union is empty (the devkit divides 0 by 0 there, and such a detection
is a false positive either way).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "METRICS",
    "COCO_THRESHOLDS",
    "Detections",
    "ClassResult",
    "EvalResult",
    "to_polygons",
    "Quads",
    "quads",
    "quad_pair_iou",
    "pairwise_iou",
    "candidate_pairs",
    "voc07_ap",
    "all_point_ap",
    "evaluate",
]

METRICS = ("voc07", "all-point", "coco")
COCO_THRESHOLDS = tuple(round(0.5 + 0.05 * i, 2) for i in range(10))


@dataclass
class Detections:
    """Flat detections: ``image`` (n,) int index into the ground-truth image list; ``classes``
    n names; ``scores`` (n,) float; ``polygons_xy_px`` (n, 4, 2) float64, px, image frame."""

    image: np.ndarray
    classes: list[str]
    scores: np.ndarray
    polygons_xy_px: np.ndarray

    def __len__(self) -> int:
        return len(self.classes)


def to_polygons(xy):
    """(n, 4, 2) corners -> shapely polygon array; invalid (self-intersecting) ones become
    their convex hull, so any corner order of a rectangle gives the rectangle."""
    import shapely

    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 4, 2)
    polys = shapely.polygons(xy)
    if len(polys):
        bad = ~shapely.is_valid(polys)
        if bad.any():
            polys[bad] = shapely.convex_hull(polys[bad])
    return polys


def _ratio(inter: np.ndarray, union: np.ndarray) -> np.ndarray:
    """inter / union, and 0 where union is 0. With bow ties both may be negative (the
    devkit divides them as they are)."""
    ok = union != 0
    return np.where(ok, inter / np.where(ok, union, 1.0), 0.0)


def _shoelace(p: np.ndarray) -> np.ndarray:
    """Signed area of (..., k, 2) rings (positive: clockwise on screen, y down)."""
    x, y = p[..., 0], p[..., 1]
    return 0.5 * np.sum(x * np.roll(y, -1, axis=-1) - np.roll(x, -1, axis=-1) * y, axis=-1)


def _crossing(a, b, c, d):
    """Where segments ab and cd cross at an inner point of both: (mask, point)."""
    r, s, q = b - a, d - c, c - a
    den = r[:, 0] * s[:, 1] - r[:, 1] * s[:, 0]
    safe = np.where(den != 0, den, 1.0)
    t = (q[:, 0] * s[:, 1] - q[:, 1] * s[:, 0]) / safe
    u = (q[:, 0] * r[:, 1] - q[:, 1] * r[:, 0]) / safe
    ok = (den != 0) & (t > 0) & (t < 1) & (u > 0) & (u < 1)
    return ok, a + t[:, None] * r


@dataclass
class Quads:
    """Four-point boxes as the devkit's ``polyiou`` sees them: a quad's winding number
    (+1 inside a simple quad, whatever its corner order; +1 and -1 in the two lobes of a
    self-intersecting "bow tie", signs chosen so the signed area is >= 0) as one or two
    simple pieces with signs. ``area``: |shoelace area|, as ``polyiou`` uses."""

    lobe1: np.ndarray
    sign1: np.ndarray
    lobe2: np.ndarray
    sign2: np.ndarray
    area: np.ndarray
    simple: np.ndarray


def quads(xy) -> Quads:
    """(n, 4, 2) corners -> :class:`Quads` (vectorised)."""
    import shapely

    P = np.asarray(xy, dtype=np.float64).reshape(-1, 4, 2)
    n = len(P)
    signed = _shoelace(P)
    polys = shapely.polygons(P) if n else np.empty(0, dtype=object)
    simple = shapely.is_valid(polys) if n else np.zeros(0, bool)
    lobe1, sign1 = polys.copy(), np.ones(n)
    lobe2, sign2 = np.full(n, None, dtype=object), np.zeros(n)
    bad = np.nonzero(~simple)[0]
    if len(bad):
        p0, p1, p2, p3 = (P[bad, k] for k in range(4))
        ok_a, x = _crossing(p0, p1, p2, p3)  # p0p1 crosses p2p3: loops x p1 p2 and p0 x p3
        ok_b, y = _crossing(p1, p2, p3, p0)  # p1p2 crosses p3p0: loops y p2 p3 and p0 p1 y
        t1 = np.where(ok_a[:, None, None], np.stack([x, p1, p2], 1), np.stack([y, p2, p3], 1))
        t2 = np.where(ok_a[:, None, None], np.stack([p0, x, p3], 1), np.stack([p0, p1, y], 1))
        flip = np.where(signed[bad] < 0, -1.0, 1.0)  # polyiou reverses a negative polygon
        cross = ok_a | ok_b
        b = bad[cross]
        lobe1[b] = shapely.polygons(t1[cross])
        sign1[b] = np.sign(_shoelace(t1[cross])) * flip[cross]
        lobe2[b] = shapely.polygons(t2[cross])
        sign2[b] = np.sign(_shoelace(t2[cross])) * flip[cross]
        # other invalid quads (zero area, a corner on another edge): repaired by shapely
        rest = bad[~cross]
        if len(rest):
            lobe1[rest] = shapely.make_valid(polys[rest])
    return Quads(lobe1, sign1, lobe2, sign2, np.abs(signed), simple)


def quad_pair_iou(a: Quads, ia, b: Quads, ib) -> np.ndarray:
    """IoU of quads ``a[ia[k]]`` and ``b[ib[k]]``: the signed intersection of their pieces
    (the integral of the product of the winding numbers, as ``polyiou`` computes it) over
    |area a| + |area b| - intersection; 0 where that is 0."""
    import shapely

    ia, ib = np.asarray(ia), np.asarray(ib)
    if len(ia) == 0:
        return np.zeros(0)
    inter = a.sign1[ia] * b.sign1[ib] * shapely.area(shapely.intersection(a.lobe1[ia], b.lobe1[ib]))
    two_a, two_b = a.sign2[ia] != 0, b.sign2[ib] != 0
    for ma, mb, la, sa, lb, sb in (
        (two_a, None, a.lobe2, a.sign2, b.lobe1, b.sign1),
        (None, two_b, a.lobe1, a.sign1, b.lobe2, b.sign2),
        (two_a, two_b, a.lobe2, a.sign2, b.lobe2, b.sign2),
    ):
        m = (ma if ma is not None else True) & (mb if mb is not None else True)
        m = np.broadcast_to(m, ia.shape)
        if m.any():
            ka, kb = ia[m], ib[m]
            inter[m] += sa[ka] * sb[kb] * shapely.area(shapely.intersection(la[ka], lb[kb]))
    return _ratio(inter, a.area[ia] + b.area[ib] - inter)


def pairwise_iou(a_xy, b_xy) -> np.ndarray:
    """(n, m) IoU table of two sets of four-point boxes, devkit semantics (vectorised)."""
    qa, qb = quads(a_xy), quads(b_xy)
    n, m = len(qa.area), len(qb.area)
    if n == 0 or m == 0:
        return np.zeros((n, m))
    return quad_pair_iou(qa, np.repeat(np.arange(n), m), qb, np.tile(np.arange(m), n)).reshape(n, m)


def candidate_pairs(a_xy, a_key, b_xy, b_key) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i, j) with ``a_key[i] == b_key[j]`` whose axis-aligned extents meet.

    One STRtree query: each key's boxes are shifted along x by key x stride, with the stride
    wider than all boxes together, so boxes of different keys never meet."""
    import shapely

    # the query only needs which boxes meet: clipping far-out coordinates to +-1e7 px keeps
    # that (for boxes within the range) and keeps the shifted x exact enough in float64
    a_xy = np.clip(np.asarray(a_xy, dtype=np.float64).reshape(-1, 4, 2), -1e7, 1e7)
    b_xy = np.clip(np.asarray(b_xy, dtype=np.float64).reshape(-1, 4, 2), -1e7, 1e7)
    if len(a_xy) == 0 or len(b_xy) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    lo = min(a_xy[..., 0].min(), b_xy[..., 0].min())
    hi = max(a_xy[..., 0].max(), b_xy[..., 0].max())
    stride = (hi - lo) + 16.0
    a_off = (np.asarray(a_key, dtype=np.float64) * stride - lo)
    b_off = (np.asarray(b_key, dtype=np.float64) * stride - lo)
    ab = shapely.box(a_xy[..., 0].min(1) + a_off, a_xy[..., 1].min(1),
                     a_xy[..., 0].max(1) + a_off, a_xy[..., 1].max(1))
    bb = shapely.box(b_xy[..., 0].min(1) + b_off, b_xy[..., 1].min(1),
                     b_xy[..., 0].max(1) + b_off, b_xy[..., 1].max(1))
    tree = shapely.STRtree(bb)
    ia, jb = tree.query(ab, predicate="intersects")
    same = np.asarray(a_key)[ia] == np.asarray(b_key)[jb]  # guard against float rounding
    return ia[same].astype(np.int64), jb[same].astype(np.int64)


def voc07_ap(rec: np.ndarray, prec: np.ndarray) -> float:
    """VOC07 11-point AP exactly as the devkit (thresholds from numpy.arange(0, 1.1, 0.1))."""
    ap = 0.0
    for t in np.arange(0.0, 1.1, 0.1):
        m = rec >= t
        ap += (float(np.max(prec[m])) if m.any() else 0.0) / 11.0
    return ap


def all_point_ap(rec: np.ndarray, prec: np.ndarray) -> float:
    """Area under the precision envelope (VOC2010+ / devkit ``use_07_metric=False``)."""
    mrec = np.concatenate(([0.0], rec, [1.0]))
    mpre = np.concatenate(([0.0], prec, [0.0]))
    mpre = np.maximum.accumulate(mpre[::-1])[::-1]
    i = np.where(mrec[1:] != mrec[:-1])[0]
    return float(np.sum((mrec[i + 1] - mrec[i]) * mpre[i + 1]))


@dataclass
class ClassResult:
    """One class at one IoU threshold. ``recall``/``precision`` (n_det,) in score order."""

    name: str
    iou_threshold: float
    ap: float | None
    n_gt: int
    n_difficult: int
    n_det: int
    tp: int
    fp: int
    ignored: int
    recall: np.ndarray
    precision: np.ndarray
    scores: np.ndarray
    #: per detection in score order: its image index, true / false positive (an ignored
    #: difficult match is neither); per image: its non-difficult truth boxes. What a
    #: bootstrap over images needs to recompute the curve (sim2real/confidence.py).
    det_image: np.ndarray | None = None
    det_tp: np.ndarray | None = None
    det_fp: np.ndarray | None = None
    npos_by_image: np.ndarray | None = None

    def to_dict(self, max_points: int = 500) -> dict:
        n = len(self.recall)
        idx = np.unique(np.linspace(0, n - 1, min(n, max_points)).round().astype(int)) if n else []
        return {
            "ap": None if self.ap is None else round(self.ap, 6),
            "iou_threshold": self.iou_threshold,
            "n_gt": self.n_gt,
            "n_difficult": self.n_difficult,
            "n_det": self.n_det,
            "tp": self.tp,
            "fp": self.fp,
            "ignored_difficult": self.ignored,
            "max_recall": round(float(self.recall[-1]), 6) if n and self.n_gt else 0.0,
            "precision_at_max_recall": round(float(self.precision[-1]), 6) if n else 0.0,
            "curve": {
                "recall": [round(float(self.recall[i]), 6) for i in idx],
                "precision": [round(float(self.precision[i]), 6) for i in idx],
                "score": [round(float(self.scores[i]), 6) for i in idx],
            },
        }


@dataclass
class EvalResult:
    metric: str
    iou_thresholds: tuple[float, ...]
    classes: list[str]
    #: per class: AP for the metric (mean over thresholds for coco); None without ground truth
    ap: dict[str, float | None]
    #: mean over classes with ground truth
    map: float | None
    #: per threshold, per class results
    per_threshold: dict[float, dict[str, ClassResult]]
    n_images: int

    def to_dict(self) -> dict:
        out = {
            "metric": self.metric,
            "iou_thresholds": list(self.iou_thresholds),
            "n_images": self.n_images,
            "classes": self.classes,
            "ap": {c: (None if v is None else round(v, 6)) for c, v in self.ap.items()},
            "map": None if self.map is None else round(self.map, 6),
            "per_threshold": {
                f"{t:.2f}": {c: r.to_dict() for c, r in d.items()} for t, d in self.per_threshold.items()
            },
        }
        if self.metric == "coco":
            for t in (0.5, 0.75):
                d = self.per_threshold.get(t)
                if d:
                    vals = [r.ap for r in d.values() if r.ap is not None]
                    out[f"map{int(t * 100)}"] = round(float(np.mean(vals)), 6) if vals else None
        return out


def _projection_bound(a_xy: np.ndarray, b_xy: np.ndarray, axes_from: np.ndarray) -> np.ndarray:
    """Upper bound of area(A & B) per pair: the product of the overlaps of A's and B's
    projections on two orthogonal axes (along the first edge of ``axes_from`` and across
    it). Holds for any shapes: A & B lies in that rectangle."""
    u = axes_from[:, 1] - axes_from[:, 0]
    norm = np.linalg.norm(u, axis=1, keepdims=True)
    u = np.where(norm > 0, u / np.where(norm > 0, norm, 1.0), (1.0, 0.0))
    v = np.stack([-u[:, 1], u[:, 0]], axis=1)
    out = np.ones(len(a_xy))
    for ax in (u, v):
        pa = np.einsum("nkd,nd->nk", a_xy, ax)
        pb = np.einsum("nkd,nd->nk", b_xy, ax)
        out *= np.maximum(np.minimum(pa.max(1), pb.max(1)) - np.maximum(pa.min(1), pb.min(1)), 0.0)
    return out


def _best_overlaps(det_xy, det_img, det_cls, gt_xy, gt_img, gt_cls, min_threshold: float = 0.0):
    """Per detection: the largest IoU with a same-image same-class box (-inf if none) and
    that box's index (first on ties, in ground-truth order).

    Pairs whose IoU cannot exceed ``min_threshold`` (an upper bound from projections on the
    two boxes' axes) are not intersected: they can never be a match, and a detection left
    without pairs is a false positive at every threshold >= ``min_threshold`` either way."""

    nd = len(det_xy)
    ovmax = np.full(nd, -np.inf)
    jmax = np.full(nd, -1, dtype=np.int64)
    ncls = int(max(det_cls.max(initial=0), gt_cls.max(initial=0))) + 1
    di, gj = candidate_pairs(det_xy, det_img * ncls + det_cls, gt_xy, gt_img * ncls + gt_cls)
    if len(di) == 0:
        return ovmax, jmax
    dq, gq = quads(det_xy), quads(gt_xy)
    da, ga = dq.area, gq.area
    if min_threshold > 0:
        a, b = det_xy[di], gt_xy[gj]
        m = np.minimum(np.minimum(da[di], ga[gj]),
                       np.minimum(_projection_bound(a, b, a), _projection_bound(a, b, b)))
        denom = da[di] + ga[gj] - m
        ub = np.where(denom > 0, m / np.where(denom > 0, denom, 1.0), 1.0)
        # the bound holds for simple quads; pairs with a bow tie are always computed
        keep = (ub >= min_threshold - 1e-9) | ~dq.simple[di] | ~gq.simple[gj]
        di, gj = di[keep], gj[keep]
        if len(di) == 0:
            return ovmax, jmax
    iou = quad_pair_iou(dq, di, gq, gj)
    order = np.lexsort((gj, -iou, di))  # by detection, then IoU descending, then box index
    di, gj, iou = di[order], gj[order], iou[order]
    first = np.ones(len(di), dtype=bool)
    first[1:] = di[1:] != di[:-1]
    ovmax[di[first]] = iou[first]
    jmax[di[first]] = gj[first]
    return ovmax, jmax


def evaluate(gt, detections: Detections, *, iou_threshold: float = 0.5, metric: str = "voc07",
             classes: list[str] | None = None) -> EvalResult:
    """Average precision per class and its mean.

    ``gt``: list of :class:`~aerial_synth.evaluate.labels.ImageLabels` (the image list);
    ``detections.image`` indexes it. ``classes``: the classes to report (default: every class
    in the ground truth or the detections, sorted); the mean runs over those with at least
    one non-difficult ground-truth box (a class without any has AP ``None``)."""
    if metric not in METRICS:
        raise ValueError(f"metric: expected one of {', '.join(METRICS)}, got {metric!r}")
    thresholds = COCO_THRESHOLDS if metric == "coco" else (float(iou_threshold),)
    gt_xy = np.concatenate([g.polygons_xy_px.reshape(-1, 4, 2) for g in gt] or [np.zeros((0, 4, 2))])
    gt_img = np.concatenate([np.full(len(g), i, np.int64) for i, g in enumerate(gt)] or [np.zeros(0, np.int64)])
    gt_names = [c for g in gt for c in g.classes]
    gt_diff = np.concatenate([np.asarray(g.difficult, bool) for g in gt] or [np.zeros(0, bool)])
    names = sorted(set(gt_names) | set(detections.classes)) if classes is None else list(classes)
    code = {c: i for i, c in enumerate(names)}
    other = len(names)
    gt_cls = np.array([code.get(c, other) for c in gt_names], dtype=np.int64)
    det_cls = np.array([code.get(c, other) for c in detections.classes], dtype=np.int64)
    det_img = np.asarray(detections.image, dtype=np.int64)
    scores = np.asarray(detections.scores, dtype=np.float64)
    det_xy = np.asarray(detections.polygons_xy_px, dtype=np.float64).reshape(-1, 4, 2)

    ovmax, jmax = _best_overlaps(det_xy, det_img, det_cls, gt_xy, gt_img, gt_cls, min(thresholds))

    per_t: dict[float, dict[str, ClassResult]] = {}
    for t in thresholds:
        per_t[t] = {}
        for c, name in enumerate(names):
            sel = np.nonzero(det_cls == c)[0]
            sel = sel[np.argsort(-scores[sel], kind="stable")]
            ov, jm = ovmax[sel], jmax[sel]
            hit = ov > t
            diff = np.zeros(len(sel), dtype=bool)
            diff[hit] = gt_diff[jm[hit]]
            cand = hit & ~diff
            tp = np.zeros(len(sel), dtype=bool)
            pos = np.nonzero(cand)[0]
            if len(pos):
                _, first = np.unique(jm[pos], return_index=True)
                tp[pos[first]] = True
            fp = ~hit | (cand & ~tp)
            is_c = gt_cls == c
            npos = int(np.count_nonzero(is_c & ~gt_diff))
            ctp = np.cumsum(tp).astype(np.float64)
            cfp = np.cumsum(fp).astype(np.float64)
            rec = ctp / npos if npos else np.zeros(len(sel))
            prec = ctp / np.maximum(ctp + cfp, np.finfo(np.float64).eps)
            if npos == 0:
                ap = None
            elif metric == "voc07":
                ap = voc07_ap(rec, prec)
            else:
                ap = all_point_ap(rec, prec)
            per_t[t][name] = ClassResult(
                name, t, ap, npos, int(np.count_nonzero(is_c & gt_diff)), len(sel),
                int(tp.sum()), int(fp.sum()), int((hit & diff).sum()), rec, prec, scores[sel],
                det_img[sel], tp, fp, np.bincount(gt_img[is_c & ~gt_diff], minlength=len(gt)))
    ap_cls: dict[str, float | None] = {}
    for name in names:
        vals = [per_t[t][name].ap for t in thresholds]
        ap_cls[name] = None if vals[0] is None else float(np.mean(vals))
    have = [v for v in ap_cls.values() if v is not None]
    return EvalResult(metric, tuple(thresholds), names, ap_cls,
                      float(np.mean(have)) if have else None, per_t, len(gt))
