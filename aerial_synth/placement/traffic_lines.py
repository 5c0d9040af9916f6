"""Traffic lines (thesis §3.2.3): seeding lines, their opposite and adjacent lanes, and
advancing every line in lock-step rounds; and the random baseline.

Batching: lines advance in lock-step waves. In each round every active line samples its
spacing, steps ahead, re-probes its two directions, and checks its candidate footprint;
all of those traces go into a handful of casts for the whole wave. Acceptance (overlap
against every placed vehicle) is then decided sequentially in line order, so the result
depends only on the seed.
"""

from __future__ import annotations

import numpy as np

from .linetrace import unit
from .traffic_engine import TWO_PI, Candidate, EngineCore, Line, angle_diff, road_end_needs_edges

__all__ = ["TrafficEngine"]


class TrafficEngine(EngineCore):
    """:class:`EngineCore` plus the lines: :meth:`run_lines` (the scenarios with lines) and
    :meth:`run_random` (the random baseline)."""

    # ------------------------------------------------------------------ line starts
    def start_lines(self, seeds: np.ndarray) -> list[Line]:
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
        self.turn_at_medians(c, offs)
        lanes_ok = self.apply_hints(c, offs)  # direction hints
        self.precheck(c, L, W)
        z = self.check_footprints(c, L, W)
        self.segment_ok(c, offs)
        self.refuse_road_ends(c, offs, lanes_ok)
        acc = self.accept_many(c, variants)
        started = []
        for i in range(P):
            if self.full():
                break
            if not acc[i]:
                self.start_failures[str(c.reason[i]) or "blocked"] += 1
                continue
            line = Line(
                line_id=len(self.lines), lane=0, target=cfg.vehicles_per_line.sample(self.rng),
                x=c.x[i], y=c.y[i], heading=c.heading[i], edge_dist=offs[i], offset=offs[i],
            )
            self.lines.append(line)
            self.add_vehicle(c, i, variants[i], z[i], line, float("nan"))
            started.append(line)
        return started

    def turn_at_medians(self, c: Candidate, offs: np.ndarray) -> None:
        """Divided road: a median beyond the traffic-side edge means a start faces the wrong
        way; turn it round (``c`` updated in place)."""
        cfg = self.cfg
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

    def refuse_road_ends(self, c: Candidate, offs: np.ndarray, lanes_ok: np.ndarray) -> None:
        """Refuse starts at a road's end and inner lanes on the wrong half of an undivided
        road (``c.ok`` and ``c.reason`` updated in place)."""
        cfg = self.cfg
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
            need = road_end_needs_edges(pr3.dist_m, pr3.found, self.coarse_m, offs[sel], cfg.lane_offset_m)
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

    def start_opposite(self, lines: list[Line]) -> list[Line]:
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
            opp = Line(
                line_id=ln.line_id, lane=1, target=cfg.vehicles_per_line.sample(self.rng),
                x=c.x[i], y=c.y[i], heading=c.heading[i], edge_dist=ln.offset, offset=ln.offset,
            )
            self.lines.append(opp)
            self.add_vehicle(c, i, variants[i], z[i], opp, float("nan"))
            started.append(opp)
        return started

    def start_adjacent(self, lines: list[Line]) -> list[Line]:
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
        turned = angle_diff(c.heading, head[idx]) > np.radians(cfg.probe.max_turn_deg)
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
            nxt = Line(
                line_id=ln.line_id, lane=ln.lane, lane_index=ln.lane_index + 1,
                target=cfg.vehicles_per_line.sample(self.rng), x=c.x[i], y=c.y[i], heading=c.heading[i],
                edge_dist=new_off[k], offset=new_off[k],
            )
            self.lines.append(nxt)
            self.add_vehicle(c, i, variants[i], z[i], nxt, float("nan"))
            started.append(nxt)
        return started

    # ------------------------------------------------------------------ advancing
    def advance_round(self, active: list[Line]) -> tuple[list[Line], list[Line]]:
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
        turned = angle_diff(c.heading, head) > np.radians(cfg.probe.max_turn_deg)
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

    def mark_road_ends(self, lines: list[Line]) -> None:
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
        active: list[Line] = []
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

    def _followers(self, finished: list[Line]) -> list[Line]:
        """The lines finished lines start: the opposite lane of a seeded line (double lanes)
        and, with fill_lanes, the next lane inwards of every line. Lines complete at their
        first vehicle finish at once and start their own followers."""
        out: list[Line] = []
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
            c = Candidate(seeds[:, 0].copy(), seeds[:, 1].copy(), head, np.ones(len(seeds), bool),
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
