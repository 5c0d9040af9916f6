#!/usr/bin/env python
"""Benchmark suite: runs the sub-benchmarks and writes one ``bench.json``.

    .venv/bin/python tools/bench_suite.py [--out bench.json] [--images 40] [--quick] [--only NAME,...]

Sections (each also records its command and wall time):

* ``placement``  tools/bench_place.py: vehicles/s, engine time / bare ray time;
* ``frame``      tools/bench_render.py: frame time, frame / bare primary cast;
* ``export``     city_park jam exports at 1 and 2 local workers: images/s, speed-up; and
                 1 worker pinned to one core, for the per-worker scaling efficiency
                 (2 workers / (2 x one worker on one core)); ``--rounds`` (3) interleaved
                 rounds of these runs (and of the dask section's), each ratio taken within
                 a round, then the median (``*_spread``: median, min, max, every round);
                 ``speedup_2_over_1_ceiling``: 2 cores over the cores one worker alone
                 keeps busy, the most 2 workers can gain on it; ``--export-presets full,fast``
                 adds the same readings for the fast preset; ``workers_2_long``: 2 workers
                 on ``--long-images`` (120) images, the start-up spread over more images,
                 with ``workers_1_one_core_long`` and ``per_worker_efficiency_2_long``;
* ``dask``       the same export on a 2-process Dask LocalCluster: images/s (and its
                 ratios to the 1-worker runs of its round), and ``local_2_long`` on
                 ``--long-images`` images with its efficiency;
* ``tiles``      tiled placement of ``city_2km`` (4 km^2) in a child process per grid:
                 peak RSS for 1 tile and for 16 tiles, vehicles, seconds; an export
                 worker's peak RSS untiled / tiled (tools/bench_tiled_export.py:
                 ``export_untiled_peak_rss_mb``, ``export_tiled_peak_rss_mb``,
                 ``export_tiled_20km_peak_rss_mb``); ``world_20k``: 20,000 jam vehicles
                 asked for on city_dense_2km as 1 tile and as 16 tiles on 2 workers
                 (tools/bench_place_world.py: vehicles, scene build and placement
                 seconds, wall and CPU, vehicles/s, peak RSS);
* ``cli``        the cold ``aerial-synth --help`` time (median of 5 fresh processes).

Timings on a shared machine are noisy: compare ratios within one run (the suite records
the load average before and after every section). Nothing here asserts a time.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PY = sys.executable
SECTIONS = ("cli", "placement", "frame", "tiles", "export", "dask")


def _load() -> list[float]:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return []


def _run(cmd: list[str], timeout: float = 1800) -> tuple[str, float]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env, cwd=ROOT)
    wall = time.perf_counter() - t0
    if r.returncode not in (0, 1):  # bench_export returns 1 when its target is missed
        raise RuntimeError(f"{' '.join(cmd)} failed ({r.returncode}): {r.stderr.strip()[-500:]}")
    return r.stdout, wall


def _num(pattern: str, text: str, cast=float):
    m = re.search(pattern, text)
    return cast(m.group(1).replace(",", "")) if m else None


# ------------------------------------------------------------------ sections


def bench_cli(a) -> dict:
    exe = str(Path(PY).with_name("aerial-synth"))
    cmd = [exe, "--help"] if Path(exe).exists() else [PY, "-m", "aerial_synth.cli", "--help"]
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        subprocess.run(cmd, capture_output=True, check=True, cwd=ROOT)
        times.append(time.perf_counter() - t0)
    return {"command": " ".join(cmd), "help_cold_s": round(statistics.median(times), 3),
            "help_s_all": [round(t, 3) for t in times]}


def bench_placement(a) -> dict:
    cmd = [PY, "tools/bench_place.py", "--vehicles", str(a.place_vehicles), "--repeat", str(a.repeat)]
    out, wall = _run(cmd)
    return {
        "command": " ".join(cmd[1:]),
        "vehicles": _num(r"median [\d.]+ s for (\d+) vehicles", out, int),
        "seconds_median": _num(r"median ([\d.]+) s for", out),
        "vehicles_per_s": _num(r"; ([\d.]+) vehicles/s;", out),
        "engine_over_bare_rays": _num(r"engine/bare = ([\d.]+)x", out),
        "wall_s": round(wall, 1),
        "raw": out.strip().splitlines()[-2:],
    }


def _stage_lines(out: str) -> list[str]:
    """bench_render's per-stage lines (name, ms and / bare primary cast, for both presets)."""
    if "stages, median ms" not in out:
        return []
    block = out.split("stages, median ms", 1)[1].split("frame 1024x1024", 1)[0]
    return [ln.strip() for ln in block.strip().splitlines()[1:]]


def bench_frame(a) -> dict:
    # at least 7 frames (but for --quick): on a shared machine the median of 3 moved the
    # ratio by +-0.2
    frames = a.repeat if a.quick else max(a.repeat, 7)
    cmd = [PY, "tools/bench_render.py", "--repeat", str(frames), "--compare-presets"]
    out, wall = _run(cmd)
    return {
        "command": " ".join(cmd[1:]),
        "frame_ms_median": _num(r"frame 1024x1024 \(\w+\) median ([\d.]+) ms", out),
        "bare_primary_cast_ms": _num(r"bare cast_rays, primary rays: median ([\d.]+) ms", out),
        "frame_over_bare_primary": _num(r"primary rays: median [\d.]+ ms -> frame / bare ([\d.]+)", out),
        "fast_frame_ms_median": _num(r"frame \(fast\) median ([\d.]+) ms", out),
        "fast_frame_over_bare_primary": _num(r"frame \(fast\) median [\d.]+ ms -> frame / bare ([\d.]+)", out),
        # each frame over the bare primary cast timed just before it (steadier under drift)
        "frame_over_bare_primary_paired": _num(r"paired: .*?: full ([\d.]+)", out),
        "fast_frame_over_bare_primary_paired": _num(r"paired: .*?, fast ([\d.]+)", out),
        "stages": _stage_lines(out),
        "wall_s": round(wall, 1),
    }


_TILES_CHILD = r"""
import json, resource, sys, time, warnings
warnings.simplefilter("ignore")
from aerial_synth.scene.tiles import TiledWorld
from aerial_synth.placement.tiled import place_tiled
tile_m, n, km = float(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
if km == 2.0:
    w = TiledWorld.load("city_2km")
else:  # the same city, larger: only tile (0, 0) is placed
    import yaml
    from aerial_synth.scene.io import SCENES_DIR
    spec = yaml.safe_load((SCENES_DIR / "city_2km.yaml").read_text())
    spec.pop("size_m", None)
    w = TiledWorld.from_spec({**spec, "name": f"city_{km:g}km", "size_km": km})
only = None if km == 2.0 else [(0, 0)]
t0 = time.perf_counter()
pl = place_tiled(w, w.grid(tile_m, 60.0), "jam", seed=0, n_vehicles=n, only=only)
wall = time.perf_counter() - t0
print(json.dumps({"world_km": km, "tiles": len(w.grid(tile_m, 60.0)), "tiles_placed": 1 if only else len(w.grid(tile_m, 60.0)),
                  "tile_m": tile_m, "vehicles": len(pl.vehicles),
                  "requested": n, "seconds": round(wall, 2),
                  "vehicles_per_s": round(len(pl.vehicles) / wall, 1),
                  "scene_seconds": round(pl.timing["scene_seconds"], 2),
                  "place_seconds": round(pl.timing["place_seconds"], 2),
                  "dropped_at_borders": pl.stats["tiles"]["dropped_at_borders"],
                  "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)}))
"""


def bench_tiles(a) -> dict:
    res = {"world": "city_2km (2 km x 2 km = 4 km^2, scenes/city_2km.yaml)", "margin_m": 60.0,
           "vehicles_requested": a.tile_vehicles}
    runs = (("one_tile", 2000.0, a.tile_vehicles, 2.0), ("sixteen_tiles", 500.0, a.tile_vehicles, 2.0),
            # memory does not grow with the world: one 500 m tile of a 50 km x 50 km city
            ("one_tile_of_50km_world", 500.0, a.tile_vehicles * 2500 // 16, 50.0))
    prev = (a.previous or {}).get("tiles", {})
    for label, tile_m, n, km in runs:
        if a.tile_runs and label not in a.tile_runs.split(","):
            if label in prev:
                res[label] = prev[label]  # kept from the merged file
            continue
        cmd = [PY, "-c", _TILES_CHILD, str(tile_m), str(n), str(km)]
        out, wall = _run(cmd)
        d = json.loads(out.strip().splitlines()[-1])
        d["wall_s_with_imports"] = round(wall, 1)
        res[label] = d
    res["command"] = "place_tiled(TiledWorld.load('city_2km'), grid(tile_m, 60), 'jam', seed=0, n_vehicles=N) in a child process"
    if not a.tile_runs or "world" in a.tile_runs.split(","):
        # issue 14's target: 20,000 vehicles on 4 km^2 (city_dense_2km holds them), as 1 tile
        # and as 16 tiles on 2 workers: vehicles, scene build and placement seconds (wall and
        # CPU), vehicles/s, peak RSS (tools/bench_place_world.py)
        cmd = [PY, "tools/bench_place_world.py", "--json", "--vehicles", str(a.world_vehicles), "--runs", "1x1,16x2"]
        out, wall = _run(cmd)
        d = json.loads(out.strip().splitlines()[-1])
        res["world_20k"] = {"command": " ".join(cmd[1:]), "scene": d["scene"], "requested": d["requested"],
                            "one_tile": d["runs"]["1x1"], "sixteen_tiles_2_workers": d["runs"]["16x2"]}
    elif "world_20k" in prev:
        res["world_20k"] = prev["world_20k"]
    if not a.tile_runs or "export" in a.tile_runs.split(","):
        # an export worker's peak RSS, untiled and tiled city_2km and a tiled 20 km city
        cmd = [PY, "tools/bench_tiled_export.py", "--json", "--images", str(min(a.images, 20))]
        out, wall = _run(cmd, timeout=3600)
        d = json.loads(out.strip().splitlines()[-1])
        res.update({k: v for k, v in d.items() if k.endswith("_peak_rss_mb") or k.endswith("_rss")})
        res["export_runs"] = d
    elif "export_runs" in prev:
        res.update({k: v for k, v in prev.items() if k.startswith("export_")})
    return res


def _export(a, *engine: str, preset: str = "full", images: int | None = None) -> dict:
    """One timed export in a fresh process (tools/bench_export.py --json): the scene load
    and, for Dask, the cluster start are included, as a user sees them."""
    images = a.images if images is None else images
    cmd = [PY, "tools/bench_export.py", "--images", str(images), "--scene", a.scene, "--format", "dota",
           "--images-per-placement", str(a.images_per_placement), "--preset", preset, "--json",
           "--target-s", "1e9", *engine]
    out, wall = _run(cmd)
    d = json.loads(out.strip().splitlines()[-1])
    return {"images": d["images"], "seconds": round(d["seconds"], 2), "images_per_s": d["images_per_s"],
            "cpu_s_per_image": d.get("cpu_s_per_image"),
            "command": " ".join(cmd[1:]), "load_avg_before": d["load_avg_before"],
            "load_avg_after": d["load_avg_after"]}


def _warm(a) -> None:
    """Fills numba's on-disk kernel cache, so no timed run pays a compile."""
    from aerial_synth.camera import CameraConfig
    from aerial_synth.dataset.export import ExportConfig, export_dataset

    tmp = Path(tempfile.mkdtemp(prefix="bench_suite_"))
    try:
        export_dataset(ExportConfig(scene=a.scene, images=2, formats="dota",
                                    camera=CameraConfig(width_px=256, height_px=256)),
                       tmp / "warm", force=True, progress=False)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


#: the export runs of the export and dask sections: name -> tools/bench_export.py options
ENGINES = {
    "workers_1_one_core": ("--workers", "1", "--pin-one-core"),
    "workers_2": ("--workers", "2"),
    "dask_local_2": ("--dask", "local:2"),
    "workers_1": ("--workers", "1"),
}


def _rounds(a, keys: list[str], preset: str = "full") -> dict[str, list[dict]]:
    """``a.rounds`` rounds of one export per engine in ``keys``, interleaved (the order
    rotates each round), so that every ratio is taken between runs minutes apart at most:
    the shared machine's speed drifts by 20-25 % within an hour."""
    runs: dict[str, list[dict]] = {k: [] for k in keys}
    for r in range(max(1, a.rounds)):
        for k in keys[r % len(keys):] + keys[:r % len(keys)]:
            runs[k].append(_export(a, *ENGINES[k], preset=preset))
    return runs


def _median_run(runs: list[dict]) -> dict:
    """The run with the median images/s (the lower middle one of an even count)."""
    return sorted(runs, key=lambda r: r["images_per_s"])[(len(runs) - 1) // 2]


def _ratios(num: list[dict], den: list[dict], factor: float = 1.0) -> list[float]:
    """Per-round ratios num / (factor x den) of images/s."""
    return [round(n["images_per_s"] / (factor * d["images_per_s"]), 3) for n, d in zip(num, den)]


def _spread(xs: list[float]) -> dict:
    return {"median": round(statistics.median(xs), 3), "min": min(xs), "max": max(xs), "rounds": xs}


def _cores_busy(run: dict) -> float:
    """Cores one export kept busy on average: CPU seconds over wall seconds."""
    return run["cpu_s_per_image"] * run["images"] / max(run["seconds"], 1e-9)


def _busy_shares(runs: list[dict], core: list[dict], cores: int = 2) -> list[float]:
    """Per round: the share of ``cores`` cores ``runs`` kept busy over the cores the pinned
    run kept busy (one factor of the per-worker efficiency, see :func:`_export_readings`)."""
    return [round(_cores_busy(r) / cores / _cores_busy(c), 3) for r, c in zip(runs, core)]


def _cpu_ratios(runs: list[dict], core: list[dict]) -> list[float]:
    """Per round: the pinned run's CPU seconds per image over ``runs``' (the other factor)."""
    return [round(c["cpu_s_per_image"] / r["cpu_s_per_image"], 3) for r, c in zip(runs, core)]


def _export_readings(a, preset: str, dask: bool = False) -> dict:
    """Interleaved rounds (:func:`_rounds`) of 1 worker, 1 worker pinned to one core, 2
    workers (and, with ``dask``, a 2-process LocalCluster); each figure is the median of
    its per-round values, the runs' keys hold the median run."""
    keys = ["workers_1_one_core", "workers_2", "workers_1"] + (["dask_local_2"] if dask else [])
    runs = _rounds(a, keys, preset)
    one, core, two = runs["workers_1"], runs["workers_1_one_core"], runs["workers_2"]
    eff = _ratios(two, core, 2.0)
    busy = [round(_cores_busy(r), 3) for r in one]
    cores = min(2, os.cpu_count() or 2)
    res = {
        **{k: _median_run(v) for k, v in runs.items() if k != "dask_local_2"},
        "rounds": max(1, a.rounds),
        "runs": runs,
        # (a) what a user sees: 2 workers against 1 worker that has every core
        "speedup_2_over_1": _spread(_ratios(two, one))["median"],
        "speedup_2_over_1_rounds": _ratios(two, one),
        # what (a) can be at most: 2 workers can keep at most 2 cores busy, and one worker
        # alone already keeps this many busy (its threads), for about the same CPU per image
        "cores_busy_workers_1": statistics.median(busy),
        "speedup_2_over_1_ceiling": round(cores / statistics.median(busy), 3),
        # (b) per-worker scaling: 2 workers (a core each) against 1 worker on one core
        "speedup_2_over_1_one_core": _spread(_ratios(two, core))["median"],
        "per_worker_efficiency_2": _spread(eff)["median"],
        "per_worker_efficiency_2_spread": _spread(eff),
        # the efficiency, round by round, is exactly (the share of 2 cores the 2 workers
        # kept busy / the cores the pinned worker kept busy: what the software controls,
        # its start, idle workers, its tail) x (the pinned worker's CPU s per image / the 2
        # workers': the machine's speed per core with one core busy against both)
        "per_worker_efficiency_2_busy_share": _spread(_busy_shares(two, core)),
        "per_worker_efficiency_2_cpu_ratio": _spread(_cpu_ratios(two, core)),
    }
    if dask:
        a.dask_rounds = {"local_2": runs["dask_local_2"], "workers_1": one, "workers_1_one_core": core}
    return res


def bench_export(a) -> dict:
    _warm(a)
    res = {
        "command": "tools/bench_export.py --images N --workers K [--pin-one-core] | --dask local:2 (a fresh "
                   f"process per run; city_park jam, images_per_placement={a.images_per_placement}, format "
                   f"dota; {max(1, a.rounds)} interleaved rounds)",
        **_export_readings(a, "full", dask="dask" in a.sections),
        "target_speedup_2": 1.7,
        "target_per_worker_efficiency": 0.85,
        "target_images_per_s_2_cores": 3.0,
    }
    for preset in a.export_presets.split(","):
        if preset.strip() and preset.strip() != "full":
            res[f"preset_{preset.strip()}"] = _export_readings(a, preset.strip())
    if a.long_images > 0:
        # a longer export: the start-up (scene, fork server, each worker's first group)
        # spread over more images, nearer what a 100,000-image export runs at
        for preset in ["full"] + [p.strip() for p in a.export_presets.split(",")
                                  if p.strip() and p.strip() != "full"]:
            key = "workers_2_long" if preset == "full" else f"preset_{preset}_workers_2_long"
            res[key] = _export(a, "--workers", "2", preset=preset, images=a.long_images)
        # the efficiency target holds "on 40 or more images": also over the longer export,
        # against one worker on one core on as many images (the same start-up share)
        res["workers_1_one_core_long"] = _export(a, "--workers", "1", "--pin-one-core",
                                                 images=a.long_images)
        res["per_worker_efficiency_2_long"] = round(
            res["workers_2_long"]["images_per_s"] / (2 * res["workers_1_one_core_long"]["images_per_s"]), 3)
    return res


def bench_dask(a, export_res: dict | None) -> dict:
    """The LocalCluster's runs: taken in the export section's rounds where it ran in this
    suite (its ratios are then per round, between neighbouring runs), else rounds of its own
    beside 1 worker and 1 worker on one core."""
    rounds = getattr(a, "dask_rounds", None)
    if rounds is None:
        runs = _rounds(a, ["workers_1_one_core", "dask_local_2", "workers_1"])
        rounds = {"local_2": runs["dask_local_2"], "workers_1": runs["workers_1"],
                  "workers_1_one_core": runs["workers_1_one_core"]}
    d = dict(_median_run(rounds["local_2"]))
    d["seconds_including_cluster_start"] = d["seconds"]
    res = {"command": "tools/bench_export.py --dask local:2 (LocalCluster, 2 processes, loopback; "
                      f"cluster start included; {len(rounds['local_2'])} rounds interleaved with the 1-worker runs)",
           "local_2": d, "runs": rounds["local_2"],
           "speedup_over_workers_1": _spread(_ratios(rounds["local_2"], rounds["workers_1"]))["median"],
           "speedup_over_workers_1_one_core": _spread(_ratios(rounds["local_2"], rounds["workers_1_one_core"]))["median"],
           "per_worker_efficiency_2": _spread(_ratios(rounds["local_2"], rounds["workers_1_one_core"], 2.0))["median"],
           "per_worker_efficiency_2_spread": _spread(_ratios(rounds["local_2"], rounds["workers_1_one_core"], 2.0)),
           "per_worker_efficiency_2_busy_share": _spread(_busy_shares(rounds["local_2"], rounds["workers_1_one_core"])),
           "per_worker_efficiency_2_cpu_ratio": _spread(_cpu_ratios(rounds["local_2"], rounds["workers_1_one_core"]))}
    if a.long_images > 0:  # the cluster's start spread over more images, as in the export section
        d2 = _export(a, "--dask", "local:2", images=a.long_images)
        res["local_2_long"] = d2
        if export_res and "workers_1_one_core_long" in export_res:
            core = export_res["workers_1_one_core_long"]["images_per_s"]
            res["per_worker_efficiency_2_long"] = round(d2["images_per_s"] / (2 * core), 3)
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="bench.json")
    ap.add_argument("--images", type=int, default=40, help="images per export run (40)")
    ap.add_argument("--images-per-placement", type=int, default=10)
    ap.add_argument("--scene", default="city_park")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--rounds", type=int, default=3,
                    help="interleaved rounds of the 40-image export runs (ratios are per round, then the median)")
    ap.add_argument("--export-presets", default="full", help="export readings for these presets (full,fast)")
    ap.add_argument("--long-images", type=int, default=120,
                    help="also a 2-worker export of this many images per preset (0: none)")
    ap.add_argument("--place-vehicles", type=int, default=1000)
    ap.add_argument("--tile-vehicles", type=int, default=20000)
    ap.add_argument("--world-vehicles", type=int, default=20000,
                    help="vehicles asked for on city_dense_2km (tiles section, world_20k)")
    ap.add_argument("--only", default=",".join(SECTIONS), help=f"comma list of {', '.join(SECTIONS)}")
    ap.add_argument("--quick", action="store_true", help="small runs (8 images, 1 repeat) to check the suite")
    ap.add_argument("--merge", action="store_true", help="keep the other sections of an existing --out file")
    ap.add_argument("--tile-runs", default="", help="only these tiles runs (one_tile, sixteen_tiles, "
                    "one_tile_of_50km_world, export, world); with --merge the others are kept")
    a = ap.parse_args(argv)
    if a.quick:
        a.images, a.repeat, a.place_vehicles, a.tile_vehicles, a.rounds = 8, 1, 300, 3000, 1
        a.world_vehicles = 3000
        a.images_per_placement = 4
        a.long_images = min(a.long_images, 12)
    only = [s.strip() for s in a.only.split(",") if s.strip()]
    bad = [s for s in only if s not in SECTIONS]
    if bad:
        print(f"--only: expected names from {', '.join(SECTIONS)}, got {bad[0]!r}", file=sys.stderr)
        return 2
    a.sections = only
    sys.path.insert(0, str(ROOT))
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=ROOT).stdout.strip()
    except OSError:
        commit = ""
    doc = {
        "suite": "tools/bench_suite.py",
        "command": " ".join([Path(PY).name, "tools/bench_suite.py", *(argv if argv is not None else sys.argv[1:])]),
        "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "git_commit": commit,
        "machine": {"cpu_count": os.cpu_count(), "platform": sys.platform, "python": sys.version.split()[0]},
        "note": "shared machines are noisy; compare ratios within one run; load averages per section",
        "sections": {},
    }
    out = Path(a.out)
    a.previous = None
    if a.merge and out.is_file():
        old = json.loads(out.read_text())
        doc["sections"] = old.get("sections", {})
        a.previous = dict(doc["sections"])
        doc["merged_into"] = {k: old.get(k) for k in ("command", "date_utc", "git_commit")}
    for name in [s for s in SECTIONS if s in only]:
        print(f"[bench] {name} ...", flush=True)
        before = _load()
        t0 = time.perf_counter()
        try:
            if name == "dask":
                res = bench_dask(a, doc["sections"].get("export"))
            else:
                res = globals()[f"bench_{name}"](a)
        except Exception as exc:  # a broken sub-benchmark is recorded, the others still run
            res = {"error": f"{type(exc).__name__}: {exc}"}
        res["load_avg_before_after"] = [before, _load()]
        res["section_wall_s"] = round(time.perf_counter() - t0, 1)
        doc["sections"][name] = res
        print(f"[bench] {name}: {json.dumps(res)[:400]}", flush=True)
        tmp = out.with_name(f".{out.name}.tmp")
        tmp.write_text(json.dumps(doc, indent=2, sort_keys=True) + "\n")
        os.replace(tmp, out)  # written after every section, so a long run keeps what it has
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
