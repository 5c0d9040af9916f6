"""``aerial-synth place``: fill the roads of a scene with traffic and write placement.json/png."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["register"]

MAX_VEHICLES = 10_000_000
MAX_LINES = 1_000_000
MAX_PNG_PX = 8000


def register(sub) -> None:
    from ..scene.cli import add_scene_args

    p = sub.add_parser(
        "place",
        help="place vehicles on roads with line traces (jam, normal, sparse, random)",
        description="Place vehicles on the roads of a scene with the thesis's line-trace "
        "method and write placement.json, placement.png and a summary.",
    )
    from ..validators import arg_choice, arg_float, arg_int
    from .config import SCENARIOS

    p.add_argument("--scenario", default="jam", metavar="NAME|FILE",
                   help=f"{', '.join(SCENARIOS)}, or a scenario .yaml (default: jam)")
    add_scene_args(p)
    p.add_argument("--seed", type=arg_int("--seed", 0), default=0,
                   help="random seed, a non-negative integer (default: 0)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--vehicles", type=arg_int("--vehicles", 1, MAX_VEHICLES), default=None,
                   metavar="N", help="place N vehicles")
    g.add_argument("--lines", type=arg_int("--lines", 1, MAX_LINES), default=None, metavar="N",
                   help="seed N traffic lines (opposite lanes come on top)")
    p.add_argument("--traffic", type=arg_choice("--traffic", ("right", "left")), default=None,
                   help="driving side: right or left (default: the scenario's, right)")
    p.add_argument("--lane-offset", type=arg_float("--lane-offset", 0.0, 50.0, lo_open=True),
                   default=None, metavar="M",
                   help="distance d from the road edge to the vehicle centre, metres (0, 50]")
    p.add_argument("--gap", type=arg_float("--gap", 0.0, 10.0), default=None, metavar="M",
                   help="clearance kept between two vehicle footprints, metres [0, 10]")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override any scenario field, e.g. --set spacing.mean_m=12 "
                   "--set double_lane_probability=1 (repeatable)")
    p.add_argument("--catalog", default=None, metavar="FILE", help="vehicle catalog YAML")
    p.add_argument("--out", default="out/place", metavar="DIR", help="output folder (default: out/place)")
    p.add_argument("--m-per-px", type=arg_float("--m-per-px", 0.01, 100.0), default=None,
                   help="placement.png resolution, metres per pixel [0.01, 100] (default 0.25, "
                   "coarser for scenes over 1 km)")
    p.add_argument("--no-png", action="store_true", help="skip placement.png")
    p.set_defaults(func=run)


def _overrides(args) -> dict:
    from .config import parse_overrides

    over = parse_overrides(args.set)
    # the dedicated options win over --set; argparse already checked their values
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

    from ..errors import ConfigError
    from ..io_utils import check_output_dir
    from ..scene.cli import scene_from_args
    from ..scene.raycast import RayScene
    from .config import load_scenario
    from .footprints import validate_placement
    from .traffic import PlacementWarning, place

    t0 = time.perf_counter()
    out = check_output_dir(args.out, "--out")  # before any work
    cfg = load_scenario(args.scenario, _overrides(args))  # validates every field
    catalog = None
    if args.catalog:
        from ..vehicles import load_catalog

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

        from ..scene.mapview import render_map
        from .draw import draw_placement

        view = render_map(scene, m_per_px=m_per_px, rayscene=rs, max_px=MAX_PNG_PX)
        img = draw_placement(view, placement, title=f"{scene.name} / {cfg.name} / seed {args.seed}: "
                             f"{len(placement.vehicles)} vehicles")
        ok, buf = cv2.imencode(".png", img)
        png = buf.tobytes()
    files = [(out / "placement.json", placement.to_json().encode("utf-8"))]
    if png is not None:
        files.append((out / "placement.png", png))
    _write_all(out, files)
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


def _write_all(out: Path, files: list[tuple[Path, bytes]]) -> None:
    """Write every file atomically; if one fails, remove the ones this run wrote before it
    (and the folder if this run made it), so a failed run leaves nothing new behind."""
    from ..io_utils import atomic_write_bytes

    made = not out.exists()
    done: list[Path] = []
    try:
        for path, data in files:
            existed = path.exists()
            atomic_write_bytes(path, data)
            if not existed:
                done.append(path)
    except BaseException:
        for path in done:
            path.unlink(missing_ok=True)
        if made:
            try:
                out.rmdir()
            except OSError:
                pass
        raise
