#!/usr/bin/env python
"""Placement on a whole world: N jam vehicles on a 4 km^2 city, as 1 tile and as 16 tiles.

Each run goes to a fresh child process, so its peak RSS is its own
(``resource.getrusage(RUSAGE_CHILDREN).ru_maxrss`` read by the child's parent after it ends:
the largest resident set of the child and of the pool workers it waited for). A run prints:
vehicles placed, the scene build seconds (window meshes, the RayScene and its Embree BVH,
summed over tiles), the placement seconds (``place()`` calls, summed over tiles), the wall
seconds of the whole tiled placement (builds and placement, tiles in parallel with
``--workers``; the process's one-time imports of open3d and scipy.special come before it,
in ``import_and_load_seconds``, with the scene's description) and its CPU seconds (this process and its pool workers, user + system),
vehicles/s of placement and of the wall time, rays and casts, the peak RSS and the load
average before and after (on a shared machine compare CPU seconds and ratios, not walls).

    .venv/bin/python tools/bench_place_world.py [--scene city_dense_2km] [--vehicles 20000]
        [--runs 1x1,16x2] [--json]

``--runs``: comma-separated ``TILESxWORKERS`` (tiles: 1, 4, 16, ... a square grid).
The last line with ``--json`` is one JSON object with every run (tools/bench_suite.py).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time

_CHILD = r"""
import json, sys, time, warnings
warnings.simplefilter("ignore")
t0 = time.perf_counter()
# the process's one-time imports, as the aerial-synth command makes them (open3d without
# its plotly viewer, aerial_synth._open3d), before the timed placement: counted in
# import_and_load_seconds, not in the scene build (RayScene's first use imports open3d)
# or the placement (a scenario's spacing law imports scipy.special)
from aerial_synth._open3d import stub_viewer
stub_viewer()
import open3d, scipy.special
import numpy as np
from aerial_synth.scene.tiles import TiledWorld
from aerial_synth.placement.tiled import place_tiled
from aerial_synth.vehicles import load_catalog
scene, n, tiles, workers, seed = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5])
w = TiledWorld.load(scene)
cat = load_catalog()
lo, hi = w.bounds[0], w.bounds[1]
k = int(round(tiles ** 0.5))
size = float(max(hi[0] - lo[0], hi[1] - lo[1]))
grid = w.grid(size / k + (1e-6 if k > 1 else 0.0), 60.0)
t_imp = time.perf_counter() - t0
import resource
def cpu():
    a, b = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return a.ru_utime + a.ru_stime + b.ru_utime + b.ru_stime
c1 = cpu()
t1 = time.perf_counter()
pl = place_tiled(w, grid, "jam", seed=seed, n_vehicles=n, catalog=cat, workers=workers)
wall = time.perf_counter() - t1
cpu_s = cpu() - c1
st = pl.stats
print(json.dumps({
    "scene": scene, "tiles": len(grid), "grid": list(grid.shape), "workers": workers,
    "requested": n, "vehicles": len(pl.vehicles),
    "scene_seconds": round(pl.timing["scene_seconds"], 2),
    "place_seconds": round(pl.timing["place_seconds"], 2),
    "wall_seconds": round(wall, 2),
    "cpu_seconds": round(cpu_s, 2),
    "scene_cpu_seconds": round(pl.timing["scene_cpu_seconds"], 2),
    "place_cpu_seconds": round(pl.timing["place_cpu_seconds"], 2),
    "import_and_load_seconds": round(t_imp, 2),
    "vehicles_per_s_place": round(len(pl.vehicles) / max(pl.timing["place_seconds"], 1e-9), 1),
    "vehicles_per_s_wall": round(len(pl.vehicles) / max(wall, 1e-9), 1),
    "rays": int(sum(t.get("rays", 0) for t in st["tiles"]["per_tile"])),
    "casts": int(sum(t.get("casts", 0) for t in st["tiles"]["per_tile"])),
    "dropped_at_borders": st["tiles"]["dropped_at_borders"],
    "stopped_full_tiles": int(sum(bool(t.get("stopped_full")) for t in st["tiles"]["per_tile"])),
}))
"""


def _load() -> str:
    import os

    return " ".join(f"{v:.2f}" for v in os.getloadavg())


#: a middle process per run: it runs the child and reports RUSAGE_CHILDREN.ru_maxrss, the
#: largest resident set of the child and of the pool workers the child waited for, so every
#: run's peak is its own whatever ran before it
_MIDDLE = r"""
import resource, subprocess, sys
out = subprocess.run(sys.argv[1:], capture_output=True, text=True)
sys.stderr.write(out.stderr)
print(out.stdout.strip().splitlines()[-1] if out.returncode == 0 and out.stdout.strip() else "")
print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
sys.exit(out.returncode)
"""


def run_one(scene: str, n: int, tiles: int, workers: int, seed: int = 0) -> dict:
    """One run in a fresh child process; adds its peak RSS (MB, largest process of the run)."""
    load0 = _load()
    t = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", _MIDDLE, sys.executable, "-c", _CHILD, scene, str(n), str(tiles),
                          str(workers), str(seed)], capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t
    if out.returncode != 0:
        raise SystemExit(f"bench_place_world: the run {tiles} tiles x {workers} workers failed:\n{out.stderr[-3000:]}")
    lines = out.stdout.strip().splitlines()
    d = json.loads(lines[-2])
    d["peak_rss_mb"] = round(int(lines[-1]) / 1024, 1)  # ru_maxrss is in KiB on Linux
    d["process_seconds"] = round(wall, 2)
    d["load_before"], d["load_after"] = load0, _load()
    return d


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="city_dense_2km")
    ap.add_argument("--vehicles", type=int, default=20000)
    ap.add_argument("--runs", default="1x1,16x2", help="comma-separated TILESxWORKERS")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", action="store_true", help="end with one JSON line of all runs")
    a = ap.parse_args(argv)
    res = {"scene": a.scene, "requested": a.vehicles, "runs": {}}
    for spec in a.runs.split(","):
        tiles, workers = (int(v) for v in spec.lower().split("x"))
        d = run_one(a.scene, a.vehicles, tiles, workers, a.seed)
        res["runs"][spec] = d
        print(f"{a.scene}, {tiles} tile(s), {workers} worker(s): {d['vehicles']} of {a.vehicles} vehicles; "
              f"scene build {d['scene_seconds']:.2f} s (CPU {d['scene_cpu_seconds']:.1f} s), "
              f"placement {d['place_seconds']:.2f} s (CPU {d['place_cpu_seconds']:.1f} s) "
              f"({d['vehicles_per_s_place']:.0f} vehicles/s), wall {d['wall_seconds']:.2f} s "
              f"({d['vehicles_per_s_wall']:.0f} vehicles/s), CPU {d['cpu_seconds']:.1f} s; {d['rays']:,} rays in {d['casts']:,} casts; "
              f"peak RSS {d['peak_rss_mb']:.0f} MB; load {d['load_before']} -> {d['load_after']}")
    if a.json:
        print(json.dumps(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
