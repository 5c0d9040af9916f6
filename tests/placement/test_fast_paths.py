"""The placement engine's fast paths give exactly what their plain formulations give.

Each test holds a straightforward reference (the formulation the engine used before it was
made cheaper: full-length road scans with a loop per origin, one label table lookup after
another, all plane heights at once, ...) and compares bit for bit, so a shortcut that
changes a single trace, edge or footprint fails here.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import shapely
from shapely.geometry import box

from aerial_synth.placement import footprints as fp_mod
from aerial_synth.placement import place, traffic_engine
from aerial_synth.placement.config import load_scenario, scenario_dir
from aerial_synth.placement.footprints import (
    EDGE_STEP_M,
    INNER_STEP_M,
    FootprintIndex,
    _unit_samples,
    footprint_points,
)
from aerial_synth.placement.linetrace import Prober, unit
from aerial_synth.placement.traffic import PlacementWarning
from aerial_synth.scene.build import polygon_object
from aerial_synth.scene.model import Scene
from aerial_synth.scene.raycast import RayScene
from aerial_synth.vehicles import load_catalog

from . import layouts


@pytest.fixture(scope="module")
def catalog():
    return load_catalog()


def _divided_scene() -> Scene:
    """Two 7 m carriageways either side of a 2 m median, a parallel road 20 m further north,
    a road across them, and a building: medians, wide gaps and corners for the scans."""
    road = shapely.union_all([box(-80, -8, 80, -1), box(-80, 1, 80, 8), box(-80, 28, 80, 35),
                              box(30, -40, 37, 60)])
    ground = box(-100, -60, 100, 80).difference(road)
    objs = [polygon_object("road", "road", road, 0.05), polygon_object("grass", "ground", ground, 0.0),
            polygon_object("roof", "building", box(-20, 12, 0, 24), 6.0)]
    return Scene("divided", objs)


@pytest.fixture(scope="module")
def divided():
    rs = RayScene(_divided_scene())
    return rs, Prober(rs, load_scenario("jam").probe)


def _probe_points(rs, n, seed):
    """n random points over the scene (road and off road) and n random directions."""
    b = rs.scene.bounds()
    rng = np.random.default_rng(seed)
    return rng.uniform(b[0, :2] - 5, b[1, :2] + 5, (n, 2)), rng.uniform(0, 2 * np.pi, n)


# ----------------------------------------------------------------------------- ray scene
def _planes_reference(rs):
    """Plane coefficients of every static face at once (the eager formulation), checked
    against the geometry: each plane passes through its triangle's three vertices."""
    from aerial_synth.scene.raycast import _planes_of

    tri = rs._static_vertices64[rs._static_faces.astype(np.int64)]
    pl = _planes_of(tri)
    ok = np.isfinite(pl[:, 0])
    z = pl[ok, 0, None] * tri[ok, :, 0] + pl[ok, 1, None] * tri[ok, :, 1] + pl[ok, 2, None]
    assert ok.any() and np.allclose(z, tri[ok, :, 2], atol=1e-9)
    return pl


@pytest.mark.parametrize("with_vehicle", [False, True])
@pytest.mark.parametrize("ignore", [None, ()])
def test_trace_labels_and_heights_agree_with_trace_down(with_vehicle, ignore):
    rs = RayScene(layouts.crown_over_road())
    if with_vehicle:  # a second geometry: the general hit mapping
        v = np.array([[0, 0, 0], [4, 0, 0], [4, 2, 0], [0, 2, 0]], float) + [1.0, -1.0, 1.5]
        rs.add_vehicle(7, v, [[0, 1, 2], [0, 2, 3]])
    xy, _ = _probe_points(rs, 4000, 1)
    xy = np.concatenate([xy, [[1e4, 1e4], [2.0, 0.0]]])  # a miss, and the vehicle (if any)
    ref = rs.trace_down(xy, ignore=ignore)
    lab = rs.trace_labels(xy, ignore=ignore)
    assert lab.dtype == ref.label_id.dtype and np.array_equal(lab, ref.label_id)
    assert lab[-2] == 0
    at = np.arange(0, len(xy), 7)
    lab2, z = rs.trace_labels_z(xy, at, ignore=ignore)
    assert np.array_equal(lab2, ref.label_id)
    assert np.array_equal(z, ref.z[at], equal_nan=True)


def test_plane_heights_computed_per_face_equal_all_at_once():
    rs = RayScene(_divided_scene())
    ref = _planes_reference(rs)
    rng = np.random.default_rng(0)
    some = rng.integers(0, len(ref), 50)
    assert np.array_equal(rs._face_planes(some), ref[some], equal_nan=True)  # first some faces
    assert np.array_equal(rs._static_planes(), ref, equal_nan=True)  # then the rest


# ----------------------------------------------------------------------------- marches
def _march_reference(pr, origins, angles, include_origin, step_m, max_distance_m=None):
    """Every step of every direction in one cast, then the bisection passes (no chunks)."""
    cfg = pr.cfg
    P, D = angles.shape
    K = int(np.ceil((max_distance_m or cfg.max_distance_m) / step_m))
    u = unit(angles)
    ks = np.arange(1, K + 1, dtype=np.float64) * step_m
    pts = origins[:, None, None, :] + u[:, :, None, :] * ks[None, None, :, None]
    nonroad = ~pr.is_road(pts.reshape(-1, 2)).reshape(P, D, K)
    found = nonroad.any(axis=2)
    count = np.where(found, nonroad.argmax(axis=2), K)
    origin_ok = pr.is_road(origins) if include_origin else np.ones(P, bool)
    dist = count * step_m
    bits = int(cfg.refine_steps) + max(0, int(np.ceil(np.log2(step_m / cfg.step_m - 1e-9))))
    fi = np.flatnonzero(found.ravel())
    o_f, u_f = np.repeat(origins, D, axis=0)[fi], u.reshape(-1, 2)[fi]
    d_f, w = dist.ravel()[fi].copy(), step_m
    while bits > 0:
        b = min(bits, 5)
        bits -= b
        m = (1 << b) - 1
        sub = (np.arange(1, m + 1) / (m + 1)) * w
        p = o_f[:, None, :] + u_f[:, None, :] * (d_f[:, None] + sub[None, :])[:, :, None]
        nr = ~pr.is_road(p.reshape(-1, 2)).reshape(len(fi), m)
        firstn = np.where(nr.any(axis=1), nr.argmax(axis=1), m)
        d_f = d_f + np.where(firstn > 0, sub[np.maximum(firstn - 1, 0)], 0.0)
        w = w / (m + 1)
    dist.ravel()[fi] = d_f
    count[~origin_ok] = -1
    found[~origin_ok] = False
    return count, found, dist, origins[:, None, :] + u * dist[..., None]


@pytest.mark.parametrize("include_origin", [False, True])
def test_march_chunks_change_the_traces_not_the_edges(divided, include_origin):
    rs, pr = divided
    xy, ang = _probe_points(rs, 300, 2)
    angles = np.stack([ang, ang + 0.17, ang + np.pi], 1)
    runs = [pr.march(xy, angles, include_origin=include_origin, chunk=c, grow=g, step_m=0.25)
            for c, g in ((48, 2), (1, 1), (4, 1), (12, 2), (5, 3))]
    ref = _march_reference(pr, xy, angles, include_origin, 0.25)
    for r in runs:
        for name, want in zip(("count", "found", "dist_m", "edge_xy"), ref, strict=True):
            assert np.array_equal(getattr(r, name), want), name
    assert len({r.n_rays for r in runs}) > 1  # the chunks did change the traces
    assert runs[0].found.any() and not runs[0].found.all()


def test_refining_later_or_only_complete_points_gives_the_same_edges(divided):
    rs, pr = divided
    xy, ang = _probe_points(rs, 300, 7)
    angles = np.stack([ang, ang - 0.17], 1)
    full = pr.march(xy, angles, include_origin=True, chunk=12, step_m=0.25)
    raw = pr.march(xy, angles, include_origin=True, chunk=12, step_m=0.25, refine=False)
    rng = np.random.default_rng(0)
    which = rng.random(angles.shape) < 0.5
    later = pr.refine(xy, angles, raw, which, 0.25)
    done = raw.found & which
    assert np.array_equal(later.dist_m[done], full.dist_m[done])
    assert np.array_equal(later.dist_m[~done], raw.dist_m[~done])
    assert np.array_equal(pr.refine(xy, angles, raw, np.ones_like(which), 0.25).edge_xy, full.edge_xy)
    part = pr.march(xy, angles, include_origin=True, chunk=12, step_m=0.25, complete_only=True)
    complete = full.found.all(axis=1)  # found is False wherever the origin is off road
    assert complete.any() and not complete.all()
    assert np.array_equal(part.edge_xy[complete], full.edge_xy[complete])
    assert np.array_equal(part.count, full.count) and np.array_equal(part.found, full.found)
    assert part.n_rays < full.n_rays


def test_road_end_brackets_decide_what_the_refined_edges_would():
    """Rows start_lines leaves unrefined give the same road-end and inner-lane answers with
    the bracket's lower end as with any refined distance inside the bracket."""
    rng = np.random.default_rng(9)
    n, step = 20000, 0.25
    lo = rng.integers(0, 128, (n, 3)) * step
    found = rng.random((n, 3)) < 0.8
    lo[~found] = 128 * step
    offs = rng.choice([1.75, 5.25], n) + rng.integers(-2, 3, n) * step / 2
    need = traffic_engine.road_end_needs_edges(lo, found, step, offs, 1.75)
    assert need.any() and not need.all()
    keep = ~need

    def answers(d):
        return d[:, 0] + d[:, 1] <= offs + d[:, 2], (offs > 1.75 + 1e-9) & (d[:, 2] < offs)

    at_lo = answers(lo)
    for frac in (0.0, 1 / 512, 0.5, 511 / 512):
        d = lo + np.where(found, frac * step, 0.0)
        for a, b in zip(answers(d), at_lo, strict=True):
            assert np.array_equal(a[keep], b[keep])


def test_nearest_edge_direction_does_not_depend_on_the_chunks(divided):
    rs, pr = divided
    xy, _ = _probe_points(rs, 400, 3)
    xy = xy[pr.is_road(xy)]
    ang = np.tile(np.arange(36) * (2 * np.pi / 36), (len(xy), 1))
    picks = []
    for c, g in ((8, 2), (4, 1), (1, 1), (3, 2)):
        m = pr.march(xy, ang, first_only=True, chunk=c, grow=g, step_m=0.25, refine=False)
        best = np.argmin(m.count, axis=1)
        picks.append((best, m.found[np.arange(len(xy)), best], m.count[np.arange(len(xy)), best]))
    for b, f, k in picks[1:]:
        assert np.array_equal(b, picks[0][0]) and np.array_equal(f, picks[0][1])
        assert np.array_equal(k, picks[0][2])


def _road_grid(pr, origins, angles, max_distance_m, step_m):
    K = int(np.ceil(max_distance_m / step_m))
    ks = np.arange(1, K + 1) * step_m
    pts = origins[:, None, :] + unit(angles)[:, None, :] * ks[None, :, None]
    return pr.is_road(pts.reshape(-1, 2)).reshape(len(origins), K), K


def _road_runs_reference(pr, origins, angles, max_distance_m, gap_m, step_m=0.25):
    road, K = _road_grid(pr, origins, angles, max_distance_m, step_m)
    gap_steps = int(np.ceil(gap_m / step_m))
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
        far[i] = (last + 1) * step_m
    return far, crossed, found


def _road_across_reference(pr, origins, angles, max_distance_m, gap_m, step_m=0.25):
    road, K = _road_grid(pr, origins, angles, max_distance_m, step_m)
    P = len(origins)
    off = ~road
    first_off = np.where(off.any(axis=1), off.argmax(axis=1), K)
    gap_steps = int(np.ceil(gap_m / step_m))
    run = np.zeros((P, K), np.int64)
    for k in range(K):
        run[:, k] = np.where(off[:, k], (run[:, k - 1] if k else 0) + 1, 0)
    long_gap = off & (run > gap_steps)
    stop = np.where(long_gap.any(axis=1), long_gap.argmax(axis=1) - gap_steps, K)
    idx = np.arange(K)[None, :]
    last_road = np.where(road & (idx < stop[:, None]), idx, -1).max(axis=1)
    near = first_off * step_m
    far = (last_road + 1) * step_m
    crossed = last_road > first_off
    found = stop < K
    on = road[:, 0]
    return np.where(on, near, 0.0), np.where(on, far, 0.0), crossed & on, found | ~on


@pytest.mark.parametrize("reach, gap", [(32.0, 14.0), (46.0, 14.0), (20.0, 3.0), (10.0, 0.0)])
def test_road_scans_stop_early_with_the_full_scan_answers(divided, reach, gap):
    rs, pr = divided
    xy, ang = _probe_points(rs, 600, 4)
    # directions across the carriageways too (north/south), where the median lies
    ang[::3] = np.pi / 2
    ang[1::3] = -np.pi / 2
    n0 = pr.n_rays
    got = pr.road_runs(xy, ang, reach, gap)
    n_scan = pr.n_rays - n0
    ref = _road_runs_reference(pr, xy, ang, reach, gap)
    n_full = pr.n_rays - n0 - n_scan
    for a, b in zip(got, ref, strict=True):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    assert np.array_equal(pr.crosses_gap(xy, ang, reach, gap), ref[1])
    for a, b in zip(pr.road_across(xy, ang, reach, gap), _road_across_reference(pr, xy, ang, reach, gap),
                    strict=True):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    if gap >= 3.0:
        assert ref[1].any()  # some rows cross the median
    assert n_scan < n_full


# ----------------------------------------------------------------------------- footprints
def _footprint_points_reference(x, y, heading, length, width):
    x, y, h, ln, w = (np.atleast_1d(np.asarray(a, dtype=np.float64)) for a in (x, y, heading, length, width))
    n = len(x)
    sizes, inv = np.unique(np.stack([ln, w], axis=1), axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    tables = [np.array(_unit_samples(float(a), float(b), EDGE_STEP_M, INNER_STEP_M)) for a, b in sizes]
    count = np.array([len(tables[j]) for j in inv], dtype=np.int64)
    start = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)
    uv = np.concatenate([tables[j] for j in inv])
    owner = np.repeat(np.arange(n), count)
    lx = uv[:, 0] * ln[owner]
    ly = uv[:, 1] * w[owner]
    c, s = np.cos(h)[owner], np.sin(h)[owner]
    pts = np.stack([x[owner] + c * lx - s * ly, y[owner] + s * lx + c * ly], axis=1)
    return pts, owner, start, count


def test_footprint_points_equal_the_per_vehicle_formulation():
    rng = np.random.default_rng(5)
    n = 400
    sizes = np.array([[4.4, 1.8], [12.0, 2.5], [4.4, 1.9], [7.5, 2.3], [4.4, 1.8], [16.5, 2.55]])
    pick = rng.integers(0, len(sizes), n)
    args = (rng.uniform(-500, 500, n), rng.uniform(-500, 500, n), rng.uniform(-7, 7, n),
            sizes[pick, 0], sizes[pick, 1])
    for a, b in zip(footprint_points(*args), _footprint_points_reference(*args), strict=True):
        assert a.shape == b.shape and np.array_equal(a, b)


@pytest.mark.parametrize("lane", [None, (7.2, 1.75, np.radians(30.0))])
def test_select_skips_the_index_test_for_cleared_candidates_with_the_same_answer(lane):
    rng = np.random.default_rng(6)

    def batch(n):
        x, y = rng.uniform(0, 120, n), rng.uniform(0, 40, n)
        h = rng.choice([0.0, np.pi], n) + rng.normal(0, 0.1, n)
        return x, y, h, np.full(n, 4.5), np.full(n, 1.9)

    old = batch(150)
    for trial in range(5):
        idx_a = FootprintIndex(0.5, lane_spacing=lane, rebuild_every=32)
        idx_b = FootprintIndex(0.5, lane_spacing=lane, rebuild_every=32)
        for idx in (idx_a, idx_b):
            g, xy, r = idx.polygons(*old)
            idx.select(g, xy, r, heading=old[2])
        new = batch(200)
        g, xy, r = idx_a.polygons(*new)
        ok = rng.random(200) < 0.8
        clear = ~idx_a.collides_many(g[ok], xy[ok], r[ok], heading=new[2][ok])
        clear_all = np.zeros(200, bool)
        clear_all[np.flatnonzero(ok)[clear]] = True
        g_lazy = np.where(ok, g, None)  # select never reads the geometry of a skipped one
        a = idx_a.select(g_lazy, xy, r, ok=ok, heading=new[2], clear=clear_all, max_n=60 + trial)
        b = idx_b.select(g, xy, r, ok=ok, heading=new[2], max_n=60 + trial)
        assert np.array_equal(a, b) and a.any() and not a[ok].all()
        assert len(idx_a) == len(idx_b)


# ----------------------------------------------------------------------------- engine
def _dump(p):
    return [v.to_dict() for v in p.vehicles], p.parameters, {k: v for k, v in p.stats.items()
                                                             if k not in ("rays", "casts")}


@pytest.mark.parametrize("layout", ["bend90", "t_junction", "ring"])
def test_placements_do_not_depend_on_march_chunks_or_index_rebuilds(catalog, monkeypatch, layout):
    """A placement with the engine's chunking and KD-tree schedule equals one with one step
    per cast and a tree rebuilt after every insertion (and one never rebuilt)."""
    rs = RayScene(getattr(layouts, layout)())

    def run(seed):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", PlacementWarning)
            return _dump(place(rs, "jam", seed=seed, catalog=catalog, n_vehicles=150))

    seeds = (0, 3)
    ref = [run(s) for s in seeds]
    assert all(len(r[0]) > 20 for r in ref)
    march = traffic_engine.Prober.march

    def one_step(self, origins, angles, *a, first_only=False, chunk=48, grow=2, **kw):
        if first_only:  # only the chosen direction is used: any chunks give it
            return march(self, origins, angles, *a, first_only=True, chunk=1, grow=1, **kw)
        return march(self, origins, angles, *a, chunk=1, grow=1, **kw)

    for rebuild in (1, 10**9):
        with monkeypatch.context() as m:
            m.setattr(traffic_engine.Prober, "march", one_step)
            m.setattr(fp_mod.FootprintIndex, "__init__",
                      lambda self, *a, _init=fp_mod.FootprintIndex.__init__, _every=rebuild, **k:
                      _init(self, *a, **{**k, "rebuild_every": _every}))
            assert [run(s) for s in seeds] == ref


def test_scenario_files_parsed_once_and_again_when_edited(tmp_path):
    a = load_scenario("jam")
    assert load_scenario("jam") is a  # immutable: kept
    assert load_scenario("jam", {"gap_m": 0.7}).gap_m == 0.7 and load_scenario("jam") is a
    f = tmp_path / "mine.yaml"
    f.write_text((scenario_dir() / "jam.yaml").read_text().replace("name: jam", "name: mine"))
    one = load_scenario(str(f))
    assert one.name == "mine" and one.gap_m == a.gap_m and load_scenario(str(f)) is one
    f.write_text(f.read_text().replace("gap_m: 0.5", "gap_m: 0.9"))
    assert load_scenario(str(f)).gap_m == 0.9


def test_option_draws_equal_the_per_model_formulation(catalog):
    rng = np.random.default_rng(8)
    mi = rng.integers(-1, len(catalog.models), 500)
    key = 123456789

    u = np.random.default_rng(np.random.SeedSequence([key, 17])).random(len(mi))
    ref = [catalog.models[i] if i >= 0 else None for i in mi]
    for i in np.unique(mi[mi >= 0]):
        rates = catalog.options_of(catalog.models[i])
        if not rates:
            continue
        sel = np.flatnonzero(mi == i)
        k = np.searchsorted(np.cumsum(list(rates.values())), u[sel], side="right")
        names = list(rates)
        for s, kk in zip(sel[k < len(names)], k[k < len(names)]):
            ref[s] = catalog.model(f"{catalog.models[i].name}+{names[kk]}")
    got = catalog.draw_options(mi, key)
    assert got == ref and any(m is not None and "+" in m.name for m in got)

