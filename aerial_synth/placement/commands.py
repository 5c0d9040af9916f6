"""The bodies of ``aerial-synth place`` and ``aerial-synth place-tiled``.

Imported by :mod:`aerial_synth.placement.cli` and :mod:`aerial_synth.placement.tiled_cli`
only when a command runs (``aerial-synth --help`` needs none of these modules).
"""

from __future__ import annotations

import argparse
import re
import resource
import sys
import time
import warnings

import numpy as np

from ..errors import ConfigError, PlacementError
from ..io_utils import atomic_write_bytes, check_output_dir
from ..out_guard import staged_dir
from ..scene.commands import scene_from_args
from ..scene.mapview import render_map
from ..scene.raycast import RayScene
from ..scene.tiles import TiledWorld
from ..vehicles import load_catalog
from .config import load_scenario, parse_overrides
from .draw import draw_placement
from .footprints import validate_placement
from .tiled import min_tile_m, place_tiled
from .traffic import PlacementWarning, place

__all__ = ["run_place", "run_place_tiled", "MAX_PNG_PX"]

#: the largest side of placement.png, pixels
MAX_PNG_PX = 8000


def _overrides(args) -> dict:
    over = parse_overrides(args.set)
    # the dedicated options win over --set; argparse already checked their values
    if args.traffic is not None:
        over["traffic"] = args.traffic
    if args.lane_offset is not None:
        over["lane_offset_m"] = args.lane_offset
    if args.gap is not None:
        over["gap_m"] = args.gap
    return over


def run_place(args: argparse.Namespace) -> int:
    """``aerial-synth place``: place, validate, write placement.json (+ .png), summarise."""
    t0 = time.perf_counter()
    out = check_output_dir(args.out, "--out")  # before any work
    cfg = load_scenario(args.scenario, _overrides(args))  # validates every field
    catalog = None
    if args.catalog:
        catalog = load_catalog(args.catalog)
    scene = scene_from_args(args)
    m_per_px = None
    if not args.no_png:
        ext = scene.bounds()[1, :2] - scene.bounds()[0, :2]
        m_per_px = args.m_per_px if args.m_per_px is not None else max(0.25, float(ext.max()) / 4000.0)
        px = int(np.ceil(float(ext.max()) / m_per_px))
        if px > MAX_PNG_PX:
            raise ConfigError(
                f"--m-per-px: expected at least {float(ext.max()) / MAX_PNG_PX:.3g} for this "
                f"{float(ext.max()):.0f} m scene (at most {MAX_PNG_PX} px), got {m_per_px:g}")
    rs = RayScene(scene)
    t_scene = time.perf_counter() - t0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", PlacementWarning)
        placement = place(rs, cfg, rng=np.random.default_rng(args.seed), n_vehicles=args.vehicles,
                          n_lines=args.lines, catalog=catalog, seed=args.seed, scene_name=scene.name)
    t_place = placement.timing["seconds"]
    report = validate_placement(rs, placement, scene.truth, traffic=cfg.traffic)
    placement.stats["validation"] = report.summary()
    moving = np.array([v.state == "moving" for v in placement.vehicles], bool)
    if len(moving) and not moving.all():  # parked vehicles follow their bays, not the road
        he = report.heading_error_deg[moving]
        he = he[np.isfinite(he)]
        placement.stats["validation"]["heading_error_deg"] = None if not len(he) else {
            "median": round(float(np.median(he)), 4), "p99": round(float(np.percentile(he, 99)), 4),
            "max": round(float(he.max()), 4), "mean": round(float(he.mean()), 4)}
        placement.stats["validation"]["heading_error_of"] = "moving vehicles"
    png = None
    if not args.no_png:
        import cv2

        view = render_map(scene, m_per_px=m_per_px, rayscene=rs, max_px=MAX_PNG_PX)
        img = draw_placement(view, placement, title=f"{scene.name} / {cfg.name} / seed {args.seed}: "
                             f"{len(placement.vehicles)} vehicles")
        ok, buf = cv2.imencode(".png", img)
        png = buf.tobytes()
    with staged_dir(out) as build:  # both files, or neither (existing files kept)
        atomic_write_bytes(build / "placement.json", placement.to_json().encode("utf-8"))
        if png is not None:
            atomic_write_bytes(build / "placement.png", png)
    st = placement.stats
    sp = st["spacing_m"]
    val = st["validation"]
    he = val["heading_error_deg"]
    lines = [
        f"scene {scene.name} ({scene.n_triangles:,} triangles), scenario {cfg.name}, seed {args.seed}",
        f"vehicles {st['vehicles']}  lines {st['lines']} (+{st['opposite_lanes']} opposite lanes)  "
        f"line ends {st['line_end_reasons']}",
    ]
    if sp["n"]:
        lines.append(f"spacing m: mean {sp['mean']:.2f}  sd {sp['sd'] if sp['sd'] is not None else float('nan'):.2f}  "
                     f"min {sp['min']:.2f}  max {sp['max']:.2f}  (n={sp['n']})")
    lines.append(
        f"validator: overlaps {val['overlaps']}  footprint on drivable {100 * val['footprint_drivable']:.1f} %  "
        f"corners on drivable {100 * val['corners_drivable']:.1f} %"
        + (f"  heading error median {he['median']:.2f} deg p99 {he['p99']:.2f} deg" if he else "")
    )
    pv = st.get("parking_validation")  # parked vehicles (placement/parking.py)
    if pv and pv.get("parked"):
        al = pv["alignment_deg"] or {}
        lines.append(f"parked {pv['parked']} (lots {len(st.get('lots', []))}, kerb lines {st.get('kerbs', 0)}): "
                     f"in bay {100 * (pv['in_bay_fraction'] or 0):.1f} %  overlaps {pv['overlaps']}  "
                     f"on lot/road {100 * pv.get('on_surface_fraction', 0):.1f} %  "
                     f"alignment to bay mean {al.get('mean', float('nan')):.2f} max {al.get('max', float('nan')):.2f} deg")
    lines.append(
        f"time: scene {t_scene:.2f} s, placement {t_place:.2f} s "
        f"({placement.timing['vehicles_per_s']:.0f} vehicles/s, {placement.timing['rays_per_s'] / 1e6:.1f} M rays/s)"
    )
    lines.append(f"wrote {out / 'placement.json'}" + (f" and {out / 'placement.png'}" if png else ""))
    print("\n".join(lines))
    for w in caught:
        if issubclass(w.category, PlacementWarning):
            print(f"aerial-synth: warning: {w.message}", file=sys.stderr)
    return 0


def run_place_tiled(args: argparse.Namespace) -> int:
    """``aerial-synth place-tiled``: tiled placement of a large world into placement.json."""
    out = check_output_dir(args.out, "--out")
    cfg = load_scenario(args.scenario)
    longest = min_tile_m()
    if args.tile_m < longest:
        raise PlacementError(
            f"--tile-m: expected a tile size of at least the longest vehicle ({longest:g} m), got {args.tile_m:g}")
    client = _dask_client(args) if args.dask else None
    t0 = time.perf_counter()
    world = TiledWorld.load(args.scene, seed=args.scene_seed, bbox=args.bbox, crs=args.crs)
    grid = world.grid(args.tile_m, args.margin_m)

    def progress(done, n, kept):
        print(f"\rtile {done}/{n}: {kept} vehicles", end="", file=sys.stderr, flush=True)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PlacementWarning)
        pl = place_tiled(world, grid, cfg, seed=args.seed, n_vehicles=args.vehicles,
                         progress=progress if sys.stderr.isatty() else None, workers=args.workers,
                         executor=client.get_executor() if client is not None else None)
    if client is not None:
        client.close()
    wall = time.perf_counter() - t0
    if sys.stderr.isatty():
        print(file=sys.stderr)
    with staged_dir(out) as build:  # a failed write leaves --out as it was
        atomic_write_bytes(build / "placement.json", pl.to_json().encode("utf-8"))
    t = pl.stats["tiles"]
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(f"world {world.name}: {t['grid'][0]} x {t['grid'][1]} tiles of {t['tile_m']:g} m (margin "
          f"{t['margin_m']:g} m); {len(pl.vehicles)} vehicles ({t['dropped_at_borders']} dropped at borders); "
          f"{wall:.1f} s; peak RSS {rss:.0f} MB")
    print(f"wrote {out / 'placement.json'}")
    return 0


def _dask_client(args):
    """A client of the running scheduler ``--dask``; one-line PlacementError otherwise."""
    if args.workers != 1:
        raise PlacementError(f"--dask and --workers: choose one, got --workers {args.workers}")
    addr = str(args.dask).strip()
    if not re.match(r"^(tcp|tls)://[^\s/:]+:\d+$", addr):
        raise PlacementError(f"--dask: expected tcp://HOST:PORT of a running dask scheduler, got {args.dask!r}")
    try:
        from distributed import Client
    except ImportError:
        raise PlacementError("--dask: needs Dask distributed; pip install 'aerial-synth[dask]'") from None
    try:
        return Client(addr, timeout="6s")
    except (OSError, TimeoutError) as exc:
        raise PlacementError(f"--dask {addr}: cannot reach a Dask scheduler there ({type(exc).__name__})") from None
