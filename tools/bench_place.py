#!/usr/bin/env python
"""Placement speed: N jam vehicles on a bundled scene (default 1,000 on city_park).

Prints wall time per placement (after one warm-up run that builds the Embree BVH and the
vehicle catalog), vehicles/s, rays/s and casts, plus the bare cast_rays time for the same
number of vertical traces so the engine's overhead over Embree is visible, and the
validator's quality figures over all timed placements (whole footprint on drivable
surface, overlaps, gap violations, heading error).

    .venv/bin/python tools/bench_place.py [--scene city_park] [--scenario jam] [--vehicles 1000] [--repeat 5]
        [--pin-one-core] [--fresh-scene]

``--pin-one-core`` pins the process to one core (and one compute thread) before open3d or
numba start, as an export worker of a 2-worker run is; ``--fresh-scene`` places on a new
RayScene each time, as an export does per placement group (so the Embree build of the
probe scene is part of every timing). CPU time (``time.process_time``) is reported beside
wall time: on a shared machine it is the steadier figure.
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="city_park")
    ap.add_argument("--scenario", default="jam")
    ap.add_argument("--vehicles", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--pin-one-core", action="store_true", help="pin to one core, one compute thread")
    ap.add_argument("--fresh-scene", action="store_true", help="a new RayScene per placement")
    args = ap.parse_args()
    if args.pin_one_core:  # before open3d, numba or OpenMP start a thread
        from aerial_synth.dataset.engines.affinity import allowed_cores, limit_threads, pin_cores

        core = allowed_cores()[0]
        if not pin_cores([core]):
            raise SystemExit("--pin-one-core: this platform does not allow pinning")
        limit_threads(1)
        print(f"pinned to core {core}")

    from aerial_synth.placement import place, validate_placement
    from aerial_synth.placement.traffic import PlacementWarning
    from aerial_synth.scene import load_scene
    from aerial_synth.scene.raycast import RayScene
    from aerial_synth.vehicles import load_catalog

    t0 = time.perf_counter()
    scene = load_scene(args.scene)
    rs = RayScene(scene)
    cat = load_catalog()
    warnings.simplefilter("ignore", PlacementWarning)
    place(rs, args.scenario, seed=12345, catalog=cat, n_vehicles=args.vehicles)  # warm-up
    print(f"setup (scene, BVH, catalog, warm-up): {time.perf_counter() - t0:.2f} s")
    times, cpus, vps, rays, casts, counts, reports = [], [], [], [], [], [], []
    for seed in range(args.repeat):
        if args.fresh_scene:
            rs = RayScene(scene, nthreads=1 if args.pin_one_core else 0)
        t, c = time.perf_counter(), time.process_time()
        p = place(rs, args.scenario, seed=seed, catalog=cat, n_vehicles=args.vehicles)
        dt = time.perf_counter() - t
        cpus.append(time.process_time() - c)
        times.append(dt)
        counts.append(len(p.vehicles))
        rays.append(p.stats["rays"])
        casts.append(p.stats["casts"])
        vps.append(len(p.vehicles) / dt)
        reports.append(validate_placement(rs, p, scene.truth, traffic=p.parameters.get("traffic", "right")))
        print(f"seed {seed}: {len(p.vehicles)} vehicles in {dt:.3f} s  "
              f"({len(p.vehicles) / dt:.0f} vehicles/s, {p.stats['rays'] / dt / 1e6:.2f} M rays/s, "
              f"{p.stats['rays']:,} rays in {p.stats['casts']} casts)")
    n_rays = int(np.median(rays))
    xy = np.random.default_rng(0).uniform(scene.bounds()[0, :2], scene.bounds()[1, :2], (n_rays, 2))
    rs.trace_labels(xy)
    t = time.perf_counter()
    rs.trace_labels(xy)
    bare = time.perf_counter() - t
    med = float(np.median(times))
    print(f"\n{args.scenario} on {args.scene}: median {med:.3f} s for {int(np.median(counts))} vehicles "
          f"(min {min(times):.3f} s); {np.median(vps):.0f} vehicles/s; "
          f"{n_rays / med / 1e6:.2f} M rays/s through the engine")
    print(f"CPU time per placement: median {np.median(cpus):.3f} s (min {min(cpus):.3f} s); "
          f"load average {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    print(f"bare trace of the same {n_rays:,} rays in one cast: {bare:.3f} s "
          f"({n_rays / bare / 1e6:.1f} M rays/s); engine/bare = {med / bare:.1f}x")
    n = sum(r.n for r in reports)
    ok = sum(int(r.footprint_ok.sum()) for r in reports)
    herr = np.concatenate([r.heading_error_deg for r in reports])
    herr = herr[np.isfinite(herr)]
    area = np.concatenate([r.area_drivable for r in reports])
    area = area[np.isfinite(area)]
    print(f"validator over {n} vehicles: footprint on drivable {100 * ok / max(n, 1):.2f} %"
          f" ({n - ok} off), footprint area on drivable min "
          f"{area.min() if len(area) else float('nan'):.4f}, corners on drivable "
          f"{100 * np.mean([r.corners_drivable for r in reports]):.2f} %, overlaps "
          f"{sum(r.overlaps for r in reports)}, gap violations {sum(r.gap_violations for r in reports)}"
          + (f", heading error median {np.median(herr):.2f} deg p99 {np.percentile(herr, 99):.2f} deg"
             if len(herr) else ""))


if __name__ == "__main__":
    main()
