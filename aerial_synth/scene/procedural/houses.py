"""Detached houses, garages and yard things of the ``residential`` and ``rural`` generators.

A house is a rectangle (centre, long axis u, short axis v, sides a >= b) with a roof of
one shape: ``gable`` (ridge along u), ``hip`` (ridge along u, shortened by b/2 at both
ends), ``pyramid`` (hip with a point ridge: a square-ish footprint) or ``flat`` (gravel
with a parapet and roof details, procedural/roofs.py). Coverings and colours come from a
palette per variant (:data:`ROOF_PALETTES`); houses with the same covering and colour are
merged into one object (label ``building``).

Yard things: fences (``building``, thin prisms along lines), hedges (``tree``), patios
(``ground``, paving at 0.02 m), pools (``water`` at 0.03 m inside a concrete coping at
0.05 m), trampolines and garden furniture (``building``). World frame: metres, x east,
y north, z up.
"""

from __future__ import annotations

import numpy as np

from ..build import cylinder, flat_polygon, merge_meshes, prism
from ..model import SceneObject
from .roofs import box, detail_objects, gable, roof_parts

__all__ = ["ROOF_PALETTES", "house_mesh", "HouseSet", "rect_poly", "Z_PATIO", "Z_POOL", "Z_COPING"]

Z_PATIO = 0.02
Z_POOL = 0.03
Z_COPING = 0.05

#: variant -> [(covering, weight, colours)]. US: asphalt shingles (roof_tiles material,
#: greys and browns), some metal and flat; EU: clay and concrete tiles, some flat and metal;
#: farm: metal halls and tiled farmhouses.
ROOF_PALETTES: dict[str, list] = {
    "us": [("roof_tiles", 0.82, ((0.30, 0.30, 0.31), (0.22, 0.21, 0.22), (0.42, 0.40, 0.38),
                                 (0.45, 0.36, 0.28), (0.55, 0.53, 0.50), (0.36, 0.30, 0.26))),
           ("roof_metal", 0.10, ((0.45, 0.50, 0.55), (0.40, 0.30, 0.25), (0.62, 0.63, 0.64))),
           ("roof_gravel", 0.08, ((0.60, 0.58, 0.54), (0.66, 0.63, 0.57)))],
    "eu": [("roof_tiles", 0.80, ((0.55, 0.28, 0.20), (0.42, 0.22, 0.18), (0.25, 0.25, 0.27),
                                 (0.60, 0.38, 0.26), (0.35, 0.30, 0.28), (0.48, 0.27, 0.20))),
           ("roof_gravel", 0.12, ((0.52, 0.50, 0.47), (0.44, 0.43, 0.41))),
           ("roof_metal", 0.08, ((0.30, 0.32, 0.34), (0.55, 0.57, 0.58)))],
    "farm": [("roof_metal", 0.6, ((0.58, 0.60, 0.62), (0.45, 0.20, 0.17), (0.35, 0.42, 0.36),
                                  (0.70, 0.70, 0.68))),
             ("roof_tiles", 0.4, ((0.55, 0.28, 0.20), (0.30, 0.30, 0.31), (0.45, 0.36, 0.28)))],
}
#: roof shape weights per variant (flat coverings are always flat)
SHAPES: dict[str, dict[str, float]] = {
    "us": {"gable": 0.5, "hip": 0.35, "pyramid": 0.15},
    "eu": {"gable": 0.6, "hip": 0.3, "pyramid": 0.1},
    "farm": {"gable": 0.85, "hip": 0.15},
}


def rect_poly(c, u, a, b):
    """Rectangle polygon: centre c (2,), unit long axis u (2,), sides a along u, b across."""
    import shapely

    v = np.array([-u[1], u[0]])
    pts = [c - u * a / 2 - v * b / 2, c + u * a / 2 - v * b / 2, c + u * a / 2 + v * b / 2,
           c - u * a / 2 + v * b / 2]
    return shapely.Polygon(pts)


def _hip(c, u, v, a, b, eave, ridge):
    """A closed hipped roof over the rectangle (a along u >= b): ridge along u, inset b/2 from
    both ends (a point when a == b: a pyramid)."""
    ha, hb = a / 2, b / 2
    r = max(ha - hb, 0.0)
    p = lambda s, t, z: (*(c + u * s + v * t), z)  # noqa: E731
    if r < 1e-6:
        verts = np.array([p(-ha, -hb, eave), p(ha, -hb, eave), p(ha, hb, eave), p(-ha, hb, eave),
                          p(0.0, 0.0, ridge)])
        f = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4], [0, 2, 1], [0, 3, 2]], np.int64)
    else:
        verts = np.array([p(-ha, -hb, eave), p(ha, -hb, eave), p(ha, hb, eave), p(-ha, hb, eave),
                          p(-r, 0.0, ridge), p(r, 0.0, ridge)])
        f = np.array([[0, 1, 5], [0, 5, 4], [2, 3, 4], [2, 4, 5], [1, 2, 5], [3, 0, 4],
                      [0, 2, 1], [0, 3, 2]], np.int64)
    tri = verts[f]
    vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum()
    if vol < 0:
        f = f[:, ::-1]
    return verts, f


def house_mesh(c, u, a, b, height, shape: str, rng: np.random.Generator, overhang: float = 0.4):
    """(vertices, faces) of walls and a pitched roof (gable, hip, pyramid), or None for flat.

    c, u: centre and unit long axis; a >= b sides; height: ridge height (metres)."""
    v = np.array([-u[1], u[0]])
    pitch = np.radians(rng.uniform(22.0, 38.0))
    rise = min(0.5 * b * np.tan(pitch), height - 2.4)
    if rise < 0.8:
        return None
    eave = height - rise
    wv, wf, _ = box(c, u, v, a, b, 0.0, eave)
    ao, bo = a + 2 * overhang, b + 2 * overhang
    if shape == "gable":
        rv, rf = gable(c, u, v, ao, bo, eave, height)
    elif shape == "pyramid":
        s = max(ao, bo)
        rv, rf = _hip(c, u, v, s, s, eave, height) if abs(a - b) < 0.15 * a else _hip(c, u, v, ao, bo, eave, height)
    else:
        rv, rf = _hip(c, u, v, ao, bo, eave, height)
    return merge_meshes([(wv, wf), (rv, rf)])


class HouseSet:
    """Collects houses and yard things; emits merged scene objects."""

    def __init__(self, variant: str, rng: np.random.Generator):
        self.variant = variant
        self.rng = rng
        self.by: dict[tuple, list] = {}  # (label, material, colour) -> [(v, f)]
        self.flat_parts: list = []
        self.footprints: list = []  # shapely polygons of everything standing (buildings, yard things)
        self.counts = {"houses": 0, "garages": 0, "outbuildings": 0, "pools": 0,
                       "trampolines": 0, "patios": 0, "furniture": 0, "fence_m": 0.0, "hedge_m": 0.0}

    def _add(self, label, material, color, vf):
        self.by.setdefault((label, material, tuple(round(float(x), 4) for x in color)), []).append(vf)

    def building(self, c, u, a, b, height, palette: str | None = None, kind: str = "houses",
                 shape: str | None = None):
        """A house, garage or farm building: rectangle (c, u, a x b), ridge height."""
        rng = self.rng
        pal = ROOF_PALETTES[palette or self.variant]
        w = np.array([p[1] for p in pal])
        mat, _, cols = pal[int(rng.choice(len(pal), p=w / w.sum()))]
        col = cols[int(rng.integers(len(cols)))]
        poly = rect_poly(c, u, a, b)
        if a < b:  # keep a the long side
            a, b = b, a
            u = np.array([-u[1], u[0]])
        self.footprints.append(poly)
        self.counts[kind] = self.counts.get(kind, 0) + 1
        if shape is None:
            sh = SHAPES[palette or self.variant]
            names = list(sh)
            p = np.array([sh[k] for k in names])
            shape = names[int(rng.choice(len(names), p=p / p.sum()))]
        if mat != "roof_gravel" and shape != "flat":
            vf = house_mesh(np.asarray(c, float), np.asarray(u, float), a, b, height, shape, rng)
            if vf is not None:
                self._add("building", mat, col, vf)
                return poly
        rp = roof_parts(poly, min(height, max(3.0, height - 2.0)), rng, {"roof_gravel": 1.0}, True)
        self._add("building", "roof_gravel", rp.color, rp.body)
        self.flat_parts.append(rp)
        return poly

    def fence(self, line, width, height, color, hedge=False):
        poly = line.buffer(width / 2, cap_style="flat")
        if poly.is_empty:
            return
        if hedge:
            self._add("tree", "foliage", color, prism(poly, 0.0, height))
            self.counts["hedge_m"] += float(line.length)
        else:
            self._add("building", "paint", color, prism(poly, 0.0, height))
            self.counts["fence_m"] += float(line.length)

    def patio(self, poly, color):
        self._add("ground", "paving", color, flat_polygon(poly, Z_PATIO))
        self.footprints.append(poly)
        self.counts["patios"] += 1

    def pool(self, poly):
        coping = poly.buffer(0.4, join_style="mitre").difference(poly)
        self._add("ground", "concrete", (0.72, 0.71, 0.68), flat_polygon(coping, Z_COPING))
        col = (0.22, 0.52, 0.62) if self.rng.random() < 0.7 else (0.30, 0.60, 0.66)
        self._add("water", "water", col, flat_polygon(poly, Z_POOL))
        self.footprints.append(poly.buffer(0.4, join_style="mitre"))
        self.counts["pools"] += 1

    def trampoline(self, xy, r):
        import shapely

        disc = shapely.Point(xy).buffer(r, quad_segs=6)
        ring = disc.difference(shapely.Point(xy).buffer(r - 0.3, quad_segs=6))
        self._add("building", "trim", (0.04, 0.04, 0.045), prism(shapely.Point(xy).buffer(r - 0.3, quad_segs=6), 0.85, 0.88))
        pad = ((0.10, 0.30, 0.60), (0.15, 0.45, 0.20), (0.20, 0.20, 0.22))[int(self.rng.integers(3))]
        self._add("building", "paint", pad, prism(ring, 0.84, 0.92))
        self.footprints.append(disc)
        self.counts["trampolines"] += 1

    def furniture(self, xy, yaw):
        """A garden table with a parasol over it."""
        u = np.array([np.cos(yaw), np.sin(yaw)])
        table = rect_poly(np.asarray(xy, float), u, 1.6, 0.9)
        col = (0.80, 0.80, 0.78) if self.rng.random() < 0.5 else (0.40, 0.28, 0.18)
        self._add("building", "paint", col, prism(table, 0.0, 0.75))
        if self.rng.random() < 0.6:
            pc = ((0.85, 0.85, 0.82), (0.70, 0.15, 0.12), (0.20, 0.35, 0.60), (0.85, 0.70, 0.20))
            self._add("building", "paint", pc[int(self.rng.integers(4))],
                      cylinder(xy, self.rng.uniform(1.1, 1.5), 2.1, 2.2, 8))
        self.footprints.append(table.buffer(0.6))
        self.counts["furniture"] += 1

    def objects(self, prefix: str) -> list[SceneObject]:
        objs = []
        for j, ((label, mat, col), vfs) in enumerate(sorted(self.by.items())):
            v, f = merge_meshes(vfs)
            objs.append(SceneObject(f"{prefix}_{label}_{mat}_{j:02d}", label, v, f, material=mat, color=col))
        return objs + detail_objects(self.flat_parts, prefix=f"{prefix}_roof_details")
