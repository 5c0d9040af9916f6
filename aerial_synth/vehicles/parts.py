"""The parts procedural vehicle bodies are built from, and the shape helpers they share.

Vehicle frame: metres, origin at the footprint centre on the ground, +x forward, +y left,
z up (see :mod:`aerial_synth.vehicles.meshes`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._hull import convex_hull as _hull

__all__ = ["Part", "fit_to_size", "sym", "wheel", "glass_slab"]


@dataclass
class Part:
    """One closed convex volume of a vehicle: vertices (n, 3) and faces (m, 3), metres,
    vehicle frame; its material and albedo (None: the variant's paint)."""

    name: str
    material: str
    rgb: tuple[float, float, float] | None  # None = the variant's paint colour
    v: np.ndarray
    f: np.ndarray



def fit_to_size(parts: list[Part], length: float, width: float, height: float) -> list[Part]:
    """Scale (per axis, factors close to 1) and shift so the bounds are exactly
    [-L/2, L/2] x [-W/2, W/2] x [0, H]."""
    allv = np.concatenate([p.v for p in parts])
    lo, hi = allv.min(axis=0), allv.max(axis=0)
    scale = np.array([length, width, height]) / (hi - lo)
    centre = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    shift = np.array([0.0, 0.0, 0.0])
    out = []
    for p in parts:
        v = (p.v - centre) * scale + shift
        out.append(Part(p.name, p.material, p.rgb, v, p.f))
    return out


def sym(points_xhz) -> list[tuple[float, float, float]]:
    """Mirror (x, half_width, z) points to both sides: [(x, +hw, z), (x, -hw, z), ...]."""
    out = []
    for x, hw, z in points_xhz:
        out.append((x, hw, z))
        out.append((x, -hw, z))
    return out


def wheel(x, y, r, width, sections=14) -> tuple[np.ndarray, np.ndarray]:
    """A closed cylinder with its axis along y, standing on the ground (z from 0 to 2r)."""
    # start at the bottom so a vertex touches z = 0
    ang = -np.pi / 2 + np.linspace(0.0, 2 * np.pi, sections, endpoint=False)
    ring = np.column_stack([x + r * np.cos(ang), r + r * np.sin(ang)])
    pts = [(px, y + s * width / 2, pz) for px, pz in ring for s in (-1, 1)]
    return _hull(pts)


def glass_slab(quad, inside_point, offset=0.012, thickness=0.012, inset=0.05):
    """A thin slab lying on a planar quad (4, 3), pushed ``offset`` outward (away from
    ``inside_point``) and shrunk by ``inset`` toward the quad centre."""
    q = np.asarray(quad, np.float64)
    c = q.mean(axis=0)
    q = c + (q - c) * (1.0 - inset)
    n = np.cross(q[1] - q[0], q[2] - q[0])
    n /= math.hypot(*n)
    if np.dot(n, c - np.asarray(inside_point, float)) < 0:
        n = -n
    a = q + n * offset
    b = q + n * (offset + thickness)
    return _hull(np.concatenate([a, b]))
