"""Benchmark: a DOTA export of city_park jam (default 200 images, 2 workers; target <= 3 min).

    .venv/bin/python tools/bench_export.py [--images 200] [--workers 2 | --dask local:2]
        [--preset full|fast] [--pin-one-core] [--out DIR] [--keep] [--json]

Prints wall time, images per second, seconds per image and the export summary.

``--pin-one-core`` restricts this process (and so every worker it starts) to one core
before anything starts a thread: with ``--workers 1`` it measures what one worker does on
a one-core share of the machine, the baseline of the per-worker scaling efficiency
``(images/s with K workers on K cores) / (K x images/s of one worker on one core)``.
``--json`` prints one more line: the figures as JSON (for tools/bench_suite.py). CPU
seconds per image (this process and its finished children) are printed beside the wall
time: on a loaded machine they move much less than the wall time.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _cpu_s() -> float:
    """User + system CPU seconds of this process, its finished (waited-for) children and
    the fork server's: a load-robust cost per image beside the wall time (the pool's and a
    LocalCluster's workers are forked by the fork server and have exited, reaped by it,
    when the export returns)."""
    import resource

    t = 0.0
    for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN):
        r = resource.getrusage(who)
        t += r.ru_utime + r.ru_stime
    return t + _fork_server_cpu_s()


def _fork_server_cpu_s() -> float:
    """CPU seconds of the export's fork server and of its finished children (the pool's
    and the LocalCluster's worker processes are forked by it, so they are not this
    process's children; the server reaps them). 0 where there is none or no /proc."""
    try:
        from multiprocessing import forkserver

        pid = getattr(forkserver._forkserver, "_forkserver_pid", None)
        if not pid:
            return 0.0
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        # after the command's ")": state is field 3, utime..cstime are fields 14..17
        return sum(int(x) for x in fields[11:15]) / os.sysconf("SC_CLK_TCK")
    except (ImportError, OSError, ValueError, IndexError):
        return 0.0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=int, default=200)
    ap.add_argument("--workers", type=int, default=None, help="local worker processes (default 2)")
    ap.add_argument("--dask", default=None, help="run on Dask instead: local:K or tcp://HOST:PORT")
    ap.add_argument("--scene", default="city_park")
    ap.add_argument("--scenario", default="jam")
    ap.add_argument("--scene-mix", default=None,
                    help="placement groups draw scene/scenario from weights (export --scene-mix)")
    ap.add_argument("--gsd", default=None, help="metres per pixel, or a range LO:HI (export --gsd)")
    ap.add_argument("--format", default="dota")
    ap.add_argument("--preset", default="full", choices=("full", "fast"))
    ap.add_argument("--images-per-placement", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--pin-one-core", action="store_true",
                    help="run on one core only (the first this process may use)")
    ap.add_argument("--out", default=None, help="output folder (default: a temporary one)")
    ap.add_argument("--keep", action="store_true", help="keep the temporary output")
    ap.add_argument("--json", action="store_true", help="also print the figures as one JSON line")
    ap.add_argument("--target-s", type=float, default=180.0)
    a = ap.parse_args(argv)
    if a.dask and a.workers is not None:
        ap.error("--dask and --workers: choose one engine")
    workers = 2 if a.workers is None else a.workers

    pinned = None
    if a.pin_one_core:  # before open3d, numba or OpenMP start a thread
        from aerial_synth.dataset.engines.affinity import allowed_cores, limit_threads, pin_cores

        pinned = allowed_cores()[0]
        if not pin_cores([pinned]):
            print("--pin-one-core: this platform does not allow pinning", file=sys.stderr)
            return 2
        limit_threads(1)

    from aerial_synth.camera import CameraConfig
    from aerial_synth.dataset.export import ExportConfig, export_dataset
    from aerial_synth.dataset.gsd import parse_range
    from aerial_synth.render.config import RenderOptions

    gsd = None if a.gsd is None else parse_range("--gsd", a.gsd)

    out = Path(a.out) if a.out else Path(tempfile.mkdtemp(prefix="bench_export_")) / "ds"
    cfg = ExportConfig(scene=a.scene, scenario=a.scenario, images=a.images, formats=a.format,
                       seed=a.seed, images_per_placement=a.images_per_placement,
                       camera=CameraConfig(gsd_m=gsd if isinstance(gsd, float) else None),
                       render=RenderOptions(preset=a.preset),
                       scene_mix=a.scene_mix,
                       gsd_range=gsd if isinstance(gsd, tuple) else None)
    load = [round(x, 2) for x in os.getloadavg()]
    cpu0 = _cpu_s()
    t0 = time.perf_counter()
    if a.dask:
        res = export_dataset(cfg, out, dask=a.dask, force=True, progress=True)
    else:
        res = export_dataset(cfg, out, workers=workers, force=True, progress=True)
    wall = time.perf_counter() - t0
    cpu = _cpu_s() - cpu0
    size = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    engine = f"dask {a.dask}" if a.dask else f"{workers} workers"
    print(f"command: {' '.join([sys.executable, *sys.argv])}")
    print(f"machine: {os.cpu_count()} cpu cores, load average before {load}"
          + (f", pinned to core {pinned}" if pinned is not None else ""))
    what = f"scene mix {cfg.scene_mix}" if a.scene_mix else f"{a.scene} {a.scenario}"
    print(f"export: {a.images} images, {what}, gsd {a.gsd or 'default'}, preset {a.preset}, format {a.format}, "
          f"{engine}, {a.images_per_placement} images per placement")
    print(f"wall time: {wall:.1f} s  ({wall / a.images:.2f} s/image, {a.images / wall:.2f} images/s)"
          f"  target <= {a.target_s:.0f} s: {'PASS' if wall <= a.target_s else 'FAIL'}")
    print(f"cpu time: {cpu:.1f} s ({cpu / a.images:.2f} s/image, this process, its finished children and the fork server's)")
    print(f"output: {out} ({size / 1e6:.1f} MB)")
    print("summary: " + json.dumps(res.summary, sort_keys=True))
    if a.json:
        print(json.dumps({"images": a.images, "seconds": round(wall, 2), "images_per_s": round(a.images / wall, 3),
                          "engine": engine, "preset": a.preset, "pinned_core": pinned,
                          "load_avg_before": load, "load_avg_after": [round(x, 2) for x in os.getloadavg()],
                          "cpu_s": round(cpu, 2), "cpu_s_per_image": round(cpu / a.images, 3), "bytes": size}))
    if not a.out and not a.keep:
        shutil.rmtree(out.parent, ignore_errors=True)
    return 0 if wall <= a.target_s else 1


if __name__ == "__main__":
    sys.exit(main())
