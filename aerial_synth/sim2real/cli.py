"""``aerial-synth sim2real``. Imports nothing heavy at import time; without the [train]
extra the command prints one line (what to install) and exits with status 2."""

from __future__ import annotations

from ..cli import Parser, one_line_usage_error
from ..dataset.cli import config_from_args
from ..dataset.cli import register as register_export
from ..safe_input import LABEL_GSD_RANGE_M
from ..validators import arg_choice, arg_float, arg_int
from .config import Sim2RealError
from .plan import EXPORT_SET_BY_SIM2REAL

__all__ = ["register", "export_parser", "export_argv", "export_config"]


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
    p.add_argument("--plan", default=None, metavar="PLAN.yaml",
                   help="an experiment as one file: real set, baseline, seeds, training, arms "
                   "(exports built here, existing sets); every arm trains once per seed, --parallel "
                   "runs at once; the report gives means, spreads and paired intervals "
                   "(docs/sim2real.md). Replaces --synthetic, --real and the training options")
    p.add_argument("--parallel", type=_parallel, default="auto", metavar="N|auto",
                   help="with --plan: runs trained at once on the device (auto: as many as "
                   "device memory and CPU cores allow, docs/sim2real.md)")
    p.add_argument("--export-workers", type=arg_int("--export-workers", 1, 1024), default=None,
                   metavar="K", help="with --plan: processes for the export arms (the CPU cores)")
    p.add_argument("--synthetic", action="append", default=None, metavar="[NAME=]DIR[,DIR]",
                   help="a synthetic set (an export with yolo-obb/ or a YOLO-OBB folder); repeat "
                   "for several arms, trained one after the other")
    p.add_argument("--real", default=None, metavar="DIR",
                   help="real images in DOTA layout (images/, labelTxt/ with gsd: headers), or a "
                   "folder of such folders (one group each)")
    p.add_argument("--out", default=None, metavar="DIR", help="new folder for the report (with "
                   "--plan: new, or the folder of an earlier run of a plan, whose exports and "
                   "finished runs are reused)")
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
    p.set_defaults(func=_cmd_sim2real, sim2real_action=None)
    _register_score(p.add_subparsers(dest="sim2real_action", metavar="score"))


def _parallel(text: str):
    if str(text).strip() == "auto":
        return "auto"
    return arg_int("--parallel", 1, 1024)(text)


def _register_score(sub) -> None:
    sub.required = False
    s = sub.add_parser(
        "score", help="predict and score real images with kept weights (no training)",
        description="Predict real images with weights kept by sim2real (runs/<arm>/seed<S>/"
        "weights.pt) and score them: the same tiling (the weights' image size and GSD), merge, "
        "scoring and report layout as a training run. Runs on the CPU too.")
    s.add_argument("--weights", nargs="+", required=True, metavar="FILE", help="weights files (.pt)")
    s.add_argument("--real", required=True, metavar="DIR", help="real images (as sim2real --real)")
    s.add_argument("--out", required=True, metavar="DIR", help="new folder for the report")
    s.add_argument("--device", default="auto", metavar="auto|cpu|0", help="(auto)")
    s.add_argument("--real-gsd", type=arg_float("--real-gsd", 0.0, lo_open=True), default=None, metavar="M",
                   help="GSD of real images whose labels carry no gsd: header")
    s.add_argument("--real-scale", default="arm", metavar="arm|native|arm,native", help="as sim2real (arm)")
    s.add_argument("--real-classes", default="small-vehicle,large-vehicle", metavar="LIST|all",
                   help="real truth classes kept (small-vehicle,large-vehicle)")
    s.add_argument("--ignore-border", action="append", default=[], metavar="PX|GROUP=PX",
                   help="ignore truth and predictions centred within PX of the border")
    s.add_argument("--ignore-classes", action="append", default=[], metavar="GROUP=CLASS[,CLASS]",
                   help="drop predictions of these classes on GROUP's images (a set labelled with "
                   "cars only: ucas_aod=large-vehicle); repeatable")
    s.add_argument("--iou-type", type=arg_choice("--iou-type", ("obb", "hbb", "auto")), default="auto",
                   metavar="obb|hbb|auto", help="(auto)")
    s.add_argument("--group", default=None, metavar="REGEX", help="groups by REGEX (default: sub-folders)")
    s.add_argument("--conf", type=arg_float("--conf", 0.0, 1.0, hi_open=True), default=0.001, metavar="F")
    s.add_argument("--merge-iou", type=arg_float("--merge-iou", 0.0, 1.0, lo_open=True, hi_open=True),
                   default=0.3, metavar="T")
    s.add_argument("--batch", type=arg_int("--batch", 1), default=8, metavar="N", help="tiles per batch (8)")
    s.add_argument("--contact-images", type=arg_int("--contact-images", 0), default=6, metavar="N")
    s.add_argument("--force", action="store_true", help="replace an existing score report in --out")
    s.set_defaults(func=_cmd_sim2real, sim2real_action="score")


def _cmd_sim2real(args) -> int:
    from .command import run_command  # lazy: the sim2real pipeline and scorer, not for --help

    return run_command(args, export_config)


# -- export arms of a plan: the export command's own options, checks and messages -------------------

def export_parser():
    """The ``export`` command's own parser, raising its one line instead of exiting."""
    class Raising(Parser):
        def error(self, message):
            raise Sim2RealError(one_line_usage_error("aerial-synth export", message))

    top = Raising(prog="aerial-synth")
    sub = top.add_subparsers(dest="command", parser_class=Raising)
    register_export(sub)
    return sub.choices["export"]


def export_argv(arm: str, value) -> list[str]:
    """The plan's ``export:`` mapping as ``export`` options (``scene_mix`` -> ``--scene-mix``;
    true: a flag; false: left out; a list: a comma list). ``format`` gains ``yolo-obb``."""
    if not isinstance(value, dict):
        raise Sim2RealError(f"arm {arm}: export: expected a mapping of export options, got {value!r}")
    p = export_parser()
    opts = p._option_string_actions
    argv = []
    fmt = None
    for k, v in value.items():
        opt = "--" + str(k).replace("_", "-")
        if str(k) in EXPORT_SET_BY_SIM2REAL:
            raise Sim2RealError(f"arm {arm}: export: {k!r} is set by sim2real (exports go into the "
                                f"report folder, with --export-workers processes)")
        if opt not in opts or opt in ("--help", "-h"):
            raise Sim2RealError(f"arm {arm}: export: unknown option {k!r} (the export command's long "
                                f"options, '-' written '_'; see aerial-synth export --help)")
        flag = opts[opt].nargs == 0
        if flag:
            if not isinstance(v, bool):
                raise Sim2RealError(f"arm {arm}: export: {k}: expected true or false, got {v!r}")
            if v:
                argv.append(opt)
            continue
        if isinstance(v, bool) or v is None or isinstance(v, dict):
            raise Sim2RealError(f"arm {arm}: export: {k}: expected a value, got {v!r}")
        text = ",".join(map(str, v)) if isinstance(v, list) else str(v)
        if k == "format":
            fmt = text
            continue
        argv += [opt, text]
    names = [f.strip() for f in (fmt or "yolo-obb").split(",") if f.strip()]
    if "yolo-obb" not in names:
        names.append("yolo-obb")
    return argv + ["--format", ",".join(names)]


def export_config(arm: str, value):
    """A plan's ``export:`` mapping -> the ExportConfig the ``export`` command would build
    from the same options (its parser's and ExportConfig's checks and messages)."""
    args = export_parser().parse_args(export_argv(arm, value) + ["--out", "unused"])
    return config_from_args(args)

