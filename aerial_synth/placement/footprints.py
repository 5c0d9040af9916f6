"""Vehicle footprints: overlap index (shapely STRtree) and the placement validator."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..scene.model import LABEL_IDS
from .model import Placement, footprint_corners_xy

__all__ = ["FootprintIndex", "ValidationReport", "validate_placement", "footprint_points", "footprint_samples",
           "footprints_on", "drivable_area"]


#: Distance tolerance of the gap rule (metres): footprints exactly gap_m apart are accepted.
GAP_TOL_M = 1e-6
#: Default spacing of the traced samples along a footprint's edges and inside it (metres).
#: 0.1 m along the edges: a right-angled (or blunter) kerb or building corner that reaches
#: more than half of that (5 cm) into a footprint always meets a sample. The interior is
#: traced as finely: a gap between two road polygons (a crack) that crosses the body is a
#: band, and a band wider than 0.1 m meets a sample of a 0.1 m grid whatever its angle;
#: any hole wider than 0.1 m x sqrt(2) does too. (With a 1 m interior grid, cracks under the
#: body that narrow to under 0.1 m where they reach the outline slipped through; issue 36.)
EDGE_STEP_M = 0.1
INNER_STEP_M = EDGE_STEP_M
#: How far a footprint may reach outside the truth's drivable area in the validator (metres):
#: the depth that EDGE_STEP_M guarantees to catch.
AREA_TOL_M = EDGE_STEP_M / 2


@lru_cache(maxsize=1024)
def _unit_samples(length: float, width: float, edge_step_m: float, inner_step_m: float) -> np.ndarray:
    """(k, 2) sample positions of one footprint as fractions (u along, v across) in
    [-0.5, 0.5]: 4 corners (front-left, front-right, rear-right, rear-left), the centre,
    the 4 edge midpoints, the edges every <= edge_step_m, an inner grid <= inner_step_m."""
    kl = max(2, int(np.ceil(length / edge_step_m)))
    kw = max(2, int(np.ceil(width / edge_step_m)))
    tl = np.arange(1, kl) / kl - 0.5
    tw = np.arange(1, kw) / kw - 0.5
    u = [0.5, 0.5, -0.5, -0.5, 0.0, 0.5, 0.0, -0.5, 0.0]
    v = [0.5, -0.5, -0.5, 0.5, 0.0, 0.0, -0.5, 0.0, 0.5]
    u += list(tl) + list(tl) + [0.5] * len(tw) + [-0.5] * len(tw)
    v += [0.5] * len(tl) + [-0.5] * len(tl) + list(tw) + list(tw)
    il = max(1, int(np.ceil(length / inner_step_m)))
    iw = max(1, int(np.ceil(width / inner_step_m)))
    gu, gv = np.meshgrid((np.arange(il) + 0.5) / il - 0.5, (np.arange(iw) + 0.5) / iw - 0.5, indexing="ij")
    out = np.stack([np.concatenate([u, gu.ravel()]), np.concatenate([v, gv.ravel()])], axis=1)
    out.setflags(write=False)  # cached: shared by every call for this size
    return out


@lru_cache(maxsize=1024)
def _scaled_samples(length: float, width: float, edge_step_m: float, inner_step_m: float) -> np.ndarray:
    """(k, 2) the samples of :func:`_unit_samples` in metres along and across the vehicle
    (u x length, v x width), cached per size."""
    uv = _unit_samples(length, width, edge_step_m, inner_step_m)
    out = np.stack([uv[:, 0] * length, uv[:, 1] * width], axis=1)
    out.setflags(write=False)
    return out


def footprint_points(x, y, heading, length, width, edge_step_m: float = EDGE_STEP_M,
                     inner_step_m: float = INNER_STEP_M):
    """Points that stand for the whole footprint of each of n vehicles, metres.

    Returns ``(points (m, 2), owner (m,), start (n,), count (n,))``: vehicle i's points are
    ``points[start[i] : start[i] + count[i]]``, in the order of :func:`_unit_samples`:
    the 4 corners, the centre (index 4), the 4 edge midpoints, points along every edge no
    more than ``edge_step_m`` apart, then an inner grid no more than ``inner_step_m`` apart.
    A kerb or a building corner that cuts into a footprint crosses its edge; a right-angled
    corner reaching more than ``edge_step_m`` / 2 into it always meets an edge sample. The
    inner grid catches posts and trunks inside. Each vehicle gets the samples its own size
    needs (a car about 140, a 12 m truck about 330 at the defaults).
    """
    x, y, h, ln, w = (np.atleast_1d(np.asarray(a, dtype=np.float64)) for a in (x, y, heading, length, width))
    x, y, h, ln, w = np.broadcast_arrays(x, y, h, ln, w)
    n = len(x)
    if n == 0:
        return np.zeros((0, 2)), np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)
    # the distinct sizes (complex keys sort like (length, width) rows, much faster)
    sizes, inv = np.unique(ln + 1j * w, return_inverse=True)
    inv = inv.reshape(-1)
    tables = [_scaled_samples(float(k.real), float(k.imag), float(edge_step_m), float(inner_step_m))
              for k in sizes]
    sizes_k = np.array([len(t) for t in tables], dtype=np.int64)
    count = sizes_k[inv]
    start = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)
    owner = np.repeat(np.arange(n), count)
    # every vehicle's rows of its size's table, gathered from all tables at once
    t_start = np.concatenate([[0], np.cumsum(sizes_k)[:-1]]).astype(np.int64)
    lxy = np.concatenate(tables)[t_start[inv][owner] + (np.arange(len(owner)) - start[owner])]
    lx, ly = lxy[:, 0], lxy[:, 1]
    c, s = np.cos(h)[owner], np.sin(h)[owner]
    pts = np.empty((len(owner), 2))
    pts[:, 0] = x[owner] + c * lx - s * ly
    pts[:, 1] = y[owner] + s * lx + c * ly
    return pts, owner, start, count


def footprint_samples(x, y, heading, length, width, edge_step_m: float = EDGE_STEP_M,
                      inner_step_m: float = INNER_STEP_M) -> np.ndarray:
    """The samples of :func:`footprint_points` for vehicles of one size, as (n, k, 2)."""
    pts, owner, start, count = footprint_points(x, y, heading, length, width, edge_step_m, inner_step_m)
    if len(count) and not np.all(count == count[0]):
        raise ValueError("footprint_samples: vehicles of different sizes; use footprint_points")
    return pts.reshape(len(count), -1, 2)


def footprints_on(labels_of, x, y, heading, length, width, allowed) -> np.ndarray:
    """(n,) bool: every sample of :func:`footprint_points` of each vehicle (the outline and
    the interior every 0.1 m, as the validator traces them) lands on an allowed label.

    labels_of : callable, (m, 2) points -> (m,) label ids (a vertical trace)
    allowed   : label ids allowed for every vehicle, or a (n, k) bool table: row i says which
                label ids (columns) vehicle i may stand on
    """
    pts, owner, _, count = footprint_points(x, y, heading, length, width)
    n = len(count)
    if n == 0:
        return np.zeros(0, bool)
    lab = np.asarray(labels_of(pts), np.int64)
    table = np.asarray(allowed)
    if table.dtype == bool and table.ndim == 2:
        ok = table[owner, lab]
    else:
        ok = np.isin(lab, table)
    return np.bincount(owner[~ok], minlength=n) == 0


class FootprintIndex:
    """Placed footprints (bare rotated rectangles) for the clearance and overlap checks.

    A new footprint collides when it comes closer than ``gap_m`` to a placed one (the
    clearance between two footprints is gap_m: exactly gap_m apart is accepted, within a
    1 µm tolerance), or, with ``gap_m`` = 0, when their interiors overlap (touching is fine);
    with ``min_center_distance_m`` also when the centres are closer than that; with
    ``lane_spacing`` also when it stands in the lane of a placed vehicle heading its way
    closer than the spacing floor (the headings of both must be given).

    Candidate pairs come from the footprints' centres and bounding radii (a scipy cKDTree
    over the older footprints, plus a brute-force pass over the recent ones: the tree is
    rebuilt once those reach an eighth of it, at least 64 and at most ``rebuild_every``);
    only those pairs get the exact shapely test, vectorised.
    :meth:`select` decides a whole batch at once with the same result as testing and adding
    its footprints one after the other.
    """

    def __init__(self, gap_m: float, min_center_distance_m: float | None = None, rebuild_every: int = 512,
                 lane_spacing=None):
        self.gap_m = float(gap_m)
        self.min_center = min_center_distance_m
        #: optional (min_m, half_lane_m, max_turn_rad): two vehicles heading the same way
        #: (within max_turn_rad) in one lane (centres less than half_lane_m apart across
        #: the heading) keep min_m centre to centre (a traffic scenario's spacing floor)
        self.lane_spacing = lane_spacing
        self._h = np.zeros(64)
        self.rebuild_every = rebuild_every
        self._geoms = np.empty(64, dtype=object)
        self._xy = np.zeros((64, 2))
        self._r = np.zeros(64)
        self._n = 0
        self._tree = None
        self._tree_n = 0
        self._rmax = 0.0

    def __len__(self) -> int:
        return self._n

    @property
    def geometries(self) -> list:
        """The indexed footprints, in insertion order."""
        return list(self._geoms[: self._n])

    _polys = geometries  # the name earlier versions used

    # ------------------------------------------------------------------ geometry
    def polygon(self, x, y, heading, length, width):
        """The bare footprint (no gap added): the gap is a distance between footprints."""
        import shapely

        return shapely.Polygon(footprint_corners_xy(x, y, heading, length, width))

    def polygons(self, x, y, heading, length, width):
        """Footprints of n vehicles at once: (geometries (n,), centres (n, 2), radii (n,))."""
        import shapely

        x, y, h, ln, w = (np.atleast_1d(np.asarray(a, dtype=np.float64)) for a in (x, y, heading, length, width))
        x, y, h, ln, w = np.broadcast_arrays(x, y, h, ln, w)
        geoms = shapely.polygons(footprint_corners_xy(x, y, h, ln, w)) if len(x) else np.empty(0, object)
        return np.asarray(geoms, dtype=object), np.stack([x, y], 1), 0.5 * np.hypot(ln, w)

    def point_zone(self, xy, radius_m: float = 2.0):
        """A disc around a seed point: seeds this close to a placed vehicle are skipped."""
        import shapely

        return shapely.Point(float(xy[0]), float(xy[1])).buffer(radius_m, quad_segs=4)

    @staticmethod
    def _describe(geom, center_xy):
        import shapely

        pts = shapely.get_coordinates(geom)
        c = np.asarray(center_xy, float) if center_xy is not None else pts.mean(axis=0)
        return c, float(np.sqrt(((pts - c) ** 2).sum(axis=1).max())) if len(pts) else 0.0

    # ------------------------------------------------------------------ pair tests
    def _exact(self, a, b) -> np.ndarray:
        """Do the geometries a[k] and b[k] come closer than the gap (overlap when gap 0)?"""
        import shapely

        d = self.gap_m - GAP_TOL_M
        if not len(a):
            return np.zeros(0, bool)
        if d > 0:
            return np.asarray(shapely.dwithin(a, b, d), bool)
        hit = np.asarray(shapely.intersects(a, b), bool)
        if hit.any():
            k = np.flatnonzero(hit)
            hit[k] = shapely.area(shapely.intersection(a[k], b[k])) > 1e-9
        return hit

    def _conflicts(self, qxy, qr, ixy, ir, qg, ig, i, j, centers: bool, qh=None, ih=None) -> np.ndarray:
        """Which candidate pairs (query i, item j) conflict: the gap rule on the footprints,
        the centre-distance rule where ``centers``, the lane rule where headings are given."""
        dxy = qxy[i] - ixy[j]
        dd = np.sqrt((dxy**2).sum(axis=1))
        out = np.zeros(len(i), bool)
        if self.min_center and centers:
            out |= dd < self.min_center
        if self.lane_spacing is not None and centers and qh is not None and ih is not None:
            lo, half, turn = self.lane_spacing
            a, b = qh[i], ih[j]
            same = np.abs(np.angle(np.exp(1j * (a - b)))) < turn
            across = np.abs(-np.sin(b) * dxy[:, 0] + np.cos(b) * dxy[:, 1])
            out |= same & (dd < lo) & (across < half)
        near = ~out & (dd <= qr[i] + ir[j] + max(self.gap_m, 0.0) + 1e-6)
        k = np.flatnonzero(near)
        out[k] = self._exact(qg[i[k]], ig[j[k]])
        return out

    def _reach(self) -> float:
        return max(self.gap_m, 0.0) + 1e-6

    def _candidates(self, qxy, qr, centers: bool):
        """Candidate pairs (query index, item index) whose bounding discs come within reach."""
        n = self._n
        if n == 0 or not len(qxy):
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        rq = qr + self._rmax + self._reach()
        if self.min_center and centers:
            rq = np.maximum(rq, self.min_center)
        if self.lane_spacing is not None and centers:
            rq = np.maximum(rq, self.lane_spacing[0])
        ii, jj = [], []
        if self._tree is not None:
            lists = self._tree.query_ball_point(qxy, rq, return_sorted=False)
            lens = np.fromiter((len(v) for v in lists), np.int64, len(lists))
            if lens.sum():
                ii.append(np.repeat(np.arange(len(qxy)), lens))
                ii_j = np.fromiter((k for v in lists for k in v), np.int64, int(lens.sum()))
                jj.append(ii_j)
        m0 = self._tree_n
        if n > m0:  # recent footprints: brute force (see add_many for how many)
            rxy = self._xy[m0:n]
            d2 = ((qxy[:, None, :] - rxy[None, :, :]) ** 2).sum(axis=2)
            a, b = np.nonzero(d2 <= (rq[:, None]) ** 2)
            ii.append(a)
            jj.append(b + m0)
        if not ii:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        return np.concatenate(ii).astype(np.int64), np.concatenate(jj).astype(np.int64)

    # ------------------------------------------------------------------ queries
    def collides_many(self, geoms, xy, r, centers: bool = True, heading=None) -> np.ndarray:
        """(n,) bool: each geometry collides with an indexed footprint (batch not mutual)."""
        geoms = np.asarray(geoms, dtype=object)
        xy = np.asarray(xy, float).reshape(-1, 2)
        r = np.asarray(r, float).reshape(-1)
        out = np.zeros(len(geoms), bool)
        i, j = self._candidates(xy, r, centers)
        if len(i):
            qh = None if heading is None else np.asarray(heading, float).reshape(-1)
            hit = self._conflicts(xy, r, self._xy, self._r, geoms, self._geoms, i, j, centers, qh, self._h)
            out[i[hit]] = True
        return out

    def near_points(self, xy, radius_m: float = 2.0) -> np.ndarray:
        """(n,) bool: a disc of ``radius_m`` around each point comes closer than the gap to
        an indexed footprint (seed points that close to a placed vehicle are skipped)."""
        import shapely

        xy = np.asarray(xy, float).reshape(-1, 2)
        if not len(xy):
            return np.zeros(0, bool)
        r = np.full(len(xy), float(radius_m))
        out = np.zeros(len(xy), bool)
        i, j = self._candidates(xy, r, centers=False)
        if len(i):
            dd = np.sqrt(((xy[i] - self._xy[j]) ** 2).sum(axis=1))
            k = np.flatnonzero(dd <= r[i] + self._r[j] + self._reach())
            if len(k):
                d = radius_m + max(self.gap_m, 0.0) - GAP_TOL_M
                pts = np.asarray(shapely.points(xy[i[k]]), dtype=object)  # the pairs' points only
                hit = np.asarray(shapely.dwithin(pts, self._geoms[j[k]], d), bool)
                out[i[k[hit]]] = True
        return out

    def collides(self, poly, center_xy=None) -> bool:
        c, r = self._describe(poly, center_xy)
        return bool(self.collides_many(np.array([poly], dtype=object), c[None], [r],
                                       centers=center_xy is not None)[0])

    def select(self, geoms, xy, r, ok=None, max_n: int | None = None, heading=None, counts=None,
               clear=None) -> np.ndarray:
        """Decide a batch in order: footprint k is accepted when it keeps the rules with every
        indexed footprint and every footprint of the batch accepted before it (as testing and
        adding them one by one would); acceptance stops once ``max_n`` accepted ones that
        ``counts`` (default: all) have been reached. Candidates with ``ok`` False are skipped
        (their geometries are never read: None will do). ``clear`` (n,) bool marks candidates
        already known to keep the rules with every indexed footprint (:meth:`collides_many`
        said so, with the same headings, and nothing was indexed since); they skip that test.
        The accepted ones are added; returns (n,) bool."""
        from scipy.spatial import cKDTree

        geoms = np.asarray(geoms, dtype=object)
        xy = np.asarray(xy, float).reshape(-1, 2)
        r = np.asarray(r, float).reshape(-1)
        n = len(geoms)
        ok = np.ones(n, bool) if ok is None else np.asarray(ok, bool).copy()
        acc = np.zeros(n, bool)
        if not n or not ok.any() or (max_n is not None and max_n <= 0):
            return acc
        h = None if heading is None else np.asarray(heading, float).reshape(-1)
        sel = np.flatnonzero(ok if clear is None else ok & ~np.asarray(clear, bool))
        ok[sel[self.collides_many(geoms[sel], xy[sel], r[sel], heading=None if h is None else h[sel])]] = False
        sel = np.flatnonzero(ok)
        earlier: dict[int, list[int]] = {}
        if len(sel) > 1:
            reach = 2.0 * float(r[sel].max()) + self._reach()
            if self.min_center:
                reach = max(reach, float(self.min_center))
            if self.lane_spacing is not None and h is not None:
                reach = max(reach, float(self.lane_spacing[0]))
            pairs = cKDTree(xy[sel]).query_pairs(reach, output_type="ndarray")
            if len(pairs):
                a, b = sel[pairs[:, 0]], sel[pairs[:, 1]]
                lo, hi = np.minimum(a, b), np.maximum(a, b)
                hit = self._conflicts(xy, r, xy, r, geoms, geoms, hi, lo, True, h, h)
                for p, q in zip(hi[hit].tolist(), lo[hit].tolist()):
                    earlier.setdefault(p, []).append(q)
        count = 0
        cnt = np.ones(n, np.int64) if counts is None else np.asarray(counts, bool).astype(np.int64)
        for k in sel.tolist():
            if any(acc[q] for q in earlier.get(k, ())):
                continue
            acc[k] = True
            count += int(cnt[k])
            if max_n is not None and count >= max_n:
                break
        idx = np.flatnonzero(acc)
        self.add_many(geoms[idx], xy[idx], r[idx], None if h is None else h[idx])
        return acc

    # ------------------------------------------------------------------ insertion
    def add(self, poly, center_xy) -> None:
        c, r = self._describe(poly, center_xy)
        self.add_many(np.array([poly], dtype=object), c[None], [r])

    def add_many(self, geoms, xy, r, heading=None) -> None:
        """Index footprints (headings: for the lane rule; NaN = none, never in a lane)."""
        from scipy.spatial import cKDTree

        k = len(geoms)
        if not k:
            return
        need = self._n + k
        if need > len(self._geoms):
            cap = max(need, 2 * len(self._geoms))
            g = np.empty(cap, dtype=object)
            g[: self._n] = self._geoms[: self._n]
            self._geoms = g
            self._xy = np.concatenate([self._xy[: self._n], np.zeros((cap - self._n, 2))])
            self._r = np.concatenate([self._r[: self._n], np.zeros(cap - self._n)])
            self._h = np.concatenate([self._h[: self._n], np.zeros(cap - self._n)])
        self._geoms[self._n:need] = geoms
        self._xy[self._n:need] = np.asarray(xy, float).reshape(-1, 2)
        self._r[self._n:need] = np.asarray(r, float).reshape(-1)
        self._h[self._n:need] = np.nan if heading is None else np.asarray(heading, float).reshape(-1)
        self._rmax = max(self._rmax, float(np.max(r)))
        self._n = need
        if self._n - self._tree_n >= min(self.rebuild_every, max(64, self._tree_n // 8)):
            self._tree = cKDTree(self._xy[: self._n].copy())
            self._tree_n = self._n


@dataclass(frozen=True)
class ValidationReport:
    """What the validator found for one placement.

    footprint_ok     : (n,) bool, the whole footprint is on drivable surface: every traced
                       sample of :func:`footprint_samples` (corners, edge midpoints, centre,
                       edges every 0.1 m, an inner grid) hits a drivable label, and, where the
                       scene has truth, the footprint polygon lies inside the drivable area
                       (within 5 cm)
    footprint_drivable : fraction of vehicles with footprint_ok (the figure to watch: 1.0)
    on_road_fraction : (n,) fraction of each footprint's traced samples on drivable labels
    area_drivable    : (n,) fraction of each footprint's area inside the truth's drivable area
                       (nan without truth)
    corners_drivable : fraction of all footprint corners (and centres) on drivable labels
    overlaps         : number of vehicle pairs whose bare footprints intersect
    gap_violations   : number of pairs closer than the placement's gap_m (0 when unknown)
    heading_error_deg: (n,) against the true road direction (nan where the scene knows none)
    lateral_offset_m : (n,) distance from the centre to the nearest road edge (truth if
                       known, else nan)
    """

    n: int
    footprint_ok: np.ndarray
    on_road_fraction: np.ndarray
    area_drivable: np.ndarray
    corners_drivable: float
    overlaps: int
    gap_violations: int
    heading_error_deg: np.ndarray
    lateral_offset_m: np.ndarray

    @property
    def footprint_drivable(self) -> float:
        return float(self.footprint_ok.mean()) if self.n else 1.0

    def summary(self) -> dict:
        def stats(a):
            a = a[np.isfinite(a)]
            if not len(a):
                return None
            return {
                "median": round(float(np.median(a)), 4),
                "p99": round(float(np.percentile(a, 99)), 4),
                "max": round(float(a.max()), 4),
                "mean": round(float(a.mean()), 4),
            }

        area = self.area_drivable[np.isfinite(self.area_drivable)]
        return {
            "vehicles": self.n,
            "footprint_drivable": round(self.footprint_drivable, 6),
            "footprint_off_drivable": int((~self.footprint_ok).sum()),
            "footprint_on_road_min": round(float(self.on_road_fraction.min()), 4) if self.n else None,
            "footprint_on_road_mean": round(float(self.on_road_fraction.mean()), 4) if self.n else None,
            "footprint_area_drivable_min": round(float(area.min()), 6) if len(area) else None,
            "corners_drivable": round(self.corners_drivable, 6),
            "overlaps": self.overlaps,
            "gap_violations": self.gap_violations,
            "heading_error_deg": stats(self.heading_error_deg),
            "lateral_offset_m": stats(self.lateral_offset_m),
        }


def drivable_area(truth, label_config):
    """The truth's drivable area (road, plus parking where parking is drivable), or None."""
    import shapely

    if truth is None or truth.road_area is None:
        return None
    parts = []
    if label_config.drivable & {"road", "lane_marking"}:
        parts.append(truth.road_area)
    if "parking" in label_config.drivable and getattr(truth, "parking_area", None) is not None:
        parts.append(truth.parking_area)
    if not parts:
        return None
    return shapely.union_all(parts)


def _heading_errors(truth, x, y, h, traffic: str) -> np.ndarray:
    """Heading error (degrees, [0, 180]) of each vehicle against the true direction of the
    road it stands on. Inside a junction a vehicle stands on several roads at once (its
    centre within half a width of more than one centre line); it is then measured against
    the one it follows best. Outside every carriageway the nearest centre line is used."""
    import shapely

    pts = shapely.points(np.stack([x, y], 1))
    n = len(x)
    errs = np.full((len(truth.roads), n), np.nan)
    inside = np.zeros((len(truth.roads), n), bool)
    dist = np.full((len(truth.roads), n), np.inf)
    for k, road in enumerate(truth.roads):
        line = road.centerline
        dist[k] = shapely.distance(line, pts)
        inside[k] = dist[k] <= road.width_m / 2 + 0.5
        s = shapely.line_locate_point(line, pts)
        a = shapely.get_coordinates(shapely.line_interpolate_point(line, np.maximum(s - 0.5, 0)))
        b = shapely.get_coordinates(shapely.line_interpolate_point(line, np.minimum(s + 0.5, line.length)))
        t = np.arctan2(b[:, 1] - a[:, 1], b[:, 0] - a[:, 0])
        if road.oneway:
            expected = t
        else:
            proj = shapely.get_coordinates(shapely.line_interpolate_point(line, s))
            side = np.cos(t) * (y - proj[:, 1]) - np.sin(t) * (x - proj[:, 0])  # > 0: left
            along = side < 0 if traffic == "right" else side >= 0
            expected = np.where(along, t, t + np.pi)
        errs[k] = np.degrees(np.abs(np.angle(np.exp(1j * (h - expected)))))
    nearest = errs[np.argmin(dist, axis=0), np.arange(n)]
    best_inside = np.where(inside, errs, np.inf).min(axis=0)
    return np.where(inside.any(axis=0), best_inside, nearest)


def validate_placement(rayscene, placement: Placement, truth=None, traffic: str = "right",
                       edge_step_m: float = EDGE_STEP_M, area_tol_m: float = AREA_TOL_M) -> ValidationReport:
    """Check a placement against the scene (traces) and, where known, the scene's truth.

    A vehicle's footprint is on drivable surface when every one of its traced samples
    (:func:`footprint_samples`) hits a drivable label and, with truth, its polygon lies
    inside the truth's drivable area grown by ``area_tol_m`` (5 cm: what 0.1 m edge samples
    are sure to catch; ``area_drivable`` reports the exact area fraction).

    Heading error is measured against the true centre line's tangent, taking the driving
    side into account: on a two-way road a right-hand vehicle must drive along the tangent
    when it is right of the line, against it when left of it; a one-way carriageway's line
    runs in its traffic direction. Errors are in [0, 180] degrees. In a junction, where the
    vehicle stands on several roads, the best-matching road counts (see _heading_errors).
    """
    import shapely

    vs = placement.vehicles
    n = len(vs)
    if n == 0:
        e = np.zeros(0)
        return ValidationReport(0, np.zeros(0, bool), e, e, 1.0, 0, 0, e, e)
    x = np.array([v.x_m for v in vs])
    y = np.array([v.y_m for v in vs])
    h = np.array([v.heading_rad for v in vs])
    L = np.array([v.length_m for v in vs])
    W = np.array([v.width_m for v in vs])
    drv = np.array(sorted(LABEL_IDS[s] for s in rayscene.label_config.drivable))

    pts, owner, start, count = footprint_points(x, y, h, L, W, edge_step_m=edge_step_m)
    tr = rayscene.trace_down(pts)
    on = np.isin(tr.label_id, drv)
    on_frac = np.bincount(owner, weights=on, minlength=n) / count
    corners_ok = float(on[start[:, None] + np.arange(5)].mean())  # 4 corners and the centre
    ok = np.bincount(owner[~on], minlength=n) == 0

    corners = footprint_corners_xy(x, y, h, L, W)  # (n, 4, 2)
    polys = shapely.polygons(corners)
    area_frac = np.full(n, np.nan)
    area = drivable_area(truth, rayscene.label_config)
    if area is not None:
        inside = shapely.area(shapely.intersection(polys, area)) / shapely.area(polys)
        area_frac = np.asarray(inside, dtype=float)
        ok &= shapely.within(polys, shapely.buffer(area, area_tol_m))

    tree = shapely.STRtree(polys)
    a, b = tree.query(polys, predicate="intersects")
    pairs = a < b
    overlaps = 0
    if pairs.any():
        inter = shapely.area(shapely.intersection(polys[a[pairs]], polys[b[pairs]]))
        overlaps = int((inter > 1e-6).sum())
    gap = placement.parameters.get("gap_m") if isinstance(placement.parameters, dict) else None
    gap_viol = 0
    if isinstance(gap, (int, float)) and gap - GAP_TOL_M > 0:
        a, b = tree.query(polys, predicate="dwithin", distance=float(gap) - GAP_TOL_M)
        gap_viol = int((a < b).sum())

    herr = np.full(n, np.nan)
    lat = np.full(n, np.nan)
    if truth is not None and truth.roads:
        herr = _heading_errors(truth, x, y, h, traffic)
        lat = shapely.distance(shapely.points(np.stack([x, y], 1)), truth.road_area.boundary)
    return ValidationReport(
        n=n,
        footprint_ok=ok,
        on_road_fraction=on_frac,
        area_drivable=area_frac,
        corners_drivable=corners_ok,
        overlaps=overlaps,
        gap_violations=gap_viol,
        heading_error_deg=herr,
        lateral_offset_m=np.asarray(lat, dtype=float),
    )
