"""Tree geometry of the procedural generators: clumped crowns of several species.

A crown is not one smooth ellipsoid but a few overlapping low-poly clumps, so its
silhouette is lumpy and the clumps shade each other. Species (``SPECIES``):

- ``broadleaf``: 4-6 jittered icosahedral clumps around a central one, a round crown;
- ``spreading``: 5-7 flatter clumps spread wide (plane tree, oak), a low, broad crown;
- ``columnar``: 3-4 clumps stacked on the trunk (poplar), a narrow crown (0.55 x radius);
- ``conifer``: 2-4 stacked 8-sided cones, narrower at every tier (spruce, fir), a narrow
  crown (0.6 x radius) in darker foliage.

Every species has :data:`N_TEMPLATES` crown templates built once from a fixed seed in a unit
frame (xy within the unit disc, z from 0 to 1). A tree picks a template and a rotation from
one uniform number ``u`` of its own and scales the template by its crown radius and crown
height, so a tree's shape depends only on its own numbers (the ``city`` generator's windows
agree) and building thousands of crowns is a few numpy operations per template.

Triangles per crown: broadleaf 80-120 (mean 100), spreading 100-140, columnar 60-80,
conifer 28-56 (a smooth ellipsoid crown had 80). Trunks are 8-sided prisms (28 triangles).
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any, Mapping

import numpy as np

from ...errors import SceneError
from ..model import SceneObject

__all__ = [
    "SPECIES",
    "SPECIES_COLORS",
    "DEFAULT_SPECIES",
    "N_TEMPLATES",
    "species_weights",
    "draw_species",
    "crown_template",
    "tree_objects",
]

SPECIES: tuple[str, ...] = ("broadleaf", "spreading", "columnar", "conifer")
#: Templates per species (a tree picks one with its own uniform number).
N_TEMPLATES = 24
#: Crown radius factor per species (the spec's crown radius is the broadleaf one).
_RADIUS_FACTOR = {"broadleaf": 1.0, "spreading": 1.15, "columnar": 0.55, "conifer": 0.6}

#: Foliage albedo per species (several per species: a tree draws one): the visible
#: reflectance of a canopy, not of a single sunlit leaf. A sunlit leaf reflects ~0.04-0.05
#: (blue), ~0.08-0.12 (green peak) and ~0.04-0.06 (red) (USGS spectral library, e.g. its
#: aspen and oak leaf spectra), but a crown seen from above also holds the shade between
#: its leaves and leaf clusters, which the clump geometry here does not model; canopy
#: albedos measured from towers put a broadleaf (aspen) stand at 0.75 x and conifer stands
#: at 0.42 x a grass site's summer albedo (0.15 and 0.083 vs 0.20, Betts & Ball 1997,
#: "Albedo over the boreal forest", JGR 102(D24)), and satellite visible-band albedos of
#: forests are ~0.03-0.05 (conifers at the low end). So, with the green lawn's visible luma
#: of ~0.11 (scene/model.py grass): broadleaf luma ~0.065-0.085, conifers ~0.04-0.05
#: (0.58 x broadleaf, as 0.083 / 0.15), columnar (poplars) a touch lighter; R:G:B ~
#: 0.55 : 1 : 0.4 as in the leaf spectra, the last broadleaf colour olive. Was 3-4 x
#: brighter (broadleaf luma ~0.25, (0.16, 0.32, 0.12)): pale "cauliflower" crowns as
#: bright as the roads.
SPECIES_COLORS: dict[str, tuple[tuple[float, float, float], ...]] = {
    "broadleaf": ((0.052, 0.095, 0.038), (0.060, 0.105, 0.042), (0.045, 0.085, 0.034),
                  (0.068, 0.100, 0.045)),
    "spreading": ((0.055, 0.095, 0.040), (0.064, 0.102, 0.044), (0.048, 0.088, 0.036)),
    "columnar": ((0.062, 0.110, 0.044), (0.055, 0.100, 0.040)),
    "conifer": ((0.030, 0.055, 0.030), (0.036, 0.062, 0.034), (0.026, 0.048, 0.028)),
}

#: Default species mix per generator (a spec's ``tree_species`` replaces it).
DEFAULT_SPECIES: dict[str, dict[str, float]] = {
    "city_park": {"broadleaf": 0.55, "spreading": 0.2, "columnar": 0.1, "conifer": 0.15},
    "suburb": {"broadleaf": 0.5, "spreading": 0.15, "columnar": 0.1, "conifer": 0.25},
    "highway": {"broadleaf": 0.45, "spreading": 0.1, "columnar": 0.15, "conifer": 0.3},
    "city": {"broadleaf": 0.6, "spreading": 0.25, "columnar": 0.1, "conifer": 0.05},
    "depot": {"broadleaf": 0.6, "columnar": 0.1, "conifer": 0.3},
}


def species_weights(value: Any, field: str = "tree_species") -> np.ndarray:
    """(len(SPECIES),) probabilities from a ``{species: weight}`` mapping; raises
    SceneError naming the field on unknown species, bad weights or a zero sum."""
    if not isinstance(value, Mapping) or not value:
        raise SceneError(f"{field}: expected a mapping of species ({', '.join(SPECIES)}) "
                         f"to weights, got {value!r}")
    w = np.zeros(len(SPECIES))
    for k, v in value.items():
        if k not in SPECIES:
            raise SceneError(f"{field}: unknown species {k!r}; expected one of {', '.join(SPECIES)}")
        try:
            f = float(v)
        except (TypeError, ValueError):
            f = float("nan")
        if isinstance(v, bool) or not (np.isfinite(f) and 0.0 <= f <= 1e6):
            raise SceneError(f"{field}.{k}: expected a weight >= 0, got {v!r}")
        w[SPECIES.index(k)] = f
    if w.sum() <= 0:
        raise SceneError(f"{field}: expected weights with a positive sum, got {dict(value)!r}")
    return w / w.sum()


def draw_species(rng: np.random.Generator, n: int, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Species index (n,) and a shape number u in [0, 1) (n,) per tree, in that order."""
    sp = rng.choice(len(SPECIES), size=n, p=weights)
    u = rng.random(n)
    return sp, u


# ----------------------------------------------------------------------- templates
#: The regular icosahedron's 12 corners, (0, +-1, +-phi) and its cyclic permutations, in the
#: order trimesh.creation.icosahedron lists them (so the crowns keep their shapes).
_PHI = (1.0 + 5.0 ** 0.5) / 2.0
_ICO_V = np.array([[-1, _PHI, 0], [1, _PHI, 0], [-1, -_PHI, 0], [1, -_PHI, 0],
                   [0, -1, _PHI], [0, 1, _PHI], [0, -1, -_PHI], [0, 1, -_PHI],
                   [_PHI, 0, -1], [_PHI, 0, 1], [-_PHI, 0, -1], [-_PHI, 0, 1]], float)


@lru_cache(maxsize=4)
def _ico(sub: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Unit icosphere: the icosahedron itself at ``sub`` 0 (its 20 faces are the triples of
    mutually adjacent corners, turned outward: no trimesh or qhull import, ~0.7 s, for
    twelve points), trimesh's subdivided one above."""
    if sub > 0:
        import trimesh

        s = trimesh.creation.icosphere(subdivisions=sub)
        return np.asarray(s.vertices, float), np.asarray(s.faces, np.int64)
    from itertools import combinations

    v = _ICO_V / np.linalg.norm(_ICO_V, axis=1, keepdims=True)
    d = np.linalg.norm(v[:, None] - v[None], axis=2)
    edge = d[d > 1e-9].min()
    adj = np.abs(d - edge) < 1e-6 * edge
    f = np.array([t for t in combinations(range(len(v)), 3)
                  if adj[t[0], t[1]] and adj[t[1], t[2]] and adj[t[0], t[2]]], np.int64)
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    inward = np.einsum("ij,ij->i", n, v[f[:, 0]]) < 0  # the centre is the origin
    f[inward] = f[inward][:, ::-1]
    return v, f


def _clumps(rng, centres, radii, sub: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Jittered icospheres (sub 0: 12 vertices, 20 faces each) at centres with radii (k, 3)."""
    sv, sf = _ico(sub)
    k = len(centres)
    jit = rng.uniform(0.86, 1.12, (k, len(sv), 1))  # radial jitter: lumpy, not faceted-round
    v = (sv[None] * jit * radii[:, None] + centres[:, None]).reshape(-1, 3)
    f = (sf[None] + (np.arange(k) * len(sv))[:, None, None]).reshape(-1, 3)
    return v, f


def _cone_tiers(rng, n_tiers: int) -> tuple[np.ndarray, np.ndarray]:
    """Stacked closed 8-sided cones, each narrower and higher than the one below."""
    vs, fs, off = [], [], 0
    a0 = rng.uniform(0, np.pi / 4, n_tiers)
    for j in range(n_tiers):
        zb = j / (n_tiers + 0.6) * rng.uniform(0.9, 1.0)
        zt = min(1.0, zb + rng.uniform(0.45, 0.6)) if j < n_tiers - 1 else 1.0
        rad = (1.0 - 0.78 * j / n_tiers) * rng.uniform(0.9, 1.0)
        a = a0[j] + np.arange(8) * (np.pi / 4)
        rr = rad * rng.uniform(0.85, 1.0, 8)
        ring = np.column_stack([rr * np.cos(a), rr * np.sin(a), np.full(8, zb)])
        apex = np.array([[rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03), zt]])
        v = np.concatenate([ring, apex])
        f = [[i, (i + 1) % 8, 8] for i in range(8)]  # sides (CCW seen from outside)
        f += [[0, i + 1, i] for i in range(1, 7)]  # base fan, facing down
        vs.append(v)
        fs.append(np.asarray(f, np.int64) + off)
        off += len(v)
    return np.concatenate(vs), np.concatenate(fs)


def _normalise(v: np.ndarray) -> np.ndarray:
    """Scale a crown so its xy reach is the unit disc and z spans [0, 1]."""
    reach = np.sqrt((v[:, 0] ** 2 + v[:, 1] ** 2).max())
    z0, z1 = v[:, 2].min(), v[:, 2].max()
    out = v.copy()
    out[:, :2] /= reach
    out[:, 2] = (v[:, 2] - z0) / (z1 - z0)
    return out


@lru_cache(maxsize=4 * len(SPECIES) * N_TEMPLATES)
def crown_template(species: str, index: int, sub: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Unit crown (vertices (n, 3), faces (m, 3), outward) of one species, template index
    0..N_TEMPLATES-1: xy within the unit disc, z in [0, 1]. Fixed seed: same everywhere.
    sub : icosphere level of each clump (0 = icosahedra, 20 faces; 1 = 80 faces)."""
    if species not in SPECIES:
        raise SceneError(f"unknown tree species {species!r}; expected one of {', '.join(SPECIES)}")
    rng = np.random.default_rng(np.random.SeedSequence([7151, SPECIES.index(species), int(index)]))
    if species == "conifer":
        v, f = _cone_tiers(rng, int(rng.integers(2, 5)))
        return _normalise(v), f
    if species == "broadleaf":
        k = int(rng.integers(4, 7))  # 1 central + 3..5 around
        ring_d, ring_r, ring_z, flat = (0.38, 0.55), (0.45, 0.62), (0.35, 0.62), 0.8
    elif species == "spreading":
        k = int(rng.integers(5, 8))
        ring_d, ring_r, ring_z, flat = (0.5, 0.68), (0.42, 0.55), (0.35, 0.5), 0.55
    else:  # columnar: clumps stacked along the trunk
        k = int(rng.integers(3, 5))
        z = np.linspace(0.25, 0.8, k) + rng.uniform(-0.05, 0.05, k)
        c = np.column_stack([rng.uniform(-0.12, 0.12, (k, 2)), z])
        r = np.column_stack([rng.uniform(0.5, 0.65, k) * np.linspace(1.0, 0.7, k)] * 2
                            + [rng.uniform(0.3, 0.4, k)])
        v, f = _clumps(rng, c, r, sub)
        return _normalise(v), f
    m = k - 1
    ang = 2 * np.pi * (np.arange(m) + rng.uniform(-0.25, 0.25, m)) / m + rng.uniform(0, 2 * np.pi)
    d = rng.uniform(*ring_d, m)
    c = np.column_stack([d * np.cos(ang), d * np.sin(ang), rng.uniform(*ring_z, m)])
    rr = rng.uniform(*ring_r, m)
    r = np.column_stack([rr, rr * rng.uniform(0.85, 1.0, m), rr * flat * rng.uniform(0.8, 1.0, m)])
    c = np.vstack([[rng.uniform(-0.08, 0.08), rng.uniform(-0.08, 0.08), 0.6], c])  # central, higher
    r = np.vstack([[0.62, 0.62, 0.5 * flat / 0.8], r])
    v, f = _clumps(rng, c, r, sub)
    return _normalise(v), f


# ----------------------------------------------------------------------- scene objects
def crown_extent(r: np.ndarray, h: np.ndarray, species: np.ndarray):
    """Crown radius, crown height and crown base height (metres) per tree.

    r : the spec's crown radius; h : tree height; species : index into SPECIES."""
    fac = np.array([_RADIUS_FACTOR[s] for s in SPECIES])[species]
    cr = r * fac
    conifer = species == SPECIES.index("conifer")
    columnar = species == SPECIES.index("columnar")
    ch = np.maximum(0.6 * h, 1.2 * r)  # a round crown: about twice the radius tall
    ch = np.where(conifer, 0.85 * h, ch)
    ch = np.where(columnar, 0.8 * h, ch)
    ch = np.minimum(ch, h - 1.0)
    return cr, ch, h - ch


def tree_objects(trees: np.ndarray, prefix: str = "tree_crowns", sub: int = 0):
    """Scene objects of trees: crowns grouped by species and colour, and one trunk object.

    trees : (n, 7) float: x, y, crown radius, height, species index, shape number u in
            [0, 1), colour number c in [0, 1) (metres for the first four)
    sub   : icosphere level of each clump (the spec's ``tree_subdivisions``)
    Returns a list of :class:`SceneObject` (label ``tree`` per species/colour group, label
    ``trunk`` for all trunks), in a fixed order.
    """
    trees = np.asarray(trees, float).reshape(-1, 7)
    if not len(trees):
        return []
    x, y, r, h = trees[:, 0], trees[:, 1], trees[:, 2], trees[:, 3]
    sp = trees[:, 4].astype(np.int64)
    u, cu = trees[:, 5], trees[:, 6]
    cr, ch, base = crown_extent(r, h, sp)
    tpl = np.minimum((u * N_TEMPLATES).astype(np.int64), N_TEMPLATES - 1)
    ang = (u * N_TEMPLATES - tpl) * 2 * np.pi  # the rest of u: the rotation
    objs = []
    for si, name in enumerate(SPECIES):
        cols = SPECIES_COLORS[name]
        col = np.minimum((cu * len(cols)).astype(np.int64), len(cols) - 1)
        for ci, rgb in enumerate(cols):
            sel = np.flatnonzero((sp == si) & (col == ci))
            if not len(sel):
                continue
            vs, fs, off = [], [], 0
            for t in np.unique(tpl[sel]):
                idx = sel[tpl[sel] == t]
                tv, tf = crown_template(name, int(t), sub)
                c, s = np.cos(ang[idx]), np.sin(ang[idx])
                vx = (tv[None, :, 0] * c[:, None] - tv[None, :, 1] * s[:, None]) * cr[idx, None]
                vy = (tv[None, :, 0] * s[:, None] + tv[None, :, 1] * c[:, None]) * cr[idx, None]
                vz = tv[None, :, 2] * ch[idx, None] + base[idx, None]
                v = np.stack([vx + x[idx, None], vy + y[idx, None], vz], axis=-1).reshape(-1, 3)
                f = (tf[None] + (np.arange(len(idx)) * len(tv))[:, None, None]).reshape(-1, 3)
                vs.append(v)
                fs.append(f + off)
                off += len(v)
            objs.append(SceneObject(f"{prefix}_{name}_{ci}", "tree", np.concatenate(vs),
                                    np.concatenate(fs), color=rgb))
    # trunks: 8-sided prisms from the ground into the crown (a third of the way up; a
    # conifer's to a fifth, hidden by its lowest tier)
    top = base + np.where(sp == SPECIES.index("conifer"), 0.2, 0.3) * ch
    rad = np.maximum(0.12, 0.06 * r)
    a = np.arange(8) * (np.pi / 4)
    ring = np.stack([np.cos(a), np.sin(a)], axis=-1)  # (8, 2)
    n = len(trees)
    lo = np.concatenate([ring[None] * rad[:, None, None] + np.stack([x, y], -1)[:, None],
                         np.zeros((n, 8, 1))], axis=-1)
    hi = lo.copy()
    hi[:, :, 2] = top[:, None]
    tv = np.concatenate([lo, hi], axis=1).reshape(-1, 3)
    f = []
    for k in range(8):
        m = (k + 1) % 8
        f += [[k, m, 8 + m], [k, 8 + m, 8 + k]]
    for k in range(1, 7):
        f.append([8, 8 + k, 8 + k + 1])
    f = np.asarray(f, np.int64)
    tf = (f[None] + (np.arange(n) * 16)[:, None, None]).reshape(-1, 3)
    objs.append(SceneObject("trunks", "trunk", tv, tf))
    return objs
