"""``aerial-synth place``: fill the roads of a scene with traffic and write placement.json/png.

Light at import (the CLI imports every command module to build its parser): the command's
body is :func:`aerial_synth.placement.commands.run_place`, imported when it runs.
"""

from __future__ import annotations

import argparse

from ..scene.cli import add_scene_args
from ..validators import arg_choice, arg_float, arg_int
from .config import SCENARIOS

__all__ = ["register", "run", "MAX_VEHICLES", "MAX_LINES"]

MAX_VEHICLES = 10_000_000
MAX_LINES = 1_000_000


def register(sub) -> None:
    p = sub.add_parser(
        "place",
        help="place vehicles on roads with line traces (jam, normal, sparse, random)",
        description="Place vehicles on the roads of a scene with the thesis's line-trace "
        "method and write placement.json, placement.png and a summary.",
    )
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


def _commands():
    from . import commands  # lazy: placement, scene and ray-casting modules; --help loads none

    return commands


def run(args: argparse.Namespace) -> int:
    """``aerial-synth place`` (:func:`aerial_synth.placement.commands.run_place`)."""
    return _commands().run_place(args)
