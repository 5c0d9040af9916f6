"""The bodies of the ``aerial-synth scene ...`` commands and the loading of ``--scene``.

Imported by :mod:`aerial_synth.scene.cli` only when a command runs (scene loading brings
numpy, PyYAML and the scene modules; ``aerial-synth --help`` needs none of them).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from collections import Counter
from pathlib import Path

from ..errors import OutputError, SceneError
from ..io_utils import check_output_file
from ..out_guard import out_lock
from ..safe_input import load_yaml_file
from .georef import SceneWarning
from .io import SCENES_DIR, export_glb, list_scenes, load_scene
from .mapview import render_map, save_png
from .osm import ATTRIBUTION, load_osm_scene
from .procedural import checked_spec

__all__ = ["scene_from_args", "load_warning_once", "cmd_list", "cmd_show", "cmd_export",
           "cmd_from_osm"]


def scene_from_args(args: argparse.Namespace):
    """Load the scene named by :func:`add_scene_args` options. Returns a Scene.

    Scene warnings (e.g. a georeferenced glTF whose float32 vertices are far from 0) are
    printed as one line each on stderr.
    """
    return load_warning_once(
        lambda: load_scene(args.scene, labels=args.labels, seed=getattr(args, "scene_seed", None),
                           bbox=getattr(args, "bbox", None), crs=getattr(args, "crs", None))
    )


def load_warning_once(load):
    """Run ``load()``; print each SceneWarning it raised as one ``aerial-synth: warning:`` line."""
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


def cmd_list(args: argparse.Namespace) -> int:
    for name in list_scenes():
        path = SCENES_DIR / f"{name}.yaml"
        try:  # the checks `scene show` applies (size_km -> size_m included), not a raw read
            spec, seed = checked_spec(load_yaml_file(path, path.name, SceneError), path.name)
            w, h = spec["size_m"]
            desc = f"{spec['generator']}, {w:g} m x {h:g} m, seed {seed}"
        except SceneError as exc:  # a broken bundled spec still gets listed
            desc = f"(invalid spec: {str(exc).splitlines()[0][:80]})"
        print(f"{name:14s} {desc}")
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    if Path(args.out).suffix.lower() != ".png":  # PNG bytes under another name mislead viewers
        raise OutputError(f"--out {args.out}: expected an output path ending in .png (a PNG is "
                          "written)")
    check_output_file(args.out, "--out")
    scene = load_warning_once(lambda: load_scene(args.scene, labels=args.labels, seed=args.scene_seed,
                                                  bbox=args.bbox, crs=args.crs))
    _warn_unmatched(scene)
    view = render_map(scene, m_per_px=args.m_per_px)
    save_png(args.out, view.image)
    w, h = view.size_wh
    print(_summary(scene))
    print(f"wrote {args.out} ({w}x{h} px, {args.m_per_px:g} m/px)")
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    if Path(args.out).suffix.lower() != ".glb":
        raise OutputError(f"--out {args.out}: expected an output path ending in .glb")
    check_output_file(args.out, "--out")
    scene = load_warning_once(lambda: load_scene(args.scene, labels=args.labels, seed=args.scene_seed,
                                                  bbox=args.bbox, crs=args.crs))
    _warn_unmatched(scene)
    export_glb(scene, args.out)
    print(_summary(scene))
    print(f"wrote {args.out}")
    return 0


def cmd_from_osm(args: argparse.Namespace) -> int:
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
