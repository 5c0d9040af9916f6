"""The body of ``aerial-synth sim2real`` (sim2real/cli.py parses the options and imports
this module only when the command runs)."""

from __future__ import annotations

from pathlib import Path

from ..evaluate.scoring import parse_ignore_border
from .config import Sim2RealConfig, Sim2RealError, parse_arms, parse_real_scale
from .pipeline import run_sim2real
from .report import plan_summary_text, score_summary_text, summary_text
from .ultra import require_train_extra

__all__ = ["run_command"]


def _classes(text: str):
    return None if text == "all" else tuple(c.strip() for c in text.split(",") if c.strip())


def run_command(args, export_config=None) -> int:
    """``aerial-synth sim2real`` once its options are parsed (sim2real/cli.py, which gives
    ``export_config``: a plan's export options -> ExportConfig, by the export's parser)."""
    if args.plan is not None and args.sim2real_action is None:
        if args.out is None:
            raise Sim2RealError("sim2real: missing required --out DIR")
        return _plan(args, export_config)  # the plan is checked first: a plan can be checked without torch
    require_train_extra()  # first: without the extra nothing else matters
    if args.sim2real_action == "score":
        return _score(args)
    if args.out is None:
        raise Sim2RealError("sim2real: missing required --out DIR")
    if not args.synthetic or args.real is None:
        raise Sim2RealError("sim2real: expected --plan PLAN.yaml, or --synthetic DIR and --real DIR")
    classes = _classes(args.real_classes)
    cfg = Sim2RealConfig(
        arms=parse_arms(args.synthetic), real=Path(args.real), out=Path(args.out), model=args.model,
        weights=None if args.weights is None else Path(args.weights), minutes=args.minutes,
        epochs=args.epochs, imgsz=args.imgsz, device=args.device, seed=args.seed, batch=args.batch,
        workers=args.workers, tile=args.tile, overlap=args.overlap, gsd=args.gsd,
        real_gsd=args.real_gsd, real_scale=parse_real_scale(args.real_scale), real_classes=classes,
        conf=args.conf, merge_iou=args.merge_iou,
        iou_type=args.iou_type, ignore_border=parse_ignore_border(args.ignore_border),
        group=args.group, contact_images=args.contact_images, force=args.force)

    report = run_sim2real(cfg)

    print(summary_text(report))
    print(f"report: {args.out}/report.json, summary.txt, pr*.png, contact_*.png")
    return 0


def _plan(args, export_config) -> int:
    import os

    from .experiment import run_plan

    given = [o for o, v in (("--synthetic", args.synthetic), ("--real", args.real), ("--weights", args.weights),
                            ("--minutes", args.minutes), ("--epochs", args.epochs)) if v]
    if given:
        raise Sim2RealError(f"--plan: {given[0]} comes from the plan (real, arms, train:); drop it")
    from .runs import cores

    report = run_plan(args.plan, Path(args.out), parallel=args.parallel, device=args.device,
                      export_workers=args.export_workers or cores() or os.cpu_count() or 1,
                      export_config=export_config)
    print(plan_summary_text(report))
    print(f"report: {args.out}/summary.txt, report.json, pr*.png, contact_*.png; weights: runs/*/seed*/weights.pt")
    return 0


def _score(args) -> int:
    from .experiment import run_score

    report = run_score(args.weights, Path(args.real), Path(args.out), device=args.device,
                       real_gsd=args.real_gsd, real_classes=_classes(args.real_classes),
                       real_scale=parse_real_scale(args.real_scale), iou_type=args.iou_type,
                       ignore_border=parse_ignore_border(args.ignore_border), group=args.group,
                       conf=args.conf, merge_iou=args.merge_iou, batch=args.batch,
                       contact_images=args.contact_images, force=args.force,
                       ignore_classes=_ignore_classes(args.ignore_classes))
    print(score_summary_text(report))
    print(f"report: {args.out}/summary.txt, report.json, pr*.png, contact_*.png")
    return 0


def _ignore_classes(values) -> dict[str, tuple[str, ...]]:
    out: dict[str, tuple[str, ...]] = {}
    for text in values:
        g, sep, cl = str(text).partition("=")
        classes = tuple(c.strip() for c in cl.split(",") if c.strip())
        if not sep or not g.strip() or not classes:
            raise Sim2RealError(f"--ignore-classes: expected GROUP=CLASS[,CLASS], got {text!r}")
        out[g.strip()] = out.get(g.strip(), ()) + classes
    return out
