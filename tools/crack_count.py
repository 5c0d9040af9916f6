"""Count camera rays that hit nothing inside a procedural scene (cracks between surfaces).

Usage: python tools/crack_count.py [SCENE ...] [--frames 6] [--tilt 0 15]
       [--method raster embree]
Prints, per scene, tilt and primary method (the renderer's z-buffer, render/raster.py, or
one Embree ray per pixel), the holes per 1024x1024 frame whose footprint lies inside the
scene (every ray should hit something there).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aerial_synth.camera import Camera, CameraConfig  # noqa: E402
from aerial_synth.render.buffers import cast_buffers  # noqa: E402
from aerial_synth.scene import RayScene, load_scene  # noqa: E402


def count(name: str, frames: int, tilts, seed: int = 0, method: str = "raster") -> list[dict]:
    scene = load_scene(name)
    rs = RayScene(scene)
    b = scene.bounds()
    w, h = scene.meta.get("size_m", [b[1, 0] - b[0, 0], b[1, 1] - b[0, 1]])
    box = (-w / 2, -h / 2, w / 2, h / 2)
    rng = np.random.default_rng(seed)
    cfg = CameraConfig(gsd_m=0.12, width_px=1024, height_px=1024)
    half = 0.12 * 1024 / 2 + 40.0  # keep the footprint (and tilt) inside the scene
    out = []
    for tilt in tilts:
        holes = []
        for _ in range(frames):
            x = rng.uniform(b[0, 0] + half, b[1, 0] - half)
            y = rng.uniform(b[0, 1] + half, b[1, 1] - half)
            cam = Camera.look_at_ground(cfg, (x, y, 0.0), yaw_deg=float(rng.uniform(0, 360)),
                                        tilt_deg=float(tilt), tilt_axis_deg=float(rng.uniform(0, 360)))
            buf = cast_buffers(rs, cam, method=method)
            # only rays that meet the ground plane inside the scene's box count
            rays = cam._all_rays().astype(np.float64)
            t = -rays[:, 2] / np.minimum(rays[:, 5], -1e-9)
            gx, gy = rays[:, 0] + t * rays[:, 3], rays[:, 1] + t * rays[:, 4]
            inside = ((gx > box[0] + 1) & (gx < box[2] - 1) & (gy > box[1] + 1) & (gy < box[3] - 1))
            holes.append(int(((buf.semantic.ravel() == 0) & inside).sum()))
        out.append({"scene": name, "tilt_deg": tilt, "method": method,
                    "holes_per_frame": float(np.mean(holes)),
                    "max": int(np.max(holes))})
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("scenes", nargs="*", default=["city_park", "suburb", "highway"])
    ap.add_argument("--frames", type=int, default=6)
    ap.add_argument("--tilt", type=float, nargs="*", default=[0.0, 15.0])
    ap.add_argument("--method", nargs="*", choices=("raster", "embree"),
                    default=["raster", "embree"])
    a = ap.parse_args()
    for name in a.scenes:
        for m in a.method:
            for r in count(name, a.frames, a.tilt, method=m):
                print(f"{r['scene']:10s} {m:6s} tilt {r['tilt_deg']:4.0f} deg: "
                      f"{r['holes_per_frame']:7.1f} holes per 1024^2 frame (max {r['max']})")


if __name__ == "__main__":
    main()
