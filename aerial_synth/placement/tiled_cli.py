"""``aerial-synth place-tiled``: tiled placement of a large world (see docs/scale.md).

Light at import (the CLI imports every command module to build its parser).
"""

from __future__ import annotations

import argparse

from ..scene.cli import add_osm_args
from ..validators import arg_float, arg_int
from .config import DEFAULT_MARGIN_M

__all__ = ["register", "run"]


def register(sub) -> None:
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
    add_osm_args(p)  # --bbox/--crs for an OSM extract as --scene
    p.add_argument("--scenario", default="jam", metavar="NAME|FILE", help="traffic scenario (jam)")
    p.add_argument("--seed", type=arg_int("--seed", 0), default=0, metavar="S")
    p.add_argument("--vehicles", type=arg_int("--vehicles", 1, 100_000_000), default=None, metavar="N",
                   help="vehicles for the whole world (approximate when tiled; default: the "
                        "scenario's amount per tile)")
    p.add_argument("--tile-m", type=arg_float("--tile-m", 0.0, lo_open=True), default=500.0, metavar="M",
                   help="tile edge in metres, at least the longest vehicle (500)")
    p.add_argument("--margin-m", type=arg_float("--margin-m", 0.0), default=DEFAULT_MARGIN_M, metavar="M",
                   help=f"how far each tile's window reaches past its core ({DEFAULT_MARGIN_M:g})")
    p.add_argument("--workers", type=arg_int("--workers", 1, 1024), default=1, metavar="K",
                   help="place tiles in K processes; the result does not depend on K (1)")
    p.add_argument("--dask", default=None, metavar="tcp://HOST:PORT",
                   help="place the tiles on a running Dask cluster instead of --workers (docs/scale.md)")
    p.add_argument("--out", default="out/place-tiled", metavar="DIR", help="output folder")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``aerial-synth place-tiled`` (:func:`aerial_synth.placement.commands.run_place_tiled`)."""
    from . import commands  # lazy: placement, scene and ray-casting modules; --help loads none

    return commands.run_place_tiled(args)
