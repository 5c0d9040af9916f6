"""Exports of a tiled world: each worker holds a few tiles, never the whole world.

``aerial-synth export --tile-m T [--margin-m M]`` cuts the scene into the square tiles of a
:class:`~aerial_synth.scene.tiles.TileGrid` (a ``generator: city`` spec is generated per
window; any other scene is loaded once and cut). What changes against an untiled export:

**Placement group -> tile.** Group ``g`` renders around one tile, drawn from
``SeedSequence([seed, g, TILE_STREAM])`` (redrawn, up to :data:`TILE_DRAWS` times, when the
tile's core holds no vehicle). Its traffic is the whole world's tiled placement with the
group's seed ``SeedSequence([seed, g, PLACEMENT_STREAM])`` (``place_tiled``: per-tile seeds
of the whole grid, vehicles decided by the tile owning their centre, border collisions
resolved in raster order), restricted to the area the group's cameras can see. Only the
tiles that can change a vehicle of that area are placed (:func:`tiles_needed`): a vehicle
of tile A is dropped at a border only for a colliding vehicle of an earlier tile B (raster
order) that was itself kept, so the dependence runs in chains of collisions, each link
shorter than :func:`hop_m` and going to a strictly earlier tile; :func:`dependency_m`
bounds how far such a chain can reach, and every tile within that distance of the area is
placed. The group's vehicles are then exactly those of a whole-world ``place_tiled`` run.

**Vehicle ids** must not depend on the rest of the world (a whole-world run numbers
vehicles 1..N in merge order, which needs every earlier tile). They are tile-stable:
``id = rank * stride + k`` where ``rank = j * nx + i`` is the tile's raster rank, ``k``
the vehicle's number in its own tile (1, 2, ... in the tile's placement order) and
``stride`` (:func:`id_stride`) one more than the vehicles a tile's core can hold. A grid of
one tile gives the untiled ids (rank 0). Line ids are offset the same way.

**Cameras** aim at the group's vehicles with their ground footprint inside the tile's core
grown by the camera's reach (:func:`camera_reach_m`: the farthest footprint corner from the
targeted vehicle at the largest tilt, plus the aim jitter, rounded up to a metre; clipped to
the world), so a camera aimed at any vehicle of the core fits. The reach follows the camera
options by itself; ``margin_m`` is only the placement margin (as ``place-tiled``: how far a
tile's placement window reaches past its core, 60 m when left out).

**Render scene** of a group: the window ``core + reach + render pad`` with the group's
vehicles; built once per group and kept per worker for the next group on the same tile.
The pads (:func:`export_pads`) follow from the world, the render config and the camera
through :func:`aerial_synth.render.cull.secondary_reach_m`, the reach past the seen area
of a shadow (``dz / tan(lowest sun)``), of a wet road's mirror image or of a tall object
seen obliquely (``dz * tan(largest view angle)``, :func:`max_view_deg`) and of ambient
occlusion: the render pad for the world's tallest structure
(:meth:`~aerial_synth.scene.tiles.TiledWorld.structure_height_m`), the vehicle area's pad
for the tallest vehicle of the catalog plus its footprint radius. The default city (32.8 m
with roof details) at the presets' 24 deg lowest sun needs 74.7 m (``fast``) or 76.7 m
(``full``: AO, wet-road mirror images at the 39.5 deg view of a 96 px camera) where 80 m
were fixed before (same images), 95 m for ``full`` at the default camera (a 91 deg field of
view tilted 15 deg: mirror rays 70 deg off the vertical); a city of 60 m buildings 142-179
m. The vehicle pad keeps its old value (the longest vehicle + :data:`VEHICLE_PAD_M`, 28.5
m) as a floor: the cameras aim at the area's vehicles. Both pads are capped at
:data:`MAX_PAD_M` (memory: a window grows with the square of its side); a cap that cuts a
derived pad (e.g. a sun under 3 deg: unbounded shadows) adds one line to the placement
warnings of every image, and the exporter prints it once.

A grid of one tile (``--tile-m`` at least the world's size) renders the untiled export's
images and labels.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np

from .. import validators as V
from ..camera import Camera
from ..errors import ExportError, PlacementError
from ..placement.config import DEFAULT_MARGIN_M, load_scenario
from ..placement.model import Placement
from ..placement.tiled import BorderMerge, min_tile_m, place_tiled
from ..placement.traffic import lane_rule
from ..render.cull import lowest_sun_deg, secondary_reach_m
from ..scene.tiles import TiledWorld
from ..vehicles import load_catalog
from .seeds import PLACEMENT_STREAM

__all__ = [
    "GroupPlacer",
    "grow_rect",
    "TILE_STREAM",
    "MAX_PAD_M",
    "camera_reach_m",
    "check_tiled_config",
    "dependency_m",
    "export_pads",
    "group_placement",
    "group_tile",
    "hop_m",
    "id_stride",
    "load_world",
    "max_view_deg",
    "nadir_in_view",
    "tiles_needed",
]

#: third SeedSequence word of a group's tile draw: [seed, group, TILE_STREAM]
TILE_STREAM = 2
#: draws of a group's tile before giving up on tiles whose core holds no vehicle
TILE_DRAWS = 16
#: the least the vehicle area reaches past the camera area, added to the longest vehicle
#: (the fixed pad before :func:`export_pads` derived it; kept as a floor: the group's
#: cameras aim at the vehicles of that area, so a smaller area would redraw every camera)
VEHICLE_PAD_M = 12.0
#: the most either pad may be: a render window of a 500 m tile and a 176 m camera reach is
#: then at most 1.45 km square
MAX_PAD_M = 300.0
#: the most vehicle ids an export may use (int32 instance ids)
MAX_ID = 2**31 - 1


# ------------------------------------------------------------------ geometry


def camera_reach_m(cam_cfg, jitter_frac: float = 0.25) -> float:
    """How far (xy metres) a targeted camera's ground footprint can reach from the vehicle
    it aims at: the farthest footprint corner over yaw, tilt up to ``max_tilt_deg`` and tilt
    axis, plus the aim jitter (``sample_pose_targeted``: up to ``jitter_frac`` of the
    footprint's half width on each axis)."""
    half = 0.5 * min(cam_cfg.width_px, cam_cfg.height_px) * cam_cfg.nadir_gsd_m
    jitter = math.hypot(jitter_frac * half, jitter_frac * half)
    tilts = [0.0] if not cam_cfg.max_tilt_deg else [cam_cfg.max_tilt_deg, -cam_cfg.max_tilt_deg]
    far = 0.0
    for tilt in tilts:
        for axis in np.arange(0.0, 180.0, 1.0):
            cam = Camera.look_at_ground(cam_cfg, (0.0, 0.0, 0.0), yaw_deg=0.0, tilt_deg=tilt,
                                        tilt_axis_deg=float(axis))
            fp = cam.ground_footprint_xy(0.0)
            if not np.isfinite(fp).all():
                return math.inf
            far = max(far, float(np.hypot(fp[:, 0], fp[:, 1]).max()))
    if far > 50.0 * cam_cfg.altitude_m:  # a corner ray at or past the horizon
        return math.inf
    # the axis is sampled every degree: the corner distance varies smoothly with it; 1 %
    # covers the angles between samples
    return 1.01 * far + jitter


def max_view_deg(cam_cfg) -> float:
    """The largest angle (degrees) off the vertical of a ray of a camera of ``cam_cfg``: the
    largest tilt plus the image corner's angle off the optical axis (reached when the tilt
    axis is square to the corner's direction)."""
    half = math.hypot(0.5 * cam_cfg.width_px, 0.5 * cam_cfg.height_px)
    return float(cam_cfg.max_tilt_deg) + math.degrees(math.atan(half / cam_cfg.f_px))


def nadir_in_view(cam_cfg) -> bool:
    """Whether every camera of ``cam_cfg`` sees the point straight below it (its tilt at
    most the half field of view across the image's narrower side). Its view between the
    ground and any height then lies over its ground footprint: a tall object outside the
    footprint never shows directly."""
    half = 0.5 * min(cam_cfg.width_px, cam_cfg.height_px)
    return math.tan(math.radians(float(cam_cfg.max_tilt_deg))) * cam_cfg.f_px <= half


@dataclasses.dataclass(frozen=True)
class Pads:
    """How far (metres) a group's render window (``render_m``) and its vehicle area
    (``vehicle_m``) reach past its camera area; ``warning``: the line saying what the
    :data:`MAX_PAD_M` cap cut, or None."""

    render_m: float
    vehicle_m: float
    warning: str | None = None


def export_pads(world, render_config, cam_cfg, catalog) -> Pads:
    """The pads of a tiled export (:class:`Pads`).

    Render window: :func:`~aerial_synth.render.cull.secondary_reach_m` of the world's tallest
    structure above its lowest surface, counting what ``render_config`` renders, at the
    camera's largest view angle (:func:`max_view_deg`) and the world's road slope
    (``oblique`` only for cameras that can tilt their nadir out of view,
    :func:`nadir_in_view`: the camera area is their ground footprints). Vehicle
    area: the same reach of the tallest vehicle standing on the highest drivable surface,
    plus the largest footprint radius (half the diagonal), and at least the longest vehicle +
    :data:`VEHICLE_PAD_M` (its fixed value before). Both at most :data:`MAX_PAD_M`."""
    models = _catalog_models(catalog)
    view = max_view_deg(cam_cfg)
    slope = world.surface_slope_deg()
    kw = {"enabled_only": True, "oblique": not nadir_in_view(cam_cfg)}
    if slope is not None:
        kw["slope_deg"] = slope
    tall = world.structure_height_m()
    render = secondary_reach_m(tall, render_config, view, **kw)
    v_dz = max(m.height_m for m in models) + world.drive_height_m()
    radius = max(0.5 * math.hypot(m.length_m, m.width_m) for m in models)
    vehicle = radius + secondary_reach_m(v_dz, render_config, view, **kw)
    vehicle = max(max(m.length_m for m in models) + VEHICLE_PAD_M, vehicle)
    cut = [(what, need) for what, need in (("render window", render), ("vehicle area", vehicle))
           if need > MAX_PAD_M]
    warning = None
    if cut:
        sun = lowest_sun_deg(render_config)
        needs = ", ".join(f"the {what} {'an unbounded pad' if not math.isfinite(need) else f'{need:.0f} m'}"
                          for what, need in cut)
        warning = (f"tiled export: pads capped at {MAX_PAD_M:g} m past the camera area, short of what "
                   f"shadows, mirror images and oblique views of {tall:g} m structures and "
                   f"{v_dz:.2f} m vehicles need at a {sun:g} deg sun and a {view:.1f} deg view "
                   f"({needs}): those of farther ones are cut at the window's edge")
    return Pads(float(min(render, MAX_PAD_M)), float(min(vehicle, MAX_PAD_M)), warning)


def _catalog_models(catalog):
    models = getattr(catalog, "models", catalog)
    return list(models.values()) if isinstance(models, dict) else list(models)


def hop_m(scenario_cfg, catalog) -> float:
    """The longest centre distance of two colliding vehicles: a link of a drop chain
    (footprints within the gap, centres within the minimum distance, or two vehicles of one
    lane within the lane rule's spacing)."""
    diag = max(math.hypot(m.length_m, m.width_m) for m in _catalog_models(catalog))
    rule = lane_rule(scenario_cfg)
    return max(diag + max(scenario_cfg.gap_m, 0.0), float(scenario_cfg.min_center_distance_m or 0.0),
               float(rule[0]) if rule is not None else 0.0)


def _cells_met(edges: np.ndarray, span: float) -> int:
    """The most cells (between consecutive ``edges``) a closed interval of length ``span``
    can meet."""
    n = len(edges) - 1
    k = np.arange(n)
    # an interval starting on the far edge of cell k meets k and the cells whose near edge
    # it reaches (the most for closed intervals is reached with an end on an edge)
    m = 1 + np.searchsorted(edges[:n], edges[1:] + span, side="right") - (k + 1)
    return int(max(1, np.minimum(m, n - k).max()))


def dependency_m(grid, hop: float) -> float:
    """How far a vehicle's keep-or-drop decision can depend on other vehicles.

    A chain of h drops links h + 1 vehicles of h + 1 distinct tiles (each link goes to a
    strictly earlier tile in raster order), all within h * hop of its first vehicle, so h + 1
    is at most the number of tiles a square of half-size h * hop can meet. The longest
    possible chain plus one spare link (collisions inside a tile, which ``place`` avoids),
    times ``hop``; ``inf`` when a chain could cross the whole world."""
    ex, ey = grid._edges(0), grid._edges(1)
    world = float(np.hypot(*(grid.bounds[1] - grid.bounds[0])))
    h = 1
    while h + 1 <= _cells_met(ex, 2 * h * hop) * _cells_met(ey, 2 * h * hop):
        h += 1
        if (h - 1) * hop > world:
            return math.inf
    return h * hop  # chains have at most h - 1 links; one spare


def id_stride(grid, catalog) -> int:
    """One more than the vehicles one tile's core can own (footprints never overlap; a
    centre in the core keeps the footprint within half the longest vehicle of it)."""
    models = _catalog_models(catalog)
    longest = max(m.length_m for m in models)
    smallest = min(m.length_m * m.width_m for m in models)
    w = min(grid.tile_m, float(grid.bounds[1, 0] - grid.bounds[0, 0])) + longest
    h = min(grid.tile_m, float(grid.bounds[1, 1] - grid.bounds[0, 1])) + longest
    return int(w * h / smallest) + 2


def grow_rect(rect, d: float, bounds=None):
    """``rect`` (x0, y0, x1, y1) grown by ``d`` on every side, clipped to ``bounds``
    ([[xmin, ymin], [xmax, ymax]]) when given."""
    x0, y0, x1, y1 = rect
    r = (x0 - d, y0 - d, x1 + d, y1 + d)
    if bounds is not None:
        (bx0, by0), (bx1, by1) = bounds
        r = (max(bx0, r[0]), max(by0, r[1]), min(bx1, r[2]), min(by1, r[3]))
    return tuple(float(c) for c in r)


def tiles_needed(grid, area, dep: float):
    """The tiles whose vehicles can change what stands in ``area`` (x0, y0, x1, y1): those
    whose core meets it grown by ``dep`` (:func:`dependency_m`), raster order."""
    if not math.isfinite(dep):
        return grid.tiles()
    return grid.touching(grow_rect(area, dep))


# ------------------------------------------------------------------ config




def check_tiled_config(cfg) -> float:
    """Validate the tiled options of an ExportConfig; returns the placement margin to use
    (:data:`DEFAULT_MARGIN_M` when ``margin_m`` is None)."""
    E = ExportError
    tile = V.in_range("--tile-m", cfg.tile_m, 0.0, 1e9, lo_open=True, error=E)
    for flag, field, why in (("--labels", "labels", "label rules are applied to a whole loaded scene"),
                             ("--distractors", "distractors", "distractors are drawn over the whole scene"),
                             ("--lines", "n_lines", "tiled placement asks each tile for vehicles, not lines")):
        val = getattr(cfg, field)
        if val is not None:
            raise E(f"--tile-m: cannot be combined with {flag} ({why}), got {flag} {V.show(val)}")
    longest = min_tile_m()
    if tile < longest:
        raise E(f"--tile-m: expected a tile size of at least the longest vehicle ({longest:g} m), got {tile:g}")
    cam = cfg.camera_config()
    if not math.isfinite(camera_reach_m(cam)):
        raise E(f"--max-tilt: a tiled export needs image corners that see the ground within 50 x the "
                f"altitude (its render window is the footprint's reach), got {cam.max_tilt_deg:g} deg "
                f"with a {2 * math.degrees(math.atan(0.5 * cam.width_px / cam.f_px)):.0f} deg field of view")
    if cfg.margin_m is None:
        return DEFAULT_MARGIN_M
    return float(V.in_range("--margin-m", cfg.margin_m, 0.0, 1e9, error=E))


def load_world(cfg):
    """The export's :class:`~aerial_synth.scene.tiles.TiledWorld` (a city spec costs only its
    street positions here; other scenes are loaded once)."""
    return TiledWorld.load(cfg.scene, seed=cfg.scene_seed, bbox=cfg.bbox, crs=cfg.crs)


# --------------------------------------------------------------- placement


def group_tile(cfg, grid, group: int, draw: int = 0):
    """The tile of placement group ``group`` (``draw``: the redraw number)."""
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, group, TILE_STREAM, draw]))
    nx, ny = grid.shape
    k = int(rng.integers(nx * ny))
    return grid.tile(k % nx, k // nx)


class GroupPlacer:
    """Places the tiles a group needs, one ``place_tiled(only=[tile])`` call each (the whole
    grid's seeds), and merges them in raster order with ``place_tiled``'s border rule."""

    def __init__(self, world, grid, cfg, catalog):
        self.world, self.grid, self.cfg, self.catalog = world, grid, cfg, catalog
        self.scenario = load_scenario(cfg.scenario)
        self.longest = max(m.length_m for m in _catalog_models(catalog))
        self.dep = dependency_m(grid, hop_m(self.scenario, catalog))
        self.stride = id_stride(grid, catalog)
        self.reach = float(math.ceil(camera_reach_m(cfg.camera_config())))
        # a capped pad is in every image's placement warnings; the exporter prints it once
        # (validate_inputs), not every worker
        self.pads = export_pads(world, cfg.render.config(), cfg.camera_config(), catalog)
        if len(grid) * self.stride > MAX_ID:
            raise ExportError(
                f"--tile-m: {len(grid)} tiles of up to {self.stride - 1} vehicles each cannot be "
                f"numbered in 31-bit ids; use larger tiles, got {grid.tile_m:g}")
        self._cache: dict = {}  # (group seed, tile) -> (vehicles, warnings)

    def tile_vehicles(self, group: int, tile):
        """The vehicles tile ``tile`` owns for group ``group``, tile-stable ids."""
        key = (group, tile.key)
        if key in self._cache:
            return self._cache[key]
        ss = np.random.SeedSequence([self.cfg.seed, group, PLACEMENT_STREAM])
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                pl = place_tiled(self.world, self.grid, self.cfg.scenario, seed=ss,
                                 n_vehicles=self.cfg.n_vehicles, catalog=self.catalog,
                                 only=[tile.key])
                vs = pl.vehicles
            except PlacementError as exc:
                if "no tile held a road" not in str(exc):
                    raise
                vs = []
        rank = tile.j * self.grid.shape[0] + tile.i
        base = rank * self.stride
        out = []
        for v in vs:
            if v.id >= self.stride or v.line_id >= self.stride:
                raise ExportError(f"tile {list(tile.key)}: vehicle or line number {max(v.id, v.line_id)} "
                                  f"exceeds the tile's id block of {self.stride - 1}")
            out.append(dataclasses.replace(v, id=base + v.id,
                                           line_id=base + v.line_id if v.line_id >= 0 else -1))
        res = (out, sorted({str(w.message) for w in caught}), pl if vs else None)
        if len(self._cache) > 32:
            self._cache.clear()
        self._cache[key] = res
        return res

    def placement(self, group: int, tile, area):
        """The whole world's vehicles (group ``group``) whose centre lies in ``area``."""
        sc = self.scenario
        merge = BorderMerge(sc, self.longest, len(self.grid))
        needed = tiles_needed(self.grid, area, self.dep)
        kept, warned, ref = [], set(), None
        for t in needed:  # raster order, as place_tiled merges
            vs, w, pl = self.tile_vehicles(group, t)
            warned.update(w)
            ref = ref or pl
            kept += [v for v in vs if merge.keep(v, t.core)]
        ax0, ay0, ax1, ay1 = area
        inside = [v for v in kept if ax0 <= v.x_m <= ax1 and ay0 <= v.y_m <= ay1]
        g = self.grid
        tile_meta = {
            "index": [tile.i, tile.j],
            "core_m": [round(c, 6) for c in tile.core],
            "grid": list(g.shape),
            "tile_m": g.tile_m,
            "margin_m": g.margin_m,
            "camera_reach_m": self.reach,
            "id_stride": self.stride,
            "tiles_placed": len(needed),
        }
        params = dict(ref.parameters) if ref is not None else self.scenario.to_dict()
        params["tile"] = tile_meta
        out = Placement(
            scene=self.world.name,
            scenario=sc.name,
            seed=None,
            parameters=params,
            vehicles=inside,
            stats={"vehicles": len(inside), "tiles": {**tile_meta, "dropped_at_borders": merge.dropped}},
            georeference=ref.georeference if ref is not None else None,
        )
        return out, sorted(warned)


def group_placement(world, grid, cfg, group: int, catalog=None, placer=None):
    """Group ``group``'s tile, camera area, vehicles and warnings: (tile, within, vehicle
    area, Placement, warnings). ``within``: where the cameras' footprints must lie."""
    if catalog is None:
        catalog = load_catalog()
    placer = placer or GroupPlacer(world, grid, cfg, catalog)
    bounds = grid.bounds
    for draw in range(TILE_DRAWS):
        tile = group_tile(cfg, grid, group, draw)
        owned, _, _ = placer.tile_vehicles(group, tile)
        if owned or len(grid) == 1:
            break
    else:
        raise ExportError(f"placement group {group}: {TILE_DRAWS} tiles drawn, none holds a vehicle "
                          f"(scenario {cfg.scenario!r} on scene {cfg.scene!r}: no road?)")
    within = grow_rect(tile.core, placer.reach, bounds)
    area = grow_rect(within, placer.pads.vehicle_m, bounds)
    pl, warned = placer.placement(group, tile, area)
    if placer.pads.warning is not None:
        warned = sorted({*warned, placer.pads.warning})
    return tile, within, area, pl, warned
