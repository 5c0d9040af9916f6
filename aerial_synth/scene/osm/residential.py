"""Residential features of an OSM scene: driveway parking sites, house/garage/shed counts,
sheds as hard negatives, swimming pools (issue 29; docs/osm.md).

- ``highway=service`` + ``service=driveway`` ways stay drivable road surface (as every
  service way); their stretch beyond the other roads' surfaces becomes a driveway site
  (``Scene.hints.driveways``, the hint format of procedural/residential.py, with
  ``labels: [road, lane_marking, parking, parking_marking]``), so the ``driveways``
  scenario (placement/driveways.py) parks cars on it and records the driveway id.
- ``building=house|detached|garage|shed`` are counted (``meta["residential"]``); sheds are
  also hard negatives (``Scene.hints.negatives``, never labelled, like the procedural ones).
- ``leisure=swimming_pool`` areas are water (tags.py) and counted here.

Nothing is added to the metadata of a scene without any of these (so other OSM scenes keep
their metadata). Frame: the scene's local metres.
"""

from __future__ import annotations

import math

import numpy as np

from ..procedural.negatives import NEGATIVE_KINDS
from ..scene_hints import DrivewayHint, NegativesHint
from .tags import RESIDENTIAL_BUILDINGS, is_driveway

__all__ = ["residential_meta", "DRIVEWAY_WIDTH_M"]

#: Width of the driveway site along an OSM driveway (metres; real driveways are 3-3.5 m,
#: the way's road surface may be wider).
DRIVEWAY_WIDTH_M = 3.2
_LABELS = ["road", "lane_marking", "parking", "parking_marking"]


def _driveways(roads, clip) -> list[dict]:
    import shapely

    lines = [r.line for r in roads]
    tree = shapely.STRtree(lines)
    hints = []
    for i, r in enumerate(roads):
        if not is_driveway(r.tags):
            continue
        w = float(r.p.width_m)
        near = [j for j in tree.query(r.line.buffer(w + 20.0)) if j != i]
        others = shapely.union_all([roads[j].line.buffer(roads[j].p.width_m / 2 + 0.6, cap_style="flat")
                                    for j in near]) if near else shapely.Polygon()
        free = r.line.intersection(clip).difference(others)
        parts = [p for p in shapely.get_parts(free) if p.geom_type == "LineString" and p.length >= 6.0]
        if not parts:
            continue
        seg = max(parts, key=lambda p: p.length)
        a, b = np.asarray(seg.coords[0]), np.asarray(seg.coords[-1])
        if not others.is_empty and others.distance(shapely.Point(b)) < others.distance(shapely.Point(a)):
            a, b = b, a  # the axis points from the street into the driveway
        # the straight stretch from a: up to the first bend of more than 20 degrees
        coords = np.asarray(seg.coords) if np.allclose(seg.coords[0], a) else np.asarray(seg.coords)[::-1]
        d0 = coords[1] - coords[0]
        end = 1
        for k in range(1, len(coords) - 1):
            d = coords[k + 1] - coords[k]
            cosang = (d[0] * d0[0] + d[1] * d0[1]) / max(math.hypot(*d) * math.hypot(*d0), 1e-12)
            if cosang < np.cos(np.radians(20.0)):
                break
            end = k + 1
        p0, p1 = coords[0], coords[end]
        L = float(math.hypot(*(p1 - p0)))
        if L < 6.0:
            continue
        u = (p1 - p0) / L
        c = (p0 + p1) / 2
        width = min(w, DRIVEWAY_WIDTH_M) - 0.3
        hints.append({"id": len(hints), "kind": "driveway", "osm_id": int(r.osm_id),
                      "center_xy": [round(float(x), 4) for x in c],
                      "axis_deg": round(float(np.degrees(np.arctan2(u[1], u[0]))), 4),
                      "long_m": round(L - 0.6, 4), "short_m": round(width, 4), "bay_m": [5.6, 2.6],
                      "occupancy": 0.6, "mix": {"small-vehicle": 1.0}, "labels": list(_LABELS)})
    return hints


def residential_meta(roads, areas, geoms, clip, where: str = "OSM file") -> tuple[dict, tuple, NegativesHint | None]:
    """Metadata entries of an OSM scene's residential features (empty: none), its driveway
    hints (:class:`DrivewayHint`) and its sheds as hard negatives (None: no shed).

    roads : the scene's drivable ways (build.py ``_Road``: tags, line, ``p.width_m``)
    areas : reader areas [(kind, id, tags, geometry)]; geoms : their local-frame geometries
    """
    import shapely

    out: dict = {}
    hints = _driveways(roads, clip) if roads else []
    counts = {"houses": 0, "garages": 0, "sheds": 0, "swimming_pools": 0, "driveways": len(hints)}
    sheds = []
    for (kind, _, tags, _), g in zip(areas, geoms):
        if g is None or g.is_empty or not clip.intersects(g):
            continue
        if kind == "building" and tags.get("building") in RESIDENTIAL_BUILDINGS:
            key = RESIDENTIAL_BUILDINGS[tags["building"]]
            counts[key] += 1
            if key == "sheds":
                c = shapely.intersection(g, clip).centroid
                sheds.append(["shed", round(float(c.x), 3), round(float(c.y), 3)])
        elif kind == "water" and tags.get("leisure") == "swimming_pool":
            counts["swimming_pools"] += 1
    if not any(counts.values()):
        return out, (), None
    out["residential"] = counts
    drive = tuple(DrivewayHint.from_dict(h, f"{where}: driveway hint") for h in hints)
    neg = NegativesHint("osm", (), tuple((k, len(sheds) if k == "shed" else 0) for k in NEGATIVE_KINDS),
                        tuple(sheds)) if sheds else None
    return out, drive, neg
