"""The traffic placement engine's state and per-vehicle steps (seeding, locating the road
edge, checking and accepting footprints, direction hints), with the records they share.

The lines that grow from them (thesis §3.2.3) are :mod:`.traffic_lines`; the entry point is
:func:`aerial_synth.placement.traffic.place`.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from ..scene.hints import road_hints
from .config import ScenarioConfig
from .footprints import FootprintIndex, footprint_points
from .linetrace import Prober, unit
from .model import PlacedVehicle

# Direction hints (OSM scenes, aerial_synth.scene.hints): the few hooks that read them are
# marked "direction hints"; line traces still find every edge and heading.

__all__ = ["EngineCore", "Line", "Candidate", "lane_rule", "road_end_needs_edges", "wrap_angle",
           "angle_diff", "TWO_PI", "LANE_RULE_FRACTION", "COARSE"]

TWO_PI = 2.0 * np.pi
#: The lane rule keeps this share of the spacing floor centre to centre between vehicles of
#: one lane (a little below 1: a chord on a curve is shorter than the step along it).
LANE_RULE_FRACTION = 0.9
#: Engine marches take steps of COARSE x probe.step_m (see EngineCore.coarse_m).
COARSE = 5


def lane_rule(cfg: ScenarioConfig):
    """The lane rule of a traffic scenario's footprint index (:class:`FootprintIndex`
    ``lane_spacing``): vehicles heading the same way in one lane keep
    ``LANE_RULE_FRACTION`` x the spacing floor centre to centre; None for scenarios
    without lines or a floor. Placement and the tiled merge use the same rule."""
    if cfg.kind == "lines" and cfg.spacing is not None and cfg.spacing.lower_m > 0:
        return (LANE_RULE_FRACTION * cfg.spacing.lower_m, 0.5 * cfg.lane_width_m,
                np.radians(cfg.probe.max_turn_deg))
    return None


def road_end_needs_edges(lo: np.ndarray, found: np.ndarray, step_m: float, offs: np.ndarray,
                          lane_offset_m: float) -> np.ndarray:
    """Which rows of start_lines' road-end test need their edges refined: (n,) bool.

    lo (n, 3): the unrefined distances of a march along, against and across the heading
    (the last road step; the march's reach where no edge was found), found (n, 3). A
    refined distance d lies in [lo, lo + step_m) where found and is lo where not, so the
    tests ``d0 + d1 <= offs + d2`` (road end) and ``d2 < offs`` (inner lane, where offs
    exceeds lane_offset_m) give with lo what they give with d wherever the bracket decides
    them; only the other rows need the refinement."""
    hi = lo + np.where(found, step_m, 0.0)
    end_known = (hi[:, 0] + hi[:, 1] <= offs + lo[:, 2]) | (lo[:, 0] + lo[:, 1] > offs + hi[:, 2])
    inner_known = (hi[:, 2] <= offs) | (lo[:, 2] >= offs)
    return ~end_known | ((offs > lane_offset_m + 1e-9) & ~inner_known)


def wrap_angle(a):
    return np.mod(a, TWO_PI)


def angle_diff(a, b):
    return np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b)))))


@dataclass
class Line:
    line_id: int
    lane: int
    target: int
    x: float
    y: float
    heading: float
    edge_dist: float = 0.0
    offset: float = 1.75  # distance d of this line's lane from the road edge
    lane_index: int = 0  # 0 = the lane at the traffic-side edge, 1 = the next one inwards, ...
    placed: list = field(default_factory=list)  # indices into the vehicle list
    reason: str = ""


@dataclass
class Candidate:
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    ok: np.ndarray
    reason: np.ndarray  # object array of str
    edge_dist: np.ndarray
    #: what :meth:`EngineCore.precheck` learnt, for :meth:`EngineCore.accept_many`: (pose (n, 3)
    #: [x, y, heading] it saw, footprints (n,) object (None where not built), clear (n,)
    #: bool: no conflict with the index, size of the index then); reused only where the
    #: pose and the index are unchanged
    checked: tuple | None = None


class EngineCore:
    """The state of one traffic placement and its per-vehicle steps: seeds, edge location,
    footprint checks, acceptance, direction hints. :class:`~.traffic_lines.TrafficEngine`
    adds the lines that grow from it."""

    def __init__(self, rayscene, cfg: ScenarioConfig, rng: np.random.Generator, catalog, region=None):
        self.rs = rayscene
        self.cfg = cfg
        self.rng = rng
        self.catalog = catalog
        self.prober = Prober(rayscene, cfg.probe)
        # Lines keep their spacing floor to vehicles in the same lane, whichever line those
        # belong to (a seed between two vehicles of a line must not squeeze a third in).
        self.index = FootprintIndex(cfg.gap_m, cfg.min_center_distance_m, lane_spacing=lane_rule(cfg))
        self.vehicles: list[PlacedVehicle] = []
        self.lines: list[Line] = []
        self.side = -1.0 if cfg.traffic == "right" else 1.0  # edge side: right = heading - 90 deg
        self.drivable_ids = self.prober.drivable_ids
        # Marches step COARSE x probe.step_m (0.25 m at the defaults) and refine the edges
        # they find to the same precision as the thesis's 0.05 m march (linetrace.Prober.march)
        self.coarse_m = COARSE * cfg.probe.step_m
        b = rayscene.scene_bounds()
        self.xy_lo, self.xy_hi = b[0, :2], b[1, :2]
        # tiled placement: seeds only inside the tile's core, vehicles only where the core
        # owns them (region = ((x0, y0, x1, y1), owns(xy) -> (n,) bool)); the rest of the
        # window is there to be seen by the traces (roads and edges beyond the border)
        self.owns = None
        if region is not None:
            rect, self.owns = region
            self.xy_lo = np.maximum(self.xy_lo, np.asarray(rect[:2], float))
            self.xy_hi = np.maximum(self.xy_lo, np.minimum(self.xy_hi, np.asarray(rect[2:], float)))
        self.counted = 0
        self._seed_pool = np.zeros((0, 2))
        self.seeds_tried = 0
        self.start_failures: Counter = Counter()
        self.seed_batches = 0
        self.road_seen = False
        self.limit = None
        self.stopped_full = False
        area_ha = float(np.prod(np.maximum(self.xy_hi - self.xy_lo, 0.0))) / 1e4
        #: random traces seeding may draw: max_seed_attempts, or more on a large scene
        self.seed_budget = max(int(cfg.max_seed_attempts), int(np.ceil(cfg.seed_attempts_per_ha * area_ha)))

        self.hints = road_hints(rayscene.scene)

    # ------------------------------------------------------------------ seeds
    def next_seeds(self, n: int, free: bool = False) -> np.ndarray:
        """Up to n random road points (vertical traces over the scene's extent, keep road);
        with ``free``, only points clear of every placed vehicle (a 2 m disc keeps the gap).
        Draws at most the seeding budget (:attr:`seed_budget`) of traces."""
        out = []
        have = 0
        empty_batches = 0
        while have < n and (len(self._seed_pool) or self.seeds_tried < self.seed_budget):
            if len(self._seed_pool) == 0:
                k = self.cfg.seed_batch
                xy = self.rng.uniform(self.xy_lo, self.xy_hi, size=(k, 2))
                self.seeds_tried += k
                self.seed_batches += 1
                road = self.prober.is_road(xy)
                self._seed_pool = xy[road]
                if len(self._seed_pool):
                    self.road_seen = True
                    empty_batches = 0
                else:
                    empty_batches += 1
                    if empty_batches >= 3 and not self.road_seen:
                        break
                    continue
            take = self._seed_pool[: n - have]
            self._seed_pool = self._seed_pool[len(take):]
            if free:
                take = take[~self.index.near_points(take, 2.0)]
            out.append(take)
            have += len(take)
        return np.concatenate(out) if out else np.zeros((0, 2))

    # ------------------------------------------------------------------ geometry
    def locate(self, q: np.ndarray, theta: np.ndarray, offset=None) -> Candidate:
        """Two-direction re-probe (thesis Fig. 3.11) from points q with heading guesses theta.

        Directions: perpendicular to theta towards the traffic-side edge, and that turned by
        side_angle_deg towards theta. The line through the two edge points is the local
        road direction; the vehicle stands lane_offset_m inside it, at the foot of the
        perpendicular from q (so the spacing along the line is the sampled one).
        """
        cfg = self.cfg
        q = np.asarray(q, float).reshape(-1, 2)
        theta = np.asarray(theta, float).reshape(-1)
        a1 = theta + self.side * np.pi / 2
        a2 = a1 - self.side * np.radians(cfg.probe.side_angle_deg)
        # only a point with both edges (and on road) can give a candidate: only its edges
        # are refined (the others' positions are never read)
        pr = self.prober.march(q, np.stack([a1, a2], axis=1), include_origin=True, chunk=12, step_m=self.coarse_m,
                               complete_only=True)
        e1, e2 = pr.edge_xy[:, 0], pr.edge_xy[:, 1]
        t = e2 - e1
        tn = np.linalg.norm(t, axis=1)
        on = pr.count[:, 0] >= 0
        ok = on & pr.found.all(axis=1) & (tn > 1e-4)
        reason = np.where(ok, "", np.where(on, "no_edge", "off_road")).astype(object)
        tu = t / np.where(tn > 0, tn, 1.0)[:, None]
        head = np.arctan2(tu[:, 1], tu[:, 0])
        foot = e1 + ((q - e1) * tu).sum(axis=1, keepdims=True) * tu
        inward = unit(head - self.side * np.pi / 2)  # towards the road's interior
        d = cfg.lane_offset_m if offset is None else np.asarray(offset, float).reshape(-1, 1)
        pos = foot + d * inward
        return Candidate(pos[:, 0], pos[:, 1], wrap_angle(head), ok, reason, pr.dist_m[:, 0])

    def relocate_on_curves(self, c: Candidate, head: np.ndarray, offs: np.ndarray, min_turn_deg: float = 2.0,
                           max_disagree_deg: float = 8.0) -> None:
        """On a curve the line through the two edge points runs along the edge near those
        points, which a straight step from the previous vehicle left behind. Where the
        heading turned by more than ``min_turn_deg``, probe again from the vehicle's position
        with the heading found: on a smooth curve the two agree within a few degrees and the
        second is the road's heading at the vehicle; where they disagree by more than
        ``max_disagree_deg`` the edge is no smooth curve (a road joins it, a junction's
        flare) and the line ends there ("junction"). Updates c in place."""
        k = np.flatnonzero(c.ok & (angle_diff(c.heading, head) > np.radians(min_turn_deg)))
        if not len(k):
            return
        r = self.locate(np.stack([c.x[k], c.y[k]], 1), c.heading[k], offs[k])
        agree = r.ok & (angle_diff(r.heading, c.heading[k]) <= np.radians(max_disagree_deg))
        good, bad = k[agree], k[~agree]
        c.x[good], c.y[good], c.heading[good] = r.x[agree], r.y[agree], r.heading[agree]
        c.edge_dist[good] = r.edge_dist[agree]
        c.ok[bad] = False
        c.reason[bad] = "junction"

    def segment_ok(self, c: Candidate, offs: np.ndarray, reach_m: float = 5.0) -> None:
        """Check harder than the thesis at a line's first vehicle: re-probe ``reach_m`` ahead
        of and behind it as a line step would; the road direction there must agree and the
        edge must stay where it is. A seed in a junction, at a road end or at the scene's
        border fails this. Marks failures in c.ok / c.reason ("junction")."""
        cfg = self.cfg
        sel = np.flatnonzero(c.ok)
        if not len(sel):
            return
        pos = np.stack([c.x[sel], c.y[sel]], 1)
        h = c.heading[sel]
        u = unit(h)
        q = np.concatenate([pos + reach_m * u, pos - reach_m * u])
        hh = np.concatenate([h, h])
        oo = np.concatenate([offs[sel], offs[sel]])
        r = self.locate(q, hh, oo)
        good = (r.ok & (angle_diff(r.heading, hh) <= np.radians(cfg.probe.max_turn_deg))
                & (np.abs(r.edge_dist - oo) <= cfg.probe.edge_jump_m))
        n = len(sel)
        bad = sel[~(good[:n] & good[n:])]
        c.ok[bad] = False
        c.reason[bad] = "junction"

    def check_footprints(self, c: Candidate, L: np.ndarray, W: np.ndarray) -> np.ndarray:
        """The whole footprint must trace (through ignorable vegetation only) to drivable
        labels: corners, centre, edge midpoints, the edges every 0.1 m and an inner grid
        (:func:`.footprints.footprint_points`), so a kerb or a building corner that cuts
        into the body between the corners refuses the vehicle. Returns z of the centre hit;
        marks failures in c.ok / c.reason."""
        sel = np.flatnonzero(c.ok)
        z = np.full(len(c.ok), np.nan)
        if not len(sel):
            return z
        pts, owner, start, _ = footprint_points(c.x[sel], c.y[sel], c.heading[sel], L[sel], W[sel])
        lab, zc = self.prober.labels_and_heights(pts, start + 4)  # sample 4 is the centre
        on = self.prober.drivable_lut[lab]
        good = np.bincount(owner[~on], minlength=len(sel)) == 0
        z[sel] = zc
        bad = sel[~good]
        c.ok[bad] = False
        c.reason[bad] = "off_road"
        return z

    def sample_variants(self, n: int):
        return self.catalog.sample(self.rng, n) if n else []

    def draw_and_accept(self, c: Candidate, n: int):
        """Draw ``n`` vehicle variants for the candidates ``c``, trace their whole footprints
        and accept what fits: (variants, centre z per candidate, accepted)."""
        variants = self.sample_variants(n)
        L = np.array([v.model.length_m for v in variants])
        W = np.array([v.model.width_m for v in variants])
        z = self.check_footprints(c, L, W)
        return variants, z, self.accept_many(c, variants)

    def precheck(self, c: Candidate, L: np.ndarray, W: np.ndarray) -> None:
        """Refuse ("blocked") the candidates that already collide with a placed vehicle before
        any trace is spent on them: the index only grows, so :meth:`accept_many` would refuse
        them too (same result, fewer rays)."""
        sel = np.flatnonzero(c.ok)
        if not len(sel) or not len(self.index):
            return
        geoms, xy, r = self.index.polygons(c.x[sel], c.y[sel], c.heading[sel], L[sel], W[sel])
        blocked = self.index.collides_many(geoms, xy, r, heading=c.heading[sel])
        hit = sel[blocked]
        c.ok[hit] = False
        c.reason[hit] = "blocked"
        all_geoms = np.full(len(c.x), None, dtype=object)
        all_geoms[sel] = geoms
        clear = np.zeros(len(c.x), bool)
        clear[sel[~blocked]] = True
        c.checked = (np.stack([c.x, c.y, c.heading], 1), all_geoms, clear, len(self.index))

    def accept_many(self, c: Candidate, variants) -> np.ndarray:
        """Overlap and gap test of a batch of candidates in order (each against every placed
        vehicle and the candidates accepted before it), at most as many as the limit leaves.
        Accepted footprints join the index; the others that were ok are marked "blocked".
        Returns (n,) bool."""
        n = len(c.x)
        L = np.array([v.model.length_m for v in variants]) if n else np.zeros(0)
        W = np.array([v.model.width_m for v in variants]) if n else np.zeros(0)
        xy = np.stack([np.asarray(c.x, np.float64), np.asarray(c.y, np.float64)], 1).reshape(-1, 2)
        r = 0.5 * np.hypot(L, W)  # as FootprintIndex.polygons
        # footprints only where they can be used (the candidates still ok), reusing the
        # precheck's where the pose is the same; its "clear" holds while the index is as then
        geoms = np.full(n, None, dtype=object)
        clear = None
        if c.checked is not None:
            pose, pg, pclear, n_index = c.checked
            same = (pose == np.stack([c.x, c.y, c.heading], 1)).all(axis=1) & (pg != None)  # noqa: E711
            geoms[same] = pg[same]
            if n_index == len(self.index):
                clear = pclear & same
        todo = np.flatnonzero(c.ok & (geoms == None))  # noqa: E711
        if len(todo):
            geoms[todo] = self.index.polygons(c.x[todo], c.y[todo], c.heading[todo], L[todo], W[todo])[0]
        max_n = None if self.limit is None else max(0, self.limit - self.counted)
        counts = None
        if self.owns is not None and n:
            # tiled placement: a vehicle the core does not own would be dropped; its line
            # ends at the core's border instead ("tile_border")
            counts = self.owns(xy)
            out = c.ok & ~counts
            c.ok[out] = False
            c.reason[out] = "tile_border"
        acc = self.index.select(geoms, xy, r, ok=c.ok, max_n=max_n, heading=c.heading, counts=counts,
                                clear=clear)
        tried = c.ok.copy()
        if max_n is not None and acc.sum() >= max_n and acc.any():
            tried[np.flatnonzero(acc)[-1] + 1:] = False  # the limit stopped the batch there
        blocked = tried & ~acc
        c.ok[blocked] = False
        c.reason[blocked] = "blocked"
        return acc

    def add_vehicle(self, c: Candidate, i: int, variant, z: float, line: Line | None, spacing: float):
        m = variant.model
        pv = PlacedVehicle(
            id=len(self.vehicles) + 1,
            model=m.name,
            color=variant.color.name,
            cls=m.cls,
            length_m=float(m.length_m),
            width_m=float(m.width_m),
            height_m=float(m.height_m),
            x_m=float(c.x[i]),
            y_m=float(c.y[i]),
            z_m=float(z),
            heading_rad=float(c.heading[i]),
            line_id=line.line_id if line is not None else -1,
            lane=line.lane if line is not None else 0,
            direction=("forward" if line.lane == 0 else "opposite") if line is not None else "random",
            spacing_m=float(spacing),
            **self._original(float(c.x[i]), float(c.y[i]), float(z)),
        )
        self.vehicles.append(pv)
        self.counted += 1 if self.owns is None else int(self.owns(np.array([[pv.x_m, pv.y_m]]))[0])
        if line is not None:
            line.placed.append(len(self.vehicles) - 1)
            line.x, line.y, line.heading = pv.x_m, pv.y_m, pv.heading_rad
        return pv

    def _original(self, x: float, y: float, z: float) -> dict:
        """The vehicle's position in the scene's original frame (``Scene.to_original``: local
        + origin, float64; the origin is read once)."""
        o = getattr(self, "_origin", None)
        if o is None:
            o = self._origin = tuple(float(v) for v in np.asarray(self.rs.scene.origin, np.float64))
        return {"x_orig_m": x + o[0], "y_orig_m": y + o[1], "z_orig_m": z + o[2]}

    # ------------------------------------------------------------------ direction hints
    def wrong_way(self, c: Candidate, mark: bool = True) -> np.ndarray:
        """Direction hints: candidates heading against a one-way road's direction, or driving
        on the wrong half of a two-way road (centre more than 0.5 m across its centre line,
        heading within 45 degrees of the road's axis; e.g. a road the map's edge cut
        lengthwise). Marks them (reasons "wrong_way", "wrong_side") unless ``mark`` is False.
        Returns (n,) bool."""
        bad = np.zeros(len(c.x), bool)
        if self.hints is None:
            return bad
        sel = np.flatnonzero(c.ok)
        if not len(sel):
            return bad
        d, left, one = self.hints.frame_at(np.stack([c.x[sel], c.y[sel]], 1))
        along = (d * unit(c.heading[sel])).sum(axis=1)  # NaN off every hinted road
        against = one & (along < 0)
        # right-hand traffic (side -1) keeps right of the line it follows: left * sign < 0
        side = ~one & (np.abs(along) > 0.7) & (left * np.sign(along) * self.side < -0.5)
        bad[sel] = against | side
        if mark:
            c.ok[sel[against]] = False
            c.reason[sel[against]] = "wrong_way"
            c.ok[sel[side]] = False
            c.reason[sel[side]] = "wrong_side"
        return bad

    def apply_hints(self, c: Candidate, offs: np.ndarray) -> np.ndarray:
        """Direction hints at a line's first vehicle. Geometry gives the road's axis but not
        which way a one-way road runs: where the hint is one-way and the heading found points
        against it (or, on a two-way road, the vehicle stands on the wrong half), take the
        other along-road heading (re-probe towards the other edge, as the median rule
        does). Lanes: an offset beyond the lanes the road has in that
        direction (``lanes:forward``/``lanes:backward``; all of a one-way road) is refused
        ("lane_count"). Returns (n,) bool: the offset lies within those lanes, so an inner
        lane needs no median to be on the right side of the road."""
        lanes_ok = np.zeros(len(c.x), bool)
        if self.hints is None:
            return lanes_ok
        sel = np.flatnonzero(c.ok)
        if not len(sel):
            return lanes_ok
        back = np.flatnonzero(self.wrong_way(c, mark=False))
        if len(back):
            cf = self.locate(np.stack([c.x[back], c.y[back]], 1), c.heading[back] + np.pi, offs[back])
            c.x[back], c.y[back], c.heading[back] = cf.x, cf.y, cf.heading
            c.ok[back] &= cf.ok
            c.reason[back] = np.where(cf.ok, c.reason[back], cf.reason)
            c.edge_dist[back] = cf.edge_dist
        self.wrong_way(c)
        sel = np.flatnonzero(c.ok)
        if len(sel) and self.cfg.lane_offsets_m:
            room = self.hints.lane_room(np.stack([c.x[sel], c.y[sel]], 1), c.heading[sel])
            over = np.isfinite(room) & (offs[sel] > room)
            c.ok[sel[over]] = False
            c.reason[sel[over]] = "lane_count"
            lanes_ok[sel] = np.isfinite(room) & ~over
        return lanes_ok

    def full(self) -> bool:
        return self.limit is not None and self.counted >= self.limit
