"""Roofs of procedural buildings: coverings (gravel, tiles, metal), gables, roof details.

Every building draws, from a generator of its own (its seed), one covering:

- ``roof_gravel``: a flat roof with a parapet round its edge (0.25-0.35 m thick, 0.3-0.8 m
  high) and details inside it: air-conditioning units, vents, skylights, a stairwell box;
- ``roof_tiles``: a gabled roof when the footprint is a rectangle (ridge along the long
  side at the building height, 30-40 degree pitch, flatter where the eaves would come
  below 2.5 m), with up to two chimneys; a flat tiled roof otherwise (or when the rise
  would be under 1 m);
- ``roof_metal``: a flat roof of an industrial hall or depot: skylight strips along the
  long side, vents and AC units.

The mix depends on the building (small low ones mostly tiles, tall ones mostly gravel, big
halls mostly metal) unless the spec's ``roofs.materials`` gives weights. Details are small
closed boxes (``metal``, ``roof_metal``, ``concrete``, ``glass``) labelled ``building``,
aligned with the footprint's minimum rotated rectangle, standing on the roof and kept
inside the footprint (flat roofs: inside the parapet). Coordinates: world metres, z up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from ..build import merge_meshes, prism
from ..model import SceneObject

__all__ = ["ROOF_MATERIALS", "ROOF_COLORS", "DEFAULT_ROOFS", "ROOF_DETAIL_MAX_M", "RoofParts",
           "roof_parts", "roof_weights", "detail_objects", "building_objects"]

ROOF_MATERIALS: tuple[str, ...] = ("roof_gravel", "roof_tiles", "roof_metal")

#: Albedo choices per covering (a building draws one).
ROOF_COLORS: dict[str, tuple[tuple[float, float, float], ...]] = {
    "roof_gravel": ((0.52, 0.50, 0.47), (0.60, 0.58, 0.54), (0.44, 0.43, 0.41), (0.66, 0.63, 0.57)),
    "roof_tiles": ((0.55, 0.30, 0.24), (0.42, 0.22, 0.18), (0.70, 0.45, 0.32), (0.30, 0.30, 0.32),
                   (0.48, 0.27, 0.20)),
    "roof_metal": ((0.58, 0.60, 0.62), (0.45, 0.50, 0.55), (0.40, 0.47, 0.42), (0.68, 0.68, 0.66)),
}
#: The most a roof detail rises above the building height: a stairwell housing (2.2-2.8 m);
#: parapets and AC units reach 0.8 and 1.0 m, chimneys 0.9 m above a gabled roof's ridge,
#: which is at the building height.
ROOF_DETAIL_MAX_M = 2.8
#: Covering mix per generator where it differs from the per-building rule (roof_weights).
DEFAULT_ROOFS: dict[str, dict[str, float]] = {"depot": {"roof_metal": 0.85, "roof_gravel": 0.15}}
_DETAIL_RGB = {"metal": (0.62, 0.63, 0.64), "roof_metal": (0.70, 0.71, 0.72),
               "concrete": (0.60, 0.59, 0.56), "glass": (0.10, 0.12, 0.15)}


@dataclass
class RoofParts:
    """One building with its roof.

    body     : (vertices, faces) of walls and roof covering (one object, ``material``)
    material : one of ROOF_MATERIALS; color: its albedo
    roof_z   : lowest height of the roof surface (flat: the building height; gabled: eaves)
    ridge_z  : highest height of the roof surface
    pitched  : gabled roof
    details  : [(material, vertices, faces)], every one a closed box on the roof
    """

    body: tuple[np.ndarray, np.ndarray]
    material: str
    color: tuple[float, float, float]
    roof_z: float
    ridge_z: float
    pitched: bool
    details: list = field(default_factory=list)


def roof_weights(area_m2: float, height_m: float, override: Mapping | None = None) -> np.ndarray:
    """Probabilities of (gravel, tiles, metal) for one building."""
    if override:
        w = np.array([float(override.get(m, 0.0)) for m in ROOF_MATERIALS])
        if w.sum() > 0:
            return w / w.sum()
    if height_m >= 12.0:
        w = (0.9, 0.0, 0.1)
    elif area_m2 >= 800.0:
        w = (0.35, 0.0, 0.65)
    elif area_m2 <= 250.0 and height_m < 10.0:
        w = (0.15, 0.75, 0.10)
    else:
        w = (0.5, 0.35, 0.15)
    w = np.asarray(w, float)
    return w / w.sum()


def _frame(poly):
    """Centre, unit long axis, unit short axis, long and short side of the minimum rotated
    rectangle of a footprint."""
    import shapely

    rect = shapely.minimum_rotated_rectangle(poly)
    c = np.asarray(rect.exterior.coords)[:4]
    e1, e2 = c[1] - c[0], c[2] - c[1]
    l1, l2 = math.hypot(*e1), math.hypot(*e2)
    if l1 >= l2:
        u, a, b = e1 / l1, l1, l2
    else:
        u, a, b = e2 / l2, l2, l1
    v = np.array([-u[1], u[0]])
    return c.mean(axis=0), u, v, a, b, rect


# a box's 12 faces over its 8 corners (bottom ring 0-3 counter-clockwise from above, top
# ring 4-7): bottom (down), top (up), then the four walls (out)
_BOX_F = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7]]
                  + [f for k in range(4) for f in ([k, (k + 1) % 4, 4 + (k + 1) % 4],
                                                   [k, 4 + (k + 1) % 4, 4 + k])], np.int64)
_BOX_F.setflags(write=False)


def box(centre, u, v, su, sv, z0, z1):
    """Closed box, sides su along u and sv along v, z from z0 to z1 (outward faces)."""
    cu, cv = su / 2, sv / 2
    a = np.array([centre - u * cu - v * cv, centre + u * cu - v * cv,
                  centre + u * cu + v * cv, centre - u * cu + v * cv])
    # make the ring counter-clockwise seen from above
    if ((a[1, 0] - a[0, 0]) * (a[2, 1] - a[0, 1]) - (a[1, 1] - a[0, 1]) * (a[2, 0] - a[0, 0])) < 0:
        a = a[::-1]
    verts = np.empty((8, 3))
    verts[:4, :2] = a
    verts[4:, :2] = a
    verts[:4, 2] = z0
    verts[4:, 2] = z1
    return verts, _BOX_F.copy(), a


def _ring_box(centre, u, v, a, b, th, z0, z1):
    """A closed rectangular ring (parapet): outer a x b, walls ``th`` thick, z0..z1."""
    _, _, outer = box(centre, u, v, a, b, z0, z1)
    _, _, inner = box(centre, u, v, a - 2 * th, b - 2 * th, z0, z1)
    # both rings counter-clockwise from above and starting at the same corner
    ring = np.concatenate([outer, inner])  # 0-3 outer, 4-7 inner
    verts = np.concatenate([np.column_stack([ring, np.full(8, z0)]),
                            np.column_stack([ring, np.full(8, z1)])])  # +8: top
    f = []
    for k in range(4):
        m = (k + 1) % 4
        f += [[8 + k, 8 + m, 12 + m], [8 + k, 12 + m, 12 + k]]  # top (up)
        f += [[k, 4 + m, m], [k, 4 + k, 4 + m]]  # bottom (down)
        f += [[k, m, 8 + m], [k, 8 + m, 8 + k]]  # outer wall (out)
        f += [[4 + k, 12 + m, 4 + m], [4 + k, 12 + k, 12 + m]]  # inner wall (towards the centre)
    return verts, np.asarray(f, np.int64)


def gable(rect_c, u, v, a, b, eave, ridge):
    """A closed gabled roof volume over the rectangle (a along u, b along v)."""
    ha, hb = a / 2, b / 2
    p = lambda s, t, z: (*(rect_c + u * s + v * t), z)  # noqa: E731
    verts = np.array([
        p(-ha, -hb, eave), p(ha, -hb, eave), p(ha, hb, eave), p(-ha, hb, eave),  # eaves 0-3
        p(-ha, 0.0, ridge), p(ha, 0.0, ridge),  # ridge ends 4, 5
    ])
    f = [
        [0, 1, 5], [0, 5, 4],  # slope on the -v side
        [2, 3, 4], [2, 4, 5],  # slope on the +v side
        [1, 2, 5], [3, 0, 4],  # gable ends
        [0, 2, 1], [0, 3, 2],  # underside
    ]
    f = np.asarray(f, np.int64)
    # orient outward: flip all faces if the signed volume is negative
    tri = verts[f]
    vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum()
    if vol < 0:
        f = f[:, ::-1]
    return verts, f


def _place(rng, frame, margin, sizes, taken, inner=None, tries=6):
    """Try to put a box of sizes (su along u, sv along v) on the roof, ``margin`` inside the
    footprint's rectangle, 0.4 m away from the ``taken`` boxes (local (s, t, su, sv)
    tuples); footprints that are not rectangles also check ``inner`` (shapely). Returns the
    box centre (world xy) or None."""
    c0, u, v, a, b, _ = frame
    su, sv = sizes
    hs, ht = a / 2 - margin - su / 2, b / 2 - margin - sv / 2
    if hs <= 0 or ht <= 0:
        return None
    for _ in range(tries):
        s, t = rng.uniform(-hs, hs), rng.uniform(-ht, ht)
        if any(abs(s - s2) < (su + su2) / 2 + 0.4 and abs(t - t2) < (sv + sv2) / 2 + 0.4
               for s2, t2, su2, sv2 in taken):
            continue
        c = c0 + u * s + v * t
        if inner is not None:
            import shapely

            ring = [c - u * su / 2 - v * sv / 2, c + u * su / 2 - v * sv / 2,
                    c + u * su / 2 + v * sv / 2, c - u * su / 2 + v * sv / 2]
            if not inner.contains(shapely.Polygon(ring)):
                continue
        taken.append((s, t, su, sv))
        return c
    return None


def roof_parts(poly, height: float, rng: np.random.Generator, override: Mapping | None = None,
               details: bool = True) -> RoofParts:
    """Walls, roof covering and roof details of one building (footprint ``poly``, shapely,
    metres; ``height`` of the walls' top or of the ridge), drawn from ``rng``."""
    area = float(poly.area)
    w = roof_weights(area, height, override)
    mat = ROOF_MATERIALS[int(rng.choice(3, p=w))]
    cols = ROOF_COLORS[mat]
    col = cols[int(rng.integers(len(cols)))]
    frame = _frame(poly)
    c0, u, v, a, b, rect = frame
    is_rect = area >= 0.98 * rect.area
    out_details: list = []

    pitch = np.radians(rng.uniform(30.0, 40.0))
    rise = min(0.5 * b * np.tan(pitch), height - 2.5)  # the ridge at the building height
    if mat == "roof_tiles" and is_rect and b >= 4.0 and rise >= 1.0:
        eave = height - rise
        ridge = height
        wv, wf, _ = box(c0, u, v, a, b, 0.0, eave)
        gv, gf = gable(c0, u, v, a, b, eave, ridge)
        body = (np.concatenate([wv, gv]), np.concatenate([wf, gf + len(wv)]))
        if details:
            for _ in range(int(rng.integers(0, 3))):  # chimneys on a slope, below the ridge
                s = rng.uniform(-0.35, 0.35) * a
                t = rng.choice([-1.0, 1.0]) * rng.uniform(0.15, 0.35) * b
                sz = rng.uniform(0.5, 0.8)
                c = c0 + u * s + v * t
                z_low = ridge - rise * (abs(t) + sz / 2) / (b / 2)  # roof under its far edge
                z_top = ridge - rise * max(abs(t) - sz / 2, 0.0) / (b / 2) + rng.uniform(0.5, 0.9)
                bv, bf, _ = box(c, u, v, sz, sz, max(z_low, eave), z_top)
                out_details.append(("concrete", bv, bf))
        return RoofParts(body, mat, col, eave, ridge, True, out_details)

    body = box(c0, u, v, a, b, 0.0, height)[:2] if is_rect else prism(poly, 0.0, height)
    if not details:
        return RoofParts(body, mat, col, height, height, False, out_details)
    taken: list = []
    margin = 0.8
    if mat == "roof_gravel":
        th = rng.uniform(0.25, 0.35)
        ph = rng.uniform(0.3, 0.8)
        if area > 40.0 and is_rect:
            out_details.append(("concrete", *_ring_box(c0, u, v, a, b, th, height - 0.02, height + ph)))
        elif area > 40.0:
            ring = poly.difference(poly.buffer(-th, join_style="mitre"))
            if not ring.is_empty:
                out_details.append(("concrete", *prism(ring, height - 0.02, height + ph)))
        margin = th + 0.6
    inner = None if is_rect else poly.buffer(-margin, join_style="mitre")
    if min(a, b) < 2 * margin + 1.0 or (inner is not None and inner.is_empty):
        return RoofParts(body, mat, col, height, height, False, out_details)

    def add(material, sizes, hz):
        c = _place(rng, frame, margin, sizes, taken, inner)
        if c is not None:
            bv, bf, _ = box(c, u, v, sizes[0], sizes[1], height - 0.02, height + hz)
            out_details.append((material, bv, bf))

    if mat == "roof_metal" and is_rect:  # skylight strips along the long side
        n = int(min(3, area // 400))
        for k in range(n):
            t = ((k + 0.5) / n - 0.5) * (b - 2 * margin - 1.2)
            bv, bf, _ = box(c0 + v * t, u, v, 0.7 * a, 1.2, height - 0.02, height + 0.18)
            taken.append((0.0, t, 0.7 * a, 1.2))
            out_details.append(("glass", bv, bf))
    if area > 200.0 and rng.random() < 0.6:  # stairwell / lift housing
        add("concrete", (rng.uniform(2.5, 3.5), rng.uniform(2.2, 3.0)), rng.uniform(2.2, ROOF_DETAIL_MAX_M))
    for _ in range(int(min(4, rng.poisson(area / 250.0)))):  # AC units
        add("metal", (rng.uniform(1.0, 1.8), rng.uniform(0.7, 1.1)), rng.uniform(0.6, 1.0))
    for _ in range(int(min(4, rng.poisson(area / 200.0)))):  # vents
        s = rng.uniform(0.3, 0.6)
        add("roof_metal", (s, s), rng.uniform(0.3, 0.8))
    if mat == "roof_gravel":
        for _ in range(int(min(2, rng.poisson(area / 500.0)))):  # skylights
            add("glass", (rng.uniform(1.0, 2.0), rng.uniform(1.0, 1.6)), rng.uniform(0.15, 0.35))
    return RoofParts(body, mat, col, height, height, False, out_details)


def detail_objects(parts: list[RoofParts], prefix: str = "roof_details"):
    """Merge every building's roof details into one object per material (label building)."""
    by: dict[str, list] = {}
    for p in parts:
        for mat, v, f in p.details:
            by.setdefault(mat, []).append((v, f))
    objs = []
    for mat in sorted(by):
        v, f = merge_meshes(by[mat])
        objs.append(SceneObject(f"{prefix}_{mat}", "building", v, f, material=mat, color=_DETAIL_RGB[mat]))
    return objs


def building_objects(buildings, seeds, spec: Mapping, names=None):
    """Scene objects of buildings with their roofs: one object per building (walls and
    covering) and one per detail material.

    buildings : [(footprint polygon, height)]; seeds : one integer (or tuple of integers
    >= 0) per building, its roof's seed; spec : the scene spec (``roofs`` section,
    ``generator``); names : object names (default ``building_000``, ...)."""
    cfg = spec.get("roofs") or {}
    override = cfg.get("materials") or DEFAULT_ROOFS.get(str(spec.get("generator")))
    on, det = cfg.get("enabled", True), cfg.get("details", True)
    objs, parts = [], []
    for i, ((poly, hgt), seed) in enumerate(zip(buildings, seeds)):
        rng = np.random.default_rng(np.random.SeedSequence([*map(int, np.atleast_1d(seed)), 3]))
        name = names[i] if names is not None else f"building_{i:03d}"
        if not on:  # plain prisms in the old 'roof' material
            cols = ROOF_COLORS["roof_tiles"] + ROOF_COLORS["roof_gravel"]
            v, f = prism(poly, 0.0, hgt)
            objs.append(SceneObject(name, "building", v, f, color=cols[int(rng.integers(len(cols)))]))
            continue
        rp = roof_parts(poly, hgt, rng, override, det)
        objs.append(SceneObject(name, "building", *rp.body, material=rp.material, color=rp.color))
        parts.append(rp)
    return objs + detail_objects(parts)


#: OSM ``roof:material`` values -> covering.
_OSM_ROOF_MATERIAL = {
    "roof_tiles": "roof_tiles", "tile": "roof_tiles", "tiles": "roof_tiles", "clay": "roof_tiles",
    "slate": "roof_tiles", "concrete_tiles": "roof_tiles",
    "metal": "roof_metal", "metal_sheet": "roof_metal", "copper": "roof_metal", "tin": "roof_metal",
    "zinc": "roof_metal", "steel": "roof_metal", "aluminium": "roof_metal",
    "gravel": "roof_gravel", "concrete": "roof_gravel", "asphalt": "roof_gravel",
    "tar_paper": "roof_gravel", "roofing_felt": "roof_gravel", "pebblestone": "roof_gravel",
}
_OSM_TILED = {"house", "detached", "semidetached_house", "terrace", "bungalow", "farm", "cabin",
              "hut", "church", "chapel", "villa"}
_OSM_METAL = {"industrial", "warehouse", "retail", "supermarket", "hangar", "shed", "garages",
              "garage", "barn", "service", "carport", "farm_auxiliary", "transportation",
              "manufacture", "storage_tank", "cowshed", "stable"}


def covering_from_tags(tags: Mapping) -> str:
    """Roof covering of an OSM building: its ``roof:material`` when known, else by
    ``building`` type (houses tiles, sheds and halls metal, everything else gravel)."""
    m = _OSM_ROOF_MATERIAL.get(str(tags.get("roof:material", "")).lower())
    if m:
        return m
    b = str(tags.get("building", ""))
    return "roof_tiles" if b in _OSM_TILED else "roof_metal" if b in _OSM_METAL else "roof_gravel"
