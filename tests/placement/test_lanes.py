"""Every lane of a multi-lane road (jam's fill_lanes), the lane rule, early stop."""

import warnings

import numpy as np
import pytest
import shapely
from shapely.geometry import LineString

from aerial_synth.placement import place, validate_placement
from aerial_synth.placement.traffic import PlacementWarning
from aerial_synth.scene.raycast import RayScene
from aerial_synth.vehicles import load_catalog

from . import layouts


@pytest.fixture(scope="module")
def catalog():
    return load_catalog()


def _place(scene, catalog, n=5000, **kw):
    rs = RayScene(scene)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PlacementWarning)
        p = place(rs, "jam", seed=3, n_vehicles=n, catalog=catalog, **kw)
    return rs, p


def _lanes(p, half_width):
    """(direction, lane index) of each vehicle on a straight east-west road centred on y=0:
    direction 0 = eastbound, 1 = westbound; lane 0 at the traffic-side (right) edge."""
    h = np.array([v.heading_rad for v in p.vehicles])
    y = np.array([v.y_m for v in p.vehicles])
    east = np.cos(h) > 0
    from_edge = np.where(east, y + half_width, half_width - y)  # right-hand traffic
    return np.where(east, 0, 1), from_edge


@pytest.mark.parametrize("width, lanes", [(14.0, 2), (21.0, 3)])
def test_jam_fills_every_lane_of_both_directions(catalog, width, lanes):
    scene = layouts.straight(length=240.0, width=width)
    rs, p = _place(scene, catalog)
    rep = validate_placement(rs, p, scene.truth)
    assert rep.overlaps == 0 and rep.gap_violations == 0 and rep.footprint_drivable == 1.0
    assert np.nanpercentile(rep.heading_error_deg, 99) < 2.0
    direction, d = _lanes(p, width / 2)
    lane = np.round((d - 1.75) / 3.5).astype(int)
    # every vehicle stands in the middle of a lane of its own half of the road
    assert np.abs(d - (1.75 + 3.5 * lane)).max() < 0.05
    assert lane.min() == 0 and lane.max() == lanes - 1
    x = np.array([v.x_m for v in p.vehicles])
    for di in (0, 1):
        for k in range(lanes):
            sel = (direction == di) & (lane == k)
            # a 240 m lane holds ~23 jam vehicles; each lane is filled along most of the road
            assert sel.sum() >= 12, (di, k, int(sel.sum()))
            assert np.ptp(x[sel]) > 150.0
    assert p.stats["inner_lanes"] >= 2 * (lanes - 1)


def test_one_lane_per_direction_gets_no_inner_lane(catalog):
    scene = layouts.straight(length=240.0, width=8.0)
    _, p = _place(scene, catalog)
    _, d = _lanes(p, 4.0)
    assert np.abs(d - 1.75).max() < 0.05
    assert p.stats["inner_lanes"] == 0


def test_fill_lanes_off_keeps_the_outer_lane(catalog):
    scene = layouts.straight(length=240.0, width=14.0)
    _, p = _place(scene, catalog, overrides={"fill_lanes": False})
    _, d = _lanes(p, 7.0)
    assert np.abs(d - 1.75).max() < 0.05 and len(p.vehicles) > 20


def test_divided_road_fills_its_carriageway(catalog):
    """Two 10.5 m one-way carriageways with a 3 m median: three lanes each side, all used."""
    a = LineString([(-120, -6.75), (120, -6.75)])
    b = LineString([(-120, 6.75), (120, 6.75)])
    scene = layouts.make_scene("divided", [(a, 10.5), (b, 10.5)])
    rs, p = _place(scene, catalog)
    rep = validate_placement(rs, p, None)
    assert rep.overlaps == 0 and rep.footprint_drivable == 1.0
    h = np.array([v.heading_rad for v in p.vehicles])
    y = np.array([v.y_m for v in p.vehicles])
    east = np.cos(h) > 0
    assert np.all(y[east] < 0) and np.all(y[~east] > 0)  # right-hand traffic, median on the left
    d = np.where(east, y + 12.0, 12.0 - y)
    lane = np.round((d - 1.75) / 3.5).astype(int)
    assert np.abs(d - (1.75 + 3.5 * lane)).max() < 0.05
    assert set(lane[east]) == {0, 1, 2} and set(lane[~east]) == {0, 1, 2}


def test_lane_rule_no_vehicle_squeezed_into_a_jam_gap(catalog):
    """Seeds that fall between two vehicles of a line start no line there: within a lane,
    centres stay at least 0.9 x the jam's 8 m floor apart, whichever lines they belong to."""
    scene = layouts.straight(length=400.0, width=8.0)
    _, p = _place(scene, catalog)
    direction, _ = _lanes(p, 4.0)
    x = np.array([v.x_m for v in p.vehicles])
    for di in (0, 1):
        xs = np.sort(x[direction == di])
        assert len(xs) > 20
        assert np.diff(xs).min() >= 0.9 * 8.0 - 1e-6


class _CountingRayScene(RayScene):
    """A RayScene that counts the traces placement asks for (calls and rays)."""

    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        self.calls = 0
        self.rays = 0

    def trace_labels(self, xy, ignore=None):
        self.calls += 1
        self.rays += len(np.asarray(xy).reshape(-1, 2))
        return super().trace_labels(xy, ignore)

    def trace_down(self, xy, ignore=None):
        self.calls += 1
        self.rays += len(np.asarray(xy).reshape(-1, 2))
        return super().trace_down(xy, ignore)


def test_asking_for_ten_times_what_fits_stops_early(catalog):
    """The roads full, placement stops: asking for 10x the capacity returns what fits (a
    warning, no error) for a bounded number of RayScene traces, and far below the seeding
    budget."""
    roads = [(LineString([(-150, y), (150, y)]), 8.0) for y in (-60.0, 0.0, 60.0)]
    roads += [(LineString([(x, -110), (x, 110)]), 8.0) for x in (-90.0, 0.0, 90.0)]
    scene = layouts.make_scene("grid", roads)
    fits = _CountingRayScene(scene)
    with pytest.warns(PlacementWarning, match="held"):
        full = place(fits, "jam", seed=1, n_vehicles=100000, catalog=catalog)
    cap = len(full.vehicles)
    assert cap > 150 and full.stats["stopped_full"]
    asked = _CountingRayScene(scene)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PlacementWarning)
        some = place(asked, "jam", seed=1, n_vehicles=cap, catalog=catalog)
    over = _CountingRayScene(scene)
    with pytest.warns(PlacementWarning, match="held"):
        ten = place(over, "jam", seed=1, n_vehicles=10 * cap, catalog=catalog)
    assert len(some.vehicles) >= 0.95 * cap
    assert len(ten.vehicles) >= 0.95 * cap and ten.stats["shortfall"] == 10 * cap - len(ten.vehicles)
    # stopped because the roads were full, before the seeding budget (50,000 traces here)
    assert ten.stats["stopped_full"] and ten.stats["seed_traces"] < 50000
    # bounded: asking for 10x what fits costs a bounded multiple of the traces of asking for
    # what fits (the stop rule's 256 probed seeds are a fixed cost, large on a scene this
    # small); before the stop rule it drew the whole seeding budget
    assert over.calls <= 2.5 * asked.calls, (over.calls, asked.calls)
    assert over.rays <= 3.0 * asked.rays, (over.rays, asked.rays)
    rep = validate_placement(over, ten, scene.truth)
    assert rep.overlaps == 0 and rep.footprint_drivable == 1.0


def test_batched_overlap_test_equals_one_by_one():
    """FootprintIndex.select decides a batch as testing and adding one by one would."""
    from aerial_synth.placement.footprints import FootprintIndex

    rng = np.random.default_rng(0)
    n = 400
    x, y = rng.uniform(0, 60, n), rng.uniform(0, 60, n)
    h = rng.uniform(0, 2 * np.pi, n)
    L, W = rng.uniform(3.5, 12.0, n), rng.uniform(1.6, 2.6, n)
    for gap, mc, lane in ((0.5, None, None), (0.0, None, None), (0.3, 6.0, None), (0.5, None, (7.2, 1.75, 0.5))):
        one = FootprintIndex(gap, mc, lane_spacing=lane, rebuild_every=16)
        ref = []
        for i in range(n):
            g, xy, r = one.polygons(x[i], y[i], h[i], L[i], W[i])
            hit = one.collides_many(g, xy, r, heading=h[i:i + 1])[0]
            ref.append(not hit)
            if not hit:
                one.add_many(g, xy, r, h[i:i + 1])
        batch = FootprintIndex(gap, mc, lane_spacing=lane, rebuild_every=16)
        acc = np.zeros(n, bool)
        for k in range(0, n, 37):  # uneven batches over a growing index
            g, xy, r = batch.polygons(x[k:k + 37], y[k:k + 37], h[k:k + 37], L[k:k + 37], W[k:k + 37])
            acc[k:k + 37] = batch.select(g, xy, r, heading=h[k:k + 37])
        assert acc.tolist() == ref and 10 < sum(ref) < n
        # and the accepted keep the gap pairwise (the exact shapely test)
        polys = np.array(batch.geometries, dtype=object)
        assert len(polys) == acc.sum()
        if gap > 0:
            a, b = shapely.STRtree(polys).query(polys, predicate="dwithin", distance=gap - 1e-5)
            assert not np.any(a != b)
