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
        self.drivable_lut = np.zeros(len(LABEL_IDS), bool)  # label id -> drivable
        self.drivable_lut[self.drivable_ids] = True
        self.n_rays = 0
        self.n_casts = 0

    # ------------------------------------------------------------------ basic traces
    def trace(self, xy: np.ndarray):
        """trace_down with the scene's ignore-set; counts rays."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        self.n_rays += len(xy)
        self.n_casts += 1
        return self.rs.trace_down(xy)

    def labels_and_heights(self, xy: np.ndarray, z_at: np.ndarray):
        """Semantic ids of traces at xy (n, 2) and the hit heights of the traces ``z_at``
        (:meth:`RayScene.trace_labels_z`, the scene's ignore-set); counts rays."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        self.n_rays += len(xy)
        self.n_casts += 1
        return self.rs.trace_labels_z(xy, z_at)

    def is_road(self, xy: np.ndarray) -> np.ndarray:
        shp = np.asarray(xy).shape[:-1]
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        self.n_rays += len(xy)
        self.n_casts += 1
        lab = self.rs.trace_labels(xy)
        return self._road_lut[lab].reshape(shp)

    def _rays(self, n: int) -> np.ndarray:
        """(n, 6) float32 vertical traces down from the scene's top (``RayScene._down_rays``)
        with x, y (columns 0, 1) left for the caller to fill."""
        rays = np.empty((n, 6), np.float32)
        rays[:, 2:] = np.array([self.rs.z_top, 0.0, 0.0, -1.0], np.float32)
        return rays

    def _road_of_rays(self, rays: np.ndarray) -> np.ndarray:
        """(n,) bool: the trace of each row of :meth:`_rays` (filled) hits road; counts rays."""
        self.n_rays += len(rays)
        self.n_casts += 1
        return self._road_lut[self.rs.cast_labels(rays)]

    def _road_along(self, o: np.ndarray, u: np.ndarray, t: np.ndarray, head: np.ndarray | None = None) -> np.ndarray:
        """Road test of the points o + u * t: o, u (n, 2) origins and unit directions, t (k,)
        or (n, k) distances (metres); with ``head`` (h, 2), those points are traced first.
        Returns (n, k) bool (and the (h,) bool of ``head`` first, when given).

        The points are computed in float64 exactly as ``o[:, None] + u[:, None] * t[..., None]``
        and written straight into one float32 ray buffer."""
        n, k = len(o), t.shape[-1]
        h = 0 if head is None else len(head)
        rays = self._rays(h + n * k)
        if h:
            rays[:h, :2] = head
        body = rays[h:].reshape(n, k, 6)
        body[:, :, 0] = o[:, 0:1] + u[:, 0:1] * t  # t (k,) broadcasts over the rows
        body[:, :, 1] = o[:, 1:2] + u[:, 1:2] * t
        road = self._road_of_rays(rays)
        if head is None:
            return road.reshape(n, k)
        return road[:h], road[h:].reshape(n, k)

    # ------------------------------------------------------------------ marching
    def march(self, origins: np.ndarray, angles: np.ndarray, max_distance_m: float | None = None,
              first_only: bool = False, include_origin: bool = False, chunk: int = 48,
              step_m: float | None = None, refine: bool = True, grow: int = 2,
              complete_only: bool = False) -> EdgeProbe:
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
        chunk, grow : the march casts ``chunk`` steps of every unfinished direction at a
                 time, ``grow`` times as many each cast after the first
        complete_only : refine only the points whose every direction met an edge (and whose
                 origin is on road): a caller that needs all of a point's edges has no use
                 for the others, whose dist_m then stays at the last road step

        The march is chunked (``chunk`` steps, then growing) so a probe pays only for the
        distance to its edge; without ``first_only`` the chunks change how many traces are
        cast, never the result (with it, only the ``count`` of the directions stopped early).
        The edge between the last road step and the first non-road step is then
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
        o_rep = np.repeat(origins, D, axis=0)  # (P * D, 2): the origin of every direction
        u_rep = u.reshape(-1, 2)
        count = np.full((P, D), K, np.int64)
        found = np.zeros((P, D), bool)
        count_f, found_f = count.reshape(-1), found.reshape(-1)  # views
        origin_ok = np.ones(P, bool)
        n_rays = 0
        k0 = 0
        ai = np.arange(P * D)  # the directions still marching (flat indices, ascending)
        first_extra = origins if include_origin else None
        while k0 < K and len(ai):
            kk = min(chunk, K - k0)
            ks = (np.arange(k0 + 1, k0 + kk + 1, dtype=np.float64) * step)
            if first_extra is not None:
                origin_ok, road = self._road_along(o_rep[ai], u_rep[ai], ks, head=first_extra)
                n_rays += P
                first_extra = None
            else:
                road = self._road_along(o_rep[ai], u_rep[ai], ks)
            n_rays += road.size
            nonroad = ~road
            first = nonroad.argmax(axis=1)
            hit = nonroad[np.arange(len(ai)), first]  # any non-road step in this chunk
            fr = ai[hit]
            count_f[fr] = k0 + first[hit]
            found_f[fr] = True
            ai = ai[~hit]
            if first_only and len(fr):
                # a point is done once any direction met its edge; its other directions
                # stop here with at least one more road hit than the edge direction had
                done_p = np.zeros(P, bool)
                done_p[fr // D] = True
                stop = done_p[ai // D]
                count_f[ai[stop]] = k0 + kk + 1
                ai = ai[~stop]
            k0 += kk
            chunk *= grow
        lo = count.astype(np.float64) * step
        dist = lo.copy()
        if refine:
            todo = found & (found.all(axis=1) & origin_ok)[:, None] if complete_only else found
            fi = np.flatnonzero(todo.ravel())
            d_f, n = self._bisect(o_rep[fi], u_rep[fi], lo.ravel()[fi], step)
            dist.ravel()[fi] = d_f
            n_rays += n
        if include_origin:
            count[~origin_ok] = -1
            found[~origin_ok] = False
        edge = origins[:, None, :] + u * dist[..., None]
        return EdgeProbe(count=count, found=found, dist_m=dist, edge_xy=edge, n_rays=n_rays)

    def _bisect(self, o: np.ndarray, u: np.ndarray, lo: np.ndarray, step: float):
        """Refine edges known to lie in (lo, lo + step] along o + u t (o, u (n, 2), lo (n,)):
        cut that bracket in passes of up to 32 evenly spaced traces (5 bisections each)
        until it is probe.step_m / 2**refine_steps wide. Each edge's answer depends on its
        own traces only. Returns (dist (n,), rays cast)."""
        cfg = self.cfg
        d_f = np.array(lo, dtype=np.float64)
        if not cfg.refine_steps or not len(d_f):
            return d_f, 0
        bits = int(cfg.refine_steps) + max(0, int(np.ceil(np.log2(step / cfg.step_m - 1e-9))))
        n_rays = 0
        w = step
        while bits > 0:
            b = min(bits, 5)
            bits -= b
            m = (1 << b) - 1
            sub = (np.arange(1, m + 1) / (m + 1)) * w  # (m,)
            road = self._road_along(o, u, d_f[:, None] + sub[None, :])
            n_rays += road.size
            # last sub-sample still on road before the first non-road one
            nonroad = ~road
            firstn = nonroad.argmax(axis=1)
            firstn = np.where(nonroad[np.arange(len(d_f)), firstn], firstn, m)
            d_f = d_f + np.where(firstn > 0, sub[np.maximum(firstn - 1, 0)], 0.0)
            w = w / (m + 1)
        return d_f, n_rays

    def refine(self, origins: np.ndarray, angles: np.ndarray, probe: EdgeProbe, which: np.ndarray,
               step_m: float) -> EdgeProbe:
        """``probe`` (a :meth:`march` of ``origins``/``angles`` in ``step_m`` steps with
        ``refine=False``) with the edges ``which`` (P, D) bool, where found, refined as the
        march would have refined them; the others as they were."""
        origins = np.asarray(origins, dtype=np.float64).reshape(-1, 2)
        angles = np.asarray(angles, dtype=np.float64).reshape(len(origins), -1)
        D = angles.shape[1]
        u = unit(angles)
        fi = np.flatnonzero((probe.found & which).ravel())
        dist = probe.dist_m.copy()
        d_f, n = self._bisect(np.repeat(origins, D, axis=0)[fi], u.reshape(-1, 2)[fi], dist.ravel()[fi],
                              float(step_m))
        dist.ravel()[fi] = d_f
        edge = origins[:, None, :] + u * dist[..., None]
        return EdgeProbe(count=probe.count, found=probe.found, dist_m=dist, edge_xy=edge,
                         n_rays=probe.n_rays + n)

    def _scan(self, origins: np.ndarray, angles: np.ndarray, max_distance_m: float, gap_m: float,
              step_m: float, until_crossed: bool = False):
        """Road runs along one direction per origin, cast in chunks that stop once a row's
        answer is known; what :meth:`road_runs` and :meth:`road_across` report.

        Step k (0-based) lies (k + 1) x step_m from the origin, K steps in all. A row is done
        when its first step is off road, or once a non-road run of more than ``gap_m``
        (``ceil(gap_m / step_m)`` steps) follows a road step (the far edge is then known),
        or, with ``until_crossed``, once road follows a shorter non-road run. Returns, per
        row: on (step 0 on road), first_off (first non-road step, K if none seen), last (last
        road step before a long non-road run, or the last road step seen), crossed (road
        after a short non-road run, before any long one), long (a long run was seen), and
        K. Rows stopped by ``until_crossed`` report first_off and crossed only.
        """
        origins = np.asarray(origins, dtype=np.float64).reshape(-1, 2)
        angles = np.asarray(angles, dtype=np.float64).reshape(-1)
        P = len(origins)
        K = int(np.ceil(max_distance_m / step_m))
        gap_steps = int(np.ceil(gap_m / step_m))
        u = unit(angles)
        on = np.zeros(P, bool)
        first_off = np.full(P, K, np.int64)
        last = np.full(P, -1, np.int64)
        crossed = np.zeros(P, bool)
        long_ = np.zeros(P, bool)
        ai = np.arange(P)
        k0 = 0
        chunk = min(K, gap_steps + 16)
        while k0 < K and len(ai):
            kk = min(chunk, K - k0)
            ks = np.arange(k0 + 1, k0 + kk + 1) * step_m
            road = self._road_along(origins[ai], u[ai], ks)
            cols = np.arange(k0, k0 + kk)
            if k0 == 0:
                on[ai] = road[:, 0]
                keep = road[:, 0]
                ai, road = ai[keep], road[keep]
            # the last road step at or before each step (carried over from earlier chunks)
            lastroad = np.maximum.accumulate(np.where(road, cols[None, :], last[ai][:, None]), axis=1)
            prev = np.concatenate([last[ai][:, None], lastroad[:, :-1]], axis=1)
            off = ~road
            # decisive steps: the end of a long non-road run, road after a short one
            end_long = off & (cols[None, :] - lastroad > gap_steps)
            cross = road & (cols[None, :] - prev > 1)
            stop_at = end_long | cross if until_crossed else end_long
            j = stop_at.argmax(axis=1)
            stopped = stop_at[np.arange(len(ai)), j]
            upto = np.where(stopped, j, kk - 1)  # the last step of this chunk that counts
            within = np.arange(kk)[None, :] <= upto[:, None]
            fo = (off & within).argmax(axis=1)
            has_off = (off & within)[np.arange(len(ai)), fo]
            new_off = has_off & (first_off[ai] == K)
            first_off[ai[new_off]] = k0 + fo[new_off]
            crossed[ai] |= (cross & within).any(axis=1)
            last[ai] = lastroad[np.arange(len(ai)), upto]
            long_[ai] = end_long[np.arange(len(ai)), upto]
            ai = ai[~stopped]
            k0 += kk
            chunk = 16
        return on, first_off, last, crossed, long_, K

    def road_runs(self, origins: np.ndarray, angles: np.ndarray, max_distance_m: float, gap_m: float,
                  step_m: float = 0.25):
        """Distance to the far edge of a road crossed along one direction per origin, jumping
        non-road gaps narrower than ``gap_m`` (a central median).

        A coarse step (default 0.25 m) is enough here: medians and roads are metres wide, and
        the far edge is located precisely afterwards by the two-direction probe.
        Returns (far_dist (P,), crossed_gap (P,) bool, found (P,) bool); an origin off road
        gives far 0, crossed False and found True.
        """
        on, _, last, crossed, _, K = self._scan(origins, angles, max_distance_m, gap_m, step_m)
        far = np.where(on, (last + 1) * step_m, 0.0)
        return far, crossed & on, ~on | (last < K - 1)

    def crosses_gap(self, origins: np.ndarray, angles: np.ndarray, max_distance_m: float, gap_m: float,
                    step_m: float = 0.25) -> np.ndarray:
        """(P,) bool: the ``crossed_gap`` of :meth:`road_runs` alone (road beyond a non-road
        gap narrower than ``gap_m``), with the traces stopping at the first such gap."""
        on, _, _, crossed, _, _ = self._scan(origins, angles, max_distance_m, gap_m, step_m, until_crossed=True)
        return crossed & on

    def road_across(self, origins: np.ndarray, angles: np.ndarray, max_distance_m: float, gap_m: float,
                    step_m: float = 0.25):
        """Across a road from points on it, one direction per origin (vectorised).

        Returns (near (P,), far (P,), crossed (P,) bool, found (P,) bool): the distance to the
        first non-road step (the edge of this carriageway), to the far edge of the road when
        non-road gaps narrower than ``gap_m`` (a central median) are jumped, whether such a
        gap was jumped, and whether the far edge lies within ``max_distance_m``. An origin
        off road gives near = far = 0. Resolution ``step_m``.
        """
        on, first_off, last, crossed, long_, _ = self._scan(origins, angles, max_distance_m, gap_m, step_m)
        near = np.where(on, first_off * step_m, 0.0)
        far = np.where(on, (last + 1) * step_m, 0.0)
        return near, far, crossed & on, long_ | ~on
