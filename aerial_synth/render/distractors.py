"""Distractors: vehicle-sized or vehicle-coloured clutter that is never a vehicle.

``add_distractors(scene, rng, per_hectare=...)`` returns a new Scene with extra static
objects and the list of what was drawn (kind, position, yaw, size, colour) for the metadata:

============  ================================  ==============  =====================
kind          shape                             label           where
============  ================================  ==============  =====================
manhole       0.6-0.7 m dark metal disc, 1 cm   road            on roads
container     6.06 x 2.44 x 2.59 m box          unknown         beside roads, 3-6 m off
dumpster      1.7-2.0 x 1.0-1.3 x 1.1-1.4 m box unknown         beside roads, 1.5-3 m off
road_sign     2.4 m pole and a 0.6 m plate      pole            beside roads, 1-2 m off
bench         1.6-2.0 x 0.5 x 0.45 m slab       unknown         beside roads, 1.5-3 m off
roof_unit     0.8-2.2 x 0.7-1.5 x 0.4-1.1 m box building        on building roofs
              (air conditioner, vent, skylight
              housing)
============  ================================  ==============  =====================

They are ordinary scene objects with non-vehicle labels, so the instance buffer, the
semantic ``vehicle`` class and every label file ignore them, while the ray caster gives them
shadows, occlusion and ambient occlusion like any other object. Sites come from vertical
line traces of the scene itself (a road below, or ground / sidewalk / parking with a road
within the given distance), so no geometry is guessed. Deterministic for a given generator.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..scene import build
from ..scene.model import LABEL_IDS, SceneObject
from ..scene.raycast import RayScene
from ..validators import in_range, integer

__all__ = ["DISTRACTOR_KEY", "DISTRACTOR_KINDS", "add_distractors"]

#: kind: (share of the distractors, label, material)
DISTRACTOR_KINDS: dict[str, tuple[float, str, str]] = {
    "manhole": (0.35, "road", "metal"),
    "container": (0.1, "unknown", "metal"),
    "dumpster": (0.2, "unknown", "metal"),
    "road_sign": (0.2, "pole", "metal"),
    "bench": (0.15, "unknown", "wall"),
    "roof_unit": (0.25, "building", "metal"),
}
_CONTAINER_RGB = [(0.45, 0.16, 0.10), (0.12, 0.22, 0.40), (0.15, 0.30, 0.18),
                  (0.55, 0.55, 0.55), (0.60, 0.45, 0.12), (0.75, 0.75, 0.72)]
_DUMPSTER_RGB = [(0.10, 0.25, 0.14), (0.12, 0.18, 0.35), (0.30, 0.31, 0.33),
                 (0.55, 0.42, 0.08)]
_KERB = ("ground", "sidewalk", "parking")


def _box(cx, cy, z0, length, width, height, yaw):
    import shapely
    from shapely import affinity

    poly = affinity.rotate(shapely.box(-length / 2, -width / 2, length / 2, width / 2),
                           yaw, use_radians=True, origin=(0, 0))
    poly = affinity.translate(poly, cx, cy)
    return build.prism(poly, z0, z0 + height)


def _near_road(rs, xy: np.ndarray, d_lo: float, d_hi: float) -> np.ndarray:
    """(n,) bool: some point at d_lo..d_hi metres in 8 directions lies on a road."""
    road = {LABEL_IDS[n] for n in ("road", "lane_marking")}
    ang = np.arange(8) * (math.pi / 4)
    dirs = np.stack([np.cos(ang), np.sin(ang)], 1)
    found = np.zeros(len(xy), bool)
    for d in (d_lo, 0.5 * (d_lo + d_hi), d_hi):
        probe = (xy[:, None, :] + d * dirs[None]).reshape(-1, 2)
        lab = rs.trace_labels(probe, ignore=("tree",)).reshape(len(xy), 8)
        found |= np.isin(lab, list(road)).any(axis=1)
    return found


#: second SeedSequence word of the distractor stream: ``SeedSequence([seed, DISTRACTOR_KEY])``
DISTRACTOR_KEY = 0x4453  # "DS"


def add_distractors(scene, rng: np.random.Generator, per_hectare: float = 6.0,
                    max_count: int = 2000):
    """(new Scene, [drawn distractor dicts]). ``per_hectare``: distractors per 10,000 m^2
    of the scene's bounding box (before the sites that fail their test are dropped)."""
    per_hectare = in_range("distractors per_hectare", per_hectare, 0.0, 1000.0)
    max_count = integer("distractors max_count", max_count, 0)
    b = scene.bounds()
    area = float((b[1, 0] - b[0, 0]) * (b[1, 1] - b[0, 1]))
    n = min(int(round(per_hectare * area / 1e4)), max_count)
    if n == 0 or not scene.objects:
        return scene, []
    kinds = list(DISTRACTOR_KINDS)
    shares = np.array([DISTRACTOR_KINDS[k][0] for k in kinds])
    kind_idx = rng.choice(len(kinds), size=4 * n, p=shares / shares.sum())
    xy = rng.uniform(b[0, :2] + 2.0, b[1, :2] - 2.0, size=(4 * n, 2))
    yaw = rng.uniform(0.0, 2 * math.pi, 4 * n)
    u = rng.uniform(0.0, 1.0, (4 * n, 3))  # size and colour draws
    rs = RayScene(scene)
    tr = rs.trace_down(xy, ignore=("tree",))
    lab = np.asarray(tr.label_id)
    on_road = np.isin(lab, [LABEL_IDS["road"]])
    kerb = np.isin(lab, [LABEL_IDS[k] for k in _KERB])
    ok = np.zeros(len(xy), bool)
    for i, k in enumerate(kinds):
        sel = kind_idx == i
        if k == "manhole":
            ok[sel] = on_road[sel]
        elif k == "roof_unit":
            ok[sel] = lab[sel] == LABEL_IDS["building"]
        else:
            lo, hi = {"container": (3.0, 6.0), "road_sign": (1.0, 2.0)}.get(k, (1.5, 3.0))
            cand = sel & kerb
            if cand.any():
                ok[np.flatnonzero(cand)] = _near_road(rs, xy[cand], lo, hi)
    picked = np.flatnonzero(ok & np.isfinite(tr.z))[:n]
    objects, drawn = [], []
    for j, i in enumerate(picked):
        k = kinds[kind_idx[i]]
        _, label, material = DISTRACTOR_KINDS[k]
        x, y, z, a = float(xy[i, 0]), float(xy[i, 1]), float(tr.z[i]), float(yaw[i])
        if k == "manhole":
            r = 0.30 + 0.05 * u[i, 0]
            v, f = build.cylinder((x, y), r, z, z + 0.01, sections=12)
            col = (0.10 + 0.1 * u[i, 1],) * 3
            size = [2 * r, 2 * r, 0.01]
        elif k == "container":
            size = [6.06, 2.44, 2.59]
            v, f = _box(x, y, z, *size, a)
            col = _CONTAINER_RGB[int(u[i, 1] * len(_CONTAINER_RGB))]
        elif k == "dumpster":
            size = [1.7 + 0.3 * u[i, 0], 1.0 + 0.3 * u[i, 1], 1.1 + 0.3 * u[i, 2]]
            v, f = _box(x, y, z, *size, a)
            col = _DUMPSTER_RGB[int(u[i, 2] * len(_DUMPSTER_RGB))]
        elif k == "road_sign":
            pv, pf = build.cylinder((x, y), 0.04, z, z + 2.4, sections=6)
            sv, sf = _box(x, y, z + 2.0, 0.05, 0.6, 0.6, a)
            v, f = build.merge_meshes([(pv, pf), (sv, sf)])
            col = (0.55, 0.56, 0.58)
            size = [0.6, 0.6, 2.6]
        elif k == "roof_unit":
            size = [0.8 + 1.4 * u[i, 0], 0.7 + 0.8 * u[i, 1], 0.4 + 0.7 * u[i, 2]]
            v, f = _box(x, y, z, *size, a)
            col = (0.62 + 0.2 * u[i, 2],) * 3
        else:  # bench
            size = [1.6 + 0.4 * u[i, 0], 0.5, 0.45]
            v, f = _box(x, y, z, *size, a)
            col = (0.42, 0.30, 0.18) if u[i, 1] < 0.6 else (0.55, 0.55, 0.52)
        col = tuple(float(c) for c in col)
        objects.append(SceneObject(f"distractor_{j}_{k}", label, v, f, material, col))
        drawn.append({"kind": k, "label": label, "x_m": round(x, 4), "y_m": round(y, 4),
                      "z_m": round(z, 4), "yaw_rad": round(a, 6),
                      "size_m": [round(s, 4) for s in size], "rgb": [round(c, 4) for c in col]})
    new = dataclasses.replace(scene, objects=list(scene.objects) + objects)
    return new, drawn
