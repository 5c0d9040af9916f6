"""Benchmark the bundled scenes: build time, triangles, RayScene build, trace throughput.

Usage: python tools/bench_scenes.py [--rays 1000000] [--georef] [SCENE ...]

--georef also times loading each scene as GLB, unshifted and shifted by (+500,000,
+5,300,000) m in the node translation (UTM-like), and checks both recentre to the same
local vertices.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aerial_synth.scene import RayScene, list_scenes, load_scene  # noqa: E402


def bench(name: str, n_rays: int) -> dict:
    t0 = time.perf_counter()
    scene = load_scene(name)
    t_build = time.perf_counter() - t0

    t0 = time.perf_counter()
    rs = RayScene(scene)
    b = scene.bounds()
    rng = np.random.default_rng(0)
    xy1 = rng.uniform(b[0, :2], b[1, :2], size=(1, 2))
    rs.trace_down(xy1)  # first cast builds the Embree BVH (default ignore-set)
    t_rs = time.perf_counter() - t0

    xy = rng.uniform(b[0, :2], b[1, :2], size=(n_rays, 2))
    t0 = time.perf_counter()
    rs.trace_down(xy)
    t_trace = time.perf_counter() - t0

    t0 = time.perf_counter()
    rs.trace_down(xy[:1], ignore=())
    t_rs2 = time.perf_counter() - t0
    t0 = time.perf_counter()
    rs.trace_down(xy, ignore=())
    t_trace2 = time.perf_counter() - t0
    return {
        "scene": name,
        "build_s": t_build,
        "triangles": scene.n_triangles,
        "objects": len(scene.objects),
        "rayscene_s": t_rs,
        "rays_per_s": n_rays / t_trace,
        "rayscene_noignore_s": t_rs2,
        "rays_per_s_noignore": n_rays / t_trace2,
    }


def bench_georef(name: str) -> dict:
    import tempfile

    import trimesh

    from aerial_synth.scene import export_glb
    from aerial_synth.scene.io import _zup_to_yup

    with tempfile.TemporaryDirectory() as d:
        glb = export_glb(load_scene(name), Path(d) / f"{name}.glb")
        ts = trimesh.load(str(glb), force="scene", process=False, maintain_order=True)
        T = np.eye(4)
        T[:3, 3] = _zup_to_yup(np.array([[500_000.0, 5_300_000.0, 0.0]]))[0]
        for node in ts.graph.nodes_geometry:
            ts.graph.update(frame_to=node, matrix=T)
        shifted = Path(d) / f"{name}_utm.glb"
        shifted.write_bytes(ts.export(file_type="glb"))
        t0 = time.perf_counter()
        a = load_scene(glb)
        t_a = time.perf_counter() - t0
        t0 = time.perf_counter()
        b = load_scene(shifted)
        t_b = time.perf_counter() - t0
    return {"scene": name, "load_s": t_a, "load_shifted_s": t_b, "origin": b.origin,
            "same_local": a.vertex_hash() == b.vertex_hash()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", help="scene names (default: all bundled)")
    ap.add_argument("--rays", type=int, default=1_000_000)
    ap.add_argument("--georef", action="store_true", help="also time georeferenced GLB loads")
    args = ap.parse_args(argv)
    names = args.scenes or list_scenes()
    print(
        f"{'scene':10s} {'build s':>8s} {'triangles':>10s} {'objects':>8s} "
        f"{'RayScene s':>10s} {'trace Mray/s':>12s} {'(no ignore)':>11s}"
    )
    for n in names:
        r = bench(n, args.rays)
        print(
            f"{r['scene']:10s} {r['build_s']:8.2f} {r['triangles']:10d} {r['objects']:8d} "
            f"{r['rayscene_s']:10.3f} {r['rays_per_s'] / 1e6:12.2f} "
            f"{r['rays_per_s_noignore'] / 1e6:11.2f}"
        )
    if args.georef:
        print(f"\n{'scene':10s} {'GLB load s':>10s} {'shifted s':>10s}  origin, same local vertices")
        for n in names:
            r = bench_georef(n)
            print(f"{r['scene']:10s} {r['load_s']:10.2f} {r['load_shifted_s']:10.2f}  "
                  f"{r['origin']}, {r['same_local']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
