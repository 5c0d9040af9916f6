"""``aerial-synth render``: place vehicles, pose cameras, render and write frames.

Every frame is :func:`~aerial_synth.dataset.sample.render_sample`'s, with the export's seed
streams: image i's camera and rendering come from ``SeedSequence([seed, i])``, the
placement from ``SeedSequence([seed, g, PLACEMENT_STREAM])`` where the placement group g is
0 (one placement per run) or i (``--placement-per-image``); distractors (``--distractors``,
per hectare) from ``SeedSequence([seed, DISTRACTOR_KEY])`` once per run. So ``render`` and
``export`` show the same image for the same scene, scenario, seed, camera and grouping.
Output::

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
)
from ..errors import AerialSynthError
from ..io_utils import atomic_write_json, atomic_write_text, check_output_dir
from ..out_guard import staged_dir
from ..scene.cli import add_scene_args
from ..validators import arg_choice, arg_float, arg_int
from .budget import check_frame_memory
from .config import RANDOMISE, RENDER_PRESETS, Backend, RenderOptions, device_spec

__all__ = ["register", "add_camera_args", "camera_config_from_args", "add_render_options",
           "render_options_from_args", "run"]

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
    p.add_argument("--backend", type=arg_choice("--backend", tuple(b.value for b in Backend)),
                   default=d.backend, help="render backend: raycast (Open3D and numba on the "
                   "CPU), warp (NVIDIA Warp on --device; every buffer and label from its own "
                   "ray casts; the [gpu] extra) or pyrender (an RGB preview) "
                   f"(docs/rendering.md) ({d.backend})")
    p.add_argument("--device", type=_device_arg, default=d.device, metavar="cpu|cuda[:N]",
                   help=f"where --backend warp runs ({d.device})")


def _device_arg(text: str) -> str:
    """argparse ``type=`` for ``--device``: its form (whether it exists is checked later)."""
    try:
        return device_spec(text)
    except AerialSynthError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("--device: ")) from None


def render_options_from_args(args) -> RenderOptions:
    """The :class:`~.config.RenderOptions` of the options :func:`add_render_options` added."""
    return RenderOptions(preset=args.preset, randomise=args.randomise, backend=args.backend,
                         device=args.device)


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
    """Render ``--images`` frames with :func:`~aerial_synth.dataset.sample.render_sample`'s
    renderer: the export's plan and seed streams (an export with the same scene, scenario,
    seed, camera and placement grouping shows the same images)."""
    import dataclasses

    import numpy as np

    from ..dataset.config import ExportConfig
    from ..dataset.plan import CameraPlan, build_plan
    from ..dataset.sample import SampleRenderer
    from ..dataset.scenes import scene_distractors
    from . import io  # lazy: the renderer (numba, OpenCV)

    # validate everything cheap before loading or writing anything
    cam_cfg = camera_config_from_args(args)
    kw = {"shadows": not args.no_shadows}
    if args.jpeg_probability is not None:
        kw["jpeg_probability"] = args.jpeg_probability
    opts = render_options_from_args(args)
    rcfg = opts.config(**kw)
    check_frame_memory(cam_cfg.width_px, cam_cfg.height_px)  # before a 30 GB frame is OOM-killed
    _check_args(args)
    # the lens (--focal / --fov) lives in the camera plan: an export's is set by its GSD
    cfg = ExportConfig(scene=args.scene, labels=args.labels, scene_seed=args.scene_seed,
                       bbox=args.bbox, crs=args.crs, scenario=args.scenario, images=args.images,
                       seed=args.seed, n_vehicles=args.vehicles, render=opts,
                       images_per_placement=1 if args.placement_per_image else args.images,
                       camera=dataclasses.replace(cam_cfg, focal_px=None, fov_deg=None),
                       distractors=args.distractors or None)
    out = check_output_dir(args.out, "--out")
    opts.check()  # e.g. pyrender without EGL, cuda without CUDA: said before any work
    t0 = time.perf_counter()
    cam_plan = CameraPlan("fixed", cfg.seed, cam_cfg)
    if args.sampler == "grid":
        scene = SampleRenderer(build_plan(cfg, render=rcfg, camera=cam_plan)).scene(0)
        lows = [o.vertices[:, 2].min() for o in scene.objects if len(o.vertices)]
        cam_plan = CameraPlan("grid", cfg.seed, cam_cfg, overlap=args.overlap,
                              ground_z=float(np.median(lows)) if lows else 0.0)
        cam_plan.grid(scene.bounds())  # before any write: a bad grid leaves nothing behind
    r = SampleRenderer(build_plan(cfg, render=rcfg, camera=cam_plan))
    scene = r.scene(0)
    extras = scene_distractors(cfg) if cfg.distractors else []
    # frames are written beside --out and put in place at the end: a failure (a full disk, a
    # signal) leaves --out as it was
    with staged_dir(out) as build:
        placement = None
        if not args.placement_per_image:
            placement = r.group(0).placement
            atomic_write_text(build / "placement.json", placement.to_json())
        atomic_write_json(build / "distractors.json", {"per_hectare": args.distractors,
                                                       "distractors": extras})
        n_veh = 0
        for i in range(args.images):
            if args.placement_per_image:
                placement = r.group(i).placement
                atomic_write_text(build / f"{i:06d}" / "placement.json", placement.to_json())
            s = r.sample(i, frame=True)
            fr = s.frame
            io.write_frame(fr, build / f"{i:06d}", depth_format=args.depth_format, extra_meta={
                "seed": args.seed, "image_index": i, "scene": scene.name,
                "scenario": placement.scenario, "sampler": args.sampler,
                "render_config": rcfg.to_dict(),
                "distractors": {"per_hectare": args.distractors, "count": len(extras)},
                "seed_streams": s.meta.seed,
            })
            n_veh += len(fr.visibility)
    dt = time.perf_counter() - t0
    print(f"rendered {args.images} frame(s) of {scene.name} ({placement.scenario}), "
          f"{n_veh} vehicles in view in total, {dt:.1f} s -> {out}", file=sys.stdout)
    return 0
