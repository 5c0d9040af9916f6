"""Vehicle footprints: overlap index (shapely STRtree) and the placement validator."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene.model import LABEL_IDS
from .model import Placement, footprint_corners_xy

__all__ = ["FootprintIndex", "ValidationReport", "validate_placement"]


class FootprintIndex:
    """Placed footprints (rotated rectangles grown by gap/2 each side) for overlap checks.

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
        import shapely

        c = footprint_corners_xy(x, y, heading, length + self.gap_m, width + self.gap_m)
        return shapely.Polygon(c)

    def point_zone(self, xy, radius_m: float = 2.0):
        """A disc around a seed point: seeds this close to a placed vehicle are skipped."""
        import shapely

        return shapely.Point(float(xy[0]), float(xy[1])).buffer(radius_m, quad_segs=4)

    def collides(self, poly, center_xy=None) -> bool:
        import shapely

        if self._tree is not None and len(self._tree.query(poly, predicate="intersects")):
            return True
        recent = self._polys[self._tree_n :]
        if recent and bool(np.any(shapely.intersects(np.array(recent, dtype=object), poly))):
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

    on_road_fraction : (n,) fraction of each footprint's sample points on drivable labels
    corners_drivable : fraction of all footprint corners (and centres) on drivable labels
    overlaps         : number of vehicle pairs whose bare footprints intersect
    heading_error_deg: (n,) against the true road direction (nan where the scene knows none)
    lateral_offset_m : (n,) distance from the centre to the nearest road edge (truth if
                       known, else probed)
    """

    n: int
    on_road_fraction: np.ndarray
    corners_drivable: float
    overlaps: int
    heading_error_deg: np.ndarray
    lateral_offset_m: np.ndarray

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

        return {
            "vehicles": self.n,
            "footprint_on_road_min": round(float(self.on_road_fraction.min()), 4) if self.n else None,
            "footprint_on_road_mean": round(float(self.on_road_fraction.mean()), 4) if self.n else None,
            "corners_drivable": round(self.corners_drivable, 6),
            "overlaps": self.overlaps,
            "heading_error_deg": stats(self.heading_error_deg),
            "lateral_offset_m": stats(self.lateral_offset_m),
        }


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
                       grid: tuple[int, int] = (8, 4)) -> ValidationReport:
    """Check a placement against the scene (traces) and, where known, the scene's truth.

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
        return ValidationReport(0, e, 1.0, 0, e, e)
    x = np.array([v.x_m for v in vs])
    y = np.array([v.y_m for v in vs])
    h = np.array([v.heading_rad for v in vs])
    L = np.array([v.length_m for v in vs])
    W = np.array([v.width_m for v in vs])
    drv = np.array(sorted(LABEL_IDS[s] for s in rayscene.label_config.drivable))

    # sample grid inside each footprint (cell centres)
    gi, gj = grid
    u = (np.arange(gi) + 0.5) / gi - 0.5
    w = (np.arange(gj) + 0.5) / gj - 0.5
    uu, ww = np.meshgrid(u, w, indexing="ij")
    lx = uu.ravel()[None, :] * L[:, None]
    ly = ww.ravel()[None, :] * W[:, None]
    c, s = np.cos(h)[:, None], np.sin(h)[:, None]
    px = x[:, None] + c * lx - s * ly
    py = y[:, None] + s * lx + c * ly
    tr = rayscene.trace_down(np.stack([px.ravel(), py.ravel()], axis=1))
    on = np.isin(tr.label_id, drv).reshape(n, -1)
    on_frac = on.mean(axis=1)

    corners = footprint_corners_xy(x, y, h, L, W)  # (n, 4, 2)
    pts = np.concatenate([corners.reshape(-1, 2), np.stack([x, y], 1)])
    tc = rayscene.trace_down(pts)
    corners_ok = float(np.isin(tc.label_id, drv).mean())

    polys = shapely.polygons(corners)
    tree = shapely.STRtree(polys)
    a, b = tree.query(polys, predicate="intersects")
    pairs = a < b
    overlaps = 0
    if pairs.any():
        inter = shapely.area(shapely.intersection(polys[a[pairs]], polys[b[pairs]]))
        overlaps = int((inter > 1e-6).sum())

    herr = np.full(n, np.nan)
    lat = np.full(n, np.nan)
    if truth is not None and truth.roads:
        herr = _heading_errors(truth, x, y, h, traffic)
        lat = shapely.distance(shapely.points(np.stack([x, y], 1)), truth.road_area.boundary)
    return ValidationReport(
        n=n,
        on_road_fraction=on_frac,
        corners_drivable=corners_ok,
        overlaps=overlaps,
        heading_error_deg=herr,
        lateral_offset_m=np.asarray(lat, dtype=float),
    )
