"""``aerial-synth scene ...`` commands and the shared ``--scene`` / ``--labels`` options.

Imports nothing heavy at import time: the command bodies live in
:mod:`aerial_synth.scene.commands`, imported when a command runs.
"""

from __future__ import annotations

import argparse

from ..validators import arg_float, arg_int

__all__ = ["register", "add_scene_args", "scene_from_args"]

DEFAULT_SCENE = "city_park"
#: ``scene show --m-per-px`` bounds: finer than 1 cm/px is never useful (and the map of a
#: bundled scene would be gigantic); coarser than 100 m/px leaves a scene a few pixels wide.
M_PER_PX_MIN = 0.01
M_PER_PX_MAX = 100.0


def add_scene_args(parser: argparse.ArgumentParser, default: str | None = DEFAULT_SCENE) -> None:
    """Add ``--scene NAME|FILE``, ``--labels FILE`` and ``--scene-seed N`` to a parser."""
    parser.add_argument(
        "--scene",
        default=default,
        metavar="NAME|FILE",
        help=f"bundled scene name, scene spec .yaml, mesh .glb/.gltf/.obj/.ply or OSM extract "
        f".osm/.osm.bz2/.osm.pbf (default: {default})",
    )
    parser.add_argument(
        "--labels", default=None, metavar="FILE",
        help="label-rules YAML for mesh files (default: NAME.labels.yaml beside the file, "
        "else the built-in rules)",
    )
    parser.add_argument(
        "--scene-seed", type=arg_int("--scene-seed", lo=0), default=None, metavar="N",
        help="override the seed of a procedural scene spec (an integer >= 0)",
    )
    add_osm_args(parser)


def add_osm_args(parser: argparse.ArgumentParser) -> None:
    """``--bbox`` and ``--crs``: how to cut and project an OSM extract given as the scene."""
    parser.add_argument(
        "--bbox", default=None, metavar="MINLON,MINLAT,MAXLON,MAXLAT",
        help="OSM extracts only: keep what falls in this WGS84 box (default: the file's bounds)",
    )
    parser.add_argument(
        "--crs", default=None, metavar="EPSG:XXXX",
        help="OSM extracts only: projected CRS in metres to build in (default: the local UTM zone)",
    )


def _commands():
    from . import commands  # lazy: numpy, PyYAML and the scene modules; --help loads none

    return commands


def scene_from_args(args: argparse.Namespace):
    """Load the scene named by :func:`add_scene_args` options. Returns a Scene (see
    :func:`aerial_synth.scene.commands.scene_from_args`)."""
    return _commands().scene_from_args(args)


def _cmd_list(args: argparse.Namespace) -> int:
    return _commands().cmd_list(args)


def _cmd_show(args: argparse.Namespace) -> int:
    return _commands().cmd_show(args)


def _cmd_export(args: argparse.Namespace) -> int:
    return _commands().cmd_export(args)


def _cmd_from_osm(args: argparse.Namespace) -> int:
    return _commands().cmd_from_osm(args)


def register(sub) -> None:
    """Add the ``scene`` command group to the top-level subparsers."""
    p = sub.add_parser("scene", help="list, show and export scenes")
    ssub = p.add_subparsers(dest="scene_command", metavar="SUBCOMMAND")
    ssub.required = True

    pl = ssub.add_parser("list", help="list the bundled scenes")
    pl.set_defaults(func=_cmd_list)

    for name, fn, help_ in (
        ("show", _cmd_show, "render a top-down label map (PNG)"),
        ("export", _cmd_export, "write the labelled scene as GLB"),
    ):
        q = ssub.add_parser(name, help=help_)
        q.add_argument("scene", metavar="SCENE",
                       help="bundled name, spec .yaml, mesh file or OSM extract")
        q.add_argument("--out", required=True, metavar="FILE")
        q.add_argument("--labels", default=None, metavar="FILE", help="label-rules YAML")
        q.add_argument("--scene-seed", type=arg_int("--scene-seed", lo=0), default=None,
                       metavar="N", help="override a procedural spec's seed (an integer >= 0)")
        add_osm_args(q)
        if name == "show":
            q.add_argument(
                "--m-per-px", default=0.5, metavar="M",
                type=arg_float("--m-per-px", M_PER_PX_MIN, M_PER_PX_MAX),
                help=f"map resolution in metres per pixel, {M_PER_PX_MIN:g} to "
                f"{M_PER_PX_MAX:g} (default 0.5); at most 8000 px a side",
            )
        q.set_defaults(func=fn)

    q = ssub.add_parser(
        "from-osm", help="build a scene from an OpenStreetMap extract and write it as GLB",
        description="Build a labelled scene from an OSM extract (.osm, .osm.bz2, .osm.pbf): "
        "roads with junctions, markings and driving directions, buildings, trees, water, "
        "parking; georeferenced (local UTM zone or --crs). Offline; see docs/osm.md.",
    )
    q.add_argument("file", metavar="FILE", help="OSM extract: .osm, .osm.bz2 or .osm.pbf")
    q.add_argument("--out", required=True, metavar="FILE", help="output scene .glb")
    add_osm_args(q)
    q.add_argument("--scene-seed", type=arg_int("--scene-seed", lo=0), default=None, metavar="N",
                   help="seed of the crowns scattered over forests (default 0)")
    q.add_argument("--no-cache", action="store_true",
                   help="build from scratch and keep no copy in the cache folder")
    q.set_defaults(func=_cmd_from_osm)
