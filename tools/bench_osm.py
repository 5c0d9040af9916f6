"""Benchmark the OSM scene reader on synthetic grid cities (no downloads).

Writes two .osm.pbf files with osmium's writer (cached under --work):

* ``city_1km2.osm.pbf``: a 1 km x 1 km city centre: a 100 m street grid (residential
  streets, some one-way, primary avenues with 2 + 2 lanes, a roundabout), nine buildings
  per block with 2-8 levels, parks with trees, parking lots, street trees;
* ``city_large.osm.pbf``: the same city repeated over a large area until the file is
  about --large-mb megabytes.

and measures

1. building the 1 km^2 scene (read + project + roads/junctions/markings + buildings + trees),
   in process and as ``aerial-synth scene from-osm`` (wall time, GLB written);
2. reading the large file with a small --bbox (500 m x 500 m) in a fresh process: wall time
   and peak resident memory (ru_maxrss), against the file size.

Run:  .venv/bin/python tools/bench_osm.py [--work out/bench_osm] [--large-mb 50]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

LAT0, LON0 = 48.1370, 11.5750  # a reference point (the grid is synthetic)
M_PER_DEG_LAT = 111320.0
BLOCK_M = 100.0


def lonlat(x, y):
    return (LON0 + x / (M_PER_DEG_LAT * math.cos(math.radians(LAT0))), LAT0 + y / M_PER_DEG_LAT)


def write_grid_city(path: Path, nx: int, ny: int, seed: int = 0, real_like: bool = False,
                    side: int = 3, footways: bool = False) -> dict:
    """A grid city of nx x ny blocks of 100 m written as PBF. Returns counts.

    side: buildings per block side (side x side buildings per block);
    footways: a footway along both sides of every street.

    real_like: jitter building corners by up to 0.5 m and give buildings address, id and
    date tags, as real data has (the file then compresses like a real extract, ~0.6 kB
    per block, instead of ~50 bytes).
    """
    import osmium
    from osmium.osm.mutable import Node, Way

    path = Path(path)
    if path.exists():
        path.unlink()
    tmp = path.with_name(path.name + ".part.osm.pbf")
    if tmp.exists():
        tmp.unlink()
    n_cross = (nx + 1) * (ny + 1)
    nb = side * side
    per_block = nb * 4 + 8  # building corners + up to 8 trees
    base_b = n_cross + 1

    def cross_id(i, j):
        return 1 + i * (ny + 1) + j

    def block_node(bi, bj, k):
        return base_b + (bi * ny + bj) * per_block + k

    def kind(bi, bj):
        r = (bi * 7919 + bj * 104729 + seed) % 100
        return "park" if r < 8 else ("parking" if r < 13 else "buildings")

    w = osmium.SimpleWriter(str(tmp))
    counts = {"nodes": 0, "ways": 0, "buildings": 0}
    try:
        for i in range(nx + 1):
            for j in range(ny + 1):
                w.add_node(Node(id=cross_id(i, j), location=lonlat(i * BLOCK_M, j * BLOCK_M)))
                counts["nodes"] += 1
        for bi in range(nx):
            for bj in range(ny):
                rng = np.random.default_rng([seed, bi, bj])
                x0, y0 = bi * BLOCK_M + 12.0, bj * BLOCK_M + 12.0
                k = kind(bi, bj)
                if k == "buildings":
                    cell = (BLOCK_M - 24.0) / side
                    for a in range(side):
                        for b in range(side):
                            cx, cy = x0 + a * cell, y0 + b * cell
                            pts = [(cx + 1, cy + 1), (cx + cell - 1, cy + 1),
                                   (cx + cell - 1, cy + cell - 1), (cx + 1, cy + cell - 1)]
                            if real_like:
                                pts = [(px + rng.uniform(-0.5, 0.5), py + rng.uniform(-0.5, 0.5))
                                       for px, py in pts]
                            for c, (px, py) in enumerate(pts):
                                w.add_node(Node(id=block_node(bi, bj, (a * side + b) * 4 + c),
                                                location=lonlat(px, py)))
                                counts["nodes"] += 1
                else:
                    pts = [(x0, y0), (x0 + 76, y0), (x0 + 76, y0 + 76), (x0, y0 + 76)]
                    for c, (px, py) in enumerate(pts):
                        w.add_node(Node(id=block_node(bi, bj, c), location=lonlat(px, py)))
                        counts["nodes"] += 1
                    if k == "park":
                        for t in range(8):
                            px, py = rng.uniform(5, 71, 2)
                            w.add_node(Node(id=block_node(bi, bj, nb * 4 + t),
                                            location=lonlat(x0 + px, y0 + py),
                                            tags={"natural": "tree"}))
                            counts["nodes"] += 1
        seg = 10  # streets split every 10 blocks, like real ways
        foot = []  # (node ids, tags) of the footways
        if footways:
            fid = base_b + nx * ny * per_block
            for vertical in (True, False):
                for i in range(nx + 1 if vertical else ny + 1):
                    half = _half_width(_street_tags(i if vertical else i + 3)) + 1.5
                    n_along = ny if vertical else nx
                    for k0 in range(0, n_along, seg):
                        k1 = min(n_along, k0 + seg)
                        for off in (-half, half):
                            ids = []
                            for k in (k0, k1):
                                a, b = i * BLOCK_M + off, k * BLOCK_M
                                w.add_node(Node(id=fid, location=lonlat(*((a, b) if vertical
                                                                           else (b, a)))))
                                ids.append(fid)
                                fid += 1
                                counts["nodes"] += 1
                            foot.append(ids)
        wid = 1
        for i in range(nx + 1):  # north-south streets
            tags = _street_tags(i)
            for j0 in range(0, ny, seg):
                ids = [cross_id(i, j) for j in range(j0, min(ny, j0 + seg) + 1)]
                w.add_way(Way(id=wid, nodes=ids, tags=tags))
                wid += 1
        for j in range(ny + 1):  # east-west streets
            tags = _street_tags(j + 3)
            for i0 in range(0, nx, seg):
                ids = [cross_id(i, j) for i in range(i0, min(nx, i0 + seg) + 1)]
                w.add_way(Way(id=wid, nodes=ids, tags=tags))
                wid += 1
        for bi in range(nx):
            for bj in range(ny):
                rng = np.random.default_rng([seed + 1, bi, bj])
                k = kind(bi, bj)
                if k == "buildings":
                    for q in range(nb):
                        ids = [block_node(bi, bj, q * 4 + c) for c in range(4)]
                        levels = int(rng.integers(2, 9))
                        tags = {"building": "apartments", "building:levels": str(levels)}
                        if real_like:
                            tags.update({
                                "addr:housenumber": str(int(rng.integers(1, 400))),
                                "addr:street": f"Street {bj}",
                                "addr:postcode": str(int(rng.integers(10000, 99999))),
                                "ref:building": f"{int(rng.integers(1, 10**12)):012d}",
                                "start_date": str(int(rng.integers(1850, 2024))),
                                "source": "survey",
                            })
                        w.add_way(Way(id=wid, nodes=ids + ids[:1], tags=tags))
                        wid += 1
                        counts["buildings"] += 1
                else:
                    ids = [block_node(bi, bj, c) for c in range(4)]
                    tags = {"leisure": "park"} if k == "park" else {"amenity": "parking"}
                    w.add_way(Way(id=wid, nodes=ids + ids[:1], tags=tags))
                    wid += 1
        for ids in foot:
            w.add_way(Way(id=wid, nodes=ids, tags={"highway": "footway"}))
            wid += 1
        counts["ways"] = wid - 1
    finally:
        w.close()
    os.replace(tmp, path)
    counts["bytes"] = path.stat().st_size
    return counts


def _half_width(tags: dict) -> float:
    return {"primary": 7.0}.get(tags["highway"], 2.25 if "oneway" in tags else 3.25)


def _street_tags(i: int) -> dict:
    if i % 5 == 0:
        return {"highway": "primary", "lanes": "4", "name": f"Avenue {i}"}
    if i % 2 == 1:
        return {"highway": "residential", "oneway": "yes" if i % 4 == 1 else "-1",
                "name": f"Street {i}"}
    return {"highway": "residential", "name": f"Street {i}"}


def bbox_of(x0, y0, x1, y1) -> str:
    a, b = lonlat(x0, y0)
    c, d = lonlat(x1, y1)
    return f"{a:.7f},{b:.7f},{c:.7f},{d:.7f}"


_CHILD = r"""
import json, resource, sys, time
t0 = time.perf_counter()
from aerial_synth.scene.osm import build_osm_scene
s = build_osm_scene(sys.argv[1], bbox=sys.argv[2] if sys.argv[2] != "-" else None)
t = time.perf_counter() - t0
print(json.dumps({"seconds": t, "max_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "roads": s.meta["osm"]["roads"], "buildings": s.meta["osm"]["buildings"],
                  "triangles": s.n_triangles, "build_seconds": s.meta["build_seconds"]}))
"""


def child(path: Path, bbox: str | None) -> dict:
    out = subprocess.run([sys.executable, "-c", _CHILD, str(path), bbox or "-"],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", default="out/bench_osm", help="folder for the generated files")
    ap.add_argument("--large-mb", type=float, default=50.0, help="size of the large file, MB")
    ap.add_argument("--repeat", type=int, default=3, help="runs of the 1 km^2 build")
    args = ap.parse_args(argv)
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    root = Path(__file__).resolve().parents[1]
    exe = Path(sys.executable).with_name("aerial-synth")

    small = work / "city_1km2.osm.pbf"
    if not small.exists():
        print("writing", small, write_grid_city(small, 10, 10, real_like=True, side=4,
                                                footways=True))
    # 1. the 1 km^2 city centre, in process (fresh interpreter each time: imports counted)
    runs = [child(small, None) for _ in range(args.repeat)]
    best = min(r["seconds"] for r in runs)
    print(f"1 km^2 build (fresh process, read + build): best {best:.2f} s of "
          f"{[round(r['seconds'], 2) for r in runs]}; {runs[0]['roads']} roads, "
          f"{runs[0]['buildings']} buildings, {runs[0]['triangles']:,} triangles; "
          f"stages {runs[0]['build_seconds']}")
    t0 = time.perf_counter()
    subprocess.run([str(exe), "scene", "from-osm", str(small), "--out", str(work / "city.glb"),
                    "--no-cache"], check=True, cwd=root, capture_output=True)
    print(f"aerial-synth scene from-osm (CLI wall, GLB written): {time.perf_counter() - t0:.2f} s")

    # 2. the large file, small bbox
    large = work / "city_large.osm.pbf"
    if not large.exists():
        # about 0.3 kB per block: choose the side from the wanted size
        n = int(math.ceil(math.sqrt(args.large_mb * 1e6 / 300.0)))
        t0 = time.perf_counter()
        c = write_grid_city(large, n, n, real_like=True)
        print(f"writing {large}: {n} x {n} blocks, {c['bytes'] / 1e6:.1f} MB, "
              f"{time.perf_counter() - t0:.0f} s")
    size_mb = large.stat().st_size / 1e6
    bb = bbox_of(1000, 1000, 1500, 1500)
    r = child(large, bb)
    base = child(small, bbox_of(100, 100, 600, 600))
    print(f"{size_mb:.1f} MB pbf, --bbox {bb} (500 m x 500 m): {r['seconds']:.2f} s, peak RSS "
          f"{r['max_rss_mb']:.0f} MB ({base['max_rss_mb']:.0f} MB for the same bbox size cut "
          f"from the {small.stat().st_size / 1e3:.0f} kB file); {r['roads']} roads, "
          f"{r['buildings']} buildings")
    print("command: .venv/bin/python tools/bench_osm.py")
    return 0


if __name__ == "__main__":
    sys.exit(main())
