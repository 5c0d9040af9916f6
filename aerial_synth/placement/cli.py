"""``aerial-synth place``: fill the roads of a scene with traffic and write placement.json/png."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["register"]


def register(sub) -> None:
    from ..scene.cli import add_scene_args

    p = sub.add_parser(
        "place",
        help="place vehicles on roads with line traces (jam, normal, sparse, random)",
        description="Place vehicles on the roads of a scene with the thesis's line-trace "
        "method and write placement.json, placement.png and a summary.",
    )
    p.add_argument("--scenario", default="jam", metavar="NAME|FILE",
                   help="jam, normal, sparse, random, or a scenario .yaml (default: jam)")
    add_scene_args(p)
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--vehicles", type=int, default=None, metavar="N", help="place N vehicles")
    g.add_argument("--lines", type=int, default=None, metavar="N",
                   help="seed N traffic lines (opposite lanes come on top)")
    p.add_argument("--traffic", choices=("right", "left"), default=None,
                   help="driving side (default: the scenario's, right)")
    p.add_argument("--lane-offset", type=float, default=None, metavar="M",
                   help="distance d from the road edge to the vehicle centre, metres")
    p.add_argument("--gap", type=float, default=None, metavar="M",
                   help="clearance kept between vehicle footprints, metres")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override any scenario field, e.g. --set spacing.mean_m=12 "
                   "--set double_lane_probability=1 (repeatable)")
    p.add_argument("--catalog", default=None, metavar="FILE", help="vehicle catalog YAML")
    p.add_argument("--out", default="out/place", metavar="DIR", help="output folder (default: out/place)")
    p.add_argument("--m-per-px", type=float, default=None,
                   help="placement.png resolution (default 0.25, coarser for scenes over 1 km)")
    p.add_argument("--no-png", action="store_true", help="skip placement.png")
    p.set_defaults(func=run)


def _overrides(args) -> dict:
    from .config import parse_overrides

    over = parse_overrides(args.set)
    if args.traffic is not None:
        over["traffic"] = args.traffic
    if args.lane_offset is not None:
        over["lane_offset_m"] = args.lane_offset
    if args.gap is not None:
        over["gap_m"] = args.gap
    return over


def run(args: argparse.Namespace) -> int:
    import time
    import warnings

    import numpy as np

    from ..io_utils import atomic_write_bytes, atomic_write_text
    from ..scene.cli import scene_from_args
    from ..scene.raycast import RayScene
    from .config import load_scenario
    from .footprints import validate_placement
    from .traffic import PlacementWarning, place

    t0 = time.perf_counter()
    cfg = load_scenario(args.scenario, _overrides(args))  # validates before any work
    catalog = None
    if args.catalog:
        from ..vehicles import load_catalog

        catalog = load_catalog(args.catalog)
    scene = scene_from_args(args)
    rs = RayScene(scene)
    t_scene = time.perf_counter() - t0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", PlacementWarning)
        placement = place(rs, cfg, rng=np.random.default_rng(args.seed), n_vehicles=args.vehicles,
                          n_lines=args.lines, catalog=catalog, seed=args.seed, scene_name=scene.name)
    t_place = placement.timing["seconds"]
    report = validate_placement(rs, placement, scene.truth, traffic=cfg.traffic)
    placement.stats["validation"] = report.summary()
    out = Path(args.out)
    png = None
    if not args.no_png:
        import cv2

        from ..scene.mapview import render_map
        from .draw import draw_placement

        m_per_px = args.m_per_px
        if m_per_px is None:
            ext = scene.bounds()[1, :2] - scene.bounds()[0, :2]
            m_per_px = max(0.25, float(ext.max()) / 4000.0)
        view = render_map(scene, m_per_px=m_per_px, rayscene=rs)
        img = draw_placement(view, placement, title=f"{scene.name} / {cfg.name} / seed {args.seed}: "
                             f"{len(placement.vehicles)} vehicles")
        ok, buf = cv2.imencode(".png", img)
        png = buf.tobytes()
    atomic_write_text(out / "placement.json", placement.to_json())
    if png is not None:
        atomic_write_bytes(out / "placement.png", png)
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
        f"validator: overlaps {val['overlaps']}  corners on drivable {100 * val['corners_drivable']:.1f} %  "
        f"footprint on road min {val['footprint_on_road_min']}"
        + (f"  heading error median {he['median']:.2f} deg p99 {he['p99']:.2f} deg" if he else "")
    )
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
