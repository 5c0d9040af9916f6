"""``aerial-synth export`` and ``aerial-synth show``. Imports nothing heavy at import time (the
exporter itself is imported when ``export`` runs)."""

from __future__ import annotations

import argparse
import sys

from ..annotate.boxes import BOX_FITS, BOX_MODES, BoxConfig
from ..camera import CameraConfig
from ..errors import AerialSynthError
from ..formats.registry import names as format_names
from ..formats.registry import parse_names
from ..out_guard import out_lock, refuse_here
from ..placement.config import SCENARIOS
from ..render.cli import (
    add_camera_args,
    add_render_options,
    camera_config_from_args,
    render_options_from_args,
)
from ..scene.cli import add_scene_args
from ..validators import arg_choice, arg_float, arg_int
from .config import IMAGE_EXTS, MAX_IMAGES, ExportConfig
from .gsd import camera_range
from .scene_mix import PRESETS as MIX_PRESETS
from .show import show_dataset

__all__ = ["register"]


def _format_list(text: str):
    """argparse ``type=`` for ``--format``: a comma list of registered formats."""
    try:
        return ",".join(parse_names(text))
    except AerialSynthError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def register(sub) -> None:
    """``aerial-synth export`` and ``aerial-synth show``."""
    box = BoxConfig()  # the one home of the box thresholds' defaults

    fmts = ", ".join(format_names())
    p = sub.add_parser(
        "export",
        help="export a labelled dataset (DOTA, EAGLE-style, YOLO-OBB, COCO)",
        description="Place vehicles, render images and write oriented-box labels in one or "
        "more formats, with per-image metadata, a manifest and a summary. Column definitions "
        "and thresholds: docs/formats.md.",
    )
    add_scene_args(p)
    p.add_argument("--scenario", default="jam", metavar="NAME|FILE",
                   help=f"traffic scenario: {', '.join(SCENARIOS)} or a YAML file (jam)")
    p.add_argument("--scene-mix", default=None, metavar="SCENE[/SCENARIO]:W,...|FILE|PRESET",
                   help="each placement group draws its scene and scenario from these weights "
                   f"(a YAML file, or a preset: {', '.join(MIX_PRESETS)}); replaces --scene; "
                   "entries without /SCENARIO use --scenario (docs/gsd.md)")
    p.add_argument("--images", type=arg_int("--images", 1, MAX_IMAGES), default=10, metavar="N",
                   help="number of images (10)")
    p.add_argument("--format", type=_format_list, default="dota", metavar="LIST",
                   help=f"comma list of {fmts} (dota)")
    p.add_argument("--split", type=arg_float("--split", 0.0, 1.0, lo_open=True), default=0.8,
                   metavar="F", help="fraction of images in train, in (0, 1] (0.8)")
    p.add_argument("--seed", type=arg_int("--seed", 0), default=0, metavar="S",
                   help="dataset seed, a non-negative integer (0)")
    p.add_argument("--workers", type=arg_int("--workers", 1, 1024), default=None, metavar="K",
                   help="worker processes; output is identical for any K (1)")
    p.add_argument("--dask", default=None, metavar="tcp://HOST:PORT|local:K",
                   help="run on a Dask cluster (a running scheduler) or a LocalCluster of K "
                        "processes instead of --workers; same output (docs/scale.md)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--resume", action="store_true", help="finish an interrupted export in DIR")
    p.add_argument("--force", action="store_true",
                   help="replace an existing dataset (once the new one is complete), or write "
                   "into a folder that is not a dataset")
    p.add_argument("--images-per-placement", type=arg_int("--images-per-placement", 1),
                   default=10, metavar="K", help="a fresh vehicle placement every K images (10)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--vehicles", type=arg_int("--vehicles", 1, 10_000_000), default=None,
                   metavar="N", help="vehicles per placement (default: the scenario's)")
    g.add_argument("--lines", type=arg_int("--lines", 1, 1_000_000), default=None, metavar="N",
                   help="traffic lines per placement (default: the scenario's)")
    add_camera_args(p, size=True, lens=False, ranges=camera_range)
    b = p.add_argument_group("boxes and flags (docs/formats.md)")
    b.add_argument("--box", type=arg_choice("--box", BOX_MODES), default=box.box,
                   metavar="|".join(BOX_MODES),
                   help="visible: rectangle of the visible mask (thesis); amodal: whole vehicle")
    b.add_argument("--difficult-fraction", type=arg_float("--difficult-fraction", 0.0, 1.0),
                   default=box.difficult_visible_fraction, metavar="F",
                   help=f"difficult when the visible fraction is below F ({box.difficult_visible_fraction:g})")
    b.add_argument("--min-visible-fraction", type=arg_float("--min-visible-fraction", 0.0, 1.0),
                   default=box.min_visible_fraction, metavar="F",
                   help=f"dropped when the visible fraction is below F ({box.min_visible_fraction:g})")
    b.add_argument("--min-visible-px", type=arg_int("--min-visible-px", 0), default=box.min_visible_px,
                   metavar="N", help=f"dropped when fewer visible pixels than N ({box.min_visible_px})")
    b.add_argument("--box-fit", type=arg_choice("--box-fit", BOX_FITS), default=box.fit,
                   metavar="|".join(BOX_FITS),
                   help="rectangle of the region's pixels (default) or of the dilated contour")
    p.add_argument("--image-ext", type=arg_choice("--image-ext", IMAGE_EXTS), default="png",
                   metavar="|".join(IMAGE_EXTS), help="image files (png)")
    r = p.add_argument_group("rendering (docs/rendering.md)")
    add_render_options(r)
    r.add_argument("--distractors", type=arg_float("--distractors", 0.0, 1000.0), default=0.0,
                   metavar="PER_HA", help="unlabelled street objects (manholes, containers, "
                   "signs, ...) per hectare; 0 = none, render's default is 6 (0)")
    t = p.add_argument_group("tiled world (docs/scale.md)")
    t.add_argument("--tile-m", type=arg_float("--tile-m", 0.0, lo_open=True), default=None,
                   metavar="M", help="cut the world into square tiles of M metres: each worker "
                   "holds only the tiles a placement group needs (a city spec is generated per "
                   "window; other scenes are loaded once and cut)")
    t.add_argument("--margin-m", type=arg_float("--margin-m", 0.0), default=None, metavar="M",
                   help="placement margin: how far a tile's placement window reaches past its "
                   "core, as place-tiled (60); cameras see past their tile by their own reach")
    p.add_argument("--simple-vehicles", action="store_true",
                   help="box-shaped vehicles instead of catalog meshes (quick tests)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_export)
    _register_show(sub)


def _register_show(sub) -> None:
    s = sub.add_parser(
        "show",
        help="draw a dataset's labels over its images, plus a contact sheet",
        description="Draw polygons, heading arrows and classes (difficult in orange) over the "
        "images of an aerial-synth dataset or a DOTA folder, and a contact sheet.",
    )
    s.add_argument("dir", metavar="DIR", help="dataset folder (or a DOTA folder)")
    s.add_argument("--out", required=True, metavar="DIR",
                   help="where previews go (not inside DIR)")
    s.add_argument("--limit", type=arg_int("--limit", 1), default=None, metavar="N",
                   help="at most N images")
    s.add_argument("--thumb", type=arg_int("--thumb", 8, 4096), default=256, metavar="PX",
                   help="contact sheet thumbnail size (256)")
    s.set_defaults(func=_cmd_show)


def config_from_args(args) -> ExportConfig:
    """The :class:`ExportConfig` of ``export``'s options: its camera from the shared camera
    group, its render options from the shared render group, its boxes from BoxConfig's."""
    # --altitude and --gsd may be ranges LO:HI (dataset/gsd.py): the config keeps the range,
    # its camera the defaults (the per-image camera is drawn from the range)
    altitude_range = args.altitude if isinstance(args.altitude, tuple) else None
    gsd_range = args.gsd if isinstance(args.gsd, tuple) else None
    cam = camera_config_from_args(argparse.Namespace(**{
        **vars(args),
        "altitude": CameraConfig().altitude_m if altitude_range else args.altitude,
        "gsd": None if gsd_range else args.gsd,
    }))
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
        bbox=getattr(args, "bbox", None),
        crs=getattr(args, "crs", None),
        scenario=args.scenario,
        images=args.images,
        formats=args.format,
        split=args.split,
        seed=args.seed,
        images_per_placement=args.images_per_placement,
        n_vehicles=args.vehicles,
        n_lines=args.lines,
        camera=cam,
        gsd_range=gsd_range,
        altitude_range=altitude_range,
        scene_mix=getattr(args, "scene_mix", None),
        box=box,
        image_ext=args.image_ext,
        simple_vehicles=args.simple_vehicles,
        render=render_options_from_args(args),
        distractors=args.distractors or None,
        tile_m=args.tile_m,
        margin_m=args.margin_m,
    )


def _cmd_export(args) -> int:
    from .export import export_dataset  # lazy: the renderer (open3d, numba) loads only to export

    cfg = config_from_args(args)
    res = export_dataset(cfg, args.out, workers=args.workers, resume=args.resume,
                         force=args.force, progress=False if args.no_progress else None, dask=args.dask)
    print(res.text())
    return 0


def _cmd_show(args) -> int:
    if args.out == "":  # Path('') would silently mean the current folder
        refuse_here(args.out)
    with out_lock(args.out, "show"):
        paths = show_dataset(args.dir, args.out, limit=args.limit, thumb_px=args.thumb)
    print(f"wrote {len(paths) - 1} previews and {paths[-1]}", file=sys.stdout)
    return 0
