"""The scoring options of ``aerial-synth eval`` (``--merge-classes``, ``--iou-type``,
``--ignore-border``, ``--group``): their arguments and the command path that uses them.

Imports nothing heavy at import time; :mod:`.scoring` does the work.
"""

from __future__ import annotations

from pathlib import Path

from ..validators import arg_choice

__all__ = ["add_scoring_args", "uses_scoring", "run_scored_eval", "scored_summary", "cmd_scored_eval"]


def add_scoring_args(parser) -> None:
    g = parser.add_argument_group("real sets (docs/sim2real.md)")
    g.add_argument("--merge-classes", default=None, metavar="NAME[=C1,C2]",
                   help="score class-agnostic: every class (or C1,C2; others dropped) becomes NAME")
    g.add_argument("--iou-type", default="obb", metavar="obb|hbb|auto",
                   type=arg_choice("--iou-type", ("obb", "hbb", "auto")),
                   help="hbb: detections and truth by their axis-aligned hulls; auto: hbb for a "
                   "group whose truth is all axis-aligned (obb)")
    g.add_argument("--ignore-border", action="append", default=[], metavar="PX|GROUP=PX",
                   help="truth and detections centred within PX of the image border are ignored "
                   "(repeatable, per group)")
    g.add_argument("--group", default=None, metavar="REGEX",
                   help="scores per group of images: REGEX's first capture group in the image name "
                   "(default: one group per sub-folder of a --gt collection)")


def uses_scoring(args) -> bool:
    """True when a scoring option is given or --gt is a collection of DOTA folders."""
    from .scoring import is_dota_folder  # lazy: the scorer, not for --help

    gt = Path(args.gt)
    collection = gt.is_dir() and not is_dota_folder(gt) and not any(p.suffix == ".txt" for p in gt.iterdir())
    return bool(args.merge_classes or args.iou_type != "obb" or args.ignore_border or args.group
                or collection)


def run_scored_eval(gt, pred, opts, *, iou: float = 0.5, metric: str = "voc07",
                    pred_format: str = "auto", names: str | None = None, split: str | None = None,
                    classes: list[str] | None = None):
    """Read ``gt`` (a DOTA folder or a collection) and ``pred``, then :func:`.scoring.score`."""
    from ..errors import EvaluationError  # lazy: the scorer, not for --help
    from .evaluation import (  # lazy: the scorer, not for --help
        PRED_FORMATS,
        detect_pred_format,
        read_task1_folder,
        read_yolo_predictions,
    )
    from .labels import parse_names  # lazy: the scorer, not for --help
    from .scoring import read_gt, score  # lazy: the scorer, not for --help

    items = read_gt(gt, split)
    pred_dir = Path(pred)
    if not pred_dir.is_dir():
        raise EvaluationError(f"--pred {pred}: " + ("expected a folder, found a file" if pred_dir.exists()
                                                    else "no such folder"))
    fmt = detect_pred_format(pred_dir) if pred_format == "auto" else pred_format
    if fmt == "dota-task1":
        dets = read_task1_folder(pred_dir, {g.name: i for i, g in enumerate(items)})
    elif fmt == "yolo-obb":
        if any("group" in g.extra for g in items):
            raise EvaluationError(f"--pred {pred}: a --gt collection of folders needs DOTA task-1 "
                                  f"predictions (Task1_<class>.txt with <folder>/<image> names)")
        if names is None:
            raise EvaluationError("--names: YOLO-OBB predictions hold class indices; give a data "
                                  "YAML or a comma list of class names")
        dets = read_yolo_predictions(pred_dir, items, parse_names(names), None)
    else:
        raise EvaluationError(f"--pred-format: expected one of {', '.join(PRED_FORMATS)}, got {pred_format!r}")
    return score(items, dets, opts, iou=iou, metric=metric, classes=classes)


def scored_summary(res) -> str:
    """The overall table, then one line per group."""
    from .evaluation import summary_table  # lazy: the scorer, not for --help

    o = res.options.to_dict()
    lines = [summary_table(res.overall),
             f"options: merge-classes {o['merge_classes'] or '-'}, iou-type {o['iou_type']}, "
             f"ignore-border {o['ignore_border_px'] or '-'}"]
    if res.groups:
        t0 = res.overall.iou_thresholds[0]
        head = f"{'group':<22} {'iou':>4} {'border':>6} {'mAP':>7} {'gt':>6} {'det':>7} {'tp':>6} {'recall':>7}"
        lines += ["", head, "-" * len(head)]
        for k, r in res.groups.items():
            n_gt = sum(c.n_gt for c in r.per_threshold[t0].values())
            tp = sum(c.tp for c in r.per_threshold[t0].values())
            det = sum(c.n_det for c in r.per_threshold[t0].values())
            m = "-" if r.map is None else f"{r.map:.4f}"
            rec = tp / n_gt if n_gt else 0.0
            lines.append(f"{k[:22]:<22} {res.iou_type[k]:>4} {res.border_px[k]:>6g} {m:>7} {n_gt:>6} "
                         f"{det:>7} {tp:>6} {rec:>7.3f}")
    return "\n".join(lines)


def cmd_scored_eval(args, out, report_as=None) -> int:
    """``aerial-synth eval`` with scoring options (called by the eval command)."""
    from ..io_utils import atomic_write_json, atomic_write_text  # lazy: the scorer, not for --help
    from .evaluation import write_eval_report  # lazy: the scorer, not for --help
    from .scoring import ScoringOptions  # lazy: the scorer, not for --help

    opts = ScoringOptions.from_text(args.merge_classes, args.iou_type, args.ignore_border, args.group)
    classes = None
    if args.classes is not None:
        classes = [c.strip() for c in args.classes.split(",") if c.strip()]
    res = run_scored_eval(args.gt, args.pred, opts, iou=args.iou, metric=args.metric,
                          pred_format=args.pred_format, names=args.names, split=args.split,
                          classes=classes)
    text = scored_summary(res)
    print(text)
    if out is not None:
        inputs = {"gt": str(args.gt), "pred": str(args.pred), "iou": args.iou, "metric": args.metric,
                  "pred_format": args.pred_format}
        write_eval_report(res.overall, out, inputs)
        data = res.to_dict()
        data["inputs"] = inputs
        atomic_write_json(out / "eval.json", data)
        atomic_write_text(out / "summary.txt", text + "\n")
        print(f"report: {report_as or out}/eval.json, summary.txt, pr_<class>.png")
    return 0
