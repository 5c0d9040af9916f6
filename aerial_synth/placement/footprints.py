"""Vehicle footprints: overlap index (shapely STRtree) and the placement validator."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene.model import LABEL_IDS
from .model import Placement, footprint_corners_xy

__all__ = ["FootprintIndex", "ValidationReport", "validate_placement", "footprint_points", "footprint_samples", "drivable_area"]


#: Distance tolerance of the gap rule (metres): footprints exactly gap_m apart are accepted.
GAP_TOL_M = 1e-6
#: Default spacing of the traced samples along a footprint's edges and inside it (metres).
#: 0.1 m along the edges: a right-angled (or blunter) kerb or building corner that reaches
#: more than half of that (5 cm) into a footprint always meets a sample.
EDGE_STEP_M = 0.1
INNER_STEP_M = 1.0
#: How far a footprint may reach outside the truth's drivable area in the validator (metres):
#: the depth that EDGE_STEP_M guarantees to catch.
AREA_TOL_M = EDGE_STEP_M / 2


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
    return np.stack([np.concatenate([u, gu.ravel()]), np.concatenate([v, gv.ravel()])], axis=1)


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
    sizes, inv = np.unique(np.stack([ln, w], axis=1), axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    tables = [_unit_samples(float(a), float(b), edge_step_m, inner_step_m) for a, b in sizes]
    count = np.array([len(tables[j]) for j in inv], dtype=np.int64)
    start = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)
    uv = np.concatenate([tables[j] for j in inv])
    owner = np.repeat(np.arange(n), count)
    lx = uv[:, 0] * ln[owner]
    ly = uv[:, 1] * w[owner]
    c, s = np.cos(h)[owner], np.sin(h)[owner]
    pts = np.stack([x[owner] + c * lx - s * ly, y[owner] + s * lx + c * ly], axis=1)
    return pts, owner, start, count


def footprint_samples(x, y, heading, length, width, edge_step_m: float = EDGE_STEP_M,
                      inner_step_m: float = INNER_STEP_M) -> np.ndarray:
    """The samples of :func:`footprint_points` for vehicles of one size, as (n, k, 2)."""
    pts, owner, start, count = footprint_points(x, y, heading, length, width, edge_step_m, inner_step_m)
    if len(count) and not np.all(count == count[0]):
        raise ValueError("footprint_samples: vehicles of different sizes; use footprint_points")
    return pts.reshape(len(count), -1, 2)


class FootprintIndex:
    """Placed footprints (bare rotated rectangles) for the clearance and overlap checks.

    A new footprint collides when it comes closer than ``gap_m`` to a placed one (the
    clearance between two footprints is gap_m: exactly gap_m apart is accepted, within a
    1 µm tolerance), or, with ``gap_m`` = 0, when their interiors overlap (touching is fine).

    shapely's STRtree is immutable, so new footprints go to a short list that is checked
    directly and folded into a rebuilt tree every ``rebuild_every`` insertions.
    """

    def __init__(self, gap_m: float, min_center_distance_m: float | None = None, rebuild_every: int = 128):
        self.gap_m = float(gap_m)
        self.min_center = min_center_distance_m
        self.rebuild_every = rebuild_every
        self._polys: list = []
        self._centers: list[tuple[float, float]] = []
        self._tree = None
        self._tree_n = 0

    def __len__(self) -> int:
        return len(self._polys)

    def polygon(self, x, y, heading, length, width):
        """The bare footprint (no gap added): the gap is a distance between footprints."""
        import shapely

        return shapely.Polygon(footprint_corners_xy(x, y, heading, length, width))

    def point_zone(self, xy, radius_m: float = 2.0):
        """A disc around a seed point: seeds this close to a placed vehicle are skipped."""
        import shapely

        return shapely.Point(float(xy[0]), float(xy[1])).buffer(radius_m, quad_segs=4)

    def _close(self, others, poly) -> bool:
        """Does any of ``others`` (array of polygons) come closer to ``poly`` than the gap?"""
        import shapely

        d = self.gap_m - GAP_TOL_M
        if d > 0:
            return bool(np.any(shapely.dwithin(others, poly, d)))
        hit = others[shapely.intersects(others, poly)]
        return bool(len(hit)) and bool(np.any(shapely.area(shapely.intersection(hit, poly)) > 1e-9))

    def collides(self, poly, center_xy=None) -> bool:
        d = self.gap_m - GAP_TOL_M
        if self._tree is not None:
            if d > 0:
                if len(self._tree.query(poly, predicate="dwithin", distance=d)):
                    return True
            else:
                idx = self._tree.query(poly, predicate="intersects")
                if len(idx) and self._close(np.asarray(self._tree.geometries)[idx], poly):
                    return True
        recent = self._polys[self._tree_n :]
        if recent and self._close(np.array(recent, dtype=object), poly):
            return True
        if self.min_center and center_xy is not None and self._centers:
            c = np.asarray(self._centers)
            d2 = ((c - np.asarray(center_xy)) ** 2).sum(axis=1)
            if d2.min() < self.min_center**2:
                return True
        return False

    def add(self, poly, center_xy) -> None:
        import shapely

        self._polys.append(poly)
        self._centers.append((float(center_xy[0]), float(center_xy[1])))
        if len(self._polys) - self._tree_n >= self.rebuild_every:
            self._tree = shapely.STRtree(self._polys)
            self._tree_n = len(self._polys)


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
