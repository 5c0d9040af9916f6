"""The report of ``sim2real``: summary text, PR curves and contact sheets (pure functions
over scored results; the pipeline writes the files)."""

from __future__ import annotations

import numpy as np

from ..evaluate.ap import pairwise_iou
from ..evaluate.plots import grid, line_chart
from ..evaluate.scoring import ScoreResult, hbb_hull

__all__ = ["agnostic", "arm_real_figures", "summary_text", "plan_summary_text", "score_summary_text", "pr_chart", "best_f1_threshold",
           "contact_sheet", "REPORT_FIELDS", "ARM_FIELDS"]

#: top-level fields of report.json (the smoke test checks each)
REPORT_FIELDS = ("format", "version", "parameters", "versions", "device", "real", "scoring", "arms",
                 "files")
#: fields of each arm in report.json
ARM_FIELDS = ("name", "dirs", "gsd_m", "classes", "training_images", "validation_images",
              "val_is_train", "epochs", "seconds", "synthetic_val_map50", "synthetic_val_map50_95",
              "real_scale", "real_ap50", "real_recall", "real", "real_by_scale", "predictions", "weights")


def agnostic(res: ScoreResult, group: str | None = None):
    """The single merged class's ClassResult at the first threshold (overall or a group)."""
    r = res.overall if group is None else res.groups[group]
    t0 = r.iou_thresholds[0]
    return next(iter(r.per_threshold[t0].values()))


def _figs(c) -> dict:
    n = len(c.recall)
    return {"ap50": None if c.ap is None else round(float(c.ap), 6),
            "recall": round(float(c.recall[-1]), 6) if n and c.n_gt else 0.0,
            "precision_at_max_recall": round(float(c.precision[-1]), 6) if n else 0.0,
            "n_gt": c.n_gt, "n_det": c.n_det, "tp": c.tp, "fp": c.fp}


def arm_real_figures(agn: ScoreResult, per_class: ScoreResult) -> dict:
    """Class-agnostic AP50/recall overall and per group; per-class AP50 (not merged)."""
    out = _figs(agnostic(agn))
    out["per_group"] = {k: dict(_figs(agnostic(agn, k)), iou_type=agn.iou_type[k],
                                ignore_border_px=agn.border_px[k]) for k in agn.groups}
    out["per_class_ap50"] = {c: (None if v is None else round(float(v), 6))
                             for c, v in per_class.overall.ap.items()}
    out["iou_type_by_group"] = dict(agn.iou_type)
    return out


def _f(v, nd=3):
    return "-" if v is None else f"{v:.{nd}f}"


def summary_text(report: dict) -> str:
    d = report["device"]
    v = report["versions"]
    lines = [f"aerial-synth sim2real: {len(report['arms'])} arm(s), real set {report['real']['dir']} "
             f"({report['real']['images']} images, {report['real']['vehicles']} vehicles)",
             f"device {d['name']} ({d['used']}); aerial-synth {v['aerial_synth']}, ultralytics "
             f"{v['ultralytics']}, torch {v['torch']}",
             "real AP50: class-agnostic (vehicle), VOC07, IoU > 0.5; "
             f"iou type by group {report['scoring']['iou_type_by_group']}", ""]
    groups = list(report["arms"][0]["real"]["per_group"]) if report["arms"] else []
    head = (f"{'arm':<16} {'train img':>9} {'epochs':>6} {'seconds':>8} {'syn mAP50':>9} "
            f"{'real AP50':>9} {'recall':>6}" + "".join(f" {g[:14]:>14}" for g in groups))
    lines += [head, "-" * len(head)]
    for a in report["arms"]:
        row = (f"{a['name'][:16]:<16} {a['training_images']:>9} {a['epochs']:>6} {a['seconds']:>8.1f} "
               f"{_f(a['synthetic_val_map50']):>9} {_f(a['real_ap50']):>9} {_f(a['real_recall']):>6}")
        for g in groups:
            pg = a["real"]["per_group"][g]
            row += f" {_f(pg['ap50']) + '/' + _f(pg['recall'], 2):>14}"
        lines.append(row)
    if groups:
        lines.append("(per group: AP50/recall)")
    scales = report["parameters"].get("real_scale") or ["arm"]
    lines.append(f"real images {_SCALE_TEXT[scales[0]]}")
    for scale in scales[1:]:
        lines += ["", f"the same weights, real images {_SCALE_TEXT[scale]}:"]
        for a in report["arms"]:
            r = a["real_by_scale"][scale]
            row = f"{a['name'][:16]:<16} {'':>9} {'':>6} {'':>8} {'':>9} {_f(r['ap50']):>9} {_f(r['recall']):>6}"
            for g in groups:
                pg = r["real"]["per_group"][g]
                row += f" {_f(pg['ap50']) + '/' + _f(pg['recall'], 2):>14}"
            lines.append(row)
    return "\n".join(lines)


def _ms(d: dict) -> str:
    """mean +- sd over seeds."""
    return "-" if d.get("mean") is None else f"{d['mean']:.3f} ± {d['sd']:.3f}"


def _interval(v: dict | None) -> str:
    if not v or v.get("diff") is None:
        return "(baseline)" if v is None else "-"
    if v.get("lo") is None:
        return f"{v['diff']:+.3f}"
    return f"{v['diff']:+.3f} [{v['lo']:+.3f}, {v['hi']:+.3f}]"


def plan_summary_text(report: dict) -> str:
    """The table a person reads first: per arm AP50 mean +- sd over seeds, the paired
    difference with the baseline and its 95 % interval, "no difference" when it holds 0."""
    p, d, par = report["plan"], report["device"], report["parallel"]
    real = report["real"]
    lines = [f"aerial-synth sim2real --plan {p['path']}: {len(report['arms'])} arms x {len(p['seeds'])} seeds "
             f"({', '.join(map(str, p['seeds']))}), baseline {p['baseline']}",
             f"real set {real['dir']} ({real['images']} images, {real['vehicles']} vehicles); device {d['name']} "
             f"({d['used']}); {par['runs_at_once']} runs at once ({par['rule']}), {par['wall_seconds']:.0f} s",
             f"real AP50: class-agnostic, VOC07, IoU > 0.5, mean ± sd over seeds; vs {p['baseline']}: "
             f"difference of the means [{report['confidence']['level']:.0%} interval: "
             f"{report['confidence']['method']}]", ""]
    head = (f"{'arm':<10} {'kind':<9} {'train img':>9} {'export s':>8} {'img/s':>7} {'epochs':>6} "
            f"{'AP50':>15} {'vs ' + p['baseline'][:8]:>27}  verdict")
    lines += [head, "-" * len(head)]
    for a in report["arms"]:
        vs = a.get("vs_baseline")
        ep = sorted({r["epochs"] for r in a["runs"]})
        exp = ("-" if a["export_seconds"] is None else "reused" if a["export_reused"]
               else f"{a['export_seconds']:.0f}")
        lines.append(
            f"{a['name'][:10]:<10} {a['kind'][:9]:<9} {a['training_images']:>9} {exp:>8} "
            f"{_f(a['images_per_s']['mean'], 1):>7} {'/'.join(map(str, ep)):>6} {_ms(a['ap50']):>15} "
            f"{_interval(vs):>27}  {'' if vs is None else vs['verdict']}")
    groups = list(report["arms"][0]["per_group"]) if report["arms"] else []
    if len(groups) > 1:
        lines += ["", "per group, AP50 mean ± sd (vs baseline: difference [interval] verdict):"]
        for g in groups:
            lines.append(f"  {g}:")
            for a in report["arms"]:
                vs = (a.get("vs_baseline_per_group") or {}).get(g)
                lines.append(f"    {a['name'][:10]:<10} {_ms(a['per_group'][g]):>15}"
                             + ("" if vs is None else f"  {_interval(vs)}  {vs['verdict']}"))
    classes = sorted({c for a in report["arms"] for c in a["per_class"]})
    if classes:
        lines += ["", "per class (not merged), AP50 mean ± sd:",
                  f"  {'arm':<10}" + "".join(f" {c[:16]:>16}" for c in classes)]
        for a in report["arms"]:
            lines.append(f"  {a['name'][:10]:<10}" + "".join(
                f" {_ms(a['per_class'].get(c, {})):>16}" for c in classes))
    gpu = report.get("gpu_utilisation")
    if gpu:
        lines += ["", f"GPU busy (nvidia-smi, every {gpu['every_s']:g} s, {gpu['n']} samples): mean "
                  f"{_f(gpu['utilisation_mean_pct'], 0)} %, memory used up to {gpu['memory_used_max_mib']} MiB; "
                  "peak per run: " + ", ".join(f"{a['name']} {a['peak_gpu_mib']} MiB" for a in report["arms"])]
    return "\n".join(lines)


def score_summary_text(report: dict) -> str:
    """``sim2real score``: one row per weights file."""
    d, real = report["device"], report["real"]
    lines = [f"aerial-synth sim2real score: {len(report['arms'])} weights file(s) on {real['dir']} "
             f"({real['images']} images, {real['vehicles']} vehicles); device {d['name']} ({d['used']})",
             "real AP50: class-agnostic, VOC07, IoU > 0.5", ""]
    groups = list(report["arms"][0]["real"]["per_group"]) if report["arms"] else []
    head = f"{'weights':<24} {'gsd m':>6} {'real AP50':>9} {'recall':>6}" + "".join(f" {g[:14]:>14}" for g in groups)
    lines += [head, "-" * len(head)]
    for a in report["arms"]:
        lines.append(f"{a['name'][:24]:<24} {_f(a['gsd_m'], 3):>6} {_f(a['real_ap50']):>9} {_f(a['real_recall']):>6}"
                     + "".join(f" {_f(a['real']['per_group'][g]['ap50']):>14}" for g in groups))
    return "\n".join(lines)


_SCALE_TEXT = {"arm": "rescaled to each arm's synthetic GSD (--real-scale arm)",
               "native": "at their own pixels, not rescaled (--real-scale native)"}


def pr_chart(title: str, curves: dict) -> np.ndarray:
    """{label: ClassResult} -> a precision-recall chart (BGR)."""
    series = []
    for label, c in curves.items():
        if c.n_gt == 0:
            continue
        rec = np.concatenate(([0.0], c.recall)) if len(c.recall) else np.array([0.0])
        pre = np.concatenate(([1.0], c.precision)) if len(c.precision) else np.array([1.0])
        series.append((f"{label} AP {_f(c.ap)}", rec, pre))
    if not series:
        series = [("no truth", np.array([0.0]), np.array([0.0]))]
    return line_chart(title, series, "recall", "precision", xlim=(0.0, 1.0), ylim=(0.0, 1.02))


def best_f1_threshold(c) -> float:
    """The score at which the class-agnostic F1 is highest (1.0 without detections)."""
    if len(c.scores) == 0 or c.n_gt == 0:
        return 1.0
    f1 = 2 * c.precision * c.recall / np.maximum(c.precision + c.recall, 1e-12)
    return float(c.scores[int(np.argmax(f1))])


def contact_sheet(items, images, dets_by_image, threshold: float, iou_type_by_image,
                  tile_px: int = 480) -> np.ndarray:
    """Real images with truth and predictions (score >= threshold) drawn: truth found green,
    truth missed yellow, ignored (difficult / border) grey; predictions matching truth
    (IoU > 0.5) cyan, false positives red. ``images``: BGR arrays of ``items``."""
    import cv2

    cells = []
    for g, img, (xy, sc), hbb in zip(items, images, dets_by_image, iou_type_by_image):
        canvas = img.copy()
        keep = np.asarray(sc) >= threshold
        dxy = np.asarray(xy, np.float64).reshape(-1, 4, 2)[keep]
        gxy = g.polygons_xy_px.reshape(-1, 4, 2)
        a, b = (hbb_hull(dxy), hbb_hull(gxy)) if hbb else (dxy, gxy)
        iou = pairwise_iou(a, b) if len(a) and len(b) else np.zeros((len(a), len(b)))
        found = (iou > 0.5).any(0) if len(a) else np.zeros(len(b), bool)
        good = (iou > 0.5).any(1) if len(b) else np.zeros(len(a), bool)
        lw = max(1, int(round(max(img.shape[:2]) / 500)))
        for p, f, dif in zip(gxy, found, np.asarray(g.difficult, bool)):
            col = (160, 160, 160) if dif else ((0, 200, 0) if f else (0, 230, 255))
            cv2.polylines(canvas, [np.round(p).astype(np.int32)], True, col, lw + 1, cv2.LINE_AA)
        for p, ok in zip(dxy, good):
            col = (255, 255, 0) if ok else (0, 0, 255)
            cv2.polylines(canvas, [np.round(p).astype(np.int32)], True, col, lw, cv2.LINE_AA)
        s = tile_px / max(canvas.shape[:2])
        canvas = cv2.resize(canvas, (max(1, int(canvas.shape[1] * s)), max(1, int(canvas.shape[0] * s))),
                            interpolation=cv2.INTER_AREA)
        cell = np.full((tile_px + 22, tile_px, 3), 255, np.uint8)
        cell[22:22 + canvas.shape[0], :canvas.shape[1]] = canvas
        n_fp = int((~good).sum())
        n_miss = int((~found & ~np.asarray(g.difficult, bool)).sum())
        cv2.putText(cell, f"{g.name[:40]}  FP {n_fp}  missed {n_miss}", (4, 16),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.42, (0, 0, 0), 1, cv2.LINE_AA)
        cells.append(cell)
    if not cells:
        return np.full((64, 64, 3), 255, np.uint8)
    sheet = grid(cells, cols=min(3, len(cells)))
    legend = np.full((24, sheet.shape[1], 3), 255, np.uint8)
    x = 4
    for text, col in ((f"predictions with score >= {threshold:.3f}:", (0, 0, 0)), ("match", (255, 255, 0)),
                      ("false positive", (0, 0, 255)), ("  truth:", (0, 0, 0)), ("found", (0, 200, 0)),
                      ("missed", (0, 230, 255)), ("ignored", (160, 160, 160))):
        if col != (0, 0, 0):
            cv2.rectangle(legend, (x, 7), (x + 14, 17), col, 2)
            x += 18
        cv2.putText(legend, text, (x, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (0, 0, 0), 1, cv2.LINE_AA)
        x += 8 * len(text) + 10
    return np.vstack([legend, sheet])
