#!/usr/bin/env python
"""Placement A/B: this checkout against another one, interleaved in one process on one core.

    .venv/bin/python tools/bench_place_ab.py --base /path/to/other/checkout
        [--scene city_park] [--scenario jam] [--vehicles 1000] [--repeat 12]

The other checkout's ``aerial_synth`` package is copied (links resolved) into a temporary
folder as ``aerial_synth_base`` and imported beside this one, so both run in the same
process, pinned to one core, on alternating turns (base, new, new, base, ...), each on a
fresh RayScene as an export's placement group does. Every pair places with the same seed
and must give the same vehicles (``to_dict`` and the raw field values) or the run stops.
Reports CPU time (``time.process_time``) per placement and the median of the paired
new/base ratios: on a shared machine the ratio of neighbouring runs is the steady figure.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import os
import shutil
import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, help="the other checkout (its aerial_synth/ is used)")
    ap.add_argument("--scene", default="city_park")
    ap.add_argument("--scenario", default="jam")
    ap.add_argument("--vehicles", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=12)
    a = ap.parse_args()

    from aerial_synth.dataset.engines.affinity import allowed_cores, limit_threads, pin_cores

    core = allowed_cores()[0]
    if not pin_cores([core]):  # before open3d, numba or OpenMP start a thread
        raise SystemExit("bench_place_ab: this platform does not allow pinning")
    limit_threads(1)
    import numpy as np

    tmp = Path(tempfile.mkdtemp(prefix="bench_place_ab_"))
    try:
        shutil.copytree(Path(a.base) / "aerial_synth", tmp / "aerial_synth_base", symlinks=False)
        sys.path.insert(0, str(tmp))

        def load(pkg: str) -> dict:
            m = {"place": importlib.import_module(pkg + ".placement").place,
                 "scene": importlib.import_module(pkg + ".scene").load_scene(a.scene),
                 "RayScene": importlib.import_module(pkg + ".scene.raycast").RayScene,
                 "catalog": importlib.import_module(pkg + ".vehicles").load_catalog()}
            warnings.simplefilter("ignore", importlib.import_module(pkg + ".placement.traffic").PlacementWarning)
            return m

        mods = {"base": load("aerial_synth_base"), "new": load("aerial_synth")}

        def run(m: dict, seed: int):
            rs = m["RayScene"](m["scene"], nthreads=1)
            c = time.process_time()
            p = m["place"](rs, a.scenario, np.random.default_rng(seed), n_vehicles=a.vehicles,
                           catalog=m["catalog"])
            return time.process_time() - c, p

        for m in mods.values():
            run(m, 10**6)  # warm-up: imports, catalog meshes, first BVH
        cpu = {k: [] for k in mods}
        for r in range(a.repeat):
            order = ["base", "new"] if r % 2 == 0 else ["new", "base"]
            out = {}
            for k in order:
                dt, p = run(mods[k], 100 + r)
                cpu[k].append(dt)
                out[k] = ([v.to_dict() for v in p.vehicles], repr([dataclasses.astuple(v) for v in p.vehicles]))
            if out["base"] != out["new"]:
                raise SystemExit(f"bench_place_ab: seed {100 + r}: the placements differ")
        ratios = [n / b for n, b in zip(cpu["new"], cpu["base"], strict=True)]
        print(f"{a.scenario} on {a.scene}, {a.vehicles} vehicles, pinned to core {core}, {a.repeat} pairs, "
              f"load average {' '.join(f'{v:.2f}' for v in os.getloadavg())}; placements identical")
        for k in ("base", "new"):
            print(f"{k:4s}: CPU per placement median {statistics.median(cpu[k]):.3f} s (min {min(cpu[k]):.3f} s)")
        print(f"paired new/base: median {statistics.median(ratios):.3f} (min {min(ratios):.3f}, "
              f"max {max(ratios):.3f}); {100 * (1 - statistics.median(ratios)):.1f} % less CPU")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
