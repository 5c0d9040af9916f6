"""Hard negatives: objects that look like vehicles from above and are never labelled.

A detector trained without them fires on sheds, small flat roofs, concrete slabs, road
patches and the like (issue 29). The ``residential`` and ``rural`` generators scatter them
with a density per scene kind (:data:`DENSITY_PER_HA`, objects per hectare of the scene),
which a spec may scale or override (``hard_negatives: {scale: 1.0, density_per_ha: {kind:
x}}``). Every kind is an ordinary scene object with a non-vehicle label, so no label file
can ever hold one; the counts go into ``Scene.hints.negatives`` (and from there into
the placement stats and every exported image's metadata).

======================  =========================================  ========  ===========
kind                    shape (metres)                             label     where
======================  =========================================  ========  ===========
shed                    2.0-3.5 x 1.8-3.0, 2.2-2.6 high, gabled    building  yards
garden_house            3.0-4.5 x 2.5-4.0, 2.5-3.0 high, gabled    building  yards
ac_unit                 0.7-1.0 x 0.6-0.9 x 0.7-1.0 condenser box  building  yards
container               6.06 / 12.19 x 2.44 x 2.59                 building  roadside, farm
dumpster                1.7-2.0 x 1.0-1.3 x 1.1-1.4 with a lid     building  roadside, farm
bus_shelter             3-4.5 x 1.4-1.8, roof slab at 2.3-2.6      building  roadside
market_stall            3 x 2.5 canopies in a row of 2-5, 2.2 high building  roadside
slab                    concrete pad 2.5-6 x 2.5-8, 2 cm high      ground    yards, farm
road_patch              asphalt patch 1-3 x 2-6 on the road        road      road
boat                    4.5-8 x 1.8-2.6 hull with a cabin, no      building  yards, farm
                        trailer
======================  =========================================  ========  ===========

Rooftop air-conditioning units, vents and skylights come with the roofs themselves
(procedural/roofs.py; flat roofs), and are counted there, not here. Road patches are
``road`` (drivable): cars may stand on them, as on any road. Heights: slabs 0.02, road
patches 0.052 (between the asphalt at 0.05 and the tyre tracks at 0.055).
World frame: metres, x east, y north, z up.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..build import flat_polygon, merge_meshes, prism
from ..model import SceneObject
from .roofs import box, gable

__all__ = ["NEGATIVE_KINDS", "DENSITY_PER_HA", "KIND_REGIONS", "densities", "add_negatives",
           "Z_SLAB", "Z_PATCH"]

NEGATIVE_KINDS: tuple[str, ...] = ("shed", "garden_house", "ac_unit", "container", "dumpster",
                                   "bus_shelter", "market_stall", "slab", "road_patch", "boat")
Z_SLAB = 0.02
Z_PATCH = 0.052

#: Objects per hectare of scene area, per scene kind (the generator and its variant). Rough
#: counts from looking at VEDAI tiles (Utah) and European suburbs: about one shed per two
#: houses in US yards, fewer in Europe; patched roads everywhere; farm yards full of
#: containers, slabs and dumpsters.
DENSITY_PER_HA: dict[str, dict[str, float]] = {
    "residential_us": {"shed": 2.5, "garden_house": 0.5, "ac_unit": 3.0, "container": 0.05,
                       "dumpster": 0.3, "bus_shelter": 0.1, "market_stall": 0.0, "slab": 1.5,
                       "road_patch": 2.0, "boat": 0.3},
    "residential_eu": {"shed": 1.5, "garden_house": 1.5, "ac_unit": 0.8, "container": 0.05,
                       "dumpster": 0.5, "bus_shelter": 0.25, "market_stall": 0.1, "slab": 1.0,
                       "road_patch": 1.5, "boat": 0.1},
    "rural": {"shed": 0.3, "garden_house": 0.08, "ac_unit": 0.08, "container": 0.3,
              "dumpster": 0.12, "bus_shelter": 0.06, "market_stall": 0.08, "slab": 0.3,
              "road_patch": 0.6, "boat": 0.06},
}
#: Kind -> the regions (named by the generator) it may stand in, in order of preference.
KIND_REGIONS: dict[str, tuple[str, ...]] = {
    "shed": ("yard",), "garden_house": ("yard",), "ac_unit": ("house_side", "yard"),
    "container": ("farm", "roadside"), "dumpster": ("roadside", "farm"),
    "bus_shelter": ("roadside",), "market_stall": ("roadside",), "slab": ("yard", "farm"),
    "road_patch": ("road",), "boat": ("yard", "farm"),
}

_CONTAINER_RGB = ((0.45, 0.16, 0.10), (0.12, 0.22, 0.40), (0.15, 0.30, 0.18),
                  (0.55, 0.55, 0.55), (0.60, 0.45, 0.12), (0.75, 0.75, 0.72))
_DUMPSTER_RGB = ((0.10, 0.25, 0.14), (0.12, 0.18, 0.35), (0.30, 0.31, 0.33), (0.55, 0.42, 0.08))
_SHED_RGB = ((0.45, 0.33, 0.22), (0.60, 0.58, 0.52), (0.35, 0.36, 0.34), (0.55, 0.30, 0.22),
             (0.70, 0.68, 0.62))
_CANOPY_RGB = ((0.85, 0.85, 0.82), (0.70, 0.12, 0.10), (0.15, 0.30, 0.60), (0.20, 0.45, 0.20),
               (0.85, 0.65, 0.10))
_BOAT_RGB = ((0.90, 0.90, 0.88), (0.85, 0.86, 0.88), (0.15, 0.22, 0.45), (0.60, 0.10, 0.08))


def densities(scene_kind: str, cfg: Mapping | None) -> dict[str, float]:
    """Per-kind densities (per hectare) of a scene kind, with the spec's ``hard_negatives``
    section (``scale``, ``density_per_ha``) applied."""
    cfg = cfg or {}
    d = dict(DENSITY_PER_HA.get(scene_kind, {}))
    d.update({str(k): float(v) for k, v in (cfg.get("density_per_ha") or {}).items()})
    s = float(cfg.get("scale", 1.0))
    return {k: float(d.get(k, 0.0)) * s for k in NEGATIVE_KINDS}


def _rect(cx, cy, a, b, yaw):
    """Rectangle polygon a (along yaw) x b centred at (cx, cy)."""
    import shapely

    c, s = np.cos(yaw), np.sin(yaw)
    loc = np.array([[-a / 2, -b / 2], [a / 2, -b / 2], [a / 2, b / 2], [-a / 2, b / 2]])
    return shapely.Polygon(np.column_stack([cx + c * loc[:, 0] - s * loc[:, 1],
                                            cy + s * loc[:, 0] + c * loc[:, 1]]))


def _gabled(cx, cy, a, b, yaw, wall, ridge):
    """Closed box to ``wall`` with a gabled roof to ``ridge`` (ridge along a)."""
    u = np.array([np.cos(yaw), np.sin(yaw)])
    v = np.array([-u[1], u[0]])
    c = np.array([cx, cy])
    wv, wf, _ = box(c, u, v, a, b, 0.0, wall)
    gv, gf = gable(c, u, v, a + 0.3, b + 0.3, wall, ridge)
    return merge_meshes([(wv, wf), (gv, gf)])


def _boat(cx, cy, L, B, yaw, z0, h):
    """A hull outline with a pointed bow (prism) and a cabin box on it."""
    import shapely
    from shapely import affinity

    xs = np.array([-L / 2, L / 4, L / 2, L / 4, -L / 2])
    ys = np.array([-B / 2, -B / 2, 0.0, B / 2, B / 2])
    hull = shapely.Polygon(np.column_stack([xs, ys]))
    cabin = shapely.box(-L * 0.15, -B * 0.3, L * 0.15, B * 0.3)
    out = []
    for poly, lo, hi in ((hull, z0, z0 + h), (cabin, z0 + h, z0 + h + 0.6)):
        p = affinity.translate(affinity.rotate(poly, yaw, origin=(0, 0), use_radians=True), cx, cy)
        out.append(prism(p, lo, hi))
    return merge_meshes(out), affinity.translate(affinity.rotate(hull, yaw, origin=(0, 0),
                                                                 use_radians=True), cx, cy)


def _draw(kind: str, rng: np.random.Generator):
    """Size (a, b) of a kind's footprint (a along its yaw) and its extra draws."""
    if kind == "shed":
        return rng.uniform(2.0, 3.5), rng.uniform(1.8, 3.0)
    if kind == "garden_house":
        return rng.uniform(3.0, 4.5), rng.uniform(2.5, 4.0)
    if kind == "ac_unit":
        return rng.uniform(0.7, 1.0), rng.uniform(0.6, 0.9)
    if kind == "container":
        return (6.06 if rng.random() < 0.75 else 12.19), 2.44
    if kind == "dumpster":
        return rng.uniform(1.7, 2.0), rng.uniform(1.0, 1.3)
    if kind == "bus_shelter":
        return rng.uniform(3.0, 4.5), rng.uniform(1.4, 1.8)
    if kind == "market_stall":
        n = int(rng.integers(2, 6))
        return 3.0 * n + 0.3 * (n - 1), 2.5
    if kind == "slab":
        return rng.uniform(2.5, 6.0), rng.uniform(2.5, 8.0)
    if kind == "road_patch":
        return rng.uniform(2.0, 6.0), rng.uniform(1.0, 3.0)
    if kind == "boat":
        return rng.uniform(4.5, 8.0), rng.uniform(1.8, 2.6)
    raise ValueError(f"unknown hard negative kind {kind!r}")


def _mesh(kind: str, poly, cx, cy, a, b, yaw, rng):
    """(objects [(label, material, colour, (v, f))], footprint) of one hard negative."""
    if kind in ("shed", "garden_house"):
        wall = rng.uniform(2.0, 2.4) if kind == "shed" else rng.uniform(2.3, 2.7)
        ridge = wall + min(a, b) * rng.uniform(0.2, 0.35)
        col = _SHED_RGB[int(rng.integers(len(_SHED_RGB)))]
        mat = "roof_metal" if rng.random() < 0.3 else "roof_tiles" if kind == "garden_house" else "paint"
        return [("building", mat, col, _gabled(cx, cy, a, b, yaw, wall, ridge))]
    if kind == "ac_unit":
        h = rng.uniform(0.7, 1.0)
        v, f = prism(poly, 0.0, h)
        return [("building", "metal", (0.72, 0.73, 0.72), (v, f))]
    if kind == "container":
        col = _CONTAINER_RGB[int(rng.integers(len(_CONTAINER_RGB)))]
        return [("building", "metal", col, prism(poly, 0.0, 2.59))]
    if kind == "dumpster":
        col = _DUMPSTER_RGB[int(rng.integers(len(_DUMPSTER_RGB)))]
        h = rng.uniform(1.1, 1.4)
        lid = _rect(cx, cy, a + 0.1, b + 0.05, yaw)
        return [("building", "metal", col, merge_meshes([prism(poly, 0.0, h), prism(lid, h, h + 0.05)]))]
    if kind == "bus_shelter":
        z = rng.uniform(2.3, 2.6)
        roof = prism(poly, z, z + 0.12)
        u = np.array([np.cos(yaw), np.sin(yaw)])
        v = np.array([-u[1], u[0]])
        back = _rect(cx - v[0] * (b / 2 - 0.05), cy - v[1] * (b / 2 - 0.05), a, 0.06, yaw)
        return [("building", "roof_metal", (0.55, 0.57, 0.58), roof),
                ("building", "glass", (0.20, 0.24, 0.26), prism(back, 0.0, z))]
    if kind == "market_stall":
        u = np.array([np.cos(yaw), np.sin(yaw)])
        n = int(round((a + 0.3) / 3.3))
        parts = []
        for k in range(n):
            off = -a / 2 + 1.5 + k * 3.3
            col = _CANOPY_RGB[int(rng.integers(len(_CANOPY_RGB)))]
            z = rng.uniform(2.1, 2.4)
            parts.append(("building", "paint", col, _gabled(cx + u[0] * off, cy + u[1] * off, 3.0, b, yaw,
                                                             z - 0.3, z + 0.35)))
        return parts
    if kind == "slab":
        k = rng.uniform(0.85, 1.15)
        col = tuple(float(min(c * k, 0.9)) for c in (0.60, 0.59, 0.56))
        return [("ground", "concrete", col, flat_polygon(poly, Z_SLAB))]
    if kind == "road_patch":
        g = rng.choice([0.15, 0.18, 0.30, 0.34])
        return [("road", "asphalt", (g, g, g * 1.03), flat_polygon(poly, Z_PATCH))]
    if kind == "boat":
        col = _BOAT_RGB[int(rng.integers(len(_BOAT_RGB)))]
        (v, f), _ = _boat(cx, cy, a, b, yaw, 0.25, rng.uniform(0.8, 1.2))
        return [("building", "paint", col, (v, f))]
    raise ValueError(kind)


def add_negatives(scene_kind: str, cfg: Mapping | None, regions: Mapping, area_m2: float,
                  rng: np.random.Generator, taken=None) -> tuple[list[SceneObject], dict]:
    """Scatter the hard negatives of one scene.

    scene_kind : key of :data:`DENSITY_PER_HA` (``residential_us``, ``residential_eu``,
                 ``rural``); cfg : the spec's ``hard_negatives`` section (or None)
    regions    : name -> shapely polygon where kinds may stand (see :data:`KIND_REGIONS`);
                 a footprint must lie wholly inside its region
    area_m2    : the scene area the densities refer to
    taken      : shapely geometries already standing (footprints may not touch them)
    Returns (scene objects, one per kind and material; metadata) where the metadata is
    ``{"scene_kind", "density_per_ha", "counts", "labelled": False, "positions": [[kind, x,
    y], ...]}`` (footprint centres, world metres).
    """
    import shapely

    dens = densities(scene_kind, cfg)
    base = shapely.STRtree(list(taken)) if taken else None
    placed: list = []  # the negatives placed so far (checked one by one: few)
    counts = {k: 0 for k in NEGATIVE_KINDS}
    where: list = []  # [kind, x, y] of every one placed
    by: dict[tuple, list] = {}
    prepared = {}
    for name, reg in regions.items():
        if reg is not None and not reg.is_empty:
            shapely.prepare(reg)
            prepared[name] = reg
    for kind in NEGATIVE_KINDS:
        n = int(rng.poisson(dens[kind] * area_m2 / 1e4)) if dens[kind] > 0 else 0
        regs = [prepared[r] for r in KIND_REGIONS[kind] if r in prepared]
        if n == 0 or not regs:
            continue
        for _ in range(n):
            a, b = _draw(kind, rng)
            for _try in range(12):
                reg = regs[0] if len(regs) == 1 or rng.random() < 0.7 else regs[int(rng.integers(1, len(regs)))]
                x0, y0, x1, y1 = reg.bounds
                cx, cy = rng.uniform(x0, x1), rng.uniform(y0, y1)
                yaw = rng.uniform(0, np.pi)
                poly = _rect(cx, cy, a, b, yaw)
                if kind == "boat":
                    _, poly = _boat(cx, cy, a, b, yaw, 0.0, 1.0)
                if not reg.contains(poly):
                    continue
                grown = poly.buffer(0.5)
                if base is not None and len(base.query(grown, predicate="intersects")):
                    continue
                if any(grown.intersects(p) for p in placed):
                    continue
                for label, mat, col, vf in _mesh(kind, poly, cx, cy, a, b, yaw, rng):
                    by.setdefault((kind, label, mat), []).append((vf, col))
                placed.append(poly)
                counts[kind] += 1
                where.append([kind, round(float(cx), 3), round(float(cy), 3)])
                break
    objs = []
    for (kind, label, mat), items in sorted(by.items()):
        # one object per kind, label and material; the colour of the first (objects carry
        # one colour each), the rest split into objects of their own colour
        by_col: dict[tuple, list] = {}
        for vf, col in items:
            by_col.setdefault(tuple(round(float(c), 4) for c in col), []).append(vf)
        for j, (col, vfs) in enumerate(sorted(by_col.items())):
            v, f = merge_meshes(vfs)
            objs.append(SceneObject(f"negative_{kind}_{mat}_{j}", label, v, f, material=mat, color=col))
    meta = {"scene_kind": scene_kind, "density_per_ha": {k: round(v, 4) for k, v in dens.items()},
            "counts": counts, "labelled": False, "positions": where}
    return objs, meta


