"""``aerial-synth eval``: read ground truth and predictions, compute AP, write a report.

Ground truth: a DOTA labelTxt folder. Predictions: DOTA task-1 files (``Task1_<class>.txt``,
lines ``image score x1 y1 .. x4 y4``) or Ultralytics YOLO-OBB prediction files
(``<image>.txt``, lines ``cls x1 y1 .. x4 y4 conf``, normalised), whose pixel sizes come from
the ground truth's images.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import EvaluationError
from ..formats import yolo_obb
from ..io_utils import (
    atomic_write_bytes,
    atomic_write_json,
    atomic_write_text,
    check_output_dir,
    is_inside,
)
from ..safe_input import MAX_COORD_PX, class_name, quote, shown
from .ap import METRICS, Detections, EvalResult, evaluate
from .labels import (
    ImageLabels,
    find_image,
    image_size,
    parse_names,
    read_dota_folder,
    read_lines,
    resolve_dota_folder,
)
from .plots import line_chart, png_bytes

__all__ = ["PRED_FORMATS", "read_task1_folder", "read_yolo_predictions", "detect_pred_format",
           "run_eval", "summary_table", "write_eval_report"]

PRED_FORMATS = ("auto", "dota-task1", "yolo-obb")


def detect_pred_format(pred_dir: Path) -> str:
    files = [p for p in pred_dir.iterdir() if p.suffix == ".txt" and p.is_file()]
    if any(p.name.startswith("Task1_") for p in files):
        return "dota-task1"
    if (pred_dir / "labels").is_dir():
        return "yolo-obb"
    if files:
        return "yolo-obb"
    raise EvaluationError(f"--pred {pred_dir}: no prediction files (Task1_<class>.txt or <image>.txt) found")


def read_task1_folder(pred_dir: Path, image_index: dict[str, int]) -> Detections:
    """Every ``Task1_<class>.txt`` of a folder -> detections (image names checked)."""
    files = sorted(p for p in pred_dir.iterdir() if p.name.startswith("Task1_") and p.suffix == ".txt")
    if not files:
        raise EvaluationError(f"--pred {pred_dir}: no Task1_<class>.txt files found")
    img, cls, score, xy = [], [], [], []
    for f in files:
        name = f.stem[len("Task1_"):]
        if not name:
            raise EvaluationError(f"{f}: expected Task1_<class>.txt, got an empty class name")
        class_name(name, f"--pred {shown(f)}", EvaluationError)  # text a report can print
        lines = _read_lines(f)
        fast = _task1_fast(lines, image_index)
        if fast is not None:
            img += fast[0]
            cls += [name] * len(fast[0])
            score.append(fast[1])
            xy.append(fast[2])
            continue
        for n, raw in enumerate(lines, start=1):
            ln = raw.strip()
            if not ln:
                continue
            t = ln.split()
            if len(t) != 10:
                raise EvaluationError(f"{f}:{n}: expected 'image score x1 y1 x2 y2 x3 y3 x4 y4' "
                                      f"(10 fields), got {len(t)} fields: {quote(ln)}")
            i = image_index.get(t[0])
            if i is None:
                raise EvaluationError(f"{f}:{n}: image {quote(t[0])} is not in the ground truth "
                                      f"({len(image_index)} images in --gt)")
            vals = []
            for k, tok in enumerate(t[1:]):
                try:
                    v = float(tok)
                except ValueError:
                    v = float("nan")
                what = "score" if k == 0 else f"coordinate {k}"
                if not np.isfinite(v):
                    raise EvaluationError(f"{f}:{n}: expected {what} as a finite number, got {quote(tok)}")
                if k and abs(v) > MAX_COORD_PX:
                    raise EvaluationError(f"{f}:{n}: expected {what} within +-{MAX_COORD_PX:g}, "
                                          f"got {quote(tok)}")
                vals.append(v)
            img.append(i)
            cls.append(name)
            score.append(np.array([vals[0]]))
            xy.append(np.asarray(vals[1:], np.float64).reshape(1, 4, 2))
    return Detections(np.asarray(img, np.int64), cls,
                      np.concatenate(score) if score else np.zeros(0),
                      np.concatenate(xy) if xy else np.zeros((0, 4, 2)))


def _task1_fast(lines, image_index):
    """Well-formed task-1 lines in one numpy conversion; None sends the file to the strict
    line-by-line reader, which names the bad line."""
    rows = [ln.split() for ln in lines if ln.strip()]
    if any(len(r) != 10 for r in rows):
        return None
    try:
        idx = [image_index[r[0]] for r in rows]
        vals = np.array([r[1:] for r in rows], dtype=np.float64).reshape(-1, 9)
    except (KeyError, ValueError):
        return None
    if not np.isfinite(vals).all() or (vals.size and np.abs(vals[:, 1:]).max() > MAX_COORD_PX):
        return None
    return idx, vals[:, 0], vals[:, 1:].reshape(-1, 4, 2)


def _read_lines(path: Path) -> list[str]:
    return read_lines(path)


def read_yolo_predictions(pred_dir: Path, gt: list[ImageLabels], names: list[str],
                          images_dir: Path | None) -> Detections:
    """Ultralytics ``save_txt=True, save_conf=True`` OBB files -> detections in pixels."""
    folder = pred_dir / "labels" if (pred_dir / "labels").is_dir() else pred_dir
    files = sorted(p for p in folder.iterdir() if p.suffix == ".txt" and p.is_file())
    if not files:
        raise EvaluationError(f"--pred {pred_dir}: no YOLO-OBB prediction files (*.txt) found")
    by_name = {g.name: i for i, g in enumerate(gt)}
    img, cls, score, xy = [], [], [], []
    for f in files:
        i = by_name.get(f.stem)
        if i is None:
            raise EvaluationError(f"{f}: image {f.stem!r} is not in the ground truth "
                                  f"({len(gt)} images in --gt)")
        g = gt[i]
        if g.size_wh is None:
            path = g.image_path or find_image(images_dir, g.name)
            if path is None:
                raise EvaluationError(f"{f}: YOLO-OBB coordinates are normalised and no image "
                                      f"{g.name}.* was found to size them (give --images DIR)")
            g.size_wh = image_size(path)
        pred = yolo_obb.labels_from_lines(_read_lines(f), str(f), names, g.size_wh, with_conf=True)
        img += [i] * len(pred)
        cls += pred.classes
        score.append(pred.scores)
        xy.append(pred.polygons_xy_px)
    return Detections(np.asarray(img, np.int64), cls,
                      np.concatenate(score) if score else np.zeros(0),
                      np.concatenate(xy) if xy else np.zeros((0, 4, 2)))


def run_eval(gt: str | Path, pred: str | Path, *, iou: float = 0.5, metric: str = "voc07",
             pred_format: str = "auto", names: str | None = None, images: str | Path | None = None,
             split: str | None = None, classes: list[str] | None = None) -> EvalResult:
    """Read ``gt`` (DOTA labelTxt) and ``pred`` and evaluate. Raises EvaluationError on bad input."""
    if metric not in METRICS:
        raise EvaluationError(f"--metric: expected one of {', '.join(METRICS)}, got {metric!r}")
    if not (0.0 <= iou < 1.0):
        raise EvaluationError(f"--iou: expected a number in [0, 1), got {iou!r}")
    labels_dir, images_dir = resolve_dota_folder(gt, split, option="--gt")
    if images is not None:
        images_dir = Path(images)
        if not images_dir.is_dir():
            raise EvaluationError(f"--images {images}: no such folder")
    gt_items = read_dota_folder(labels_dir, images_dir, option="--gt")
    pred_dir = Path(pred)
    if not pred_dir.exists():
        raise EvaluationError(f"--pred {pred}: no such folder")
    if not pred_dir.is_dir():
        raise EvaluationError(f"--pred {pred}: expected a folder, found a file")
    fmt = detect_pred_format(pred_dir) if pred_format == "auto" else pred_format
    if fmt == "dota-task1":
        dets = read_task1_folder(pred_dir, {g.name: i for i, g in enumerate(gt_items)})
    elif fmt == "yolo-obb":
        if names is None:
            raise EvaluationError("--names: YOLO-OBB predictions hold class indices; give a data "
                                  "YAML or a comma list of class names")
        for g in gt_items:
            g.image_path = g.image_path or find_image(images_dir, g.name)
        dets = read_yolo_predictions(pred_dir, gt_items, parse_names(names), images_dir)
    else:
        raise EvaluationError(f"--pred-format: expected one of {', '.join(PRED_FORMATS)}, got {pred_format!r}")
    return evaluate(gt_items, dets, iou_threshold=iou, metric=metric, classes=classes)


def summary_table(res: EvalResult) -> str:
    """One screen: per class AP, ground truth, detections, TP/FP at the first threshold."""
    t0 = res.iou_thresholds[0]
    thr = "IoU 0.50:0.95" if res.metric == "coco" else f"IoU > {t0:.2f}"
    head = f"{'class':<22} {'AP':>7} {'gt':>7} {'diff':>6} {'det':>8} {'tp':>7} {'fp':>8} {'recall':>7}"
    lines = [f"oriented-box AP ({res.metric}, {thr}), {res.n_images} images", head, "-" * len(head)]
    for c in res.classes:
        r = res.per_threshold[t0][c]
        ap = "-" if res.ap[c] is None else f"{res.ap[c]:.4f}"
        rec = r.tp / r.n_gt if r.n_gt else 0.0
        lines.append(f"{c[:22]:<22} {ap:>7} {r.n_gt:>7} {r.n_difficult:>6} {r.n_det:>8} {r.tp:>7} {r.fp:>8} {rec:>7.3f}")
    lines.append("-" * len(head))
    lines.append(f"{'mAP':<22} {'-' if res.map is None else f'{res.map:.4f}':>7}")
    if res.metric == "coco":
        d = res.to_dict()
        f4 = lambda v: "-" if v is None else f"{v:.4f}"
        lines.append(f"mAP50 {f4(d.get('map50'))}  mAP75 {f4(d.get('map75'))}  "
                     f"(TP/FP columns at IoU > {t0:.2f})")
    return "\n".join(lines)


def write_eval_report(res: EvalResult, out: Path, inputs: dict) -> list[Path]:
    """eval.json, summary.txt and pr_<class>.png (one curve per threshold for coco)."""

    written = []
    data = res.to_dict()
    data["inputs"] = inputs
    written.append(atomic_write_json(out / "eval.json", data))
    written.append(atomic_write_text(out / "summary.txt", summary_table(res) + "\n"))
    for c in res.classes:
        series = []
        for t in (res.iou_thresholds if len(res.iou_thresholds) <= 3 else (0.5, 0.75, 0.95)):
            r = res.per_threshold[t][c]
            if r.n_gt == 0:
                continue
            rec = np.concatenate(([0.0], r.recall)) if len(r.recall) else np.array([0.0])
            pre = np.concatenate(([1.0], r.precision)) if len(r.precision) else np.array([1.0])
            ap = "-" if r.ap is None else f"{r.ap:.3f}"
            series.append((f"IoU>{t:.2f} AP {ap}", rec, pre))
        if not series:
            continue
        img = line_chart(f"precision-recall: {c}", series, "recall", "precision",
                         xlim=(0.0, 1.0), ylim=(0.0, 1.02))
        safe = "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in c)
        written.append(atomic_write_bytes(out / f"pr_{safe}.png", png_bytes(img)))
    return written


def check_report_dir(out, inputs: list[tuple[str, Path]]) -> Path:
    """Refuse an --out that is a file, unwritable, or inside / around an input folder."""
    out_p = check_output_dir(out, "--out")
    for opt, p in inputs:
        if p is None:
            continue
        if is_inside(out_p, p):
            raise EvaluationError(f"--out {out}: is inside the input folder {opt} {p}; choose another folder")
        if is_inside(p, out_p):
            raise EvaluationError(f"--out {out}: contains the input folder {opt} {p}; choose another folder")
    return out_p
