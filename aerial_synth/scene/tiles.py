"""Tiles of a large world: square cores with margins, loaded one window at a time.

A world is cut into square tiles of ``tile_m`` metres (the last row and column may be
narrower). Each tile **owns** its core, a half-open rectangle ``[x0, x1) x [y0, y1)`` (the
world's far edges are closed), so every point of the world belongs to exactly one tile.
A tile's **window** is its core grown by ``margin_m`` on every side and clipped to the
world: placement works in the window so that vehicles near the border see their
neighbours, then keeps only what the core owns (see :mod:`aerial_synth.placement.tiled`).

Worlds come from one of two sources (:class:`TiledWorld`):

* a procedural spec whose generator can build any window on its own (``city``: the
  window's content is decided by the world seed and block indices only, so a 100 km world
  is never in memory at once), via the spec key ``window_m``;
* an in-memory :class:`~aerial_synth.scene.model.Scene` (a mesh file, a small spec): a
  window keeps the whole triangles whose bounding box meets it. This bounds the ray
  tracing structures, not the loaded mesh.

A render task needs only the tiles its camera footprint touches:
:meth:`TiledWorld.scene_for_xy` builds the scene of the rectangle of those tiles' cores
(grown by ``pad_m`` for shadows and tilted views).

World frame: metres, x east, y north, z up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..errors import SceneError
from .io import SCENES_DIR, load_scene, read_yaml
from .model import Scene, SceneObject
from .procedural import generate
from .procedural.builder import Z_GROUND, Z_MARKING
from .procedural.city import city_max_height_m, with_size_m

__all__ = ["Tile", "TileGrid", "TiledWorld", "cut_scene"]

Rect = tuple[float, float, float, float]  # x0, y0, x1, y1 (metres, world frame)


@dataclass(frozen=True)
class Tile:
    """One tile: indices (column i from the west, row j from the south), core and window."""

    i: int
    j: int
    core: Rect
    window: Rect

    @property
    def key(self) -> tuple[int, int]:
        return (self.i, self.j)


class TileGrid:
    """Square tiles over ``bounds`` ((2, 2): [[xmin, ymin], [xmax, ymax]], metres).

    tile_m   : core edge length (> 0; the last column/row takes what is left)
    margin_m : how far a window reaches past its core (>= 0)
    """

    def __init__(self, bounds, tile_m: float, margin_m: float = 0.0):
        b = np.asarray(bounds, dtype=np.float64).reshape(2, 2)
        if not (np.isfinite(b).all() and (b[1] > b[0]).all()):
            raise SceneError(f"tile grid: bounds must be [[xmin, ymin], [xmax, ymax]] with max > min, got {b.tolist()}")
        for name, v, lo in (("tile_m", tile_m, 0.0), ("margin_m", margin_m, -1.0)):
            try:
                f = float(v)
            except (TypeError, ValueError):
                f = float("nan")
            if isinstance(v, bool) or not math.isfinite(f) or f <= lo or (name == "margin_m" and f < 0):
                want = "> 0" if name == "tile_m" else ">= 0"
                raise SceneError(f"tile grid: {name} must be a number of metres {want}, got {v!r}")
        self.bounds = b
        self.tile_m = float(tile_m)
        self.margin_m = float(margin_m)
        ext = b[1] - b[0]
        # a sliver under 1 mm (float noise) does not make its own tile
        self.shape = tuple(max(1, int(math.ceil(e / self.tile_m - 1e-9))) for e in ext)  # (nx, ny)

    def __len__(self) -> int:
        return self.shape[0] * self.shape[1]

    def _edges(self, axis: int) -> np.ndarray:
        lo, hi = self.bounds[0, axis], self.bounds[1, axis]
        e = lo + self.tile_m * np.arange(self.shape[axis] + 1)
        e[-1] = hi
        return e

    def tile(self, i: int, j: int) -> Tile:
        ex, ey = self._edges(0), self._edges(1)
        core = (float(ex[i]), float(ey[j]), float(ex[i + 1]), float(ey[j + 1]))
        m = self.margin_m
        (bx0, by0), (bx1, by1) = self.bounds
        win = (max(bx0, core[0] - m), max(by0, core[1] - m), min(bx1, core[2] + m), min(by1, core[3] + m))
        return Tile(i, j, core, win)

    def tiles(self) -> list[Tile]:
        """All tiles in raster order: rows from the south, columns from the west."""
        return [self.tile(i, j) for j in range(self.shape[1]) for i in range(self.shape[0])]

    def owner(self, xy) -> np.ndarray:
        """(n, 2) column, row of the tile owning each point (n, 2); -1 outside the world.

        Cores are half-open [x0, x1) except at the world's east/north edge (closed)."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        out = np.full((len(xy), 2), -1, np.int64)
        inside = ((xy >= self.bounds[0]) & (xy <= self.bounds[1])).all(axis=1)
        for a in range(2):
            e = self._edges(a)
            k = np.searchsorted(e, xy[:, a], side="right") - 1
            k = np.clip(k, 0, self.shape[a] - 1)
            out[:, a] = np.where(inside, k, -1)
        return out

    def owns(self, tile: Tile, xy) -> np.ndarray:
        """(n,) bool: the points (n, 2) that ``tile`` owns."""
        o = self.owner(xy)
        return (o[:, 0] == tile.i) & (o[:, 1] == tile.j)

    def touching(self, rect: Rect) -> list[Tile]:
        """Tiles whose core meets the rectangle (x0, y0, x1, y1), raster order."""
        x0, y0, x1, y1 = rect
        ex, ey = self._edges(0), self._edges(1)
        ii = [i for i in range(self.shape[0]) if ex[i + 1] >= x0 and ex[i] <= x1]
        jj = [j for j in range(self.shape[1]) if ey[j + 1] >= y0 and ey[j] <= y1]
        return [self.tile(i, j) for j in jj for i in ii]


class TiledWorld:
    """A world that can produce the scene of any rectangular window.

    Build with :meth:`from_spec` (procedural, generated per window) or :meth:`from_scene`
    (an in-memory scene, cut per window). ``bounds`` is the world's (2, 2) xy extent.
    """

    def __init__(self, name: str, bounds, spec: Mapping | None = None, seed: int | None = None,
                 scene: Scene | None = None):
        self.name = name
        self.bounds = np.asarray(bounds, dtype=np.float64).reshape(2, 2)
        self._spec = spec
        self._seed = seed
        self._scene = scene
        self.windows_built = 0  # how many window scenes were made (tests, benchmarks)

    @classmethod
    def from_spec(cls, spec: Mapping, seed: int | None = None) -> "TiledWorld":
        """A procedural world whose generator supports ``window_m`` (the ``city``)."""
        spec = with_size_m(spec)
        if not isinstance(spec, Mapping) or spec.get("generator") != "city":
            got = spec.get("generator") if isinstance(spec, Mapping) else type(spec).__name__
            raise SceneError(f"tiled world: field 'generator' must be city (windows are generated), got {got!r}; "
                             "use TiledWorld.from_scene for other scenes")
        w, h = (float(v) for v in spec["size_m"])
        return cls(str(spec.get("name", "city")), [[-w / 2, -h / 2], [w / 2, h / 2]], spec=dict(spec), seed=seed)

    @classmethod
    def from_scene(cls, scene: Scene) -> "TiledWorld":
        return cls(scene.name, scene.bounds()[:, :2], scene=scene)

    @classmethod
    def load(cls, name_or_path, seed: int | None = None, bbox=None, crs=None) -> "TiledWorld":
        """A bundled scene name, a spec or a mesh file: city specs are generated per window,
        everything else is loaded once and cut. bbox/crs: OSM extracts only (load_scene)."""
        from pathlib import Path


        if bbox is not None or crs is not None:  # an OSM extract (load_scene refuses others)
            return cls.from_scene(load_scene(name_or_path, seed=seed, bbox=bbox, crs=crs))

        s = str(name_or_path)
        p = Path(s)
        if p.suffix.lower() not in (".yaml", ".yml") and not (p.suffix or "/" in s):
            p = SCENES_DIR / f"{s}.yaml"
        if p.suffix.lower() in (".yaml", ".yml") and p.is_file():
            data = read_yaml(p, "scene spec")
            if isinstance(data, Mapping) and data.get("generator") == "city":
                return cls.from_spec(data, seed=seed)
        return cls.from_scene(load_scene(name_or_path, seed=seed))

    def structure_height_m(self) -> float:
        """How far the world's tallest structure rises above its lowest surface (metres): a
        ``city`` spec's bound from its parameters (:func:`~.procedural.city.city_max_height_m`:
        tallest building with roof details, trees, poles), a scene's z extent otherwise."""
        if self._spec is not None:
            return city_max_height_m(self._spec)
        b = self._scene.bounds()
        return max(float(b[1, 2] - b[0, 2]), 0.0)

    def drive_height_m(self) -> float:
        """How far a vehicle's wheels can stand above the world's lowest surface (metres): a
        city's road surfaces are at most 6 cm above its ground; a scene's highest drivable
        surface (``label_config.drivable``) above its lowest vertex (its z extent when it
        has none)."""
        if self._spec is not None:
            return Z_MARKING - Z_GROUND
        sc = self._scene
        drivable = sc.label_config.drivable
        tops = [float(o.vertices[:, 2].max()) for o in sc.objects
                if o.label in drivable and len(o.vertices)]
        if not tops:
            return self.structure_height_m()
        return max(max(tops) - float(sc.bounds()[0, 2]), 0.0)

    def surface_slope_deg(self) -> float | None:
        """The steepest tilt of a wet-glossed surface off the horizontal that a mirror ray
        can leave from: 0 for a city (its roads, markings, sidewalks and flat roofs are
        horizontal, their sides vertical: a ray reflected off a vertical face keeps its
        downward angle), None (not known: the cull's margin applies) for a scene."""
        return 0.0 if self._spec is not None else None

    def georeference(self) -> dict:
        """``Scene.georeference()`` of the world's scenes (a generated city: origin 0, no CRS)."""
        if self._scene is not None:
            return self._scene.georeference()
        return {"origin": [0.0, 0.0, 0.0], "crs": None}

    def grid(self, tile_m: float, margin_m: float = 0.0) -> TileGrid:
        return TileGrid(self.bounds, tile_m, margin_m)

    def covers_world(self, rect: Rect) -> bool:
        (bx0, by0), (bx1, by1) = self.bounds
        return rect[0] <= bx0 and rect[1] <= by0 and rect[2] >= bx1 and rect[3] >= by1

    def scene_for(self, rect: Rect) -> Scene:
        """The scene of the window ``rect`` (x0, y0, x1, y1), clipped to the world. A window
        that covers the whole world gives the untiled scene."""
        x0, y0, x1, y1 = (float(v) for v in rect)
        self.windows_built += 1
        if self._spec is not None:
            spec = dict(self._spec)
            if not self.covers_world((x0, y0, x1, y1)):
                spec["window_m"] = [x0, y0, x1, y1]
            return generate(spec, seed=self._seed, source=f"procedural:{self.name}")
        assert self._scene is not None
        if self.covers_world((x0, y0, x1, y1)):
            return self._scene
        return cut_scene(self._scene, (x0, y0, x1, y1))

    def scene_for_xy(self, grid: TileGrid, xy, pad_m: float = 30.0) -> tuple[Scene, list[Tile]]:
        """The scene a render task needs: the tiles whose cores meet the bounding box of the
        points ``xy`` (n, 2) (e.g. a camera's ground footprint) grown by ``pad_m``; the
        window is the rectangle of those cores grown by ``pad_m`` (clipped to the world)."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        lo, hi = xy.min(axis=0) - pad_m, xy.max(axis=0) + pad_m
        tiles = grid.touching((lo[0], lo[1], hi[0], hi[1]))
        if not tiles:
            raise SceneError(f"tiled world {self.name!r}: the area {lo.tolist()}..{hi.tolist()} lies outside the world")
        cx0 = min(t.core[0] for t in tiles) - pad_m
        cy0 = min(t.core[1] for t in tiles) - pad_m
        cx1 = max(t.core[2] for t in tiles) + pad_m
        cy1 = max(t.core[3] for t in tiles) + pad_m
        (bx0, by0), (bx1, by1) = self.bounds
        rect = (max(bx0, cx0), max(by0, cy0), min(bx1, cx1), min(by1, cy1))
        return self.scene_for(rect), tiles


def cut_scene(scene: Scene, rect: Rect) -> Scene:
    """The whole triangles of ``scene`` whose xy bounding box meets ``rect`` (objects with
    none are dropped; vertices are compacted)."""
    x0, y0, x1, y1 = rect
    objs = []

    for o in scene.objects:
        v, f = o.vertices, o.faces
        if not len(f):
            continue
        tri = v[f][:, :, :2]  # (m, 3, 2)
        lo, hi = tri.min(axis=1), tri.max(axis=1)
        keep = (hi[:, 0] >= x0) & (lo[:, 0] <= x1) & (hi[:, 1] >= y0) & (lo[:, 1] <= y1)
        if not keep.any():
            continue
        if keep.all():
            objs.append(o)
            continue
        ff = f[keep]
        used, inv = np.unique(ff, return_inverse=True)
        objs.append(SceneObject(o.name, o.label, v[used], inv.reshape(-1, 3), material=o.material, color=o.color))
    return Scene(name=scene.name, objects=objs, source=scene.source, truth=None, label_config=scene.label_config,
                 meta={**scene.meta, "window_m": [float(c) for c in rect]}, origin=scene.origin, crs=scene.crs, hints=scene.hints)

