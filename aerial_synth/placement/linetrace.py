"""Line-trace probing (thesis §3.2.2-3.2.3), vectorised.

Every probe is a set of vertical traces (:meth:`RayScene.trace_down`); all directions, all
steps and many probe points go into one cast. Nothing here reads road polygons.

Frames: world metres, angles in radians, 0 = +x, counter-clockwise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene.model import LABEL_IDS
from .config import ProbeConfig

__all__ = ["EdgeProbe", "Prober"]


def unit(angle: np.ndarray) -> np.ndarray:
    """(..., 2) unit vectors for angles (radians)."""
    a = np.asarray(angle, dtype=np.float64)
    return np.stack([np.cos(a), np.sin(a)], axis=-1)


@dataclass(frozen=True)
class EdgeProbe:
    """Result of marching from P points along D directions each.

    count     : (P, D) int, road hits before the first non-road step (thesis's count)
    found     : (P, D) bool, a non-road step was met within max_distance_m
    dist_m    : (P, D) float, distance from the origin to the road edge (the last road
                point, refined by bisection to < 1 mm when refine_steps > 0)
    edge_xy   : (P, D, 2) float, the edge points, metres, world
    n_rays    : number of traces this probe cast
    """

    count: np.ndarray
    found: np.ndarray
    dist_m: np.ndarray
    edge_xy: np.ndarray
    n_rays: int


class Prober:
    """Probes a RayScene with vertical traces. Counts the rays it casts."""

    def __init__(self, rayscene, cfg: ProbeConfig):
        self.rs = rayscene
        self.cfg = cfg
        lc = rayscene.label_config
        self.road_ids = np.array(sorted(LABEL_IDS[n] for n in lc.road), dtype=np.int16)
        self.drivable_ids = np.array(sorted(LABEL_IDS[n] for n in lc.drivable), dtype=np.int16)
        self.n_rays = 0
        self.n_casts = 0

    # ------------------------------------------------------------------ basic traces
    def trace(self, xy: np.ndarray):
        """trace_down with the scene's ignore-set; counts rays."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        self.n_rays += len(xy)
        self.n_casts += 1
        return self.rs.trace_down(xy)

    def is_road(self, xy: np.ndarray) -> np.ndarray:
        shp = np.asarray(xy).shape[:-1]
        r = self.trace(xy)
        return np.isin(r.label_id, self.road_ids).reshape(shp)

    # ------------------------------------------------------------------ marching
    def march(self, origins: np.ndarray, angles: np.ndarray, max_distance_m: float | None = None) -> EdgeProbe:
        """March from each origin along each of its directions in ``step_m`` steps.

        origins : (P, 2) metres, world (assumed on road)
        angles  : (P, D) radians
        """
        cfg = self.cfg
        origins = np.asarray(origins, dtype=np.float64).reshape(-1, 2)
        angles = np.asarray(angles, dtype=np.float64).reshape(len(origins), -1)
        P, D = angles.shape
        step = cfg.step_m
        K = int(np.ceil((max_distance_m or cfg.max_distance_m) / step))
        u = unit(angles)  # (P, D, 2)
        ks = np.arange(1, K + 1, dtype=np.float64) * step  # (K,)
        pts = origins[:, None, None, :] + u[:, :, None, :] * ks[None, None, :, None]
        road = self.is_road(pts.reshape(-1, 2)).reshape(P, D, K)
        nonroad = ~road
        found = nonroad.any(axis=2)
        first = np.where(found, nonroad.argmax(axis=2), K)  # 0-based index of first non-road step
        count = first.copy()
        lo = first * step  # distance of the last road point (0 = origin)
        n_rays = P * D * K
        if cfg.refine_steps and found.any():
            hi = lo + step
            fi = np.flatnonzero(found.ravel())
            lo_f = lo.ravel()[fi].astype(np.float64)
            hi_f = hi.ravel()[fi].astype(np.float64)
            o_f = np.repeat(origins, D, axis=0)[fi]
            u_f = u.reshape(-1, 2)[fi]
            for _ in range(int(cfg.refine_steps)):
                mid = 0.5 * (lo_f + hi_f)
                on = self.is_road(o_f + u_f * mid[:, None])
                n_rays += len(fi)
                lo_f = np.where(on, mid, lo_f)
                hi_f = np.where(on, hi_f, mid)
            dist = lo.astype(np.float64).ravel()
            dist[fi] = lo_f
            dist = dist.reshape(P, D)
        else:
            dist = lo.astype(np.float64)
        edge = origins[:, None, :] + u * dist[..., None]
        return EdgeProbe(count=count, found=found, dist_m=dist, edge_xy=edge, n_rays=n_rays)

    def road_runs(self, origins: np.ndarray, angles: np.ndarray, max_distance_m: float, gap_m: float):
        """Distance to the far edge of a road crossed along one direction per origin, jumping
        non-road gaps narrower than ``gap_m`` (a central median).

        Returns (far_dist (P,), crossed_gap (P,) bool, found (P,) bool).
        """
        step = self.cfg.step_m
        origins = np.asarray(origins, dtype=np.float64).reshape(-1, 2)
        angles = np.asarray(angles, dtype=np.float64).reshape(-1)
        K = int(np.ceil(max_distance_m / step))
        u = unit(angles)
        ks = np.arange(1, K + 1) * step
        pts = origins[:, None, :] + u[:, None, :] * ks[None, :, None]
        road = self.is_road(pts.reshape(-1, 2)).reshape(len(origins), K)
        gap_steps = int(np.ceil(gap_m / step))
        far = np.zeros(len(origins))
        crossed = np.zeros(len(origins), bool)
        found = np.zeros(len(origins), bool)
        for i in range(len(origins)):
            idx = np.flatnonzero(road[i])
            if len(idx) == 0 or idx[0] != 0:
                far[i] = 0.0
                found[i] = True
                continue
            jumps = np.flatnonzero(np.diff(idx) > gap_steps + 1)
            last = idx[jumps[0]] if len(jumps) else idx[-1]
            crossed[i] = bool(np.any(np.diff(idx[: (jumps[0] + 1) if len(jumps) else len(idx)]) > 1))
            found[i] = last < K - 1
            far[i] = (last + 1) * step
        return far, crossed, found
