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
        self._road_lut = np.zeros(len(LABEL_IDS), bool)
        self._road_lut[self.road_ids] = True
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
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        self.n_rays += len(xy)
        self.n_casts += 1
        lab = self.rs.trace_labels(xy)
        return self._road_lut[lab].reshape(shp)

    # ------------------------------------------------------------------ marching
    def march(self, origins: np.ndarray, angles: np.ndarray, max_distance_m: float | None = None,
              first_only: bool = False, include_origin: bool = False, chunk: int = 48,
              step_m: float | None = None, refine: bool = True) -> EdgeProbe:
        """March from each origin along each of its directions in ``step_m`` steps.

        origins : (P, 2) metres, world (assumed on road)
        angles  : (P, D) radians
        first_only : stop marching a point's directions once any of them met the edge (the
                 direction with the fewest road hits is then known; the others report
                 ``count`` = steps marched so far + 1 and ``found`` = False)
        include_origin : also trace the origin itself (step 0); an origin off road gives
                 count -1 and found False in every direction
        step_m : the march step (default: the probe's step_m)
        refine : refine the edges found (``refine_steps``); False leaves dist_m at the last
                 road step

        The march is chunked (2.4 m, then doubling) so a probe pays only for the distance to
        its edge. The edge between the last road step and the first non-road step is then
        refined by bisection to step_m / 2**refine_steps (< 1 mm at the defaults), in casts of
        up to 31 evenly spaced traces (5 bisections each). A coarser ``step_m`` than the
        probe's (the engine marches in 0.25 m steps) gets as many more bisections, so the
        edge comes out as precise; only a non-road gap narrower than the step can be missed,
        and the footprint check (0.1 m samples) still refuses a vehicle that meets one.
        """
        cfg = self.cfg
        origins = np.asarray(origins, dtype=np.float64).reshape(-1, 2)
        angles = np.asarray(angles, dtype=np.float64).reshape(len(origins), -1)
        P, D = angles.shape
        step = cfg.step_m if step_m is None else float(step_m)
        K = int(np.ceil((max_distance_m or cfg.max_distance_m) / step))
        u = unit(angles)  # (P, D, 2)
        count = np.full((P, D), K, np.int64)
        found = np.zeros((P, D), bool)
        active = np.ones((P, D), bool)
        origin_ok = np.ones(P, bool)
        n_rays = 0
        k0 = 0
        first_extra = origins if include_origin else None
        while k0 < K and active.any():
            kk = min(chunk, K - k0)
            ai = np.flatnonzero(active.ravel())
            o_a = np.repeat(origins, D, axis=0)[ai]
            u_a = u.reshape(-1, 2)[ai]
            ks = (np.arange(k0 + 1, k0 + kk + 1, dtype=np.float64) * step)
            pts = o_a[:, None, :] + u_a[:, None, :] * ks[None, :, None]
            flat = pts.reshape(-1, 2)
            if first_extra is not None:
                flat = np.concatenate([first_extra, flat])
            road = self.is_road(flat)
            n_rays += len(flat)
            if first_extra is not None:
                origin_ok = road[:P]
                road = road[P:]
                first_extra = None
            road = road.reshape(len(ai), kk)
            nonroad = ~road
            hit = nonroad.any(axis=1)
            first = nonroad.argmax(axis=1)
            fr = ai[hit]
            count.ravel()[fr] = k0 + first[hit]
            found.ravel()[fr] = True
            active.ravel()[fr] = False
            if first_only:
                # a point is done once any direction met its edge; its other directions
                # stop here with at least one more road hit than the edge direction had
                done_p = found.any(axis=1)
                stopped = active & done_p[:, None]
                count[stopped] = k0 + kk + 1
                active[stopped] = False
            k0 += kk
            chunk *= 2
        lo = count.astype(np.float64) * step
        dist = lo.copy()
        if refine and cfg.refine_steps and found.any():
            # the edge lies in (lo, lo + step]: cut that bracket in passes of up to 32 evenly
            # spaced traces (5 bisections each) until it is step_m / 2**refine_steps wide
            bits = int(cfg.refine_steps) + max(0, int(np.ceil(np.log2(step / cfg.step_m - 1e-9))))
            fi = np.flatnonzero(found.ravel())
            o_f = np.repeat(origins, D, axis=0)[fi]
            u_f = u.reshape(-1, 2)[fi]
            d_f = lo.ravel()[fi].copy()
            w = step
            while bits > 0:
                b = min(bits, 5)
                bits -= b
                m = (1 << b) - 1
                sub = (np.arange(1, m + 1) / (m + 1)) * w  # (m,)
                pts = o_f[:, None, :] + u_f[:, None, :] * (d_f[:, None] + sub[None, :])[:, :, None]
                road = self.is_road(pts.reshape(-1, 2)).reshape(len(fi), m)
                n_rays += road.size
                # last sub-sample still on road before the first non-road one
                nonroad = ~road
                firstn = np.where(nonroad.any(axis=1), nonroad.argmax(axis=1), m)
                d_f = d_f + np.where(firstn > 0, sub[np.maximum(firstn - 1, 0)], 0.0)
                w = w / (m + 1)
            dist.ravel()[fi] = d_f
        if include_origin:
            count[~origin_ok] = -1
            found[~origin_ok] = False
        edge = origins[:, None, :] + u * dist[..., None]
        return EdgeProbe(count=count, found=found, dist_m=dist, edge_xy=edge, n_rays=n_rays)

    def road_runs(self, origins: np.ndarray, angles: np.ndarray, max_distance_m: float, gap_m: float,
                  step_m: float = 0.25):
        """Distance to the far edge of a road crossed along one direction per origin, jumping
        non-road gaps narrower than ``gap_m`` (a central median).

        A coarse step (default 0.25 m) is enough here: medians and roads are metres wide, and
        the far edge is located precisely afterwards by the two-direction probe.
        Returns (far_dist (P,), crossed_gap (P,) bool, found (P,) bool).
        """
        step = step_m
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

    def road_across(self, origins: np.ndarray, angles: np.ndarray, max_distance_m: float, gap_m: float,
                    step_m: float = 0.25):
        """Across a road from points on it, one direction per origin (vectorised).

        Returns (near (P,), far (P,), crossed (P,) bool, found (P,) bool): the distance to the
        first non-road step (the edge of this carriageway), to the far edge of the road when
        non-road gaps narrower than ``gap_m`` (a central median) are jumped, whether such a
        gap was jumped, and whether the far edge lies within ``max_distance_m``. An origin
        off road gives near = far = 0. Resolution ``step_m``.
        """
        origins = np.asarray(origins, dtype=np.float64).reshape(-1, 2)
        angles = np.asarray(angles, dtype=np.float64).reshape(-1)
        P = len(origins)
        K = int(np.ceil(max_distance_m / step_m))
        ks = np.arange(1, K + 1) * step_m
        pts = origins[:, None, :] + unit(angles)[:, None, :] * ks[None, :, None]
        road = self.is_road(pts.reshape(-1, 2)).reshape(P, K)
        off = ~road
        first_off = np.where(off.any(axis=1), off.argmax(axis=1), K)  # road steps before the edge
        gap_steps = int(np.ceil(gap_m / step_m))
        # far edge: the last road step before a non-road run longer than gap_steps (or the end)
        run = np.zeros((P, K), np.int64)  # length of the non-road run ending at each step
        for k in range(K):
            run[:, k] = np.where(off[:, k], (run[:, k - 1] if k else 0) + 1, 0)
        long_gap = off & (run > gap_steps)
        stop = np.where(long_gap.any(axis=1), long_gap.argmax(axis=1) - gap_steps, K)  # first step of that run
        idx = np.arange(K)[None, :]
        last_road = np.where(road & (idx < stop[:, None]), idx, -1).max(axis=1)
        near = first_off * step_m
        far = (last_road + 1) * step_m
        crossed = last_road > first_off
        found = stop < K
        on = road[:, 0] if K else np.zeros(P, bool)
        near = np.where(on, near, 0.0)
        far = np.where(on, far, 0.0)
        return near, far, crossed & on, found | ~on

