"""Closed convex solids for the procedural vehicle parts, straight from qhull.

Every procedural part is a convex volume. ``trimesh.convex.convex_hull`` wraps the same
qhull call in a full ``Trimesh`` (caches, normal repair, merging): about 1.6 ms a part, and a
car has ~17 parts, so building the meshes of one placement cost seconds. Here the hull comes
from :class:`scipy.spatial.ConvexHull` directly and each triangle is turned to face away from
the centroid (a convex solid contains its centroid): ~0.1 ms a part; boxes are written out.
"""

from __future__ import annotations

import numpy as np

__all__ = ["box", "convex_hull"]

# the 12 outward (counter-clockwise seen from outside) triangles of the 8 corners
# ordered x-major: index = 4 * ix + 2 * iy + iz
_BOX_FACES = np.array([
    [0, 1, 3], [0, 3, 2],  # x = x0
    [4, 6, 7], [4, 7, 5],  # x = x1
    [0, 4, 5], [0, 5, 1],  # y = y0
    [2, 3, 7], [2, 7, 6],  # y = y1
    [0, 2, 6], [0, 6, 4],  # z = z0
    [1, 5, 7], [1, 7, 3],  # z = z1
], np.int64)
_BOX_FACES.setflags(write=False)


def convex_hull(points) -> tuple[np.ndarray, np.ndarray]:
    """Closed convex hull: (vertices (n, 3) float64, faces (m, 3) int64), outward normals.

    Only the hull's vertices are kept (in input order); zero-area triangles are dropped."""
    from scipy.spatial import ConvexHull

    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    h = ConvexHull(p, qhull_options="Qt")  # triangulated facets
    used = np.unique(h.simplices)
    remap = np.full(len(p), -1, np.int64)
    remap[used] = np.arange(len(used))
    v = p[used]
    f = remap[h.simplices]
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    n = np.cross(b - a, c - a)
    area2 = np.linalg.norm(n, axis=1)
    keep = area2 > 1e-12 * max(1.0, float(np.ptp(v, axis=0).max()) ** 2)
    f, n, a = f[keep], n[keep], a[keep]
    flip = np.einsum("ij,ij->i", n, a - v.mean(axis=0)) < 0
    f[flip] = f[flip][:, [0, 2, 1]]
    return v, np.ascontiguousarray(f)


def box(x0, x1, y0, y1, z0, z1) -> tuple[np.ndarray, np.ndarray]:
    """The axis-aligned box [x0, x1] x [y0, y1] x [z0, z1] (bounds in either order)."""
    xs, ys, zs = sorted((x0, x1)), sorted((y0, y1)), sorted((z0, z1))
    v = np.array([(x, y, z) for x in xs for y in ys for z in zs], np.float64)
    return v, _BOX_FACES.copy()
