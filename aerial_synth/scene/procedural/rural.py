"""Generator ``rural``: farmland with country roads, gravel and dirt tracks, farmyards.

- Country roads: ``roads.paved`` (1 or 2) curved asphalt roads across the scene, centre
  line dashed, no sidewalks.
- Farm tracks: ``roads.tracks`` gravel or dirt roads off the paved ones (label ``road``:
  drivable, but ``soil``/``paving`` coloured, no markings), each with two darker wheel
  ruts and, on dirt tracks, a grass strip between them (label ``road``, 5 mm up).
- Fields: the land between the roads cut into a rotated, jittered grid of fields; each
  is crop rows (green rows on soil, ``row_spacing_m`` apart), bare ploughed soil with
  furrows, stubble, or pasture (the ground's grass). Field surfaces are ``ground``
  (1-1.5 cm up), so placement never parks on them.
- Farmyards: at the end of a farm track, a gravel yard (``parking``, hint kind ``yard``:
  placement parks tractors, farm trailers and pickups there) with a farmhouse, a barn, a
  machinery shed and silos round it, farm trees.
- Hard negatives at the ``rural`` densities of procedural/negatives.py.

Spec keys (all optional)::

    roads:  {paved: 1, paved_width_m: 6.5, tracks: 4, track_width_m: [3.5, 4.5],
             dirt_share: 0.4, curve_m: 40}
    fields: {size_m: [90, 170], row_spacing_m: 0.75,
             types: {crop: 0.45, soil: 0.25, stubble: 0.15, pasture: 0.15}}
    farms:  {count: 2}
    trees:  {windbreaks: 4, farm_trees: 14}
    vehicles: {yard_occupancy: 0.35, yard_mix: {tractor: 0.35, farm_trailer: 0.3, ...}}
    hard_negatives: {scale: 1.0}

World frame: metres, x east, y north, z up; the scene is centred on the origin.
"""

from __future__ import annotations

import functools
import math
from typing import Mapping

import numpy as np

from ... import validators as V
from ...errors import SceneError
from ..build import polygon_object, prism
from ..model import SceneObject
from ..scene_hints import DrivewayHint, NegativesHint
from . import spec as S
from .builder import Z_ROAD, Z_TRACK, Builder
from .generators import Generator
from .houses import HouseSet, rect_poly
from .negatives import add_negatives
from .residential import NEGATIVES_SECTION, VEHICLES_SECTION
from .roads import Road, chaikin, offset_line, polygonal, road_polygon

__all__ = ["generate_rural", "RURAL_DEFAULTS", "FIELD_TYPES", "Z_FIELD", "Z_ROWS"]

Z_FIELD = 0.01
Z_ROWS = 0.015
FIELD_TYPES = ("crop", "soil", "stubble", "pasture")

RURAL_DEFAULTS: dict[str, dict] = {
    "roads": {"paved": 1, "paved_width_m": 6.5, "tracks": 4, "track_width_m": [3.5, 4.5],
              "dirt_share": 0.4, "curve_m": 40.0},
    "fields": {"size_m": [90.0, 170.0], "row_spacing_m": 0.75,
               "types": {"crop": 0.45, "soil": 0.25, "stubble": 0.15, "pasture": 0.15}},
    "farms": {"count": 2},
    "trees": {"windbreaks": 4, "farm_trees": 14},
    "vehicles": {"yard_occupancy": 0.35,
                 "yard_mix": {"tractor": 0.35, "farm_trailer": 0.25, "pickup_truck": 0.2,
                              "utility_trailer": 0.1, "suv": 0.1}},
}


def _types(f, v):
    V.mapping(f, v, error=SceneError)
    V.known_keys(f, v, FIELD_TYPES, error=SceneError)
    out = {k: V.in_range(f"{f}.{k}", w, 0.0, 1e6, error=SceneError) for k, w in v.items()}
    if sum(out.values()) <= 0:
        raise SceneError(f"{f}: expected a positive total weight, got {V.show(v)}")
    return out


_KEYS = {
    "roads": S.section({"paved": S.integer(1, 2), "paved_width_m": S.pos(30.0),
                        "tracks": S.integer(0, 40), "track_width_m": S.span(2.5, 10.0),
                        "dirt_share": S.prob, "curve_m": S.nonneg(500.0)}),
    "fields": S.section({"size_m": S.span(20.0, 2000.0), "row_spacing_m": S.pos(10.0),
                         "types": _types}),
    "farms": S.section({"count": S.integer(0, 50)}),
    "trees": S.section({"windbreaks": S.integer(0, 200), "farm_trees": S.integer(0, 500)}),
    "vehicles": VEHICLES_SECTION,
    "hard_negatives": NEGATIVES_SECTION,
}

_SOIL = ((0.36, 0.28, 0.20), (0.44, 0.35, 0.25), (0.30, 0.24, 0.18), (0.50, 0.42, 0.32))
_CROP = ((0.10, 0.20, 0.07), (0.14, 0.24, 0.08), (0.18, 0.26, 0.10), (0.22, 0.28, 0.12))
_STUBBLE = ((0.62, 0.55, 0.38), (0.56, 0.50, 0.34), (0.68, 0.60, 0.42))


def _check(spec: Mapping) -> dict:
    V.known_keys("top level", spec, S._COMMON + tuple(_KEYS), error=SceneError)
    out = dict(spec)
    for k, chk in _KEYS.items():
        if k in spec:
            out[k] = chk(k, spec[k])
    for sec, d in RURAL_DEFAULTS.items():
        out[sec] = {**d, **(out.get(sec) or {})}
    if out["fields"]["row_spacing_m"] < 0.3:
        raise SceneError(f"fields.row_spacing_m: expected a number >= 0.3, got {out['fields']['row_spacing_m']}")
    return out


def _curve(rng, a, b, amp, n=9):
    t = np.linspace(0.0, 1.0, n)
    d = b - a
    nrm = np.array([-d[1], d[0]]) / max(math.hypot(*d), 1e-9)
    off = amp * np.sin(np.pi * t * rng.uniform(1.0, 2.0) + rng.uniform(0, np.pi)) * np.sin(np.pi * t)
    pts = a + np.outer(t, d) + np.outer(off, nrm)
    return chaikin(pts, 3)


def generate_rural(b: Builder, spec: Mapping) -> None:
    """Fill ``b`` with farmland (see the module doc)."""
    import shapely
    from shapely.geometry import Point
    from shapely.ops import substring

    cfg = _check(spec)
    b.spec = cfg
    rng = b.rng
    W, H = (float(x) for x in cfg["size_m"])
    rc = cfg["roads"]
    paved, tracks = _rural_roads(b, rng, rc, W, H)
    road = b.road_area()
    houses, hints, farm_zones, yard_polys, house_yards, road_buf = _farmyards(b, cfg, rng, tracks, road)
    b.freeze_areas()
    # ---- fields
    fcfg = cfg["fields"]
    land = b.box.difference(road.buffer(3.0))
    if farm_zones:
        land = land.difference(shapely.union_all(farm_zones))
    ang = rng.uniform(0.0, np.pi)
    field_objs, field_counts = _fields(rng, land, ang, fcfg, W, H)
    # ---- trees: windbreaks along field edges and roads, trees round the farms
    tcfg = cfg["trees"]
    for _ in range(int(tcfg["windbreaks"])):
        r = paved[int(rng.integers(len(paved)))]
        s0 = rng.uniform(0.0, r.line.length * 0.7)
        seg = substring(r.line, s0, min(s0 + rng.uniform(60.0, 160.0), r.line.length))
        off = offset_line(seg, (1 if rng.random() < 0.5 else -1) * (r.width_m / 2 + rng.uniform(4.0, 7.0)))
        if not off.is_empty:
            b.add_tree_row(off, rng.uniform(6.0, 9.0), [2.5, 4.0], [8.0, 16.0],
                           species={"broadleaf": 0.4, "columnar": 0.4, "conifer": 0.2})
    for z in farm_zones:
        ring = z.buffer(8.0).difference(z)
        b.add_tree_cluster(int(tcfg["farm_trees"]), ring.difference(road_buf), [2.5, 4.5], [8.0, 15.0],
                           species={"broadleaf": 0.6, "spreading": 0.2, "conifer": 0.2})
    # ---- hard negatives
    standing = houses.footprints + [Point(t[0], t[1]).buffer(0.8) for t in b.trees]
    farm = None
    if farm_zones:
        farm = shapely.union_all(farm_zones).difference(shapely.union_all(yard_polys).buffer(0.5)) \
            .difference(road_buf)
    paved_area = shapely.union_all([road_polygon(r) for r in paved]).intersection(b.box)
    roadside = paved_area.buffer(9.0).difference(road.buffer(2.5)).intersection(b.box.buffer(-2.0))
    if farm_zones:
        roadside = roadside.difference(shapely.union_all(farm_zones))
    regions = {"farm": farm, "roadside": roadside, "road": paved_area.buffer(-1.0),
               "yard": shapely.union_all(house_yards) if house_yards else None}
    neg_objs, neg_meta = add_negatives("rural", cfg.get("hard_negatives"), regions, W * H, rng, taken=standing)
    b._rural = {"houses": houses, "negatives": neg_objs, "neg_meta": neg_meta, "hints": hints,
                "fields": field_objs, "field_counts": field_counts, "paved": paved_area,
                "tracks": tracks}
    b.scene = functools.partial(_rural_scene, b)


GENERATOR = Generator("rural", generate_rural)


def _rural_roads(b: Builder, rng, rc: Mapping, W: float, H: float):
    """The paved country roads and the farm tracks off them (added to ``b.roads``): returns
    (paved roads, [(track road, "dirt" | "gravel")])."""
    from shapely.geometry import LineString

    # ---- paved country roads
    paved = []
    a = np.array([-W / 2 - 10, rng.uniform(-0.2, 0.2) * H])
    e = np.array([W / 2 + 10, rng.uniform(-0.2, 0.2) * H])
    paved.append(Road("country_0", LineString(_curve(rng, a, e, rc["curve_m"])), rc["paved_width_m"]))
    if rc["paved"] >= 2:
        a = np.array([rng.uniform(-0.25, 0.25) * W, -H / 2 - 10])
        e = np.array([rng.uniform(-0.25, 0.25) * W, H / 2 + 10])
        paved.append(Road("country_1", LineString(_curve(rng, a, e, rc["curve_m"])), rc["paved_width_m"]))
    b.roads.extend(paved)
    # ---- farm tracks: off a paved road, north or south
    tracks = []
    nt = int(rc["tracks"])
    for i in range(nt):
        base = paved[i % len(paved)].line
        s = base.length * (i + 0.5 + rng.uniform(-0.3, 0.3)) / max(nt, 1) if len(paved) == 1 else \
            base.length * rng.uniform(0.15, 0.85)
        p0 = np.asarray(base.interpolate(s).coords[0])
        q = np.asarray(base.interpolate(min(s + 1.0, base.length)).coords[0]) - p0
        q /= max(math.hypot(*q), 1e-9)
        nrm = np.array([-q[1], q[0]]) * (1.0 if i % 2 == 0 else -1.0)
        length = rng.uniform(0.25, 0.42) * min(W, H)
        end = p0 + nrm * length + q * rng.uniform(-0.3, 0.3) * length
        end = np.clip(end, [-W / 2 + 85, -H / 2 + 85], [W / 2 - 85, H / 2 - 85])
        pts = _curve(rng, p0, end, rc["curve_m"] * 0.3, n=6)
        pts[0] = p0
        w = rng.uniform(*rc["track_width_m"])
        kind = "dirt" if rng.random() < rc["dirt_share"] else "gravel"
        tracks.append((Road(f"track_{i}_{kind}", LineString(pts), float(w), lanes=0, centre="none"), kind))
    b.roads.extend(t for t, _ in tracks)
    return paved, tracks


def _farmyards(b: Builder, cfg: Mapping, rng, tracks, road):
    """Farmyards at the ends of the first tracks: yard sites (parking), barn, machinery
    shed, farmhouse with its garden, silos. Returns (houses, hints, farm zones, yard
    polygons, house gardens, the road area grown by 2 m)."""
    import shapely

    # ---- farmyards at the ends of the first tracks
    houses = HouseSet("farm", rng)
    hints, farm_zones, yard_polys, house_yards = [], [], [], []
    fc = cfg["farms"]
    road_buf = road.buffer(2.0)
    for k in range(min(int(fc["count"]), len(tracks))):
        tr = tracks[k][0]
        e = np.asarray(tr.line.coords[-1])
        e0 = np.asarray(tr.line.interpolate(tr.line.length - 2.0).coords[0])
        u = (e - e0) / max(math.hypot(*(e - e0)), 1e-9)
        v = np.array([-u[1], u[0]])
        ya, yb = rng.uniform(40.0, 55.0), rng.uniform(30.0, 40.0)  # along u, across
        yc = e + u * (ya / 2 - 1.0)
        yard = rect_poly(yc, u, ya, yb)
        if not b.box.buffer(-25.0).contains(yard):
            continue
        others = road.difference(tr.line.buffer(tr.width_m / 2 + 0.5))
        if yard.buffer(8.0).intersects(others) or any(yard.buffer(40).intersects(z) for z in farm_zones):
            continue
        b.parking.append(yard)
        yard_polys.append(yard)
        hints.append({"id": len(hints), "kind": "yard",
                      "center_xy": [round(float(x), 4) for x in yc],
                      "axis_deg": round(float(np.degrees(np.arctan2(v[1], v[0]))), 4),
                      "long_m": round(float(yb - 2.0), 4), "short_m": round(float(ya - 2.0), 4),
                      "bay_m": [9.5, 4.4], "occupancy": cfg["vehicles"]["yard_occupancy"],
                      "mix": dict(cfg["vehicles"]["yard_mix"])})
        # buildings round the yard: barn beyond its far end, machinery shed on one long
        # side, farmhouse on the other, silos beside the barn
        bl, bw = rng.uniform(26.0, 40.0), rng.uniform(13.0, 18.0)
        barn_c = yc + u * (ya / 2 + 3.0 + bw / 2)
        houses.building(barn_c, v, bl, bw, rng.uniform(8.0, 11.0), kind="outbuildings", shape="gable")
        sl, sw = rng.uniform(20.0, 32.0), rng.uniform(10.0, 14.0)
        sgn = 1.0 if rng.random() < 0.5 else -1.0
        shed_c = yc + v * sgn * (yb / 2 + 3.0 + sw / 2)
        houses.building(shed_c, u, sl, sw, rng.uniform(5.5, 7.5), kind="outbuildings",
                        shape="flat" if rng.random() < 0.4 else "gable")
        hl, hw = rng.uniform(11.0, 15.0), rng.uniform(9.0, 11.0)
        house_c = yc - v * sgn * (yb / 2 + 4.0 + hw / 2) - u * (ya / 4)
        houses.building(house_c, u, hl, hw, rng.uniform(7.5, 9.5), palette="eu", kind="houses")
        garden = rect_poly(house_c, u, hl + 16.0, hw + 14.0).difference(rect_poly(house_c, u, hl + 1.0, hw + 1.0))
        house_yards.append(garden.difference(road_buf).difference(yard.buffer(1.0)))
        n_silo = int(rng.integers(1, 4))
        r_s = rng.uniform(2.5, 3.8)
        for j in range(n_silo):
            c = barn_c + u * (bw / 2 + r_s + 2.0) + v * (-bl / 2 + r_s + j * (2 * r_s + 1.0))
            _silo(houses, c, r_s, rng.uniform(12.0, 20.0))
        zone = shapely.union_all([yard, rect_poly(barn_c, v, bl, bw), rect_poly(shed_c, u, sl, sw),
                                  rect_poly(house_c, u, hl + 16.0, hw + 14.0)]).convex_hull.buffer(6.0)
        farm_zones.append(zone)
    return houses, hints, farm_zones, yard_polys, house_yards, road_buf


def _silo(houses: HouseSet, c, r, h):
    import shapely

    disc = shapely.Point(c).buffer(r, quad_segs=4)
    col = (0.70, 0.71, 0.72) if houses.rng.random() < 0.7 else (0.45, 0.50, 0.48)
    houses._add("building", "roof_metal", col, prism(disc, 0.0, h))
    top = shapely.Point(c).buffer(r * 0.35, quad_segs=4)
    houses._add("building", "roof_metal", col, prism(top, h, h + r * 0.45))
    houses.footprints.append(disc)
    houses.counts["silos"] = houses.counts.get("silos", 0) + 1


def _stripes(field, ang, spacing, width):
    """Parallel stripes (shapely polygons) at angle ``ang`` across ``field``, ``spacing``
    apart, ``width`` wide, clipped to the field."""
    import shapely

    c = np.asarray(field.centroid.coords[0])
    x0, y0, x1, y1 = field.bounds
    R = 0.5 * np.hypot(x1 - x0, y1 - y0) + 1.0
    u = np.array([np.cos(ang), np.sin(ang)])
    v = np.array([-u[1], u[0]])
    offs = np.arange(-R, R, spacing)
    a = c + np.outer(offs, v)
    quad = np.stack([a - u * R, a + u * R, a + u * R + v * width, a - u * R + v * width], 1)
    polys = shapely.polygons(quad)
    clipped = shapely.intersection(polys, field)
    return [g for g in clipped if not g.is_empty and g.area > 0.05]


def _fields(rng, land, ang, fcfg, W, H):
    """Field objects (ground surfaces and rows) and counts by type."""
    import shapely
    from shapely import affinity

    lo, hi = fcfg["size_m"]
    R = 0.75 * np.hypot(W, H)
    cells = []
    xs = [-R]
    while xs[-1] < R:
        xs.append(xs[-1] + rng.uniform(lo, hi))
    ys = [-R]
    while ys[-1] < R:
        ys.append(ys[-1] + rng.uniform(lo * 0.7, hi * 0.8))
    for i in range(len(xs) - 1):
        for j in range(len(ys) - 1):
            cells.append(shapely.box(xs[i], ys[j], xs[i + 1], ys[j + 1]))
    cells = [affinity.rotate(c, ang, origin=(0, 0), use_radians=True) for c in cells]
    types = list(fcfg["types"])
    w = np.array([fcfg["types"][t] for t in types], float)
    base: dict[tuple, list] = {}
    rows: dict[tuple, list] = {}
    counts = {t: 0 for t in FIELD_TYPES}
    shapely.prepare(land)
    for c in cells:
        if not land.intersects(c):
            continue
        f = polygonal(c.buffer(-1.5, join_style="mitre").intersection(land))
        parts = [p for p in shapely.get_parts(f) if p.area > 400.0]
        if not parts:
            continue
        t = types[int(rng.choice(len(types), p=w / w.sum()))]
        k = rng.random()
        row_ang = ang + (0.0 if rng.random() < 0.6 else np.pi / 2)
        for p in parts:
            counts[t] += 1
            if t == "pasture":
                continue
            if t == "crop":
                soil = _SOIL[int(k * len(_SOIL))]
                base.setdefault(("soil", soil), []).append(p)
                rows.setdefault(("grass", _CROP[int(rng.integers(len(_CROP)))]), []).extend(
                    _stripes(p, row_ang, fcfg["row_spacing_m"], fcfg["row_spacing_m"] * rng.uniform(0.35, 0.55)))
            elif t == "soil":
                soil = _SOIL[int(k * len(_SOIL))]
                base.setdefault(("soil", soil), []).append(p)
                dark = tuple(x * 0.82 for x in soil)
                rows.setdefault(("soil", dark), []).extend(_stripes(p, row_ang, 0.9, 0.35))
            else:  # stubble: straw with darker swaths
                st = _STUBBLE[int(k * len(_STUBBLE))]
                base.setdefault(("grass", st), []).append(p)
                rows.setdefault(("soil", tuple(x * 0.85 for x in st)), []).extend(
                    _stripes(p, row_ang, rng.uniform(5.0, 8.0), 1.2))
    objs: list[SceneObject] = []
    for j, ((mat, col), polys) in enumerate(sorted(base.items())):
        g = shapely.MultiPolygon([q for p in polys for q in shapely.get_parts(p)])
        objs.append(polygon_object(f"field_{j:02d}", "ground", g, Z_FIELD, material=mat,
                                   color=tuple(float(x) for x in col)))
    for j, ((mat, col), polys) in enumerate(sorted(rows.items())):
        parts = [q for p in polys for q in shapely.get_parts(polygonal(p))]
        if not parts:
            continue
        objs.append(polygon_object(f"field_rows_{j:02d}", "ground", shapely.MultiPolygon(parts), Z_ROWS,
                                   material=mat, color=tuple(float(x) for x in col)))
    return objs, counts


def _rural_scene(b: Builder, source: str, meta: dict):
    """Builder.scene, then: road surfaces split into asphalt, gravel and dirt, wheel ruts
    on the tracks, fields, farm buildings, hard negatives; hints and counts in the meta."""
    import dataclasses

    import shapely

    r = b._rural
    scene = Builder.scene(b, source, meta)
    road_area = b.road_area()
    paved = r["paved"].intersection(road_area)
    objs = [o for o in scene.objects if not (o.label == "road" and o.name.startswith("road_"))]
    i0 = next((i for i, o in enumerate(scene.objects) if o.name.startswith("road_")), 1)
    out = [polygon_object("road_paved", "road", polygonal(paved), Z_ROAD)]
    rest = road_area.difference(paved)
    ruts: dict[str, list] = {"gravel": [], "dirt": []}
    middles = []
    used = shapely.Polygon()
    for j, (tr, kind) in enumerate(r["tracks"]):
        own = road_polygon(tr).intersection(rest).difference(used)
        if own.is_empty:
            continue
        used = used.union(own)
        col = (0.50, 0.46, 0.40) if kind == "gravel" else (0.40, 0.33, 0.25)
        mat = "paving" if kind == "gravel" else "soil"
        g = polygonal(own)
        if not g.is_empty:
            out.append(polygon_object(f"road_track_{j:02d}", "road", g, Z_ROAD, material=mat, color=col))
        clip = own.difference(paved.buffer(1.5))
        for sgn in (1.0, -1.0):
            rut = offset_line(tr.line, sgn * 0.85)
            if not rut.is_empty:
                ruts[kind].append(rut.buffer(0.22, cap_style="flat").intersection(clip))
        if kind == "dirt":
            middles.append(tr.line.buffer(0.45, cap_style="flat").intersection(clip))
    # the road pieces no track claims (none, unless two surfaces meet oddly) stay asphalt
    left = polygonal(rest.difference(used))
    if not left.is_empty:
        out.append(polygon_object("road_rest", "road", left, Z_ROAD))
    for kind, polys in ruts.items():
        g = polygonal(shapely.union_all(polys)) if polys else shapely.Polygon()
        if not g.is_empty:
            col = (0.36, 0.33, 0.29) if kind == "gravel" else (0.27, 0.22, 0.17)
            out.append(polygon_object(f"ruts_{kind}", "road", g, Z_TRACK, material="soil", color=col))
    if middles:
        g = polygonal(shapely.union_all(middles))
        if not g.is_empty:
            out.append(polygon_object("track_grass", "road", g, Z_TRACK, material="grass",
                                      color=(0.16, 0.22, 0.10)))
    objs[i0:i0] = out
    # farm yards are gravel, not asphalt
    objs = [dataclasses.replace(o, material="paving", color=(0.50, 0.47, 0.41)) if o.name == "parking" else o
            for o in objs]
    objs.extend(r["fields"])
    objs.extend(r["houses"].objects("farm"))
    objs.extend(r["negatives"])
    scene.objects = [o for o in objs if o.n_triangles]
    scene.hints = scene.hints.replace(
        driveways=tuple(DrivewayHint.from_dict(h, f"scene {scene.name}: driveway hint") for h in r["hints"]),
        negatives=NegativesHint.from_dict(r["neg_meta"], f"scene {scene.name}: hard negatives"))
    scene.meta = {**scene.meta,
                  "fields": r["field_counts"],
                  "farm_counts": {k: (round(v, 2) if isinstance(v, float) else v)
                                  for k, v in r["houses"].counts.items()}}
    return scene
