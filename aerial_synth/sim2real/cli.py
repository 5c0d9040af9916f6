"""``aerial-synth sim2real``. Imports nothing heavy at import time; without the [train]
extra the command prints one line (what to install) and exits with status 2."""

from __future__ import annotations

from ..safe_input import LABEL_GSD_RANGE_M
from ..validators import arg_choice, arg_float, arg_int

__all__ = ["register"]


def register(sub) -> None:
    p = sub.add_parser(
        "sim2real",
        help="what the data is worth: train a detector per synthetic set, score it on real images",
        description="Train one oriented-box detector (Ultralytics YOLO-OBB, the optional [train] "
        "extra) per synthetic set, predict the real images (rescaled to the synthetic GSD, cut "
        "into tiles, merged back with rotated NMS into their own pixel frame), score them "
        "(class-agnostic AP50, per class, per group) and write one report comparing the sets. "
        "Runs offline. See docs/sim2real.md.",
    )
    p.add_argument("--synthetic", action="append", required=True, metavar="[NAME=]DIR[,DIR]",
                   help="a synthetic set (an export with yolo-obb/ or a YOLO-OBB folder); repeat "
                   "for several arms, trained one after the other")
    p.add_argument("--real", required=True, metavar="DIR",
                   help="real images in DOTA layout (images/, labelTxt/ with gsd: headers), or a "
                   "folder of such folders (one group each)")
    p.add_argument("--out", required=True, metavar="DIR", help="new folder for the report")
    m = p.add_mutually_exclusive_group()
    m.add_argument("--model", default="yolo11n-obb.yaml", metavar="YAML",
                   help="model yaml, trained from scratch (yolo11n-obb.yaml)")
    m.add_argument("--weights", default=None, metavar="FILE", help="start from a local .pt file")
    b = p.add_mutually_exclusive_group()
    b.add_argument("--minutes", type=arg_float("--minutes", 0.0, lo_open=True), default=None,
                   metavar="M", help="training time per arm (10 unless --epochs)")
    b.add_argument("--epochs", type=arg_int("--epochs", 1), default=None, metavar="N")
    p.add_argument("--imgsz", type=arg_int("--imgsz", 32), default=640, metavar="PX", help="(640)")
    p.add_argument("--device", default="auto", metavar="auto|cpu|0",
                   help="auto: the first CUDA device, else the CPU (auto)")
    p.add_argument("--seed", type=arg_int("--seed", 0), default=0, metavar="S", help="(0)")
    p.add_argument("--batch", type=arg_int("--batch", 1), default=8, metavar="N", help="(8)")
    p.add_argument("--workers", type=arg_int("--workers", 0), default=2, metavar="N",
                   help="data-loader workers (2)")
    p.add_argument("--tile", type=arg_int("--tile", 32), default=None, metavar="PX",
                   help="real tiles of PX x PX at the synthetic GSD (--imgsz)")
    p.add_argument("--overlap", type=arg_int("--overlap", 0), default=None, metavar="PX",
                   help="tile overlap (tile / 5)")
    p.add_argument("--gsd", type=arg_float("--gsd", *LABEL_GSD_RANGE_M), default=None, metavar="M",
                   help="synthetic GSD to rescale real images to (default: the export's)")
    p.add_argument("--real-gsd", type=arg_float("--real-gsd", *LABEL_GSD_RANGE_M), default=None,
                   metavar="M", help="GSD of real images whose labels carry no gsd: header")
    p.add_argument("--real-scale", default="arm", metavar="arm|native|arm,native",
                   help="arm: rescale real images to each arm's GSD; native: predict them at their "
                   "own pixels; both: score both ways, the first is the headline (arm)")
    p.add_argument("--real-classes", default="small-vehicle,large-vehicle", metavar="LIST|all",
                   help="real truth classes kept (small-vehicle,large-vehicle)")
    p.add_argument("--conf", type=arg_float("--conf", 0.0, 1.0, hi_open=True), default=0.001,
                   metavar="F", help="lowest prediction score kept (0.001, as Ultralytics' mAP)")
    p.add_argument("--merge-iou", type=arg_float("--merge-iou", 0.0, 1.0, lo_open=True, hi_open=True),
                   default=0.3, metavar="T", help="rotated NMS across tiles, IoU > T (0.3, as the DOTA devkit)")
    p.add_argument("--iou-type", type=arg_choice("--iou-type", ("obb", "hbb", "auto")), default="auto",
                   metavar="obb|hbb|auto", help="auto: hbb for a group whose truth is axis-aligned (auto)")
    p.add_argument("--ignore-border", action="append", default=[], metavar="PX|GROUP=PX",
                   help="ignore truth and predictions centred within PX of the border (repeatable)")
    p.add_argument("--group", default=None, metavar="REGEX",
                   help="groups of real images by REGEX on the name (default: sub-folders)")
    p.add_argument("--contact-images", type=arg_int("--contact-images", 0), default=6, metavar="N",
                   help="real images on each contact sheet (6)")
    p.add_argument("--force", action="store_true", help="replace an existing report in --out")
    p.set_defaults(func=_cmd_sim2real)


def _cmd_sim2real(args) -> int:
    from .command import run_command  # lazy: the sim2real pipeline and scorer, not for --help

    return run_command(args)
