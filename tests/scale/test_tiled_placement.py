"""Tiled placement: one tile equals untiled; no vehicle lost or duplicated at borders."""

import warnings

import numpy as np
import pytest

from aerial_synth.errors import PlacementError
from aerial_synth.placement import place
from aerial_synth.placement.footprints import FootprintIndex
from aerial_synth.placement.tiled import place_tiled, tile_seed
from aerial_synth.scene.raycast import RayScene
from aerial_synth.scene.tiles import TiledWorld

N = 240


@pytest.fixture(scope="module")
def world(small_city_spec):
    return TiledWorld.from_spec(small_city_spec)


@pytest.fixture(scope="module")
def tiled(world):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        g = world.grid(250.0, 50.0)
        return g, place_tiled(world, g, "jam", seed=7, n_vehicles=N)


def _dicts(pl):
    return [v.to_dict() for v in pl.vehicles]


def test_one_tile_equals_untiled(world, small_city_scene):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        one = place_tiled(world, world.grid(600.0, 40.0), "jam", seed=7, n_vehicles=N)
        ref = place(RayScene(small_city_scene), "jam", seed=7, n_vehicles=N, scene_name=world.name)
    assert one.stats["tiles"]["grid"] == [1, 1]
    assert len(ref.vehicles) > 100
    assert _dicts(one) == _dicts(ref)


def test_every_vehicle_decided_once_by_its_owner(world, tiled):
    """Re-run each tile on its own: the merged vehicles of a tile are exactly that tile's
    core-owned vehicles minus the ones dropped at borders (nothing lost, nothing added)."""
    g, pl = tiled
    assert g.shape == (2, 2)
    xy = np.array([[v.x_m, v.y_m] for v in pl.vehicles])
    owner = g.owner(xy)
    assert (owner >= 0).all()
    keys = {tuple(round(c, 6) for c in (v.x_m, v.y_m, v.heading_rad)) for v in pl.vehicles}
    assert len(keys) == len(pl.vehicles)  # no duplicates
    assert [v.id for v in pl.vehicles] == list(range(1, len(pl.vehicles) + 1))
    dropped_total = 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for t in g.tiles():
            sc = world.scene_for(t.window)
            # a tile of a grid seeds in its core and asks for its core's share
            want = max(1, int(round(N * (t.core[2] - t.core[0]) * (t.core[3] - t.core[1]) / 500.0**2)))
            own = place(RayScene(sc), "jam", np.random.default_rng(tile_seed(7, t.i, t.j, 4)), n_vehicles=want,
                        region=(t.core, lambda xy, t=t: g.owns(t, xy)))
            oxy = np.array([[v.x_m, v.y_m] for v in own.vehicles])
            mine = {tuple(round(c, 6) for c in (v.x_m, v.y_m, v.heading_rad))
                    for v, o in zip(own.vehicles, g.owns(t, oxy)) if o}
            merged = {tuple(round(c, 6) for c in (v.x_m, v.y_m, v.heading_rad))
                      for v, o in zip(pl.vehicles, owner) if tuple(o) == t.key}
            assert merged <= mine
            dropped_total += len(mine - merged)
            assert len(mine) > 20
    assert dropped_total == pl.stats["tiles"]["dropped_at_borders"]


def test_no_overlap_across_borders(tiled):
    g, pl = tiled
    gap = pl.parameters["gap_m"]
    idx = FootprintIndex(gap)
    for v in pl.vehicles:
        poly = idx.polygon(v.x_m, v.y_m, v.heading_rad, v.length_m, v.width_m)
        assert not idx.collides(poly), f"vehicle {v.id} comes closer than {gap} m to another"
        idx.add(poly, (v.x_m, v.y_m))
    # vehicles stand near the borders too (no empty band along the tile edges)
    xy = np.array([[v.x_m, v.y_m] for v in pl.vehicles])
    near = (np.abs(xy[:, 0]) < 15) | (np.abs(xy[:, 1]) < 15)
    assert near.sum() >= 5


def test_lane_rule_holds_across_borders(world):
    """The merge keeps the lane rule placement keeps inside a tile: two vehicles heading the
    same way in one lane stay LANE_RULE_FRACTION x the jam spacing floor apart, whichever
    tiles placed them (full roads on 16 tiles: before the merge knew the rule, 15 pairs
    of this placement broke it)."""
    from aerial_synth.placement import load_scenario
    from aerial_synth.placement.traffic import lane_rule

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pl = place_tiled(world, world.grid(125.0, 50.0), "jam", seed=7, n_vehicles=2000)
    assert pl.stats["tiles"]["grid"] == [4, 4] and len(pl.vehicles) > 700
    lo, half, turn = lane_rule(load_scenario("jam"))
    xy = np.array([[v.x_m, v.y_m] for v in pl.vehicles])
    h = np.array([v.heading_rad for v in pl.vehicles])
    d = xy[:, None] - xy[None]
    dist = np.hypot(d[..., 0], d[..., 1])
    same = np.abs(np.angle(np.exp(1j * (h[:, None] - h[None])))) < turn
    across = np.abs(-np.sin(h[None]) * d[..., 0] + np.cos(h[None]) * d[..., 1])
    bad = same & (dist < lo) & (across < half) & ~np.eye(len(h), dtype=bool)
    assert not bad.any(), f"{bad.sum() // 2} same-lane pairs closer than {lo:.2f} m"


def test_deterministic(world, tiled):
    g, pl = tiled
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        again = place_tiled(world, g, "jam", seed=7, n_vehicles=N)
    assert _dicts(again) == _dicts(pl)


def test_tile_smaller_than_longest_vehicle_refused(world):
    with pytest.raises(PlacementError) as e:
        place_tiled(world, world.grid(3.0, 1.0), "jam", seed=0, n_vehicles=10)
    msg = str(e.value)
    assert "--tile-m" in msg and "3" in msg and "\n" not in msg


def test_cli_tile_smaller_than_longest_vehicle(tmp_path):
    from .conftest import run_cli

    out = tmp_path / "out"
    r = run_cli("place-tiled", "--tile-m", 3, "--out", out)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "--tile-m" in lines[0] and "longest vehicle" in lines[0] and "3" in lines[0]
    assert not out.exists()


def test_cli_writes_the_tiled_placement(tmp_path):
    import json

    import yaml

    from .conftest import run_cli

    spec = tmp_path / "town.yaml"
    spec.write_text(yaml.safe_dump({"generator": "city", "name": "town", "seed": 2, "size_km": 0.3}))
    out = tmp_path / "out"
    r = run_cli("place-tiled", "--scene", spec, "--tile-m", 150, "--margin-m", 30, "--vehicles", 60,
                "--out", out)
    assert r.returncode == 0, r.stderr
    d = json.loads((out / "placement.json").read_text())
    assert d["stats"]["tiles"]["grid"] == [2, 2] and len(d["vehicles"]) > 20
    assert [v["id"] for v in d["vehicles"]] == list(range(1, len(d["vehicles"]) + 1))


@pytest.mark.slow  # spawns 2 processes that import open3d and build tiles: 30-60 s here
def test_two_processes_same_result(world, tiled):
    g, pl = tiled
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        par = place_tiled(world, g, "jam", seed=7, n_vehicles=N, workers=2)
    assert _dicts(par) == _dicts(pl)
    assert par.stats["tiles"] == pl.stats["tiles"]


class _ReversedExecutor:
    """Places the tiles in reverse order (as a pool whose workers finish in any order
    would), yields the results in tile order, as ``Executor.map`` does."""

    def __init__(self):
        self.jobs = 0

    def map(self, fn, jobs):
        jobs = list(jobs)
        self.jobs = len(jobs)
        out = [fn(j) for j in reversed(jobs)]
        return iter(out[::-1])


def test_same_result_whatever_order_tiles_are_placed_in(world, tiled):
    """Tiles are independent until the raster-order merge: placing them in another order
    (any number of workers) gives the same vehicles, ids and stats."""
    g, pl = tiled
    ex = _ReversedExecutor()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rev = place_tiled(world, g, "jam", seed=7, n_vehicles=N, executor=ex)
    assert ex.jobs == 4
    assert _dicts(rev) == _dicts(pl)
    assert rev.stats["tiles"] == pl.stats["tiles"]


def test_tiles_ask_for_their_core_share(world, tiled):
    """A tile seeds in its core and counts what its core owns: the merged world holds the
    vehicles asked for, less only those dropped at borders."""
    g, pl = tiled
    per = pl.stats["tiles"]["per_tile"]
    asked = sum(max(1, int(round(N * (t.core[2] - t.core[0]) * (t.core[3] - t.core[1]) / 500.0**2)))
                for t in g.tiles())
    assert len(pl.vehicles) == asked - pl.stats["tiles"]["dropped_at_borders"]
    assert all(t["kept"] <= t["placed"] for t in per)


def test_only_some_tiles(world, tiled):
    """A part of the world (one machine's share) gives the same vehicles for its tiles."""
    g, pl = tiled
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        part = place_tiled(world, g, "jam", seed=7, n_vehicles=N, only=[(0, 0)])
    owner = g.owner(np.array([[v.x_m, v.y_m] for v in pl.vehicles]))
    first = [v for v, o in zip(pl.vehicles, owner) if tuple(o) == (0, 0)]  # merged first: nothing dropped
    assert len(part.vehicles) == len(first) > 10
    assert _dicts(part) == _dicts(type(pl)(**{**pl.__dict__, "vehicles": first}))


@pytest.mark.parametrize("extra, field", [
    (["--dask", "foo"], "--dask"),
    (["--dask", "tcp://127.0.0.1:9", "--workers", "2"], "--workers"),
    (["--dask", "tcp://127.0.0.1:9"], "cannot reach"),
])
def test_cli_bad_dask(tmp_path, extra, field):
    from .conftest import run_cli

    out = tmp_path / "out"
    r = run_cli("place-tiled", "--out", out, *extra)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and field in lines[0]
    assert not out.exists()


def _spawned_children() -> set[int]:
    """This process's children started by multiprocessing's spawn (the tiles' pool)."""
    import os

    from ..helpers import children

    return children(os.getpid(), b"multiprocessing.spawn")


@pytest.mark.skipif(not __import__("sys").platform.startswith("linux"), reason="reads /proc")
def test_a_killed_worker_has_its_tiles_placed_again(world, tiled):
    """A tiles' worker killed (SIGKILL, as the OOM killer does): the tiles not returned are
    placed again on a new pool, with a warning, and the result is the same; it used to end
    in BrokenProcessPool's traceback."""
    import os
    import signal
    import threading
    import time

    g, pl = tiled
    killed, stop = [], threading.Event()

    def killer():  # the first worker, 1 s after it appears (while it imports)
        seen = {}
        while not killed and not stop.is_set():
            now = time.monotonic()
            for pid in _spawned_children():
                if now - seen.setdefault(pid, now) > 1.0:
                    os.kill(pid, signal.SIGKILL)
                    killed.append(pid)
                    break
            time.sleep(0.01)

    th = threading.Thread(target=killer, daemon=True)
    th.start()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            par = place_tiled(world, g, "jam", seed=7, n_vehicles=N, workers=2)
    finally:
        stop.set()
        th.join()
    assert killed
    assert any("a worker process died" in str(w.message) for w in caught)
    assert _dicts(par) == _dicts(pl)
