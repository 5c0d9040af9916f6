"""``aerial-synth render``: place vehicles, pose cameras, render and write frames.

Per image i the generator is ``default_rng(SeedSequence([seed, i]))`` (camera pose, factors,
noise); the placement uses ``SeedSequence([seed, PLACEMENT_KEY])`` (once per run, or per
image with ``--placement-per-image``: ``SeedSequence([seed, i, PLACEMENT_KEY])``);
distractors (``--distractors``, per hectare) use ``SeedSequence([seed, DISTRACTOR_KEY])``
once per run. Output::

    OUT/placement.json                (once per run)
    OUT/distractors.json              (once per run: every drawn distractor)
    OUT/000000/rgb.png instance.png instance_color.png semantic.png depth.npy meta.json
"""

from __future__ import annotations

import argparse
import sys
import time

from ..camera import (
    DEFAULT_GSD_M,
    MAX_ALTITUDE_M,
    MAX_FOCAL_PX,
    MAX_GSD_M,
    MAX_IMAGE_PX,
    MAX_TILT_LIMIT_DEG,
    MIN_ALTITUDE_M,
    MIN_GSD_M,
    CameraConfig,
    grid_poses,
    sample_pose_targeted,
)
from ..io_utils import atomic_write_json, atomic_write_text, check_output_dir
from ..out_guard import staged_dir
from ..scene.cli import add_scene_args, scene_from_args
from ..scene.raycast import RayScene
from ..validators import arg_choice, arg_float, arg_int
from . import backends
from .budget import check_frame_memory
from .config import RANDOMISE, RENDER_PRESETS, Backend, RenderOptions

__all__ = ["register", "add_camera_args", "camera_config_from_args", "add_render_options",
           "render_options_from_args", "run"]

PLACEMENT_KEY = 0x504C  # "PL"


def add_camera_args(p: argparse.ArgumentParser, *, size: bool = False, lens: bool = True,
                    ranges=None) -> None:
    """The one camera option group of every command that renders: defaults from
    :class:`~aerial_synth.camera.CameraConfig`, bounds from :mod:`aerial_synth.camera`.

    size : also ``--size`` (a square image; ``--width``/``--height`` then default to it)
    lens : ``--focal`` and ``--fov`` besides ``--gsd``
    ranges : ``ranges(option, max_value, min_value)`` -> an argparse type for ``--altitude`` and
             ``--gsd`` that also takes a range ``LO:HI`` (export's per-image draw,
             :func:`aerial_synth.dataset.gsd.camera_range`); the bounds stay these"""
    d = CameraConfig()
    g = p.add_argument_group("camera")
    rng = " or a range LO:HI drawn per image (docs/gsd.md)" if ranges else ""
    g.add_argument("--altitude", type=(ranges("--altitude", MAX_ALTITUDE_M, MIN_ALTITUDE_M) if ranges
                                       else arg_float("--altitude", MIN_ALTITUDE_M, MAX_ALTITUDE_M)),
                   default=d.altitude_m, metavar="M|LO:HI" if ranges else "M",
                   help=f"camera height above the target ground, metres ({d.altitude_m:g}){rng}")
    if size:
        g.add_argument("--size", type=arg_int("--size", 1, MAX_IMAGE_PX), default=None, metavar="PX",
                       help=f"square image size in pixels ({d.width_px})")
    g.add_argument("--width", type=arg_int("--width", 1, MAX_IMAGE_PX), default=None if size else d.width_px,
                   metavar="PX", help=f"image width ({d.width_px})")
    g.add_argument("--height", type=arg_int("--height", 1, MAX_IMAGE_PX),
                   default=None if size else d.height_px, metavar="PX", help=f"image height ({d.height_px})")
    g.add_argument("--gsd", type=(ranges("--gsd", MAX_GSD_M, MIN_GSD_M) if ranges else
                                  arg_float("--gsd", MIN_GSD_M, MAX_GSD_M)), default=None,
                   metavar="M|LO:HI" if ranges else "M",
                   help=f"ground sampling distance at nadir, m/px ({DEFAULT_GSD_M:g}){rng}")
    if lens:
        g.add_argument("--focal", type=arg_float("--focal", 0.0, MAX_FOCAL_PX, lo_open=True), default=None,
                       metavar="PX", help="focal length, px")
        g.add_argument("--fov", type=arg_float("--fov", 0.0, 180.0, lo_open=True, hi_open=True),
                       default=None, metavar="DEG", help="horizontal field of view, degrees")
    g.add_argument("--max-tilt", type=arg_float("--max-tilt", 0.0, MAX_TILT_LIMIT_DEG, hi_open=True),
                   default=d.max_tilt_deg, metavar="DEG",
                   help=f"tilt off nadir ~ U[-max, max] ({d.max_tilt_deg:g}; must be < {MAX_TILT_LIMIT_DEG:g})")


def camera_config_from_args(args) -> CameraConfig:
    """The :class:`CameraConfig` of the options :func:`add_camera_args` added."""
    size = getattr(args, "size", None)
    d = CameraConfig()
    width = args.width if args.width is not None else size if size is not None else d.width_px
    height = args.height if args.height is not None else size if size is not None else d.height_px
    return CameraConfig(
        altitude_m=args.altitude, width_px=width, height_px=height, gsd_m=args.gsd,
        focal_px=getattr(args, "focal", None), fov_deg=getattr(args, "fov", None),
        max_tilt_deg=args.max_tilt,
    )


def add_render_options(p) -> None:
    """``--preset`` and ``--randomise`` of every command that renders (a parser or an argument
    group): the choices are the values of :class:`~.config.Preset` and
    :class:`~.config.Randomise`, the defaults :class:`~.config.RenderOptions`'."""
    d = RenderOptions()
    p.add_argument("--preset", type=arg_choice("--preset", RENDER_PRESETS), default=d.preset,
                   help="shading preset: full (every realism factor) or fast (no ambient "
                   f"occlusion or sun-disk sampling, coarser shadow rays) ({d.preset})")
    p.add_argument("--randomise", type=arg_choice("--randomise", RANDOMISE), default=d.randomise,
                   help="domain randomisation: textures = random material, sun and sky "
                   f"colours (Tobin et al. 2017), a style to mix with realistic frames ({d.randomise})")


def render_options_from_args(args) -> RenderOptions:
    """The :class:`~.config.RenderOptions` of the options :func:`add_render_options` added."""
    return RenderOptions(preset=args.preset, randomise=args.randomise)


def register(sub) -> None:
    p = sub.add_parser(
        "render",
        help="render frames (RGB, instance, semantic, depth, meta) of a placed scene",
        description="Place vehicles in a scene, sample camera poses and write per-frame "
        "rgb.png, instance.png (16-bit ids), instance_color.png, semantic.png, depth and "
        "meta.json.",
    )
    add_scene_args(p)
    p.add_argument("--scenario", default="jam", metavar="NAME|FILE",
                   help="traffic scenario: a bundled name (listed by 'aerial-synth place --help') "
                   "or a YAML file (jam)")
    p.add_argument("--vehicles", type=arg_int("--vehicles", 1, 10_000_000), default=None,
                   metavar="N", help="vehicles to place (default: the scenario's)")
    p.add_argument("--images", type=arg_int("--images", 1, 10_000_000), default=1, metavar="N",
                   help="frames to render (1)")
    p.add_argument("--seed", type=arg_int("--seed", 0, 2**63 - 1), default=0, metavar="S",
                   help="run seed (0)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--sampler", type=arg_choice("--sampler", ("targeted", "grid")),
                   default="targeted",
                   help="camera poses: near a random vehicle, or survey tiles (targeted)")
    p.add_argument("--overlap", type=arg_float("--overlap", 0.0, 1.0, hi_open=True),
                   default=0.2, metavar="F",
                   help="grid sampler tile overlap fraction in [0, 1) (0.2)")
    p.add_argument("--placement-per-image", action="store_true",
                   help="a new placement for every image (default: one per run)")
    p.add_argument("--depth-format", type=arg_choice("--depth-format", ("npy", "png")),
                   default="npy",
                   help="depth as float32 metres .npy or 16-bit centimetre PNG (npy)")
    p.add_argument("--backend", type=arg_choice("--backend", tuple(b.value for b in Backend)),
                   default="raycast", help="RGB backend (labels always come from ray casting)")
    add_render_options(p)
    p.add_argument("--distractors", type=arg_float("--distractors", 0.0, 1000.0), default=6.0,
                   metavar="PER_HA",
                   help="manholes, containers, dumpsters, road signs and benches per hectare, "
                   "never labelled (6; 0 = none)")
    p.add_argument("--no-shadows", action="store_true", help="skip shadow rays")
    p.add_argument("--jpeg-probability", type=arg_float("--jpeg-probability", 0.0, 1.0),
                   default=None, metavar="P",
                   help="probability of JPEG artefacts per frame (0.6)")
    add_camera_args(p)
    p.set_defaults(func=run)


def _check_args(args) -> None:
    from ..placement import load_scenario  # lazy: shapely, only when render runs

    # the one list of bundled scenarios (placement.SCENARIOS) or a .yaml file, every field checked
    load_scenario(args.scenario)


def run(args) -> int:
    import numpy as np

    from ..placement import place  # lazy: shapely, only when render runs
    from . import distractors, frame, io, world  # lazy: the renderer (numba, OpenCV)

    # validate everything cheap before loading or writing anything
    cam_cfg = camera_config_from_args(args)
    kw = {"backend": args.backend, "shadows": not args.no_shadows}
    if args.jpeg_probability is not None:
        kw["jpeg_probability"] = args.jpeg_probability
    rcfg = render_options_from_args(args).config(**kw)
    check_frame_memory(cam_cfg.width_px, cam_cfg.height_px)  # before a 30 GB frame is OOM-killed
    _check_args(args)
    out = check_output_dir(args.out, "--out")
    backends.get(args.backend).check()  # e.g. pyrender without EGL: said before any work
    t0 = time.perf_counter()
    scene = scene_from_args(args)
    grid = None
    if args.sampler == "grid":  # before any write: a bad grid leaves nothing behind
        b = scene.bounds()
        lows = [o.vertices[:, 2].min() for o in scene.objects if len(o.vertices)]
        gz = float(np.median(lows)) if lows else 0.0
        grid = grid_poses(cam_cfg, b[:, :2], overlap=args.overlap, ground_z=gz)
    extras = []
    if args.distractors > 0:
        scene, extras = distractors.add_distractors(
            scene, np.random.default_rng(np.random.SeedSequence([args.seed, distractors.DISTRACTOR_KEY])),
            per_hectare=args.distractors)
    rs = RayScene(scene)

    def make_placement(key):
        rng = np.random.default_rng(np.random.SeedSequence(key))
        pl = place(rs, args.scenario, rng, n_vehicles=args.vehicles, seed=args.seed,
                   scene_name=scene.name)
        rs.clear_vehicles()
        world.add_placement(rs, pl)
        return pl

    # frames are written beside --out and put in place at the end: a failure (a full disk, a
    # signal) leaves --out as it was
    with staged_dir(out) as build:
        placement = None
        if not args.placement_per_image:
            placement = make_placement([args.seed, PLACEMENT_KEY])
            atomic_write_text(build / "placement.json", placement.to_json())
        atomic_write_json(build / "distractors.json", {"per_hectare": args.distractors,
                                                       "distractors": extras})
        n_veh = 0
        for i in range(args.images):
            if args.placement_per_image:
                placement = make_placement([args.seed, i, PLACEMENT_KEY])
                atomic_write_text(build / f"{i:06d}" / "placement.json", placement.to_json())
            rng = np.random.default_rng(np.random.SeedSequence([args.seed, i]))
            if grid is not None:
                cam = grid[i % len(grid)]
            else:
                cam = sample_pose_targeted(cam_cfg, placement, rng, within_xy=scene.bounds()[:, :2],
                                           clear=lambda c: rs.open_above(c.center))
            fr = frame.render_frame(rs, cam, placement, rng, rcfg)
            io.write_frame(fr, build / f"{i:06d}", depth_format=args.depth_format, extra_meta={
                "seed": args.seed, "image_index": i, "scene": scene.name,
                "scenario": placement.scenario, "sampler": args.sampler,
                "render_config": rcfg.to_dict(),
                "distractors": {"per_hectare": args.distractors, "count": len(extras)},
            })
            n_veh += len(fr.visibility)
    dt = time.perf_counter() - t0
    print(f"rendered {args.images} frame(s) of {scene.name} ({placement.scenario}), "
          f"{n_veh} vehicles in view in total, {dt:.1f} s -> {out}", file=sys.stdout)
    return 0
