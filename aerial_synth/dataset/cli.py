"""``aerial-synth export`` and ``aerial-synth show``. Imports nothing heavy at import time."""

from __future__ import annotations

import argparse
import sys

__all__ = ["register"]


def _positive_int(name):
    def conv(text):
        try:
            return int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name}: expected an integer, got {text!r}") from None

    return conv


def register(sub) -> None:
    from ..scene.cli import add_scene_args

    p = sub.add_parser(
        "export",
        help="export a labelled dataset (DOTA, EAGLE-style, YOLO-OBB, COCO)",
        description="Place vehicles, render images and write oriented-box labels in one or "
        "more formats, with per-image metadata, a manifest and a summary. Column definitions "
        "and thresholds: docs/formats.md.",
    )
    add_scene_args(p)
    p.add_argument("--scenario", default="jam", metavar="NAME|FILE",
                   help="traffic scenario: jam, normal, sparse, random or a YAML file (jam)")
    p.add_argument("--images", type=_positive_int("--images"), default=10, metavar="N",
                   help="number of images (10)")
    p.add_argument("--format", default="dota", metavar="LIST",
                   help="comma list of dota, eagle, yolo-obb, coco (dota)")
    p.add_argument("--split", type=float, default=0.8, metavar="F",
                   help="fraction of images in train, in (0, 1] (0.8)")
    p.add_argument("--seed", type=_positive_int("--seed"), default=0, metavar="S", help="dataset seed (0)")
    p.add_argument("--workers", type=_positive_int("--workers"), default=1, metavar="K",
                   help="worker processes; output is identical for any K (1)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--resume", action="store_true", help="finish an interrupted export in DIR")
    p.add_argument("--force", action="store_true",
                   help="overwrite an existing dataset, or write into a non-dataset folder")
    p.add_argument("--images-per-placement", type=_positive_int("--images-per-placement"),
                   default=10, metavar="K", help="a fresh vehicle placement every K images (10)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--vehicles", type=int, default=None, metavar="N",
                   help="vehicles per placement (default: the scenario's)")
    g.add_argument("--lines", type=int, default=None, metavar="N",
                   help="traffic lines per placement (default: the scenario's)")
    c = p.add_argument_group("camera")
    c.add_argument("--size", type=_positive_int("--size"), default=None, metavar="PX",
                   help="square image size in pixels (1024)")
    c.add_argument("--width", type=_positive_int("--width"), default=None, metavar="PX")
    c.add_argument("--height", type=_positive_int("--height"), default=None, metavar="PX")
    c.add_argument("--altitude", type=float, default=60.0, metavar="M", help="metres (60)")
    c.add_argument("--gsd", type=float, default=None, metavar="M",
                   help="metres per pixel at nadir (0.12)")
    c.add_argument("--max-tilt", type=float, default=15.0, metavar="DEG",
                   help="tilt drawn in [-DEG, DEG] (15)")
    b = p.add_argument_group("boxes and flags (docs/formats.md)")
    b.add_argument("--box", default="visible", metavar="visible|amodal",
                   help="visible: rectangle of the visible mask (thesis); amodal: whole vehicle")
    b.add_argument("--difficult-fraction", type=float, default=0.5, metavar="F",
                   help="difficult when the visible fraction is below F (0.5)")
    b.add_argument("--min-visible-fraction", type=float, default=0.1, metavar="F",
                   help="dropped when the visible fraction is below F (0.1)")
    b.add_argument("--min-visible-px", type=int, default=20, metavar="N",
                   help="dropped when fewer visible pixels than N (20)")
    b.add_argument("--box-fit", default="pixels", metavar="pixels|dilated",
                   help="rectangle of the region's pixels (default) or of the dilated contour")
    p.add_argument("--image-ext", default="png", metavar="png|jpg", help="image files (png)")
    p.add_argument("--simple-vehicles", action="store_true",
                   help="box-shaped vehicles instead of catalog meshes (quick tests)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_export)

    s = sub.add_parser(
        "show",
        help="draw a dataset's labels over its images, plus a contact sheet",
        description="Draw polygons, heading arrows and classes (difficult in orange) over the "
        "images of an aerial-synth dataset or a DOTA folder, and a contact sheet.",
    )
    s.add_argument("dir", metavar="DIR", help="dataset folder (or a DOTA folder)")
    s.add_argument("--out", required=True, metavar="DIR", help="where previews go")
    s.add_argument("--limit", type=_positive_int("--limit"), default=None, metavar="N",
                   help="at most N images")
    s.add_argument("--thumb", type=_positive_int("--thumb"), default=256, metavar="PX",
                   help="contact sheet thumbnail size (256)")
    s.set_defaults(func=_cmd_show)


def config_from_args(args):
    from ..annotate.boxes import BoxConfig
    from .export import ExportConfig

    size = args.size or 1024
    box = BoxConfig(
        box=args.box,
        fit=args.box_fit,
        difficult_visible_fraction=args.difficult_fraction,
        min_visible_fraction=args.min_visible_fraction,
        min_visible_px=args.min_visible_px,
    )
    return ExportConfig(
        scene=args.scene,
        labels=args.labels,
        scene_seed=getattr(args, "scene_seed", None),
        scenario=args.scenario,
        images=args.images,
        formats=args.format,
        split=args.split,
        seed=args.seed,
        images_per_placement=args.images_per_placement,
        n_vehicles=args.vehicles,
        n_lines=args.lines,
        width_px=args.width or size,
        height_px=args.height or size,
        altitude_m=args.altitude,
        gsd_m=args.gsd,
        max_tilt_deg=args.max_tilt,
        box=box,
        image_ext=args.image_ext,
        simple_vehicles=args.simple_vehicles,
    )


def _cmd_export(args) -> int:
    from ..errors import ExportError
    from .export import export_dataset

    if args.workers < 1:
        raise ExportError(f"--workers: expected an integer >= 1, got {args.workers}")
    cfg = config_from_args(args)
    res = export_dataset(cfg, args.out, workers=args.workers, resume=args.resume,
                         force=args.force, progress=False if args.no_progress else None)
    print(res.text())
    return 0


def _cmd_show(args) -> int:
    from .show import show_dataset

    paths = show_dataset(args.dir, args.out, limit=args.limit, thumb_px=args.thumb)
    print(f"wrote {len(paths) - 1} previews and {paths[-1]}", file=sys.stdout)
    return 0
