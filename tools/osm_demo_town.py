"""A hand-written demo town as OSM XML, and the docs figure made from it (no real extract).

The town is authored here (metres east/north of a reference point, turned into WGS84 like
the test town): a curved two-way high street with footways and street trees, a
dual carriageway with a tree-lined median, a four-arm roundabout, a one-way loop around a
pedestrian market square, residential side streets and a cul-de-sac, a parking lot with
aisles, rows of houses, a church, a courtyard block, a supermarket, a park with a pond, a
wood and a river under a bridge.

  .venv/bin/python tools/osm_demo_town.py --out out/demo_town           # writes the .osm
  .venv/bin/python tools/osm_demo_town.py --out out/demo_town --figure  # + docs figure

The figure: ``aerial-synth place`` (normal traffic) on the scene built from the file, drawn on
its label map, beside one rendered frame (docs/osm_demo_town.png).
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.scene.osm_town import Town, circle, rect  # noqa: E402


def _bend(p0, p1, sag, n=8):
    """Points of a gently bent street from p0 to p1 (sag metres sideways at the middle)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    t = np.linspace(0, 1, n)
    d = p1 - p0
    nrm = np.array([-d[1], d[0]]) / np.linalg.norm(d)
    pts = p0[None] + t[:, None] * d[None] + (sag * np.sin(np.pi * t))[:, None] * nrm[None]
    return [tuple(np.round(p, 2)) for p in pts]


def _houses(t: Town, a, b, side, rng, depth=(9, 14), width=(8, 14), gap=(2, 5), setback=6.0,
            levels=(2, 4), kind="house"):
    """A row of houses along the straight line a -> b, on its left (side=+1) or right."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    d = (b - a) / np.linalg.norm(b - a)
    n = np.array([-d[1], d[0]]) * side
    s, L = 0.0, float(np.linalg.norm(b - a))
    while True:
        w = rng.uniform(*width)
        if s + w > L:
            break
        dep = rng.uniform(*depth)
        p = a + d * s + n * setback
        pts = [p, p + d * w, p + d * w + n * dep, p + n * dep]
        if side < 0:
            pts = pts[::-1]
        tags = {"building": kind, "building:levels": str(int(rng.integers(*levels)))}
        if rng.random() < 0.3:
            tags.pop("building:levels")
        t.way([tuple(np.round(q, 2)) for q in pts], tags, close=True)
        s += w + rng.uniform(*gap)


def make_demo_town(seed: int = 4) -> Town:
    rng = np.random.default_rng(seed)
    t = Town()
    # high street: two-way primary, bends, west -> east, ending on the roundabout; every
    # street meeting it shares one of its nodes (OSM junctions are shared nodes)
    def f(x):
        u = (x + 330.0) / 541.0
        return round(10.0 * u + 14.0 * math.sin(math.pi * u), 2)

    xs = [-330, -281, -250, -223, -201, -160, -100, -60, -30, 13, 40, 80, 120, 160, 211]
    hs = [(float(x), f(x)) for x in xs]
    hs[-1] = (211.0, 10.0)
    t.way(hs, {"highway": "primary", "lanes": "2", "width": "9", "name": "High Street"})
    # footways both sides and street trees
    line = np.array(hs)
    for off in (-8.0, 8.0):
        d = np.gradient(line, axis=0)
        nrm = np.stack([-d[:, 1], d[:, 0]], 1) / np.linalg.norm(d, axis=1)[:, None]
        pts = line + off * nrm
        t.way([tuple(np.round(p, 2)) for p in pts[1:-1]], {"highway": "footway"})
        tr = line + (off * 1.35) * nrm
        t.way([tuple(np.round(p, 2)) for p in tr[2:-2]], {"natural": "tree_row"})
    # roundabout with four arms
    ring = circle(235, 10, 24, 24, start_deg=180.0)  # first node (211, 10) meets high street
    t.way(ring, {"highway": "secondary", "junction": "roundabout", "width": "8",
                 "name": "Ring"}, close=True)
    t.way([(235, 34), (240, 120), (236, 240)], {"highway": "secondary", "name": "North Road"})
    t.way([(235, -14), (232, -120), (236, -240)], {"highway": "secondary", "name": "South Road"})
    t.way([(259, 10), (330, 14)], {"highway": "secondary", "name": "East Road"})
    # dual carriageway with a tree-lined median (right-hand: northbound on the east side)
    t.way([(-205, -240), (-203, -120), (-201, f(-201)), (-199, 120), (-198, 240)],
          {"highway": "secondary", "oneway": "yes", "lanes": "2", "name": "Avenue (N)"})
    t.way([(-220, 240), (-221, 120), (-223, f(-223)), (-225, -120), (-227, -240)],
          {"highway": "secondary", "oneway": "yes", "lanes": "2", "name": "Avenue (S)"})
    t.way([(-212, -230), (-211, -12)], {"natural": "tree_row"})
    t.way([(-211, 12), (-210, 230)], {"natural": "tree_row"})
    # the median is grass
    t.way([(-208.5, -240), (-206.5, 240), (-214.5, 240), (-218.5, -240)], {"landuse": "grass"},
          close=True)
    # one-way loop around the market square (counter-clockwise) and the square itself
    loop = [(-100, 60), (-20, 60), (-20, 140), (-100, 140)]
    t.way([(-100, f(-100)), (-100, 60)], {"highway": "residential", "name": "Market Lane"})
    t.way([loop[0], loop[1]], {"highway": "residential", "oneway": "yes", "name": "Market S"})
    t.way([loop[1], loop[2]], {"highway": "residential", "oneway": "yes", "name": "Market E"})
    t.way([loop[2], loop[3]], {"highway": "residential", "oneway": "yes", "name": "Market N"})
    t.way([loop[3], loop[0]], {"highway": "residential", "oneway": "yes", "name": "Market W"})
    t.way(rect(-90, 70, -30, 130), {"highway": "pedestrian", "area": "yes"}, close=True)
    t.node(-60, 100, {"natural": "tree", "diameter_crown": "10", "height": "15"}, shared=False)
    # residential side streets, a living street and a cul-de-sac
    t.way(_bend((40, f(40)), (60, 230), -15, n=8), {"highway": "residential",
                                                     "name": "Elm Street"})
    t.way(_bend((-250, f(-250)), (-250, -230), 12, n=8), {"highway": "residential",
                                                         "name": "Mill Road"})
    t.way([(120, f(120)), (125, 80), (150, 95)], {"highway": "living_street", "name": "Court"})
    t.way([(-30, f(-30)), (-28, -90)], {"highway": "residential", "name": "Close"})
    t.way(circle(-28, -100, 10, 12), {"highway": "footway"}, close=True)
    # river with a bridge (the side street crosses it)
    t.way([(-330, -170), (-150, -160), (0, -175), (150, -150), (330, -165)],
          {"waterway": "river", "width": "16", "name": "River"})
    t.way([(120, f(120)), (110, -60), (100, -230)], {"highway": "tertiary", "name": "Bridge Road",
                                                 "bridge": "yes"})
    # parking lot with aisles off the high street
    t.way(rect(60, -100, 100, -30), {"amenity": "parking", "parking": "surface"}, close=True)
    t.way([(80, f(80)), (80, -95)], {"highway": "service", "service": "parking_aisle"})
    # buildings: rows of houses along the streets
    _houses(t, (-190, -10), (-110, -8), -1, rng)
    _houses(t, (-5, -12), (30, -12), -1, rng, levels=(3, 5))
    _houses(t, (-190, 12), (-110, 14), 1, rng, levels=(3, 6), kind="apartments")
    _houses(t, (10, 16), (30, 20), 1, rng)
    _houses(t, (55, 40), (70, 220), -1, rng, setback=8)
    _houses(t, (40, 40), (50, 220), 1, rng, setback=8)
    _houses(t, (-245, -30), (-240, -140), 1, rng)
    _houses(t, (-262, -30), (-262, -140), -1, rng)
    _houses(t, (-100, 150), (-20, 150), -1, rng, kind="apartments", levels=(3, 6), setback=4)
    _houses(t, (-10, 60), (-10, 140), -1, rng, kind="retail", levels=(2, 4), setback=4)
    _houses(t, (250, 40), (255, 200), -1, rng, setback=8)
    _houses(t, (220, -40), (215, -140), -1, rng, setback=8)
    t.way(rect(-150, 30, -120, 55), {"building": "church", "height": "24"}, close=True)
    outer = t.way(rect(140, 30, 200, 90), {}, close=True)
    inner = t.way(rect(155, 45, 185, 75), {}, close=True)
    t.relation([("w", outer, "outer"), ("w", inner, "inner")],
               {"type": "multipolygon", "building": "apartments", "building:levels": "5"})
    t.way(rect(140, -110, 190, -60), {"building": "retail", "name": "Supermarket",
                                      "height": "7"}, close=True)
    # park with a pond, a wood
    t.way(rect(-180, 170, -40, 240), {"leisure": "park"}, close=True)
    t.way(circle(-110, 205, 18, 16), {"natural": "water"}, close=True)
    for k in range(10):
        t.node(-175 + 13 * k, 178 + 5 * (k % 3), {"natural": "tree"}, shared=False)
    t.way([(270, -240), (330, -240), (330, -100), (275, -110)], {"landuse": "forest"}, close=True)
    return t


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out/demo_town", help="output folder")
    ap.add_argument("--figure", action="store_true", help="also make docs/osm_demo_town.png")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    osm = make_demo_town().write(out / "demo_town.osm")
    print("wrote", osm)
    if not args.figure:
        return 0
    exe = str(Path(sys.executable).with_name("aerial-synth"))
    subprocess.run([exe, "scene", "from-osm", str(osm), "--out", str(out / "demo_town.glb")],
                   check=True)
    subprocess.run([exe, "place", "--scene", str(osm), "--scenario", "normal", "--seed", "1",
                    "--out", str(out / "place"), "--m-per-px", "0.5"], check=True)
    subprocess.run([exe, "render", "--scene", str(osm), "--scenario", "jam", "--vehicles", "300",
                    "--seed", "2", "--images", "1", "--out", str(out / "frames")], check=True)
    import cv2

    m = cv2.imread(str(out / "place" / "placement.png"))
    frames = sorted((out / "frames").rglob("rgb.png"))
    if frames:
        f = cv2.imread(str(frames[0]))
        h = m.shape[0]
        f = cv2.resize(f, (int(round(f.shape[1] * h / f.shape[0])), h),
                       interpolation=cv2.INTER_AREA)
        m = np.concatenate([m, np.full((h, 8, 3), 255, np.uint8), f], axis=1)
    scale = min(1.0, 2400 / m.shape[1])
    if scale < 1:
        m = cv2.resize(m, (int(m.shape[1] * scale), int(m.shape[0] * scale)),
                       interpolation=cv2.INTER_AREA)
    dst = ROOT / "docs" / "osm_demo_town.png"
    ok, buf = cv2.imencode(".png", m, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    dst.write_bytes(buf.tobytes())
    print("wrote", dst, f"{dst.stat().st_size / 1e6:.1f} MB", "(the demo town is hand-written, "
          "not a real extract)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
