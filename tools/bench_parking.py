"""Benchmark: place 5,000+ parked vehicles (issue 12: at most 2 s).

A synthetic scene of 50 lots of 55 m x 50 m (102 bays each, 5,100 bays, no markings, so
the default 2.5 x 5.0 m / 6 m aisle layout applies) beside one road; the ``parking``
scenario fills them completely (occupancy mean 1.0). The figure is the wall-clock time of
``place()`` on a warm process (ray-casting scene built, modules imported): lot detection
by traces, bay checks, filling, overlap resolution and the parking validator. The first
(cold) call is printed too.

    .venv/bin/python tools/bench_parking.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def lots_scene(n: int = 50, w: float = 55.0, h: float = 50.0, pitch: float = 70.0):
    import shapely

    from aerial_synth.scene.build import polygon_object
    from aerial_synth.scene.model import Scene

    cols = 10
    lots = [shapely.box((i % cols) * pitch - w / 2, (i // cols) * pitch + 40 - h / 2,
                        (i % cols) * pitch + w / 2, (i // cols) * pitch + 40 + h / 2) for i in range(n)]
    road = shapely.box(-pitch, -10, cols * pitch, -2)
    area = shapely.box(-pitch, -20, cols * pitch + pitch, (n // cols + 1) * pitch + 40)
    ground = area.difference(shapely.union_all(lots)).difference(road)
    objs = [polygon_object("ground", "ground", ground, 0.0), polygon_object("road_0", "road", road, 0.05),
            polygon_object("parking", "parking", shapely.union_all(lots), 0.05)]
    return Scene("bench_lots", objs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()

    from aerial_synth.placement import place
    from aerial_synth.scene import RayScene

    rs = RayScene(lots_scene())
    over = {"parking": {"occupancy_mean": 1.0}}
    t = time.perf_counter()
    p = place(rs, "parking", seed=0, overrides=over)
    cold = time.perf_counter() - t
    times = []
    for k in range(args.repeat):
        t = time.perf_counter()
        p = place(rs, "parking", seed=k + 1, overrides=over)
        times.append(time.perf_counter() - t)
    n = len(p.vehicles)
    v = p.stats["parking_validation"]
    print(f"lots {len(p.stats['lots'])}, bays {sum(lt['bays'] for lt in p.stats['lots'])}, parked {n}")
    print(f"validator: in bay {100 * v['in_bay_fraction']:.1f} %, overlaps {v['overlaps']}, "
          f"on lot {100 * v['on_surface_fraction']:.1f} %, alignment max {v['alignment_deg']['max']:.2f} deg")
    print(f"place(): cold {cold:.2f} s, warm median {np.median(times):.2f} s "
          f"(min {min(times):.2f}, {n / np.median(times):.0f} vehicles/s) over {args.repeat} runs")


if __name__ == "__main__":
    main()
