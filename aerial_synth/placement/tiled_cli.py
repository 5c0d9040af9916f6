"""``aerial-synth place-tiled``: tiled placement of a large world (see docs/scale.md).

Light at import (the CLI imports every command module to build its parser).
"""

from __future__ import annotations

import argparse
import sys

__all__ = ["register", "run"]


def register(sub) -> None:
    from ..validators import arg_float, arg_int

    p = sub.add_parser(
        "place-tiled",
        help="place vehicles tile by tile on a large world (city of size_km, big meshes)",
        description="Place vehicles on a world tile by tile: each tile places into its core "
        "plus a margin and keeps the vehicles whose centre its core owns; peak memory is one "
        "tile's window, whatever the world's size. Writes placement.json.",
    )
    p.add_argument("--scene", default="city_2km", metavar="NAME|FILE",
                   help="a city spec (generated per window) or any scene (cut per window) (city_2km)")
    p.add_argument("--scene-seed", type=arg_int("--scene-seed", 0), default=None, metavar="N")
    from ..scene.cli import add_osm_args

    add_osm_args(p)  # --bbox/--crs for an OSM extract as --scene
    p.add_argument("--scenario", default="jam", metavar="NAME|FILE", help="traffic scenario (jam)")
    p.add_argument("--seed", type=arg_int("--seed", 0), default=0, metavar="S")
    p.add_argument("--vehicles", type=arg_int("--vehicles", 1, 100_000_000), default=None, metavar="N",
                   help="vehicles for the whole world (approximate when tiled; default: the "
                        "scenario's amount per tile)")
    p.add_argument("--tile-m", type=arg_float("--tile-m", 0.0, lo_open=True), default=500.0, metavar="M",
                   help="tile edge in metres, at least the longest vehicle (500)")
    p.add_argument("--margin-m", type=arg_float("--margin-m", 0.0), default=60.0, metavar="M",
                   help="how far each tile's window reaches past its core (60)")
    p.add_argument("--workers", type=arg_int("--workers", 1, 1024), default=1, metavar="K",
                   help="place tiles in K processes; the result does not depend on K (1)")
    p.add_argument("--dask", default=None, metavar="tcp://HOST:PORT",
                   help="place the tiles on a running Dask cluster instead of --workers (docs/scale.md)")
    p.add_argument("--out", default="out/place-tiled", metavar="DIR", help="output folder")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import resource
    import time
    import warnings

    from ..errors import PlacementError
    from ..io_utils import atomic_write_bytes, check_output_dir
    from ..scene.tiles import TiledWorld
    from .config import load_scenario
    from .tiled import min_tile_m, place_tiled
    from .traffic import PlacementWarning

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
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(out / "placement.json", pl.to_json().encode("utf-8"))
    t = pl.stats["tiles"]
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(f"world {world.name}: {t['grid'][0]} x {t['grid'][1]} tiles of {t['tile_m']:g} m (margin "
          f"{t['margin_m']:g} m); {len(pl.vehicles)} vehicles ({t['dropped_at_borders']} dropped at borders); "
          f"{wall:.1f} s; peak RSS {rss:.0f} MB")
    print(f"wrote {out / 'placement.json'}")
    return 0


def _dask_client(args):
    """A client of the running scheduler ``--dask``; one-line PlacementError otherwise."""
    import re

    from ..errors import PlacementError

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
