"""Throughput of the stream (aerial_synth.stream) against export, in one run.

Usage::

    .venv/bin/python tools/bench_stream.py [--images 8] [--size 512] [--preset full]
                                           [--scene city_park] [--scenario jam]

Runs, each in a fresh process (start-up, imports and scene loading included, as a
training job or an export pays them):

- ``export``  K=1 and K=2 (``--workers``), PNG and DOTA written to a temp folder;
- ``stream``  K=1: one process iterating ``iter_samples``; K=2: two processes, each its
  shard (``shard_indices``), pinned to half the cores each (as export's pool workers).

Prints one line per run (seconds, images/s, images/s per worker) and a JSON object last.
The stream does not encode or write, so it should be at least as fast as export.
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

REPO = Path(__file__).resolve().parent.parent

_STREAM = r"""
import json, sys
from aerial_synth.camera import CameraConfig
from aerial_synth.dataset.config import ExportConfig
from aerial_synth.render.config import RenderOptions
from aerial_synth.stream import iter_samples, shard_indices
a = json.loads(sys.argv[1])
cfg = ExportConfig(scene=a["scene"], scenario=a["scenario"], images=a["images"], seed=a["seed"],
                   images_per_placement=a["ipp"], render=RenderOptions(preset=a["preset"]),
                   camera=CameraConfig(width_px=a["size"], height_px=a["size"]))
if a["K"] > 1:  # each worker on its share of the cores, as export's pool workers are
    from aerial_synth.dataset.engines.affinity import pin_share
    pin_share(a["k"], a["K"])
idx = shard_indices(cfg.images, a["k"], a["K"], cfg.images_per_placement)
n = sum(1 for s in iter_samples(cfg, indices=idx, nthreads=a["nthreads"]) if s.rgb.size)
print(n)
"""


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env


def run_export(a, K: int) -> float:
    with tempfile.TemporaryDirectory(prefix="bench_stream_") as d:
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "aerial_synth.cli", "export", "--scene", a.scene, "--scenario",
                        a.scenario, "--images", str(a.images), "--size", str(a.size), "--preset", a.preset,
                        "--images-per-placement", str(a.ipp), "--seed", str(a.seed), "--format", "dota",
                        "--workers", str(K), "--no-progress", "--out", str(Path(d) / "ds")],
                       check=True, env=_env(), capture_output=True, text=True)
        return time.perf_counter() - t0


def run_stream(a, K: int) -> float:
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    t0 = time.perf_counter()
    procs = []
    for k in range(K):
        arg = dict(scene=a.scene, scenario=a.scenario, images=a.images, seed=a.seed, ipp=a.ipp, preset=a.preset,
                   size=a.size, k=k, K=K, nthreads=max(1, cores // K))
        procs.append(subprocess.Popen([sys.executable, "-c", _STREAM, json.dumps(arg)], env=_env(),
                                      stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
    made = 0
    for p in procs:
        out, err = p.communicate()
        if p.returncode != 0:
            raise SystemExit(f"bench_stream: a stream worker failed: {err.strip()[-800:]}")
        made += int(out.strip().splitlines()[-1])
    if made != a.images:
        raise SystemExit(f"bench_stream: the shards made {made} images, expected {a.images}")
    return time.perf_counter() - t0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--images", type=int, default=8)
    p.add_argument("--size", type=int, default=512)
    p.add_argument("--preset", default="full", choices=("full", "fast"))
    p.add_argument("--scene", default="city_park")
    p.add_argument("--scenario", default="jam")
    p.add_argument("--ipp", type=int, default=4, help="images per placement (4)")
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)
    res = {"images": a.images, "size": a.size, "preset": a.preset, "scene": a.scene, "scenario": a.scenario,
           "images_per_placement": a.ipp, "cores": os.cpu_count(), "load_avg_start": os.getloadavg()[0]}
    for kind, fn in (("export", run_export), ("stream", run_stream)):
        for K in (1, 2):
            s = fn(a, K)
            ips = a.images / s
            res[f"{kind}_k{K}"] = {"seconds": round(s, 2), "images_per_s": round(ips, 3),
                                   "images_per_s_per_worker": round(ips / K, 3)}
            print(f"{kind:6s} K={K}: {s:7.1f} s, {ips:.3f} images/s, {ips / K:.3f} images/s per worker",
                  flush=True)
    res["load_avg_end"] = os.getloadavg()[0]
    print(json.dumps(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
