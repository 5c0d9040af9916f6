"""``aerial-synth scene ...`` commands and the shared ``--scene`` / ``--labels`` options.

Imports nothing heavy at import time: the scene is loaded inside the command functions.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["register", "add_scene_args", "scene_from_args"]

DEFAULT_SCENE = "city_park"


def add_scene_args(parser: argparse.ArgumentParser, default: str | None = DEFAULT_SCENE) -> None:
    """Add ``--scene NAME|FILE``, ``--labels FILE`` and ``--scene-seed N`` to a parser."""
    parser.add_argument(
        "--scene",
        default=default,
        metavar="NAME|FILE",
        help=f"bundled scene name, scene spec .yaml or mesh .glb/.gltf/.obj/.ply "
        f"(default: {default})",
    )
    parser.add_argument(
        "--labels", default=None, metavar="FILE",
        help="label-rules YAML for mesh files (default: NAME.labels.yaml beside the file, "
        "else the built-in rules)",
    )
    parser.add_argument(
        "--scene-seed", type=int, default=None, metavar="N",
        help="override the seed of a procedural scene spec",
    )


def scene_from_args(args: argparse.Namespace):
    """Load the scene named by :func:`add_scene_args` options. Returns a Scene."""
    from .io import load_scene

    return load_scene(args.scene, labels=args.labels, seed=getattr(args, "scene_seed", None))


def _summary(scene) -> str:
    from collections import Counter

    tri = Counter()
    for o in scene.objects:
        tri[o.label] += o.n_triangles
    b = scene.bounds()
    parts = ", ".join(f"{k} {v}" for k, v in sorted(tri.items()))
    size = f"{b[1, 0] - b[0, 0]:.0f} m x {b[1, 1] - b[0, 1]:.0f} m"
    return f"{scene.name}: {len(scene.objects)} objects, {scene.n_triangles} triangles, {size} ({parts})"


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
    from .io import load_scene
    from .mapview import render_map, save_png

    scene = load_scene(args.scene, labels=args.labels, seed=args.scene_seed)
    _warn_unmatched(scene)
    view = render_map(scene, m_per_px=args.m_per_px)
    save_png(args.out, view.image)
    w, h = view.size_wh
    print(_summary(scene))
    print(f"wrote {args.out} ({w}x{h} px, {args.m_per_px:g} m/px)")
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    from ..errors import SceneError
    from .io import export_glb, load_scene

    if Path(args.out).suffix.lower() != ".glb":
        raise SceneError(f"export {args.out}: expected an output path ending in .glb")
    scene = load_scene(args.scene, labels=args.labels, seed=args.scene_seed)
    _warn_unmatched(scene)
    export_glb(scene, args.out)
    print(_summary(scene))
    print(f"wrote {args.out}")
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
        q.add_argument("scene", metavar="SCENE", help="bundled name, spec .yaml or mesh file")
        q.add_argument("--out", required=True, metavar="FILE")
        q.add_argument("--labels", default=None, metavar="FILE", help="label-rules YAML")
        q.add_argument("--scene-seed", type=int, default=None, metavar="N",
                       help="override a procedural spec's seed")
        if name == "show":
            q.add_argument("--m-per-px", type=float, default=0.5, metavar="M",
                           help="map resolution in metres per pixel (default 0.5)")
        q.set_defaults(func=fn)
