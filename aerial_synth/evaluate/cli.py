"""``aerial-synth eval``, ``aerial-synth mix`` and ``aerial-synth stats``.

Imports nothing heavy at import time (``aerial-synth --help`` stays instant).
"""

from __future__ import annotations

import sys
from pathlib import Path

from ..errors import EvaluationError
from ..out_guard import out_lock, refuse_here, remove_dead_temps, staged_dir
from ..safe_input import LABEL_GSD_RANGE_M
from ..validators import arg_choice, arg_float, arg_int
from .scoring_cli import add_scoring_args, cmd_scored_eval, uses_scoring

__all__ = ["register"]


def register(sub) -> None:
    e = sub.add_parser(
        "eval",
        help="oriented-box average precision of predictions against DOTA ground truth",
        description="Oriented-box AP per class and mAP, matched as the DOTA devkit's task-1 "
        "evaluation does (greedy by score, IoU > threshold, difficult ignored). See "
        "docs/evaluate.md.",
    )
    e.add_argument("--gt", required=True, metavar="DIR",
                   help="DOTA labelTxt folder (or a folder with labelTxt/, <split>/labelTxt/, an export)")
    e.add_argument("--pred", required=True, metavar="DIR",
                   help="Task1_<class>.txt files, or Ultralytics YOLO-OBB prediction txt files")
    e.add_argument("--pred-format", type=arg_choice("--pred-format", ("auto", "dota-task1", "yolo-obb")),
                   default="auto", metavar="auto|dota-task1|yolo-obb", help="(auto)")
    e.add_argument("--names", default=None, metavar="YAML|LIST",
                   help="class names for YOLO-OBB class indices: a data YAML or a comma list")
    e.add_argument("--images", default=None, metavar="DIR",
                   help="images that size normalised YOLO-OBB predictions (default: next to --gt)")
    e.add_argument("--split", default=None, metavar="NAME",
                   help="split of a DOTA root or export given as --gt (val, then test, then train)")
    e.add_argument("--iou", type=arg_float("--iou", 0.0, 1.0, hi_open=True), default=0.5,
                   metavar="T", help="a match needs IoU > T (0.5; coco uses 0.50:0.05:0.95)")
    e.add_argument("--metric", type=arg_choice("--metric", ("voc07", "all-point", "coco")),
                   default="voc07", metavar="voc07|all-point|coco", help="(voc07, as the DOTA devkit)")
    e.add_argument("--classes", default=None, metavar="LIST",
                   help="comma list of classes to report (default: all in gt or predictions)")
    e.add_argument("--out", default=None, metavar="DIR",
                   help="write eval.json, summary.txt and pr_<class>.png here")
    add_scoring_args(e)
    e.set_defaults(func=_cmd_eval)

    m = sub.add_parser(
        "mix",
        help="mix real and synthetic images into one training set (deterministic, linked)",
        description="Mix real (DOTA-format) and synthetic images with an exact real share. "
        "Images are hard-linked (copied across devices); real images can be rescaled to the "
        "synthetic GSD and cut into tiles as the DOTA devkit's splitter does. The validation "
        "split is real images only by default. See docs/evaluate.md.",
    )
    m.add_argument("--real", required=True, metavar="DIR",
                   help="real images: DOTA layout, or a YOLO-OBB folder (images/, labels/, data.yaml)")
    m.add_argument("--synthetic", required=True, metavar="DIR", help="an aerial-synth export or DOTA folder")
    g = m.add_mutually_exclusive_group(required=True)
    g.add_argument("--real-fraction", type=arg_float("--real-fraction", 0.0, 1.0), metavar="F",
                   help="real images / all training images, in [0, 1]")
    g.add_argument("--real-images", type=arg_int("--real-images", 0), metavar="N",
                   help="number of real training images added to the synthetic ones")
    m.add_argument("--synthetic-images", type=arg_int("--synthetic-images", 0), default=None,
                   metavar="N", help="use N synthetic training images (default: all)")
    m.add_argument("--out", required=True, metavar="DIR", help="new folder for the mix")
    m.add_argument("--format", type=arg_choice("--format", ("dota", "yolo-obb", "dota,yolo-obb")),
                   default="dota", metavar="dota|yolo-obb|dota,yolo-obb", help="(dota)")
    m.add_argument("--seed", type=arg_int("--seed", 0), default=0, metavar="S", help="(0)")
    m.add_argument("--val", type=arg_choice("--val", ("real", "synthetic", "both")), default="real",
                   metavar="real|synthetic|both", help="what the validation split holds (real)")
    m.add_argument("--val-fraction", type=arg_float("--val-fraction", 0.0, 1.0, hi_open=True),
                   default=0.2, metavar="F",
                   help="share of real source images held out for val when --real has no val split (0.2)")
    m.add_argument("--tile", type=arg_int("--tile", 1), default=None, metavar="PX",
                   help="cut real images into PX x PX tiles (DOTA devkit splitter)")
    m.add_argument("--overlap", type=arg_int("--overlap", 0), default=None, metavar="PX",
                   help="tile overlap (200; with --tile only)")
    m.add_argument("--keep-threshold", type=arg_float("--keep-threshold", 0.0, 1.0, lo_open=True),
                   default=0.7, metavar="F",
                   help="keep a cut box when this share of its area is inside the tile (0.7)")
    m.add_argument("--gsd", type=arg_float("--gsd", *LABEL_GSD_RANGE_M), default=None, metavar="M",
                   help="rescale real images to M metres per pixel first (their gsd: header)")
    m.add_argument("--real-gsd", type=arg_float("--real-gsd", *LABEL_GSD_RANGE_M), default=None,
                   metavar="M", help="GSD of real images whose labels carry none (YOLO-OBB folders)")
    m.add_argument("--gsd-missing", type=arg_choice("--gsd-missing", ("error", "keep", "skip")),
                   default="error", metavar="error|keep|skip",
                   help="a real image without a gsd: header with --gsd (error)")
    m.add_argument("--classes", default="small-vehicle,large-vehicle", metavar="LIST|all",
                   help="classes kept in the labels (small-vehicle,large-vehicle)")
    m.add_argument("--force", action="store_true", help="replace an existing mix in --out")
    m.set_defaults(func=_cmd_mix)

    s = sub.add_parser(
        "stats",
        help="dataset statistics and, with --compare, the domain-gap report",
        description="Per-dataset statistics (vehicles per image, box sizes in px and m, "
        "aspect, heading, nearest neighbours, flags, classes, brightness, contrast, colour, "
        "vehicle contrast) and, with --compare, each distribution side by side with its KS "
        "and Wasserstein distance, largest gaps first. See docs/evaluate.md.",
    )
    s.add_argument("dir", metavar="DIR",
                   help="export, DOTA folder, YOLO-OBB folder (images/, labels/, data YAML), "
                   "VEDAI folder or a folder of images")
    s.add_argument("--compare", default=None, metavar="DIR2", help="second dataset")
    s.add_argument("--out", required=True, metavar="DIR", help="report folder (stats.json, PNGs)")
    s.add_argument("--gsd", type=arg_float("--gsd", *LABEL_GSD_RANGE_M), default=None, metavar="M",
                   help="GSD of DIR where its labels carry none")
    s.add_argument("--compare-gsd", type=arg_float("--compare-gsd", *LABEL_GSD_RANGE_M), default=None,
                   metavar="M", help="GSD of DIR2 where its labels carry none")
    s.add_argument("--max-images", type=arg_int("--max-images", 1), default=500, metavar="N",
                   help="pixel statistics on at most N images per dataset, drawn by --seed (500)")
    s.add_argument("--seed", type=arg_int("--seed", 0), default=0, metavar="S", help="(0)")
    s.add_argument("--classes", default="small-vehicle,large-vehicle", metavar="LIST|all",
                   help="classes whose boxes are measured (small-vehicle,large-vehicle)")
    s.set_defaults(func=_cmd_stats)


def _classes(text):
    if text is None:
        return None
    out = [c.strip() for c in text.split(",") if c.strip()]
    if not out:
        raise EvaluationError(f"--classes: expected a comma list of class names, got {text!r}")
    return out


def _cmd_eval(args) -> int:
    from .evaluation import check_report_dir  # lazy: shapely

    out = None
    if args.out is not None:
        out = check_report_dir(args.out, [("--gt", Path(args.gt)), ("--pred", Path(args.pred))])
    if out is None:
        return cmd_scored_eval(args, None) if uses_scoring(args) else _eval(args, None)
    # the report is built beside --out and put in place at the end: a failure leaves nothing
    with out_lock(args.out, "eval"), staged_dir(out) as build:
        if uses_scoring(args):  # --merge-classes, --iou-type, --ignore-border, --group
            return cmd_scored_eval(args, build, out)
        return _eval(args, build, out)


def _eval(args, out, report_as=None) -> int:
    from .evaluation import run_eval, summary_table, write_eval_report  # lazy: shapely

    res = run_eval(args.gt, args.pred, iou=args.iou, metric=args.metric, pred_format=args.pred_format,
                   names=args.names, images=args.images, split=args.split,
                   classes=_classes(args.classes))
    print(summary_table(res))
    if out is not None:
        write_eval_report(res, out, {"gt": str(args.gt), "pred": str(args.pred), "iou": args.iou,
                                     "metric": args.metric, "pred_format": args.pred_format})
        print(f"report: {report_as or out}/eval.json, summary.txt, pr_<class>.png")
    return 0


def _cmd_mix(args) -> int:
    from .mix import MixConfig, make_mix  # lazy: shapely, OpenCV; the parser is built at --help

    refuse_here(args.out)  # the mix is built beside --out and renamed into place
    if args.overlap is not None and args.tile is None:
        raise EvaluationError(f"--overlap {args.overlap}: applies to tiles; give --tile PX too, "
                              "or drop --overlap")
    classes = None if args.classes == "all" else _classes(args.classes)
    cfg = MixConfig(
        real=Path(args.real), synthetic=Path(args.synthetic), out=Path(args.out),
        real_fraction=args.real_fraction, real_images=args.real_images,
        synthetic_images=args.synthetic_images, format=args.format, seed=args.seed,
        val=args.val, val_fraction=args.val_fraction, tile=args.tile,
        overlap=200 if args.overlap is None else args.overlap,
        keep_threshold=args.keep_threshold, gsd=args.gsd, gsd_missing=args.gsd_missing,
        real_gsd=args.real_gsd,
        classes=classes, force=args.force,
    )
    with out_lock(args.out, "mix"):
        remove_dead_temps(args.out)  # left by a killed mix: no live run owns them now
        res = make_mix(cfg)
    c = res["counts"]
    print(f"mix: {c['train_real']} real + {c['train_synthetic']} synthetic training images "
          f"(real share {c['real_share']:.4f}), {c['val_real']} real + {c['val_synthetic']} "
          f"synthetic validation images -> {args.out}")
    if c.get("copied"):
        print(f"note: {c['copied']} files copied (no hard link across devices); see manifest.json",
              file=sys.stderr)
    return 0


def _cmd_stats(args) -> int:
    # lazy: shapely and OpenCV load only when stats runs (the parser is built at --help)
    from . import evaluation, stats

    if args.compare_gsd is not None and args.compare is None:
        raise EvaluationError(f"--compare-gsd {args.compare_gsd:g}: is the GSD of --compare DIR2; "
                              "give --compare too, or drop --compare-gsd")
    inputs = [("DIR", Path(args.dir))] + ([("--compare", Path(args.compare))] if args.compare else [])
    out = evaluation.check_report_dir(args.out, inputs)
    with out_lock(args.out, "stats"), staged_dir(out) as build:  # nothing half-written
        text = stats.run_stats(Path(args.dir), build, report_as=out,
                               compare=Path(args.compare) if args.compare else None,
                               gsd=args.gsd, compare_gsd=args.compare_gsd,
                               max_images=args.max_images, seed=args.seed,
                               classes=None if args.classes == "all" else _classes(args.classes))
    print(text)
    return 0
