"""The body of ``aerial-synth sim2real`` (sim2real/cli.py parses the options and imports
this module only when the command runs)."""

from __future__ import annotations

from pathlib import Path

from ..evaluate.scoring import parse_ignore_border
from .config import Sim2RealConfig, parse_arms, parse_real_scale
from .pipeline import run_sim2real
from .report import summary_text
from .ultra import require_train_extra

__all__ = ["run_command"]


def run_command(args) -> int:
    """``aerial-synth sim2real`` once its options are parsed (sim2real/cli.py)."""
    require_train_extra()  # first: without the extra nothing else matters
    classes = None if args.real_classes == "all" else tuple(
        c.strip() for c in args.real_classes.split(",") if c.strip())
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
