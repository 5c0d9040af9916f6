"""``aerial-synth scene ...`` commands and the shared ``--scene`` / ``--labels`` options.

Imports nothing heavy at import time: the scene is loaded inside the command functions.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

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


def scene_from_args(args: argparse.Namespace):
    """Load the scene named by :func:`add_scene_args` options. Returns a Scene.

    Scene warnings (e.g. a georeferenced glTF whose float32 vertices are far from 0) are
    printed as one line each on stderr.
    """
    from .io import load_scene

    return _load_warning_once(
        lambda: load_scene(args.scene, labels=args.labels, seed=getattr(args, "scene_seed", None),
                           bbox=getattr(args, "bbox", None), crs=getattr(args, "crs", None))
    )


def _load_warning_once(load):
    """Run ``load()``; print each SceneWarning it raised as one ``aerial-synth: warning:`` line."""
    import warnings

    from .georef import SceneWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", SceneWarning)
        scene = load()
    for w in caught:
        if issubclass(w.category, SceneWarning):
            print(f"aerial-synth: warning: {' '.join(str(w.message).split())}", file=sys.stderr)
        else:
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    return scene


def _summary(scene) -> str:
    from collections import Counter

    tri = Counter()
    for o in scene.objects:
        tri[o.label] += o.n_triangles
    b = scene.bounds()
    parts = ", ".join(f"{k} {v}" for k, v in sorted(tri.items()))
    size = f"{b[1, 0] - b[0, 0]:.0f} m x {b[1, 1] - b[0, 1]:.0f} m"
    geo = ""
    if any(scene.origin) or scene.crs:
        o = ", ".join(f"{c + 0.0:.3f}".rstrip("0").rstrip(".") for c in scene.origin)
        geo = f"; local frame origin ({o}) m" + (f" in {scene.crs}" if scene.crs else "")
    return (f"{scene.name}: {len(scene.objects)} objects, {scene.n_triangles} triangles, {size} "
            f"({parts}){geo}")


def _warn_unmatched(scene) -> None:
    n = int(scene.meta.get("n_unmatched", 0) or 0)
    if n:
        names = ", ".join(scene.meta["unmatched"][:5]) + (" ..." if n > 5 else "")
        print(
            f"aerial-synth: warning: {n} mesh name(s) matched no label rule and are labelled "
            f"'unknown' (treated as obstacles): {names}",
            file=sys.stderr,
        )


def _cmd_list(args: argparse.Namespace) -> int:
    import yaml

    from .io import SCENES_DIR, list_scenes

    for name in list_scenes():
        desc = ""
        try:
            data = yaml.safe_load((SCENES_DIR / f"{name}.yaml").read_text(encoding="utf-8"))
            size = data.get("size_m")
            desc = f"{data.get('generator', '?')}, {size[0]:g} m x {size[1]:g} m, seed {data.get('seed')}"
        except Exception:  # a broken bundled spec still gets listed
            desc = "(unreadable spec)"
        print(f"{name:12s} {desc}")
    return 0


def _cmd_show(args: argparse.Namespace) -> int:
    from ..errors import OutputError
    from ..io_utils import check_output_file
    from .io import load_scene
    from .mapview import render_map, save_png

    if Path(args.out).suffix.lower() != ".png":  # PNG bytes under another name mislead viewers
        raise OutputError(f"--out {args.out}: expected an output path ending in .png (a PNG is "
                          "written)")
    check_output_file(args.out, "--out")
    scene = _load_warning_once(lambda: load_scene(args.scene, labels=args.labels, seed=args.scene_seed,
                                                  bbox=args.bbox, crs=args.crs))
    _warn_unmatched(scene)
    view = render_map(scene, m_per_px=args.m_per_px)
    save_png(args.out, view.image)
    w, h = view.size_wh
    print(_summary(scene))
    print(f"wrote {args.out} ({w}x{h} px, {args.m_per_px:g} m/px)")
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    from ..errors import OutputError
    from ..io_utils import check_output_file
    from .io import export_glb, load_scene

    if Path(args.out).suffix.lower() != ".glb":
        raise OutputError(f"--out {args.out}: expected an output path ending in .glb")
    check_output_file(args.out, "--out")
    scene = _load_warning_once(lambda: load_scene(args.scene, labels=args.labels, seed=args.scene_seed,
                                                  bbox=args.bbox, crs=args.crs))
    _warn_unmatched(scene)
    export_glb(scene, args.out)
    print(_summary(scene))
    print(f"wrote {args.out}")
    return 0


def _cmd_from_osm(args: argparse.Namespace) -> int:
    import time

    from ..errors import OutputError
    from ..io_utils import check_output_file
    from ..out_guard import out_lock
    from .io import export_glb
    from .osm import ATTRIBUTION, load_osm_scene

    if Path(args.out).suffix.lower() != ".glb":
        raise OutputError(f"--out {args.out}: expected an output path ending in .glb")
    check_output_file(args.out, "--out")
    with out_lock(args.out, "scene from-osm"):
        t0 = time.perf_counter()
        scene = load_osm_scene(args.file, bbox=args.bbox, crs=args.crs,
                               seed=0 if args.scene_seed is None else args.scene_seed,
                               use_cache=not args.no_cache)
        t_build = time.perf_counter() - t0
        export_glb(scene, args.out)
    osm = scene.meta.get("osm", {})
    print(_summary(scene))
    print(f"{osm.get('roads', 0)} roads ({osm.get('oneway_roads', 0)} one-way), "
          f"{osm.get('buildings', 0)} buildings, {osm.get('trees', 0)} trees; crs {scene.crs}, "
          f"origin {scene.origin[0]:.0f} {scene.origin[1]:.0f}; built in {t_build:.2f} s"
          + (" (cached)" if scene.meta.get("cache") and t_build < 0.5 else ""))
    print(f"wrote {args.out}  (map data {ATTRIBUTION}, ODbL)")
    return 0


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
