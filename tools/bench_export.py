"""Benchmark: a DOTA export of city_park jam (default 200 images, 2 workers; target <= 3 min).

    .venv/bin/python tools/bench_export.py [--images 200] [--workers 2] [--out DIR] [--keep]

Prints wall time, images per second, seconds per image and the export summary.
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=int, default=200)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--scene", default="city_park")
    ap.add_argument("--scenario", default="jam")
    ap.add_argument("--format", default="dota")
    ap.add_argument("--images-per-placement", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=None, help="output folder (default: a temporary one)")
    ap.add_argument("--keep", action="store_true", help="keep the temporary output")
    ap.add_argument("--target-s", type=float, default=180.0)
    a = ap.parse_args(argv)

    from aerial_synth.dataset.export import ExportConfig, export_dataset

    out = Path(a.out) if a.out else Path(tempfile.mkdtemp(prefix="bench_export_")) / "ds"
    cfg = ExportConfig(scene=a.scene, scenario=a.scenario, images=a.images, formats=a.format,
                       seed=a.seed, images_per_placement=a.images_per_placement)
    t0 = time.perf_counter()
    res = export_dataset(cfg, out, workers=a.workers, force=True, progress=True)
    wall = time.perf_counter() - t0
    size = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    print(f"command: {' '.join([sys.executable, *sys.argv])}")
    print(f"machine: {os.cpu_count()} cpu cores")
    print(f"export: {a.images} images, {a.scene} {a.scenario}, format {a.format}, "
          f"{a.workers} workers, {a.images_per_placement} images per placement")
    print(f"wall time: {wall:.1f} s  ({wall / a.images:.2f} s/image, {a.images / wall:.2f} images/s)"
          f"  target <= {a.target_s:.0f} s: {'PASS' if wall <= a.target_s else 'FAIL'}")
    print(f"output: {out} ({size / 1e6:.1f} MB)")
    print("summary: " + json.dumps(res.summary, sort_keys=True))
    if not a.out and not a.keep:
        shutil.rmtree(out.parent, ignore_errors=True)
    return 0 if wall <= a.target_s else 1


if __name__ == "__main__":
    sys.exit(main())
