"""Mesh builders for scenes: flat polygons, prisms, crowns, trunks (all z-up, metres).

Used by the procedural generators and by tests that hand-build layouts.
Faces are counter-clockwise seen from outside (normals outward / upward).
"""

from __future__ import annotations

import numpy as np

from .model import SceneObject

__all__ = [
    "triangulate_polygon",
    "flat_polygon",
    "prism",
    "ellipsoid",
    "cylinder",
    "polygon_object",
    "merge_meshes",
    "snap_to_grid",
    "GRID_M",
]

#: Generated x, y coordinates are snapped to this grid (2**-20 m, about a micrometre) before
#: they are triangulated and when a procedural scene is finished. The grid is a power of two, so
#: snapping is exact arithmetic. Why: the last bits of a coordinate may differ between CPUs
#: (OpenBLAS picks its kernels by CPU; glibc's sin/cos/exp have FMA variants), and where
#: points are cocircular (a disc's ring) the constrained Delaunay triangulation of the
#: unsnapped points flips diagonals on such a difference. On the grid, two machines agree
#: unless a coordinate lies within a few ulps of a grid boundary (odds ~1e-8 per coordinate).
GRID_M = 2.0 ** -20


def snap_to_grid(a: np.ndarray) -> np.ndarray:
    """Coordinates rounded to :data:`GRID_M` (float64, exact: a power-of-two scale)."""
    return np.rint(np.asarray(a, np.float64) / GRID_M) * GRID_M + 0.0


def triangulate_polygon(polygon) -> tuple[np.ndarray, np.ndarray]:
    """Triangulate a shapely (Multi)Polygon with holes (constrained Delaunay).

    Returns vertices (n, 2) float64 and faces (m, 3) int64, counter-clockwise.
    """
    import shapely

    polygon = shapely.set_precision(polygon, GRID_M)  # see GRID_M: no diagonal flips
    if polygon.is_empty:
        return np.zeros((0, 2)), np.zeros((0, 3), np.int64)
    tris = shapely.constrained_delaunay_triangles(polygon)
    parts = shapely.get_parts(tris)
    if len(parts) == 0:
        return np.zeros((0, 2)), np.zeros((0, 3), np.int64)
    coords = shapely.get_coordinates(shapely.get_exterior_ring(parts))  # (4k, 2): closed rings
    tri = coords.reshape(-1, 4, 2)[:, :3, :]
    # orient counter-clockwise
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    keep = np.abs(cross) > 1e-12
    tri = tri[keep]
    cw = cross[keep] < 0
    tri[cw] = tri[cw][:, ::-1]
    flat = tri.reshape(-1, 2)
    verts, inv = np.unique(snap_to_grid(flat), axis=0, return_inverse=True)  # exact: on the grid
    faces = inv.reshape(-1, 3).astype(np.int64)
    return verts.astype(np.float64), faces


def flat_polygon(polygon, z: float) -> tuple[np.ndarray, np.ndarray]:
    """A horizontal, upward-facing surface at height z covering ``polygon``."""
    v2, f = triangulate_polygon(polygon)
    v = np.column_stack([v2, np.full(len(v2), float(z))])
    return v, f


def prism(polygon, z0: float, z1: float, top: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Closed vertical prism over a shapely Polygon between z0 and z1 (buildings, kerbs)."""
    import shapely

    polys = list(shapely.get_parts(shapely.set_precision(polygon, GRID_M)))  # walls meet the top
    vs, fs, off = [], [], 0
    for poly in polys:
        poly = shapely.geometry.polygon.orient(poly, 1.0)
        vt, ft = flat_polygon(poly, z1)
        if top:
            vs.append(vt)
            fs.append(ft + off)
            off += len(vt)
        rings = [np.asarray(poly.exterior.coords)[:-1]] + [
            np.asarray(r.coords)[:-1] for r in poly.interiors
        ]
        for ring in rings:
            n = len(ring)
            lo = np.column_stack([ring, np.full(n, z0)])
            hi = np.column_stack([ring, np.full(n, z1)])
            i = np.arange(n)
            j = (i + 1) % n
            # exterior ring is CCW, so outward faces are (lo_i, lo_j, hi_j), (lo_i, hi_j, hi_i)
            f = np.concatenate(
                [np.column_stack([i, j, n + j]), np.column_stack([i, n + j, n + i])]
            )
            vs.append(np.concatenate([lo, hi]))
            fs.append(f + off)
            off += 2 * n
    if not vs:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    return np.concatenate(vs), np.concatenate(fs).astype(np.int64)


def ellipsoid(center, radii, subdivisions: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """An ellipsoid (tree crown) from an icosphere scaled by radii (rx, ry, rz)."""
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=subdivisions)
    v = np.asarray(s.vertices) * np.asarray(radii, float) + np.asarray(center, float)
    return v, np.asarray(s.faces, np.int64)


def cylinder(center_xy, radius: float, z0: float, z1: float, sections: int = 8):
    """A vertical closed cylinder (trunk, pole): a regular ``sections``-gon prism with
    capped ends, outward faces (written out: importing trimesh for it costs ~0.7 s)."""
    n = int(sections)
    a = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    ring = np.column_stack([center_xy[0] + radius * np.cos(a), center_xy[1] + radius * np.sin(a)])
    v = np.concatenate([np.column_stack([ring, np.full(n, z0)]),
                        np.column_stack([ring, np.full(n, z1)]),
                        [[center_xy[0], center_xy[1], z0], [center_xy[0], center_xy[1], z1]]])
    i = np.arange(n)
    j = (i + 1) % n
    bot, top = 2 * n, 2 * n + 1
    f = np.concatenate([np.column_stack([i, j, n + j]), np.column_stack([i, n + j, n + i]),  # sides
                        np.column_stack([np.full(n, top), n + i, n + j]),  # top, facing up
                        np.column_stack([np.full(n, bot), j, i])])  # bottom, facing down
    return v.astype(np.float64), f.astype(np.int64)


def merge_meshes(parts) -> tuple[np.ndarray, np.ndarray]:
    """Concatenate [(vertices, faces), ...] into one mesh (no vertex merging)."""
    parts = [p for p in parts if len(p[1])]
    if not parts:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    vs, fs, off = [], [], 0
    for v, f in parts:
        vs.append(v)
        fs.append(f + off)
        off += len(v)
    return np.concatenate(vs), np.concatenate(fs)


def polygon_object(name: str, label: str, polygon, z: float, **kw) -> SceneObject:
    """A flat labelled object (road, grass, marking) covering ``polygon`` at height z."""
    v, f = flat_polygon(polygon, z)
    return SceneObject(name=name, label=label, vertices=v, faces=f, **kw)
