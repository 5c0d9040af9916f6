"""Measure how often labelled vehicles of an export are partly hidden by trees.

    .venv/bin/python tools/tree_occlusion.py DATASET [--grid 5x3] [--json]

For every kept or difficult vehicle of every image (its world pose and size from the
metadata), a grid of points on its roof plane (``--grid`` along x across, at 90 % of its
height) is joined to the image's camera centre by rays cast against the scene (vehicles
left out: a vehicle hidden by another is not counted). A point is hidden by a tree when the
first thing the ray meets before it is a ``tree`` surface. A vehicle is *partly occluded by
trees* when some but not all of its points are, *fully* when all are. Prints the rates over
all vehicles, and per scene for a ``--scene-mix`` export.

The same scene and camera as the export: the labels' visibility comes from one ray-casting
scene (DESIGN.md), so this is what the labels saw, not a second model of it.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def roof_points(world: dict, nx: int, ny: int) -> np.ndarray:
    """(nx * ny, 3) points (metres, world) on the vehicle's roof plane, inset 10 %."""
    L, W, H = float(world["length_m"]), float(world["width_m"]), float(world["height_m"])
    u = (np.linspace(-0.4, 0.4, nx) * L)[:, None]
    v = (np.linspace(-0.4, 0.4, ny) * W)[None, :]
    uu, vv = np.broadcast_arrays(u, v)
    c, s = np.cos(world["heading_rad"]), np.sin(world["heading_rad"])
    x = world["x_m"] + c * uu - s * vv
    y = world["y_m"] + s * uu + c * vv
    z = np.full_like(x, world["z_m"] + 0.9 * H)
    return np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)


def measure(dataset: Path, nx: int = 5, ny: int = 3) -> dict:
    from aerial_synth.camera import Camera
    from aerial_synth.dataset.config import ExportConfig
    from aerial_synth.dataset.scenes import load_export_scene
    from aerial_synth.formats.meta import FORMAT
    from aerial_synth.scene.model import LABEL_IDS
    from aerial_synth.scene.raycast import RayScene

    params = json.loads((dataset / "manifest.json").read_text())["parameters"]
    cfg = ExportConfig.from_dict(params)
    tree = LABEL_IDS["tree"]
    scenes: dict[str, RayScene] = {}
    per: dict[str, list[int]] = {}  # scene -> [vehicles, partly, fully]
    for mp in sorted((dataset / "meta").glob("*.json")):
        d = json.loads(mp.read_text())
        if d.get("format") != FORMAT:
            continue
        mix = d["placement"].get("scene_mix")
        name = mix["scene"] if mix else cfg.scene
        if name not in scenes:
            import dataclasses

            scenes[name] = RayScene(load_export_scene(dataclasses.replace(cfg, scene=name, scene_mix=None)))
        rs = scenes[name]
        cam = Camera.from_dict(d["camera"])
        centre = np.asarray(cam.cam_to_world)[:3, 3]
        counts = per.setdefault(name, [0, 0, 0])
        for v in d["vehicles"]:
            if v["status"] == "dropped":
                continue
            pts = roof_points(v["world"], nx, ny)
            dirs = pts - centre
            dist = np.linalg.norm(dirs, axis=1)
            rays = np.concatenate([np.repeat(centre[None], len(pts), 0), dirs / dist[:, None]], 1)
            hits = rs.cast_rays(rays.astype(np.float32))
            hidden = hits.hit & (hits.t < dist - 0.05) & (hits.label_id == tree)
            counts[0] += 1
            if hidden.all():
                counts[2] += 1
            elif hidden.any():
                counts[1] += 1
    tot = np.sum(list(per.values()), axis=0) if per else np.zeros(3, int)

    def rates(c):
        n = max(int(c[0]), 1)
        return {"vehicles": int(c[0]), "partly_by_trees": int(c[1]), "fully_by_trees": int(c[2]),
                "partly_rate": round(c[1] / n, 4), "fully_rate": round(c[2] / n, 4)}

    return {"dataset": str(dataset), "grid": [nx, ny], "all": rates(tot),
            "per_scene": {k: rates(c) for k, c in sorted(per.items())}}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--grid", default="5x3", help="roof points along x across (5x3)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    try:
        nx, ny = (int(t) for t in a.grid.lower().split("x"))
        if nx < 1 or ny < 1:
            raise ValueError
    except ValueError:
        print(f"--grid: expected NXxNY of positive integers, got {a.grid!r}", file=sys.stderr)
        return 2
    if not (a.dataset / "manifest.json").is_file():
        print(f"{a.dataset}: not an aerial-synth dataset (no manifest.json)", file=sys.stderr)
        return 2
    r = measure(a.dataset, nx, ny)
    if a.json:
        print(json.dumps(r))
    else:
        al = r["all"]
        print(f"{r['dataset']}: {al['vehicles']} labelled vehicles; partly occluded by trees "
              f"{al['partly_by_trees']} ({100 * al['partly_rate']:.1f} %), fully "
              f"{al['fully_by_trees']} ({100 * al['fully_rate']:.1f} %)")
        for k, c in r["per_scene"].items():
            print(f"  {k}: {c['vehicles']} vehicles, partly {100 * c['partly_rate']:.1f} %, "
                  f"fully {100 * c['fully_rate']:.1f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
