"""Peak memory of an export worker: untiled city_2km, tiled city_2km and a tiled 20 km city.

Each run is one ``export_dataset(..., workers=1)`` in a fresh child process (the single
worker is that process), so its peak RSS (``ru_maxrss``) is the worker's. Prints one line
per run, or with ``--json`` one JSON object (``tools/bench_suite.py`` stores it in its
``tiles`` section):

    export_untiled_peak_rss_mb, export_tiled_peak_rss_mb, export_tiled_20km_peak_rss_mb
    (+ seconds, images, tiles placed per group, load averages), and the same keys with
    ``_group_`` for a child that only builds placement group 0 (scene or window, placement,
    RayScene; no frame): the part of the peak that depends on the world

The target (issue 14): the per-worker peak follows the tile, not the world, <= 1.5 GB.
Timings are noisy on a shared machine; memory is what this measures.

    .venv/bin/python tools/bench_tiled_export.py --images 20
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_CHILD = r"""
import json, resource, sys, time, warnings
from pathlib import Path
warnings.simplefilter("ignore")
from aerial_synth.dataset.export import ExportConfig, export_dataset
scene, tile, n, images, out = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
cfg = ExportConfig(scene=scene, images=images, images_per_placement=images, n_vehicles=n, seed=0,
                   tile_m=None if tile == "none" else float(tile))
if sys.argv[6] == "group":  # the world's part only: group 0's scene, placement and RayScene
    from aerial_synth.dataset.worker import ImageWorker
    t0 = time.perf_counter()
    w = ImageWorker.for_config(cfg, Path(out))
    grp = w.renderer.group(0)
    print(json.dumps({"seconds": round(time.perf_counter() - t0, 1), "vehicles": len(grp.placement.vehicles),
                      "triangles": int(grp.rayscene.scene.n_triangles),
                      "windows_built": getattr(w.scene, "windows_built", None),
                      "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)}))
    sys.exit(0)
t0 = time.perf_counter()
res = export_dataset(cfg, out, workers=1, progress=False)
wall = time.perf_counter() - t0
meta = json.loads((Path(out) / "meta" / "000000.json").read_text())
tile_meta = meta["placement"]["parameters"].get("tile") or {}
print(json.dumps({"seconds": round(wall, 1), "images": images, "vehicles_requested": n,
                  "labelled": sum(res.summary["vehicles_per_class"].values()),
                  "grid": tile_meta.get("grid"), "tiles_placed_per_group": tile_meta.get("tiles_placed"),
                  "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)}))
"""


def _load() -> list[float]:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return []


def _run(scene: str, tile: str, n: int, images: int, tmp: Path, mode: str = "export") -> dict:
    out = tmp / f"ds_{len(list(tmp.iterdir()))}"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    before = _load()
    r = subprocess.run([sys.executable, "-c", _CHILD, scene, tile, str(n), str(images), str(out), mode],
                       capture_output=True, text=True, env=env, cwd=ROOT, timeout=3600)
    if r.returncode != 0:
        raise RuntimeError(f"export of {scene} (tile {tile}) failed: {r.stderr.strip()[-500:]}")
    d = json.loads(r.stdout.strip().splitlines()[-1])
    d["load_avg_before_after"] = [before, _load()]
    return d


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=int, default=20, help="images per export (20, one placement group)")
    ap.add_argument("--tile-m", type=float, default=500.0)
    ap.add_argument("--big-km", type=float, default=20.0, help="size of the large city (20)")
    ap.add_argument("--density", type=float, default=500.0, help="vehicles requested per km^2 (500)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    import yaml

    spec = yaml.safe_load((ROOT / "scenes" / "city_2km.yaml").read_text())
    spec.pop("size_m", None)
    res = {"command": " ".join(["python", "tools/bench_tiled_export.py", *(argv or sys.argv[1:])]),
           "tile_m": a.tile_m, "note": "export_dataset(workers=1) in a fresh child process; peak RSS "
           "= ru_maxrss of that process (the worker); default camera (1024 px, 0.12 m, tilt 15 deg)"}
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        big = tmp / "city_big.yaml"
        big.write_text(yaml.safe_dump({**spec, "name": f"city_{a.big_km:g}km", "size_km": a.big_km}))
        n2 = int(a.density * 4)
        nbig = int(a.density * a.big_km ** 2)
        runs = (("export_untiled", "city_2km", "none", n2),
                ("export_tiled", "city_2km", str(a.tile_m), n2),
                (f"export_tiled_{a.big_km:g}km", str(big), str(a.tile_m), nbig))
        for key, scene, tile, n in runs:
            t0 = time.perf_counter()
            r = _run(scene, tile, n, a.images, tmp)
            r["wall_s_with_imports"] = round(time.perf_counter() - t0, 1)
            res[key] = r
            res[f"{key}_peak_rss_mb"] = r["peak_rss_mb"]
            if not a.json:
                print(f"{key}: {json.dumps(r)}", flush=True)
            # the world's share of it: group 0's scene, placement and RayScene, no frame
            g = _run(scene, tile, n, a.images, tmp, mode="group")
            res[f"{key}_group"] = g
            res[f"{key}_group_peak_rss_mb"] = g["peak_rss_mb"]
            if not a.json:
                print(f"{key} (group only): {json.dumps(g)}", flush=True)
    res["tiled_over_untiled_peak_rss"] = round(res["export_tiled_peak_rss_mb"] / res["export_untiled_peak_rss_mb"], 3)
    if a.json:
        print(json.dumps(res))
    else:
        print(json.dumps({k: v for k, v in res.items() if k.endswith("_mb") or k.endswith("_rss")}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
