"""Build a labelled :class:`~aerial_synth.scene.model.Scene` from what the OSM reader kept.

Frame: the local metric frame of the scene, metres, x east / y north of the chosen CRS (grid
north), origin at the bbox centre rounded to whole metres; ``Scene.origin`` holds that
centre's projected coordinates (float64) and ``Scene.crs`` the CRS. Terrain is flat.

Layers (heights keep coincident surfaces apart so the first hit of a vertical trace is the
right one): ground plane -0.10 m, grass/soil -0.08, water -0.06, sidewalk -0.04,
parking -0.02, road 0.00, tyre tracks +0.005 (label road, material track), lane markings
+0.01; buildings, trees and trunks stand on 0. Roofs take a covering from the tags
(procedural/roofs.py).
"""

from __future__ import annotations

import time

import numpy as np

from ...errors import SceneError
from ..build import flat_polygon, merge_meshes
from ..hints import HintRoad, RoadHints
from ..model import RoadTruth, Scene, SceneObject, SceneTruth
from ..procedural.roofs import ROOF_MATERIALS, covering_from_tags
from ..scene_hints import KerbHint, SceneHints
from .read import OsmData
from .residential import residential_meta
from .roads import OsmRoad, find_junctions, road_markings, road_surface, tyre_tracks
from .tags import (
    SIDEWALK_WIDTH_M,
    building_height_m,
    kerb_parking,
    parse_metres,
    road_params,
    waterway_width_m,
)

__all__ = ["build_scene", "ATTRIBUTION", "Z"]

ATTRIBUTION = "© OpenStreetMap contributors"

#: surface heights, metres
Z = {"ground": -0.10, "grass": -0.08, "water": -0.06, "sidewalk": -0.04, "parking": -0.02,
     "road": 0.0, "track": 0.005, "marking": 0.01}
TREE_ROW_SPACING_M = 8.0
FOREST_SPACING_M = 6.0
MAX_FOREST_TREES = 30000


def _project(geoms: np.ndarray, transformer, origin_xy) -> np.ndarray:
    import shapely

    if not len(geoms):
        return geoms
    ox, oy = origin_xy

    def fn(xy):
        x, y = transformer.transform(xy[:, 0], xy[:, 1])
        out = np.column_stack([np.asarray(x) - ox, np.asarray(y) - oy])
        if not np.isfinite(out).all():  # e.g. an extract spanning the globe: no one CRS holds it
            i = int(np.argmin(np.isfinite(out).all(axis=1)))
            crs = getattr(transformer, "target_crs", None)
            name = crs.to_string() if hasattr(crs, "to_string") else "the projected CRS"
            raise SceneError(
                f"OSM extract: the point lon {xy[i, 0]:.6f}, lat {xy[i, 1]:.6f} has no finite "
                f"coordinates in {name}; cut the extract with --bbox to one region (or give --crs)")
        return out

    return shapely.transform(geoms, fn)


def _crowns(centres, radii_xy, radii_z):
    """Merged icosphere crowns: centres (n, 3), radii (n,), (n,)."""
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=1)
    uv, uf = np.asarray(s.vertices), np.asarray(s.faces, np.int64)
    n = len(centres)
    if not n:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    scale = np.stack([radii_xy, radii_xy, radii_z], 1)
    v = uv[None] * scale[:, None, :] + centres[:, None, :]
    f = uf[None] + (np.arange(n) * len(uv))[:, None, None]
    return v.reshape(-1, 3), f.reshape(-1, 3)


def _trunks(xy, top_z, radius=0.15, sections=6):
    import trimesh

    n = len(xy)
    if not n:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    c = trimesh.creation.cylinder(radius=radius, height=1.0, sections=sections)
    uv, uf = np.asarray(c.vertices), np.asarray(c.faces, np.int64)
    v = np.repeat(uv[None], n, axis=0)
    v[:, :, 2] = (v[:, :, 2] + 0.5) * top_z[:, None]
    v[:, :, :2] += xy[:, None, :]
    f = uf[None] + (np.arange(n) * len(uv))[:, None, None]
    return v.reshape(-1, 3), f.reshape(-1, 3)


def _triangles(polys, z):
    """Flat triangles covering each polygon of an array (no union: overlapping parts of
    the same layer simply overlap). polys: (n,) Polygons; z: scalar or (n,) metres.
    Returns (v (3m, 3), f (m, 3)), counter-clockwise seen from above."""
    import shapely

    polys = np.asarray(polys, dtype=object)
    if not len(polys):
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    tris = shapely.constrained_delaunay_triangles(polys)
    parts, idx = shapely.get_parts(tris, return_index=True)
    if not len(parts):
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    t = shapely.get_coordinates(shapely.get_exterior_ring(parts)).reshape(-1, 4, 2)[:, :3]
    a, b, c = t[:, 0], t[:, 1], t[:, 2]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    keep = np.abs(cross) > 1e-12
    t, idx, cw = t[keep], idx[keep], cross[keep] < 0
    t[cw] = t[cw][:, ::-1]
    zz = np.broadcast_to(np.asarray(z, float), (len(polys),))[idx]
    v = np.concatenate([t.reshape(-1, 2), np.repeat(zz, 3)[:, None]], axis=1)
    return v, np.arange(len(v), dtype=np.int64).reshape(-1, 3)


def _roofs_and_walls(polys, heights):
    """Flat roofs at each building's height and vertical walls down to 0, for all buildings
    at once. polys: (n,) shapely Polygons (holes allowed); heights: (n,) metres.
    Returns ((v, f) roofs, (v, f) walls); faces counter-clockwise seen from outside."""
    import shapely

    polys = shapely.orient_polygons(np.asarray(polys, dtype=object))  # exterior CCW, holes CW
    rv, rf = _triangles(polys, heights)
    rings, ridx = shapely.get_rings(polys, return_index=True)
    xy, k = shapely.get_coordinates(rings, return_index=True)
    seg = np.flatnonzero(k[:-1] == k[1:])  # consecutive points of the same (closed) ring
    p, q = xy[seg], xy[seg + 1]
    h = heights[ridx[k[seg]]]
    z0 = np.zeros(len(seg))
    wv = np.stack([np.column_stack([p, z0]), np.column_stack([q, z0]),
                   np.column_stack([q, h]), np.column_stack([p, h])], axis=1).reshape(-1, 3)
    o = (np.arange(len(seg)) * 4)[:, None]
    wf = np.concatenate([o + [0, 1, 2], o + [0, 2, 3]]).astype(np.int64)
    return (rv, rf), (wv, wf)


def _union(geoms):
    import shapely

    g = [x for x in geoms if x is not None and not x.is_empty]
    if not g:
        return shapely.Polygon()
    return shapely.union_all(np.array(g, dtype=object))


def _polys(geoms, clip):
    """The polygonal parts of ``geoms`` ∩ clip, as an array (not unioned)."""
    import shapely

    if not len(geoms):
        return np.array([], dtype=object)
    g = shapely.intersection(np.asarray(geoms, dtype=object), clip)
    parts = shapely.get_parts(g)
    return parts[(shapely.get_type_id(parts) == 3) & ~shapely.is_empty(parts)]


def _scene_meta(data: OsmData, source: str, roads, n_buildings: int, n_trees: int,
                n_junctions: int, seconds: dict) -> dict:
    """The OSM scene's ``meta``: its file, bbox, attribution, what was built, how long it took."""
    return {
        "file": source,
        "format": "osm",
        "bbox": [float(c) for c in data.bbox],
        "attribution": ATTRIBUTION,
        "osm": {
            "roads": len(roads),
            "oneway_roads": int(sum(r.p.oneway for r in roads)),
            "buildings": n_buildings,
            "trees": int(n_trees),
            "junctions": int(n_junctions),
            "objects_read": dict(data.counts),
        },
        "build_seconds": seconds,
    }


def build_scene(data: OsmData, crs, transformer, origin_xy, name: str, source: str,
                seed: int = 0) -> Scene:
    """Turn reader output into a Scene (see the module docstring for frame and layers).

    crs         : the CRS string stored in the scene (e.g. "EPSG:32632")
    transformer : pyproj Transformer WGS84 (lon, lat) -> crs (x, y)
    origin_xy   : projected coordinates of the local origin (float64)
    Raises SceneError when the bbox holds no drivable road.
    """
    import shapely

    t0 = time.perf_counter()
    bx0, by0, bx1, by1 = data.bbox
    ring = shapely.segmentize(shapely.box(bx0, by0, bx1, by1), max(bx1 - bx0, by1 - by0) / 64)
    clip = _project(np.array([ring], dtype=object), transformer, origin_xy)[0]
    clip = shapely.make_valid(clip)
    shapely.prepare(clip)
    margin = shapely.buffer(clip, 60.0, join_style="mitre")

    kinds = np.array([k for k, *_ in data.lines], dtype=object)
    lgeoms = _project(np.array([g for *_, g in data.lines], dtype=object), transformer, origin_xy)
    akinds = np.array([k for k, *_ in data.areas], dtype=object)
    ageoms = _project(np.array([g for *_, g in data.areas], dtype=object), transformer, origin_xy)
    if len(ageoms):
        ageoms = shapely.make_valid(ageoms)

    # -------------------------------------------------------------- roads
    roads = _roads_of(data, kinds, lgeoms, margin, source)
    widths = np.array([r.p.width_m for r in roads])
    road_area = road_surface([r.line for r in roads], widths, clip)
    if road_area.is_empty:
        raise SceneError(f"OSM file {source}: no drivable road surface inside bbox "
                         f"{_fmt_bbox(data.bbox)}")
    truth_roads, hint_roads, kerbs = _centre_lines(roads, clip)
    t_roads = time.perf_counter()
    junctions = find_junctions(roads)
    markings = road_markings(roads, road_area, junctions)
    tracks = tyre_tracks(roads, road_area, junctions)

    # -------------------------------------------------------------- other surfaces
    sidewalk, water, spaces, parking, grass, soil = _surfaces(data, kinds, lgeoms, akinds, ageoms,
                                                              clip)

    objects: list[SceneObject] = []

    def flat(name, label, poly, z, material=None):
        if isinstance(poly, np.ndarray):
            v, f = _triangles(poly, z)  # many polygons, each triangulated on its own
        elif poly is None or poly.is_empty:
            return
        else:
            v, f = flat_polygon(poly, z)
        if len(f):
            objects.append(SceneObject(name, label, v, f, material or ""))

    flat("ground", "ground", clip, Z["ground"], "concrete")
    flat("grass", "ground", grass, Z["grass"], "grass")
    flat("soil", "ground", soil, Z["grass"], "soil")
    flat("water", "water", water, Z["water"])
    flat("sidewalks", "sidewalk", sidewalk, Z["sidewalk"])
    flat("parking", "parking", parking, Z["parking"])
    flat("road", "road", road_area, Z["road"])
    flat("tyre_tracks", "road", tracks, Z["track"], "track")  # drivable: label road
    flat("lane_markings", "lane_marking", markings, Z["marking"])

    # -------------------------------------------------------------- buildings
    n_buildings = _buildings(data, akinds, ageoms, clip, objects)

    # -------------------------------------------------------------- trees
    txy, tr, th = _tree_points(data, kinds, lgeoms, akinds, ageoms, clip, transformer, origin_xy, seed)
    _add_trees(objects, txy, tr, th)

    hints = RoadHints(hint_roads)
    truth = SceneTruth(road_area=road_area, roads=tuple(truth_roads),
                       parking_area=_union(list(parking)) if len(parking) else None)
    meta = _scene_meta(data, source, roads, n_buildings, len(txy), len(junctions),
                       {"roads": round(t_roads - t0, 3), "total": round(time.perf_counter() - t0, 3)})
    # driveway sites, house/garage/shed counts, sheds as hard negatives (osm/residential.py)
    w = f"OSM file {source}"
    res, drive, neg = residential_meta(roads, data.areas, ageoms, clip, w)
    meta.update(res)
    scene_hints = SceneHints(
        roads=hints, driveways=drive, negatives=neg,
        spaces=tuple(np.asarray(p.exterior.coords)[:-1].round(4) for p in spaces),
        kerbs=tuple(KerbHint.from_dict(k, f"{w}: kerb parking") for k in kerbs))
    return Scene(name=name, objects=objects, source=source, truth=truth, meta=meta,
                 origin=(float(origin_xy[0]), float(origin_xy[1]), 0.0), crs=crs, hints=scene_hints)



def _roads_of(data: OsmData, kinds, lgeoms, margin, source: str) -> list:
    """The drivable ways near the scene (within ``margin``) as :class:`OsmRoad` parts, each
    running in its driving direction; SceneError when there is none."""
    import shapely

    roads: list[OsmRoad] = []
    sel = np.flatnonzero(kinds == "road")
    if len(sel):
        near = shapely.intersection(lgeoms[sel], margin)
        for i, g in zip(sel, near):
            _, oid, tags, _ = data.lines[i]
            p = road_params(tags)
            for part in shapely.get_parts(g):
                if shapely.get_type_id(part) != 1 or part.length < 0.5:
                    continue
                if p.reverse:
                    part = shapely.reverse(part)
                roads.append(OsmRoad(oid, tags, p, part))
    if not roads:
        raise SceneError(
            f"OSM file {source}: no drivable road (highway=motorway ... service) inside bbox "
            f"{_fmt_bbox(data.bbox)}; expected at least one"
        )
    return roads


def _centre_lines(roads: list, clip) -> tuple[list, list, list]:
    """The roads' centre lines inside the scene: (RoadTruth list, HintRoad list, kerb
    parking records per tagged side)."""
    import shapely

    truth_roads, hint_roads = [], []
    kerbs = []  # kerb parking allowed per side, where the way tags it (placement/parking.py)
    inside = shapely.intersection(np.array([r.line for r in roads], dtype=object), clip)
    for r, g in zip(roads, inside):
        for part in shapely.get_parts(g):
            if shapely.get_type_id(part) != 1 or part.length < 0.5:
                continue
            truth_roads.append(RoadTruth(centerline=part, width_m=r.p.width_m,
                                         oneway=r.p.oneway, name=r.name))
            hint_roads.append(HintRoad(shapely.get_coordinates(part), r.p.width_m, r.p.oneway,
                                       r.p.lanes_forward, r.p.lanes_backward, int(r.osm_id),
                                       r.name))
            left, right = kerb_parking(r.tags)
            if r.p.reverse:  # the line runs against the way's node order
                left, right = right, left
            if left is not None or right is not None:
                kerbs.append({"coords": shapely.get_coordinates(part).round(4).tolist(),
                              "width_m": float(r.p.width_m), "left": left, "right": right})
    return truth_roads, hint_roads, kerbs


def _surfaces(data: OsmData, kinds, lgeoms, akinds, ageoms, clip):
    """Polygon arrays (clipped, not unioned) of sidewalks, water, parking spaces, parking,
    grass (and forest floor) and soil."""
    import shapely

    side_l = np.flatnonzero(kinds == "sidewalk")
    side_geoms = []
    if len(side_l):
        w = np.array([parse_metres(data.lines[i][2].get("width"), lo=0.5, hi=50)
                      or SIDEWALK_WIDTH_M.get(data.lines[i][2].get("highway"), 2.0)
                      for i in side_l])
        side_geoms.append(shapely.buffer(lgeoms[side_l], w / 2, quad_segs=3))
    water_l = np.flatnonzero(kinds == "waterway")
    water_geoms = []
    if len(water_l):
        w = np.array([waterway_width_m(data.lines[i][2]) for i in water_l])
        water_geoms.append(shapely.buffer(lgeoms[water_l], w / 2, cap_style="flat", quad_segs=3))

    def areas(kind):
        return ageoms[akinds == kind] if len(ageoms) else np.array([], dtype=object)

    sidewalk = _polys(np.concatenate(side_geoms + [areas("sidewalk")]), clip)
    water = _polys(np.concatenate(water_geoms + [areas("water")]), clip)
    # parking spaces (amenity=parking_space) are parking surface too, and their rectangles
    # go to placement as bays (``Scene.hints.spaces``, docs/parking.md)
    spaces = _polys(areas("parking_space"), clip)
    parking = _polys(np.concatenate([areas("parking"), areas("parking_space")]), clip)
    grass = _polys(np.concatenate([areas("grass"), areas("forest")]), clip)
    soil = _polys(areas("soil"), clip)

    return sidewalk, water, spaces, parking, grass, soil


def _buildings(data: OsmData, akinds, ageoms, clip, objects: list) -> int:
    """Append the buildings' roofs (one object per covering) and walls to ``objects``;
    returns how many buildings lie in the scene."""
    import shapely

    bsel = np.flatnonzero(akinds == "building") if len(akinds) else np.zeros(0, int)
    n_buildings = 0
    if len(bsel):
        bg = shapely.intersection(ageoms[bsel], clip)
        parts, pidx = shapely.get_parts(bg, return_index=True)
        ok = (shapely.get_type_id(parts) == 3) & (shapely.area(parts) >= 1.0)
        parts, pidx = parts[ok], pidx[ok]
        n_buildings = int(len(np.unique(pidx)))
        if len(parts):
            h = np.array([building_height_m(data.areas[i][2]) for i in bsel])[pidx]
            cov = np.array([covering_from_tags(data.areas[i][2]) for i in bsel])[pidx]
            walls = []
            for mat in ROOF_MATERIALS:  # one roof object per covering, from the tags
                sel = np.flatnonzero(cov == mat)
                if not len(sel):
                    continue
                (v, f), w = _roofs_and_walls(parts[sel], h[sel])
                walls.append(w)
                if len(f):
                    objects.append(SceneObject(f"building_roofs_{mat[5:]}", "building", v, f, mat))
            wv, wf = merge_meshes(walls)
            if len(wf):
                objects.append(SceneObject("building_walls", "building", wv, wf, "wall"))
    return n_buildings


def _tree_points(data: OsmData, kinds, lgeoms, akinds, ageoms, clip, transformer, origin_xy,
                 seed: int):
    """(xy list, crown radius list, height list), metres, of the single trees, tree rows
    and forest crowns (seeded per forest) in the scene."""
    import shapely

    txy, tr, th = [], [], []
    if data.trees:
        ll = np.array([[lon, lat] for _, lon, lat, _ in data.trees])
        x, y = transformer.transform(ll[:, 0], ll[:, 1])
        xy = np.column_stack([np.asarray(x) - origin_xy[0], np.asarray(y) - origin_xy[1]])
        ok = shapely.contains_xy(clip, xy[:, 0], xy[:, 1])
        for k in np.flatnonzero(ok):
            tags = data.trees[k][3]
            d = parse_metres(tags.get("diameter_crown"), lo=0.5, hi=40)
            txy.append(xy[k])
            tr.append(d / 2 if d else 2.5)
            th.append(parse_metres(tags.get("height"), lo=2.0, hi=60) or 8.0)
    rows = np.flatnonzero(kinds == "tree_row")
    if len(rows):
        g = shapely.intersection(lgeoms[rows], clip)
        for part in shapely.get_parts(g):
            if shapely.get_type_id(part) != 1:
                continue
            s = np.arange(0.0, part.length + 1e-9, TREE_ROW_SPACING_M)
            pts = shapely.get_coordinates(shapely.line_interpolate_point(part, s))
            txy.extend(pts)
            tr.extend([2.0] * len(pts))
            th.extend([7.0] * len(pts))
    fsel = np.flatnonzero(akinds == "forest") if len(akinds) else np.zeros(0, int)
    n_forest = 0
    for i in fsel:
        poly = shapely.intersection(ageoms[i], clip)
        if poly.is_empty or poly.area < 10:
            continue
        rng = np.random.default_rng([int(seed), abs(int(data.areas[i][1]))])
        x0, y0, x1, y1 = poly.bounds
        gx, gy = np.meshgrid(np.arange(x0, x1, FOREST_SPACING_M), np.arange(y0, y1, FOREST_SPACING_M))
        pts = np.column_stack([gx.ravel(), gy.ravel()])
        pts = pts + rng.uniform(-0.35, 0.35, pts.shape) * FOREST_SPACING_M
        pts = pts[shapely.contains_xy(poly, pts[:, 0], pts[:, 1])]
        pts = pts[: max(0, MAX_FOREST_TREES - n_forest)]
        n_forest += len(pts)
        txy.extend(pts)
        tr.extend(rng.uniform(2.0, 3.5, len(pts)))
        th.extend(rng.uniform(10.0, 18.0, len(pts)))
    return txy, tr, th



def _add_trees(objects: list, txy, tr, th) -> None:
    """Append the crowns and trunks of the trees at ``txy`` (crown radius ``tr``, height
    ``th``, metres) to ``objects``."""
    if len(txy):
        txy = np.asarray(txy, float).reshape(-1, 2)
        tr = np.asarray(tr, float)
        th = np.asarray(th, float)
        rz = np.minimum(tr * 0.8, th / 2.5)
        cz = th - rz
        v, f = _crowns(np.column_stack([txy, cz]), tr, rz)
        objects.append(SceneObject("trees", "tree", v, f))
        v, f = _trunks(txy, cz)
        objects.append(SceneObject("trunks", "trunk", v, f))

def _fmt_bbox(b) -> str:
    return ",".join(f"{c:.6f}" for c in b)
