"""Traffic scenarios: traffic lines with double lanes (thesis §3.2.3) and the random baseline.

The engine only probes the RayScene with vertical traces (see :mod:`.linetrace`); road
polygons a generator may know are never read here.

Batching: lines advance in lock-step waves. In each round every active line samples its
spacing, steps ahead, re-probes its two directions, and checks its candidate footprint;
all of those traces go into a handful of casts for the whole wave. Acceptance (overlap
against every placed vehicle) is then decided sequentially in line order, so the result
depends only on the seed.
"""

from __future__ import annotations

import time
import warnings
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from .. import validators as V
from ..errors import PlacementError
from ..scene.hints import road_hints
from ..vehicles import load_catalog
from .config import ScenarioConfig, load_scenario
from .footprints import FootprintIndex, footprint_points
from .linetrace import Prober, unit
from .model import PlacedVehicle, Placement, with_lonlat
from .parking import place_parking
from .parking_config import PARKING_KINDS

# Direction hints (OSM scenes, aerial_synth.scene.hints): the few hooks that read them are
# marked "direction hints"; line traces still find every edge and heading.

__all__ = ["place", "PlacementWarning"]

TWO_PI = 2.0 * np.pi
#: The lane rule keeps this share of the spacing floor centre to centre between vehicles of
#: one lane (a little below 1: a chord on a curve is shorter than the step along it).
LANE_RULE_FRACTION = 0.9
#: Engine marches take steps of COARSE x probe.step_m (see _Engine.coarse_m).
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


class PlacementWarning(UserWarning):
    """Fewer vehicles than asked for fit on the roads."""


def _road_end_needs_edges(lo: np.ndarray, found: np.ndarray, step_m: float, offs: np.ndarray,
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


def _wrap(a):
    return np.mod(a, TWO_PI)


def _angdiff(a, b):
    return np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b)))))


@dataclass
class _Line:
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
class _Cand:
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    ok: np.ndarray
    reason: np.ndarray  # object array of str
    edge_dist: np.ndarray
    #: what :meth:`_Engine.precheck` learnt, for :meth:`_Engine.accept_many`: (pose (n, 3)
    #: [x, y, heading] it saw, footprints (n,) object (None where not built), clear (n,)
    #: bool: no conflict with the index, size of the index then); reused only where the
    #: pose and the index are unchanged
    checked: tuple | None = None


class _Engine:
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
        self.lines: list[_Line] = []
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
    def locate(self, q: np.ndarray, theta: np.ndarray, offset=None) -> _Cand:
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
        return _Cand(pos[:, 0], pos[:, 1], _wrap(head), ok, reason, pr.dist_m[:, 0])

    def relocate_on_curves(self, c: _Cand, head: np.ndarray, offs: np.ndarray, min_turn_deg: float = 2.0,
                           max_disagree_deg: float = 8.0) -> None:
        """On a curve the line through the two edge points runs along the edge near those
        points, which a straight step from the previous vehicle left behind. Where the
        heading turned by more than ``min_turn_deg``, probe again from the vehicle's position
        with the heading found: on a smooth curve the two agree within a few degrees and the
        second is the road's heading at the vehicle; where they disagree by more than
        ``max_disagree_deg`` the edge is no smooth curve (a road joins it, a junction's
        flare) and the line ends there ("junction"). Updates c in place."""
        k = np.flatnonzero(c.ok & (_angdiff(c.heading, head) > np.radians(min_turn_deg)))
        if not len(k):
            return
        r = self.locate(np.stack([c.x[k], c.y[k]], 1), c.heading[k], offs[k])
        agree = r.ok & (_angdiff(r.heading, c.heading[k]) <= np.radians(max_disagree_deg))
        good, bad = k[agree], k[~agree]
        c.x[good], c.y[good], c.heading[good] = r.x[agree], r.y[agree], r.heading[agree]
        c.edge_dist[good] = r.edge_dist[agree]
        c.ok[bad] = False
        c.reason[bad] = "junction"

    def segment_ok(self, c: _Cand, offs: np.ndarray, reach_m: float = 5.0) -> None:
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
        good = (r.ok & (_angdiff(r.heading, hh) <= np.radians(cfg.probe.max_turn_deg))
                & (np.abs(r.edge_dist - oo) <= cfg.probe.edge_jump_m))
        n = len(sel)
        bad = sel[~(good[:n] & good[n:])]
        c.ok[bad] = False
        c.reason[bad] = "junction"

    def check_footprints(self, c: _Cand, L: np.ndarray, W: np.ndarray) -> np.ndarray:
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

    def draw_and_accept(self, c: _Cand, n: int):
        """Draw ``n`` vehicle variants for the candidates ``c``, trace their whole footprints
        and accept what fits: (variants, centre z per candidate, accepted)."""
        variants = self.sample_variants(n)
        L = np.array([v.model.length_m for v in variants])
        W = np.array([v.model.width_m for v in variants])
        z = self.check_footprints(c, L, W)
        return variants, z, self.accept_many(c, variants)

    def precheck(self, c: _Cand, L: np.ndarray, W: np.ndarray) -> None:
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

    def accept_many(self, c: _Cand, variants) -> np.ndarray:
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

    def add_vehicle(self, c: _Cand, i: int, variant, z: float, line: _Line | None, spacing: float):
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
    def wrong_way(self, c: _Cand, mark: bool = True) -> np.ndarray:
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

    def apply_hints(self, c: _Cand, offs: np.ndarray) -> np.ndarray:
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

    # ------------------------------------------------------------------ line starts
    def start_lines(self, seeds: np.ndarray) -> list[_Line]:
        """36-direction probe at each seed → nearest edge → first vehicle of a line."""
        cfg = self.cfg
        P = len(seeds)
        D = int(cfg.probe.directions)
        ang = np.tile(np.arange(D) * (TWO_PI / D), (P, 1))
        # Only the direction with the fewest road hits is used (a first heading guess that
        # the two-direction probe below refines), so this march takes coarse steps: 5 x
        # step_m (0.25 m at the defaults), without edge refinement. That direction is the
        # first to meet a non-road step whatever the chunks, so the march casts 4 steps at a
        # time: a seed stops within 4 steps of its nearest edge (36 traces a step).
        pr = self.prober.march(seeds, ang, first_only=True, chunk=4, grow=1, step_m=self.coarse_m, refine=False)
        best = np.argmin(pr.count, axis=1)  # fewest road hits: perpendicular to the edge
        has_edge = pr.found[np.arange(P), best]
        phi = ang[np.arange(P), best]
        theta0 = phi - self.side * np.pi / 2  # the edge lies on the traffic side
        if cfg.lane_offsets_m:
            offs = self.rng.choice(np.asarray(cfg.lane_offsets_m, float), size=P)
        else:
            offs = np.full(P, cfg.lane_offset_m)
        variants = self.sample_variants(P)  # the next draw either way: drawn here to precheck
        L = np.array([v.model.length_m for v in variants])
        W = np.array([v.model.width_m for v in variants])
        # refine with the two-direction probe from the seed itself
        c = self.locate(seeds, theta0, offs)
        c.ok &= has_edge
        # divided road: a median beyond the traffic-side edge means we face the wrong way
        sel = np.flatnonzero(c.ok)
        if len(sel) and cfg.probe.median_max_m > 0:
            pos = np.stack([c.x[sel], c.y[sel]], 1)
            reach = cfg.probe.max_distance_m + cfg.probe.median_max_m + 2.0
            # road beyond a narrow gap on the traffic side only: that gap is our median (the
            # far side is probed only where the traffic side has one)
            near = self.prober.crosses_gap(pos, c.heading[sel] + self.side * np.pi / 2,  # traffic side
                                           reach, cfg.probe.median_max_m)
            k = np.flatnonzero(near)
            if len(k):
                far = self.prober.crosses_gap(pos[k], c.heading[sel[k]] - self.side * np.pi / 2,  # far side
                                              reach, cfg.probe.median_max_m)
                near[k[far]] = False
            flip = sel[near]
            if len(flip):
                cf = self.locate(np.stack([c.x[flip], c.y[flip]], 1), c.heading[flip] + np.pi, offs[flip])
                c.x[flip], c.y[flip], c.heading[flip] = cf.x, cf.y, cf.heading
                c.ok[flip] &= cf.ok
                c.edge_dist[flip] = cf.edge_dist
        lanes_ok = self.apply_hints(c, offs)  # direction hints
        self.precheck(c, L, W)
        z = self.check_footprints(c, L, W)
        self.segment_ok(c, offs)
        # Check harder than the thesis: at a dead end or where a road leaves the scene the
        # nearest edge is the road's end, and the heading found runs across the road. A real
        # road runs further along the heading than across it.
        sel = np.flatnonzero(c.ok)
        if len(sel):
            pos = np.stack([c.x[sel], c.y[sel]], 1)
            h = c.heading[sel]
            # both reach 2 x probe.max_distance_m (32 m): further than any carriageway is
            # wide, so a vehicle turned across a wide road at its end is refused too
            reach = 2.0 * cfg.probe.max_distance_m
            # one march for the three directions (each direction's edge is its own); an edge
            # is refined only where the comparisons below need it: a refined distance lies in
            # [last road step, + one step), so the bracket often decides them already
            ang3 = np.stack([h, h + np.pi, h - self.side * np.pi / 2], 1)
            pr3 = self.prober.march(pos, ang3, max_distance_m=reach, chunk=12, step_m=self.coarse_m,
                                    refine=False)
            need = _road_end_needs_edges(pr3.dist_m, pr3.found, self.coarse_m, offs[sel], cfg.lane_offset_m)
            if need.any():
                pr3 = self.prober.refine(pos, ang3, pr3, np.repeat(need[:, None], 3, axis=1), self.coarse_m)
            along = pr3.dist_m[:, 0] + pr3.dist_m[:, 1]
            across_d = pr3.dist_m[:, 2]
            across = offs[sel] + across_d
            bad = sel[along <= across]
            c.ok[bad] = False
            c.reason[bad] = "road_end"
            # Multi-lane: an inner lane beyond the middle of the road is only right where a
            # median lies on the far side (a divided carriageway); on an undivided road it
            # would be the opposite lane, driven the wrong way.
            inner = (offs[sel] > cfg.lane_offset_m + 1e-9) & (across_d < offs[sel]) & c.ok[sel]
            if inner.any():
                ii = sel[inner]
                crossed = self.prober.crosses_gap(
                    np.stack([c.x[ii], c.y[ii]], 1), c.heading[ii] - self.side * np.pi / 2,
                    float(offs.max()) + cfg.probe.median_max_m + 2.0, cfg.probe.median_max_m)
                wrong = ii[~crossed & ~lanes_ok[ii]]  # direction hints: tagged lanes say it is ours
                c.ok[wrong] = False
                c.reason[wrong] = "opposite_half"
        acc = self.accept_many(c, variants)
        started = []
        for i in range(P):
            if self.full():
                break
            if not acc[i]:
                self.start_failures[str(c.reason[i]) or "blocked"] += 1
                continue
            line = _Line(
                line_id=len(self.lines), lane=0, target=cfg.vehicles_per_line.sample(self.rng),
                x=c.x[i], y=c.y[i], heading=c.heading[i], edge_dist=offs[i], offset=offs[i],
            )
            self.lines.append(line)
            self.add_vehicle(c, i, variants[i], z[i], line, float("nan"))
            started.append(line)
        return started

    def start_opposite(self, lines: list[_Line]) -> list[_Line]:
        """Double lanes: rotate a random vehicle of each line by 180 degrees, find the
        opposite edge (across a median if there is one) and start the opposite lane."""
        cfg = self.cfg
        picks = []
        for ln in lines:
            if self.rng.random() < cfg.double_lane_probability and ln.placed:
                picks.append((ln, self.vehicles[ln.placed[int(self.rng.integers(len(ln.placed)))]]))
        if picks and self.hints is not None:  # direction hints: no opposite lane on a one-way road
            d = self.hints.direction_at(np.array([[v.x_m, v.y_m] for _, v in picks]))
            picks = [pk for pk, one in zip(picks, np.isfinite(d[:, 0])) if not one]
        if not picks:
            return []
        pos = np.array([[v.x_m, v.y_m] for _, v in picks])
        new_head = np.array([v.heading_rad for _, v in picks]) + np.pi
        toward = new_head + self.side * np.pi / 2  # the new traffic side = the old far side
        reach = 2 * cfg.probe.max_distance_m + cfg.probe.median_max_m
        far, _, found = self.prober.road_runs(pos, toward, reach, cfg.probe.median_max_m)
        offs = np.array([ln.offset for ln, _ in picks])
        q = pos + unit(toward) * np.maximum(far - offs, 0.0)[:, None]
        c = self.locate(q, new_head, offs)
        c.ok &= found & (far > offs)
        c.reason[~found] = "no_edge"
        self.wrong_way(c)  # direction hints: the far side may be a one-way road of its own
        self.segment_ok(c, offs)
        variants, z, acc = self.draw_and_accept(c, len(picks))
        started = []
        for i, (ln, _) in enumerate(picks):
            if self.full():
                break
            if not acc[i]:
                continue
            opp = _Line(
                line_id=ln.line_id, lane=1, target=cfg.vehicles_per_line.sample(self.rng),
                x=c.x[i], y=c.y[i], heading=c.heading[i], edge_dist=ln.offset, offset=ln.offset,
            )
            self.lines.append(opp)
            self.add_vehicle(c, i, variants[i], z[i], opp, float("nan"))
            started.append(opp)
        return started

    def start_adjacent(self, lines: list[_Line]) -> list[_Line]:
        """Every lane (``fill_lanes``): a finished line starts the line of the next lane
        inwards, ``lane_width_m`` further from the traffic-side edge, at its first vehicle
        (the way a double lane starts the opposite lane), while that lane lies on the line's
        side of the road: its half of an undivided road, the whole carriageway up to a
        median, or the room direction hints give (one-way roads, tagged lanes)."""
        cfg = self.cfg
        if not cfg.fill_lanes or self.full():
            return []
        lines = [ln for ln in lines if ln.placed and ln.reason != "limit"]
        if not lines:
            return []
        first = [self.vehicles[ln.placed[0]] for ln in lines]
        pos = np.array([[v.x_m, v.y_m] for v in first])
        head = np.array([v.heading_rad for v in first])
        offs = np.array([ln.offset for ln in lines])
        lw = float(cfg.lane_width_m)
        inward = head - self.side * np.pi / 2
        reach = 2 * cfg.probe.max_distance_m + cfg.probe.median_max_m
        near, far, crossed, found = self.prober.road_across(pos, inward, reach, cfg.probe.median_max_m)
        own = np.where(crossed, offs + near, 0.5 * (offs + far))
        if self.hints is not None:  # direction hints: one-way roads and tagged lanes
            room = self.hints.lane_room(pos, head)
            own = np.where(np.isfinite(room), room, own)
        new_off = offs + lw
        ok = found & (new_off + 0.5 * lw <= own + 0.25 * lw)
        idx = np.flatnonzero(ok)
        if not len(idx):
            return []
        q = pos[idx] + unit(inward[idx]) * lw
        c = self.locate(q, head[idx], new_off[idx])
        turned = _angdiff(c.heading, head[idx]) > np.radians(cfg.probe.max_turn_deg)
        jump = np.abs(c.edge_dist - new_off[idx]) > cfg.probe.edge_jump_m
        bad = c.ok & (turned | jump)
        c.ok[bad] = False
        c.reason[bad] = "junction"
        self.wrong_way(c)  # direction hints
        self.segment_ok(c, new_off[idx])
        variants, z, acc = self.draw_and_accept(c, len(idx))
        started = []
        for i, k in enumerate(idx):
            if self.full():
                break
            if not acc[i]:
                continue
            ln = lines[k]
            nxt = _Line(
                line_id=ln.line_id, lane=ln.lane, lane_index=ln.lane_index + 1,
                target=cfg.vehicles_per_line.sample(self.rng), x=c.x[i], y=c.y[i], heading=c.heading[i],
                edge_dist=new_off[k], offset=new_off[k],
            )
            self.lines.append(nxt)
            self.add_vehicle(c, i, variants[i], z[i], nxt, float("nan"))
            started.append(nxt)
        return started

    # ------------------------------------------------------------------ advancing
    def advance_round(self, active: list[_Line]) -> tuple[list[_Line], list[_Line]]:
        """One lock-step round for every active line (thesis Fig. 3.12 steps a-e):
        sample s, step ahead, re-probe two directions, check and place.
        Returns (still active, finished this round)."""
        cfg = self.cfg
        n = len(active)
        s = cfg.spacing.sample(self.rng, n)
        head = np.array([ln.heading for ln in active])
        prev = np.array([[ln.x, ln.y] for ln in active])
        q = prev + unit(head) * s[:, None]
        offs = np.array([ln.offset for ln in active])
        c = self.locate(q, head, offs)
        self.relocate_on_curves(c, head, offs)
        turned = _angdiff(c.heading, head) > np.radians(cfg.probe.max_turn_deg)
        jump = np.abs(c.edge_dist - offs) > cfg.probe.edge_jump_m
        bad = c.ok & (turned | jump)
        c.ok[bad] = False
        c.reason[bad] = "junction"
        self.wrong_way(c)  # direction hints: a line never runs into a one-way road backwards
        variants = self.sample_variants(n)
        L = np.array([v.model.length_m for v in variants])
        W = np.array([v.model.width_m for v in variants])
        self.precheck(c, L, W)
        z = self.check_footprints(c, L, W)
        acc = self.accept_many(c, variants)
        still, done = [], []
        for i, ln in enumerate(active):
            if self.full():
                ln.reason = ln.reason or "limit"
                done.append(ln)
                continue
            if acc[i]:
                spacing = float(np.hypot(c.x[i] - ln.x, c.y[i] - ln.y))
                self.add_vehicle(c, i, variants[i], z[i], ln, spacing)
                if len(ln.placed) >= ln.target:
                    ln.reason = "complete"
                    done.append(ln)
                else:
                    still.append(ln)
            else:
                ln.reason = str(c.reason[i]) or "blocked"
                done.append(ln)
        self.mark_road_ends([ln for ln in done if ln.reason in ("off_road", "no_edge", "junction")])
        return still, done

    def mark_road_ends(self, lines: list[_Line]) -> None:
        """A line whose next spot failed because the road ahead stops is recorded as ended at
        a ``road_end``: straight ahead of its last vehicle, along its heading, the road gives
        out within one maximum spacing plus half a long vehicle (6 m)."""
        if not lines or self.cfg.spacing is None:
            return
        reach = float(self.cfg.spacing.max_m) + 6.0
        pos = np.array([[ln.x, ln.y] for ln in lines])
        ahead = self.prober.march(pos, np.array([[ln.heading] for ln in lines]), max_distance_m=reach,
                                  chunk=24, step_m=self.coarse_m, refine=False)
        for ln, found in zip(lines, ahead.found[:, 0], strict=True):
            if found:
                ln.reason = "road_end"

    # ------------------------------------------------------------------ scenarios
    def run_lines(self, n_vehicles: int | None, n_lines: int | None, in_flight: int | None = None) -> None:
        """Pipelined traffic lines: keep up to ``in_flight`` lines advancing together (64, or
        one per 10 vehicles asked for, at most 512: a large request takes fewer, larger
        casts); a finished line may spawn its opposite lane and its next lane inwards, and
        new seeds (road points clear of every placed vehicle) refill the pool.

        Early stop: seeding ends when the seeds run out (the scene's seeding budget) or when
        the roads are full: the last 256 or more seeds that were probed started fewer than
        one line per 8 seeds. Asking for far more vehicles than fit therefore costs a bounded
        multiple of what asking for what fits costs."""
        self.limit = n_vehicles
        active: list[_Line] = []
        seeds_exhausted = False
        window: list[tuple[int, int]] = []  # (seeds probed, lines they started) per round
        if in_flight is None:
            in_flight = int(np.clip((n_vehicles or 0) // 10, 64, 512))
        win_min = 256
        while not self.full():
            probed = n_started = 0
            n_fwd = sum(1 for ln in self.lines if ln.lane == 0 and ln.lane_index == 0)
            want = in_flight - len(active)
            if n_lines is not None:
                want = min(want, n_lines - n_fwd)
            if want > 0 and not seeds_exhausted:
                seeds = self.next_seeds(want, free=True)
                if not len(seeds):
                    seeds_exhausted = True
                else:
                    probed = len(seeds)
                    started = self.start_lines(seeds)
                    n_started = len(started)
                    for ln in started:
                        if ln.target <= 1:
                            ln.reason = "complete"
                    active += [ln for ln in started if len(ln.placed) < ln.target]
                    finished_now = [ln for ln in started if len(ln.placed) >= ln.target]
                    active += self._followers(finished_now)
            if active:
                still, done = self.advance_round(active)
                active = still + self._followers(done)
            if probed:
                window.append((probed, n_started))
                while len(window) > 1 and sum(p for p, _ in window[1:]) >= win_min:
                    window.pop(0)
                tried = sum(p for p, _ in window)
                if tried >= win_min and 8 * sum(g for _, g in window) < tried:
                    seeds_exhausted = True
                    self.stopped_full = True
            if not active and (seeds_exhausted or (n_lines is not None and n_fwd >= n_lines)):
                break
        for ln in active:
            ln.reason = ln.reason or "limit"

    def _followers(self, finished: list[_Line]) -> list[_Line]:
        """The lines finished lines start: the opposite lane of a seeded line (double lanes)
        and, with fill_lanes, the next lane inwards of every line. Lines complete at their
        first vehicle finish at once and start their own followers."""
        out: list[_Line] = []
        while finished and not self.full():
            new = self.start_opposite([ln for ln in finished if ln.lane == 0 and ln.lane_index == 0])
            new += self.start_adjacent(finished)
            for ln in new:
                if len(ln.placed) >= ln.target:
                    ln.reason = "complete"
            out += [ln for ln in new if len(ln.placed) < ln.target]
            finished = [ln for ln in new if len(ln.placed) >= ln.target]
        return out

    def run_random(self, n_vehicles: int) -> None:
        self.limit = n_vehicles
        fails = 0
        while not self.full():
            seeds = self.next_seeds(max(64, min(1024, 2 * (n_vehicles - len(self.vehicles)))))
            if not len(seeds):
                break
            head = self.rng.uniform(0.0, TWO_PI, len(seeds))
            c = _Cand(seeds[:, 0].copy(), seeds[:, 1].copy(), head, np.ones(len(seeds), bool),
                      np.full(len(seeds), "", object), np.zeros(len(seeds)))
            variants, z, acc = self.draw_and_accept(c, len(seeds))
            placed_before = len(self.vehicles)
            for i in range(len(seeds)):
                if self.full():
                    break
                if acc[i]:
                    self.add_vehicle(c, i, variants[i], z[i], None, float("nan"))
            fails = fails + len(seeds) if len(self.vehicles) == placed_before else 0
            if fails > 20000:
                break


def place(
    rayscene,
    scenario: str | ScenarioConfig = "jam",
    rng: np.random.Generator | None = None,
    n_vehicles: int | None = None,
    n_lines: int | None = None,
    catalog=None,
    overrides: dict | None = None,
    seed: int | None = None,
    scene_name: str | None = None,
    obstacles=None,
    region=None,
) -> Placement:
    """Place vehicles on the roads of ``rayscene`` for one traffic scenario.

    scenario  : a bundled name (jam, normal, sparse, random), a YAML path or a ScenarioConfig
    rng       : the random generator; if None, ``np.random.default_rng(seed)``
    n_vehicles / n_lines : how much to place (at most one; default from the scenario).
                For lines scenarios n_lines counts seeded lines; opposite lanes come on top.
    catalog   : vehicle catalog (default: the bundled one)
    obstacles : vehicles already standing (PlacedVehicle, e.g. parked ones): footprints keep
                gap_m from them (the ``mixed`` scenario, placement/parking.py)
    region    : tiled placement (placement/tiled.py), traffic scenarios: ``((x0, y0, x1, y1),
                owns)``: line seeds are drawn inside the rectangle only, and only vehicles
                whose centres ``owns(xy) -> (n,) bool`` accepts are placed (a line ends
                at the border: reason "tile_border"); the traces still see the whole scene
    Returns a :class:`Placement`. If the roads hold fewer vehicles than asked for, it places
    what fits, records the shortfall in ``stats`` and emits a :class:`PlacementWarning`.
    """
    if n_vehicles is not None and n_lines is not None:
        raise PlacementError("give either a vehicle count or a line count, not both")

    n_vehicles = None if n_vehicles is None else V.integer("--vehicles", n_vehicles, 1, error=PlacementError)
    n_lines = None if n_lines is None else V.integer("--lines", n_lines, 1, error=PlacementError)
    seed = None if seed is None else V.integer("--seed", seed, 0, error=PlacementError)
    cfg = load_scenario(scenario, overrides)
    if rng is None:
        rng = np.random.default_rng(seed)
    if catalog is None:
        catalog = load_catalog()
    if cfg.kind in PARKING_KINDS:  # parking, street-parking, mixed: placement/parking.py

        return place_parking(rayscene, cfg, rng, catalog, seed=seed, scene_name=scene_name,
                             n_vehicles=n_vehicles, n_lines=n_lines, place_traffic=place)
    t0 = time.perf_counter()
    eng = _Engine(rayscene, cfg, rng, catalog, region=region)
    for v in obstacles or ():
        eng.index.add(eng.index.polygon(v.x_m, v.y_m, v.heading_rad, v.length_m, v.width_m), (v.x_m, v.y_m))
    if cfg.kind == "random":
        n = n_vehicles or cfg.vehicles or (n_lines * 30 if n_lines else 400)
        eng.run_random(int(n))
        asked = int(n)
    else:
        if n_vehicles is None and n_lines is None:
            n_vehicles, n_lines = cfg.vehicles, (cfg.lines if cfg.vehicles is None else None)
        eng.run_lines(n_vehicles, n_lines)
        asked = n_vehicles
    if not eng.road_seen:
        raise PlacementError(
            f"scene {rayscene.scene.name!r}: {eng.seeds_tried} vertical traces over its extent found no "
            f"road (labels {sorted(rayscene.label_config.road)})"
        )
    elapsed = time.perf_counter() - t0
    spac = np.array([v.spacing_m for v in eng.vehicles if np.isfinite(v.spacing_m)])
    reasons: dict[str, int] = {}
    for ln in eng.lines:
        reasons[ln.reason or "complete"] = reasons.get(ln.reason or "complete", 0) + 1
    stats = {
        "vehicles": len(eng.vehicles),
        "requested_vehicles": asked,
        "lines": sum(1 for ln in eng.lines if ln.lane == 0 and ln.lane_index == 0),
        "opposite_lanes": sum(1 for ln in eng.lines if ln.lane == 1 and ln.lane_index == 0),
        "inner_lanes": sum(1 for ln in eng.lines if ln.lane_index > 0),
        "line_end_reasons": dict(sorted(reasons.items())),
        # per line: [line id, lane, why it ended, vehicles]
        "line_table": [[ln.line_id, ln.lane, ln.reason or "complete", len(ln.placed)] for ln in eng.lines],
        "spacing_m": {
            "n": int(len(spac)),
            "mean": round(float(spac.mean()), 4) if len(spac) else None,
            "sd": round(float(spac.std(ddof=1)), 4) if len(spac) > 1 else None,
            "min": round(float(spac.min()), 4) if len(spac) else None,
            "max": round(float(spac.max()), 4) if len(spac) else None,
        },
        "seed_traces": int(eng.seeds_tried),
        "stopped_full": bool(eng.stopped_full),
        "seed_failures": dict(sorted(eng.start_failures.items())),
        "rays": int(eng.prober.n_rays),
        "casts": int(eng.prober.n_casts),
    }
    timing = {"seconds": elapsed, "vehicles_per_s": len(eng.vehicles) / elapsed if elapsed else 0.0,
              "rays_per_s": eng.prober.n_rays / elapsed if elapsed else 0.0}
    placement = Placement(
        scene=scene_name or rayscene.scene.name,
        scenario=cfg.name,
        seed=seed,
        parameters=cfg.to_dict(),
        vehicles=with_lonlat(eng.vehicles, rayscene.scene.crs),  # lon/lat where the CRS is known
        stats=stats,
        timing=timing,
        georeference=rayscene.scene.georeference(),
    )
    if asked is not None and eng.counted < asked:
        msg = (f"the roads of {placement.scene!r} held {eng.counted} of the {asked} vehicles asked "
               f"for ({cfg.name})")
        stats["shortfall"] = asked - eng.counted
        warnings.warn(msg, PlacementWarning, stacklevel=2)
    return placement
