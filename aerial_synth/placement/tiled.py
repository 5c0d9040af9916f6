"""Tiled placement: vehicles on a world far larger than memory, one tile at a time.

For every tile of a :class:`~aerial_synth.scene.tiles.TileGrid`, in raster order:

1. build the scene of the tile's **window** (core + margin) and its RayScene;
2. call the public :func:`aerial_synth.placement.place` on it with the tile's own seed
   (``SeedSequence(entropy, spawn_key + (i, j))`` of the caller's seed; a grid of one tile
   uses the caller's seed itself, so it equals untiled placement); in a grid of several
   tiles a traffic scenario seeds its lines in the core only and places only vehicles the
   core owns (``place(..., region=...)``; a line ends at the core's border): the margin is
   there for the traces (roads and edges beyond the border), nothing is placed there;
3. keep only the vehicles whose footprint centre lies in the tile's **core** (cores are
   half-open, so each point of the world has exactly one owner: a vehicle is decided once,
   by one tile);
4. drop the scene (peak memory is one window, whatever the world's size).

Vehicles of neighbouring tiles were placed independently, so two of them may come closer
than the scenario's gap across a border. That is resolved deterministically: tiles are
merged in raster order and a vehicle near its core's border that collides with an already
kept vehicle of another tile is dropped (counted in ``stats["tiles"]["dropped_at_borders"]``).
Ids are renumbered 1..N in merge order; line ids are offset per tile so they stay unique.

``n_vehicles`` is for the whole world: each tile asks for its core's share by area (traffic;
parking scenarios: its window's share, of which the core keeps about its core's share).
None uses the scenario's default per tile.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from typing import Mapping

import numpy as np

from ..errors import PlacementError, own_warnings
from ..scene.raycast import RayScene
from ..vehicles import load_catalog
from .config import load_scenario
from .footprints import FootprintIndex
from .model import Placement
from .parking_config import PARKING_KINDS
from .traffic import PlacementWarning, lane_rule, place

__all__ = ["BorderMerge", "min_tile_m", "place_tiled", "tile_seed"]


def min_tile_m(catalog=None) -> float:
    """The smallest allowed tile edge: the longest vehicle of the catalog (metres; the
    bundled catalog when None)."""
    if catalog is None:
        catalog = load_catalog()
    models = getattr(catalog, "models", None)
    if isinstance(models, Mapping):
        models = list(models.values())
    return float(max(m.length_m for m in models))


def tile_seed(seed, i: int, j: int, n_tiles: int) -> np.random.SeedSequence | int | None:
    """The seed of tile (i, j): the caller's seed for a single tile, else an independent
    child ``SeedSequence(entropy, spawn_key + (i, j))``."""
    if n_tiles == 1:
        return seed
    ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    return np.random.SeedSequence(ss.entropy, spawn_key=tuple(ss.spawn_key) + (int(i), int(j)))


def place_tiled(
    world,
    grid,
    scenario="jam",
    seed=0,
    n_vehicles: int | None = None,
    catalog=None,
    overrides: dict | None = None,
    progress=None,
    workers: int = 1,
    only=None,
    executor=None,
) -> Placement:
    """Place vehicles tile by tile on ``world`` (a :class:`~aerial_synth.scene.tiles.TiledWorld`)
    over ``grid`` (its :class:`~aerial_synth.scene.tiles.TileGrid`).

    seed : an int or a numpy SeedSequence (per-tile seeds: :func:`tile_seed`)
    n_vehicles : vehicles for the whole world (approximate when tiled), or None
    progress : optional callable(done_tiles, n_tiles, kept_so_far)
    workers : place tiles in this many processes (spawn); the result does not depend on it
              (tiles are independent; the merge runs in raster order here)
    executor : instead of ``workers``, any executor whose ``map(fn, jobs)`` yields results in
               order: ``distributed.Client(...).get_executor()`` places tiles on a Dask cluster
    only : optional (i, j) tile indices to place (the others stay empty): a part of a huge
           world, or one machine's share of it (seeds are those of the whole grid)
    Raises PlacementError when the grid's tiles are smaller than the longest vehicle.
    """
    if catalog is None:
        catalog = load_catalog()
    longest = min_tile_m(catalog)
    if grid.tile_m < longest:
        raise PlacementError(
            f"--tile-m: expected a tile size of at least the longest vehicle ({longest:g} m), got {grid.tile_m:g}"
        )
    cfg = load_scenario(scenario, overrides)
    tiles = grid.tiles()
    n_tiles = len(tiles)
    if only is not None:
        keys = {(int(i), int(j)) for i, j in only}
        tiles = [t for t in tiles if t.key in keys]
    world_area = float(np.prod(grid.bounds[1] - grid.bounds[0]))
    merge = BorderMerge(cfg, longest, n_tiles)
    kept: list = []
    line_base = 0
    per_tile = []
    warned: list[str] = []
    single_stats = None
    t_scene = t_place = c_scene = c_place = 0.0
    t0 = time.perf_counter()

    # traffic: a tile seeds its lines in its core and counts the vehicles its core owns, so it
    # asks for its core's share; parking scenarios fill the window and ask for its share
    by_core = cfg.kind not in PARKING_KINDS and n_tiles > 1
    wants = _tile_wants(tiles, n_vehicles, n_tiles, by_core, world_area)
    jobs = [(world, grid, tile, cfg, tile_seed(seed, tile.i, tile.j, n_tiles), want, catalog, 0, by_core)
            for tile, want in zip(tiles, wants)]
    results = _run_tiles(jobs, executor, workers, n_tiles)
    for k, (tile, res) in enumerate(zip(tiles, results)):
        warned += res["warnings"]
        t_scene += res["scene_s"]
        t_place += res["place_s"]
        c_scene += res.get("scene_cpu_s", 0.0)
        c_place += res.get("place_cpu_s", 0.0)
        n_kept = 0
        for v in res["owned"]:
            if not merge.keep(v, tile.core):
                continue
            kept.append(dataclasses.replace(
                v, id=len(kept) + 1, line_id=v.line_id + line_base if v.line_id >= 0 else -1,
            ))
            n_kept += 1
        line_base += res["max_line"] + 1
        per_tile.append({"tile": [tile.i, tile.j], "placed": res["placed"], "kept": n_kept,
                         "rays": res.get("rays", 0), "casts": res.get("casts", 0),
                         "stopped_full": res.get("stopped_full", False)})
        if progress is not None:
            progress(k + 1, n_tiles, len(kept))
        if n_tiles == 1 and res["stats"] is not None:
            single_stats = dict(res["stats"])
    elapsed = time.perf_counter() - t0
    stats = single_stats if single_stats is not None else {"vehicles": len(kept),
                                                           "requested_vehicles": n_vehicles}
    stats["tiles"] = {"grid": list(grid.shape), "tile_m": grid.tile_m, "margin_m": grid.margin_m,
                      "dropped_at_borders": merge.dropped, "per_tile": per_tile}
    if not kept and not any(t["placed"] for t in per_tile):
        raise PlacementError(f"tiled world {world.name!r}: no tile held a road to place vehicles on")
    out = Placement(
        scene=world.name,
        scenario=cfg.name,
        seed=seed if isinstance(seed, (int, type(None))) else None,
        parameters=cfg.to_dict(),
        vehicles=kept,
        stats=stats,
        timing={"seconds": elapsed, "vehicles_per_s": len(kept) / elapsed if elapsed else 0.0,
                "scene_seconds": t_scene, "place_seconds": t_place,
                "scene_cpu_seconds": c_scene, "place_cpu_seconds": c_place},
    )
    if warned and n_tiles == 1:
        warnings.warn(warned[0], PlacementWarning, stacklevel=2)
    return out



def _tile_wants(tiles, n_vehicles, n_tiles: int, by_core: bool, world_area: float) -> list:
    """Vehicles each tile asks for (None: the scenario's amount): its core's (traffic) or
    window's (parking) share of ``n_vehicles``."""
    wants = []
    for tile in tiles:
        want = None
        if n_vehicles is not None:
            x0, y0, x1, y1 = tile.core if by_core else tile.window
            want = n_vehicles if n_tiles == 1 else max(1, int(round(n_vehicles * (x1 - x0) * (y1 - y0) / world_area)))
        wants.append(want)
    return wants


def _run_tiles(jobs: list, executor, workers: int, n_tiles: int):
    """The results of :func:`_place_tile` over ``jobs``, in order: on ``executor``, a
    process pool of ``workers`` or here."""
    if executor is not None:
        return executor.map(_place_tile, jobs)
    if workers > 1 and n_tiles > 1:
        return _pool_map(jobs, workers)
    return map(_place_tile, jobs)

class BorderMerge:
    """The border rule of a tiled placement. Tiles are merged in raster order; a vehicle
    whose centre lies within ``reach`` of its tile core's edge is dropped when it collides
    with one kept before it (footprint gap, centre distance and the lane rule
    :func:`.traffic.lane_rule`: the rules ``place`` keeps inside a tile). One grid of one
    tile keeps everything. Used by :func:`place_tiled` and by a tiled export's groups
    (:mod:`aerial_synth.dataset.tiled`), so both decide every border alike."""

    def __init__(self, cfg, longest_m: float, n_tiles: int):
        rule = lane_rule(cfg)
        self.index = FootprintIndex(cfg.gap_m, cfg.min_center_distance_m, lane_spacing=rule)
        reach = longest_m + max(cfg.gap_m, 0.0) + float(cfg.min_center_distance_m or 0.0)
        if rule is not None:
            reach = max(reach, longest_m + float(rule[0]))
        self.reach = reach
        self.active = n_tiles > 1
        self.dropped = 0

    def keep(self, v, core) -> bool:
        """Keep vehicle ``v`` of the tile whose core is ``core`` (x0, y0, x1, y1)?"""
        x0, y0, x1, y1 = core
        x, y = v.x_m, v.y_m
        if not self.active or min(x - x0, x1 - x, y - y0, y1 - y) >= self.reach:
            return True
        geoms, xy, r = self.index.polygons(x, y, v.heading_rad, v.length_m, v.width_m)
        h = np.array([np.nan if v.state == "parked" else v.heading_rad])  # parked: no lane
        if self.index.collides_many(geoms, xy, r, heading=h)[0]:
            self.dropped += 1
            return False
        self.index.add_many(geoms, xy, r, h)
        return True


def _place_tile(job) -> dict:
    """Place one tile: its window's scene, ``place()`` with the tile's seed, and the vehicles
    its core owns. Runs in the caller's process or in a pool worker."""
    world, grid, tile, cfg, seed, want, catalog, nthreads, by_core = job
    ts = time.perf_counter()
    cs = _cpu()
    scene = world.scene_for(tile.window)
    rs = RayScene(scene, nthreads=nthreads)
    rs.trace_labels(np.zeros((1, 2)))  # builds the BVH now: it is part of the scene build
    scene_s = time.perf_counter() - ts
    scene_cpu = _cpu() - cs
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", PlacementWarning)
        try:
            region = (tile.core, lambda xy: grid.owns(tile, xy)) if by_core else None
            pl = place(rs, cfg, np.random.default_rng(seed), n_vehicles=want, catalog=catalog,
                       scene_name=world.name, region=region)
        except PlacementError as exc:
            if "found no road" not in str(exc):
                raise
            pl = None  # a tile without roads (a park, a lake) holds no vehicles
    out = {"warnings": own_warnings(caught), "scene_s": scene_s, "place_s": 0.0,
           "scene_cpu_s": scene_cpu, "place_cpu_s": _cpu() - cs - scene_cpu,
           "owned": [], "placed": 0, "max_line": -1, "stats": None, "rays": 0, "casts": 0,
           "stopped_full": False}
    if pl is None:
        return out
    xy = np.array([[v.x_m, v.y_m] for v in pl.vehicles]).reshape(-1, 2)
    own = grid.owns(tile, xy) if len(xy) else np.zeros(0, bool)
    out.update(place_s=pl.timing.get("seconds", 0.0), placed=len(pl.vehicles), stats=pl.stats,
               rays=int(pl.stats.get("rays", 0)), casts=int(pl.stats.get("casts", 0)),
               stopped_full=bool(pl.stats.get("stopped_full", False)),
               owned=[v for v, o in zip(pl.vehicles, own) if o],
               max_line=max([v.line_id for v in pl.vehicles], default=-1))
    return out


def _cpu() -> float:
    """CPU seconds of this process so far (user + system, all its threads)."""
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _pool_init(nthreads: int) -> None:
    """Share the cores among the pool's processes (numba; Embree gets ``nthreads`` per RayScene)."""
    import os

    os.environ["OMP_NUM_THREADS"] = str(nthreads)
    import numba

    numba.set_num_threads(max(1, min(nthreads, numba.config.NUMBA_NUM_THREADS)))


#: How often the tiles' pool is started again after one of its workers died.
MAX_POOL_RESTARTS = 3


def _pool_map(jobs, workers: int):
    """Tiles on a spawn process pool, results in tile order (streamed).

    A worker that dies (the OOM killer's SIGKILL, say) breaks the pool: the tiles not yet
    returned are placed again on a new pool (a tile's result depends only on its job), up
    to :data:`MAX_POOL_RESTARTS` times, then one PlacementError."""
    import multiprocessing as mp
    import os
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    n = max(1, (os.cpu_count() or 1) // int(workers))
    jobs = [j[:7] + (n,) + j[8:] for j in jobs]
    start, restarts = 0, 0
    while start < len(jobs):
        try:
            with ProcessPoolExecutor(int(workers), mp_context=mp.get_context("spawn"), initializer=_pool_init,
                                     initargs=(n,)) as ex:
                for res in ex.map(_place_tile, jobs[start:]):
                    start += 1
                    yield res
        except BrokenProcessPool:
            restarts += 1
            if restarts > MAX_POOL_RESTARTS:
                raise PlacementError(
                    f"--workers {workers}: a worker process died {restarts} times (out of memory? each "
                    "worker builds one tile's window at a time: a smaller --tile-m needs less)"
                ) from None
            warnings.warn(f"a worker process died; the tiles from tile {start + 1} of {len(jobs)} on are "
                          f"placed again on a new pool (restart {restarts} of at most {MAX_POOL_RESTARTS})",
                          RuntimeWarning, stacklevel=2)
