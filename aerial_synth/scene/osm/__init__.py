"""Scenes from OpenStreetMap extracts (``.osm``, ``.osm.bz2``, ``.osm.pbf``), fully offline.

Public API::

    build_osm_scene(path, bbox=None, crs=None, seed=0) -> Scene
    load_osm_scene(path, bbox=None, crs=None, seed=0, cache_dir=None) -> Scene   (cached)
    parse_bbox("MINLON,MINLAT,MAXLON,MAXLAT") -> tuple
    resolve_crs(crs, lon, lat) -> (pyproj.CRS, "EPSG:...")
    is_osm_path(path) -> bool

The reader streams the file once with pyosmium (:mod:`.read`); :mod:`.build` projects to the
local UTM zone (or ``crs``) and makes the meshes, the truth and the direction hints
(:mod:`aerial_synth.scene.hints`). Data © OpenStreetMap contributors (ODbL).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from pathlib import Path

from ...errors import SceneError
from ...io_utils import atomic_write_bytes
from ...safe_input import check_link
from ..model import Scene
from .build import ATTRIBUTION, build_scene
from .read import OSM_SUFFIXES, is_osm_path, read_osm

__all__ = [
    "ATTRIBUTION",
    "OSM_SUFFIXES",
    "is_osm_path",
    "parse_bbox",
    "resolve_crs",
    "utm_epsg",
    "build_osm_scene",
    "load_osm_scene",
    "cache_dir",
]

#: bump when the builder's output changes, so cached scenes are rebuilt
BUILDER_VERSION = 1


def parse_bbox(value, option: str = "--bbox") -> tuple[float, float, float, float] | None:
    """``"MINLON,MINLAT,MAXLON,MAXLAT"`` (or a 4-sequence) -> floats; None stays None.

    Raises :class:`SceneError` for anything but four finite numbers with min < max,
    longitudes in [-180, 180] and latitudes in [-85, 85] (the UTM range used here).
    """
    if value is None:
        return None
    raw = value
    if isinstance(value, str):
        parts = [p.strip() for p in value.split(",")]
    else:
        parts = list(value)
    try:
        vals = [float(p) for p in parts]
    except (TypeError, ValueError):
        vals = []
    if len(vals) != 4 or not all(math.isfinite(v) for v in vals):
        raise SceneError(f"{option}: expected MINLON,MINLAT,MAXLON,MAXLAT (four numbers), "
                         f"got {raw!r}")
    x0, y0, x1, y1 = vals
    if not (-180 <= x0 <= 180 and -180 <= x1 <= 180):
        raise SceneError(f"{option}: longitudes must be within [-180, 180], got {raw!r}")
    if not (-85 <= y0 <= 85 and -85 <= y1 <= 85):
        raise SceneError(f"{option}: latitudes must be within [-85, 85], got {raw!r}")
    if not (x0 < x1 and y0 < y1):
        raise SceneError(f"{option}: expected MINLON < MAXLON and MINLAT < MAXLAT, got {raw!r}")
    return (x0, y0, x1, y1)


def utm_epsg(lon: float, lat: float) -> str:
    """The standard 6-degree UTM zone of a point: "EPSG:326zz" (north) or "EPSG:327zz"."""
    zone = min(60, int(math.floor((lon + 180.0) / 6.0)) + 1)
    return f"EPSG:{32600 + zone if lat >= 0 else 32700 + zone}"


def resolve_crs(crs, lon: float, lat: float):
    """The projected CRS to build in: ``crs`` if given (must be projected, in metres), else
    the local UTM zone at (lon, lat). Returns (pyproj.CRS, its string)."""
    import pyproj

    name = crs if crs is not None else utm_epsg(lon, lat)
    try:
        c = pyproj.CRS.from_user_input(name)
    except (pyproj.exceptions.CRSError, TypeError, ValueError):
        raise SceneError(f"--crs: unknown CRS {name!r}; expected e.g. EPSG:32633") from None
    if not c.is_projected:
        raise SceneError(f"--crs: expected a projected CRS in metres (e.g. a UTM zone), got "
                         f"{name!r} ({c.name})")
    units = {(a.unit_name or "").lower() for a in c.axis_info[:2]}
    if not units <= {"metre", "meter"}:
        raise SceneError(f"--crs: expected a CRS in metres, got {name!r} with axis units "
                         f"{sorted(units)}")
    auth = c.to_authority()
    return c, (f"{auth[0]}:{auth[1]}" if auth else c.to_string())


def _scene_name(path: Path) -> str:
    n = path.name
    for s in sorted(OSM_SUFFIXES, key=len, reverse=True):
        if n.lower().endswith(s):
            return n[: -len(s)] or n
    return path.stem


def build_osm_scene(path, bbox=None, crs=None, seed: int = 0):
    """Read an OSM file and build its scene (no cache). See the module docstring.

    bbox : (minlon, minlat, maxlon, maxlat), a "MINLON,MINLAT,MAXLON,MAXLAT" string or None
           (the file's bounds, else its extent)
    crs  : a projected CRS in metres ("EPSG:25832", ...) or None for the local UTM zone
    seed : seeds the crowns scattered over forests (nothing else is random)
    """
    import pyproj

    path = Path(path)
    bb = parse_bbox(bbox)
    if crs is not None:  # fail fast on a bad CRS, before reading the file
        resolve_crs(crs, 0.0, 0.0)
    data = read_osm(path, bb)
    if data.empty or data.bbox is None:
        where = f"inside bbox {','.join(f'{c:g}' for c in bb)}" if bb else "in the file"
        raise SceneError(f"OSM file {path}: no map data {where}; expected roads, buildings or "
                         f"land use (check the bbox: MINLON,MINLAT,MAXLON,MAXLAT)")
    x0, y0, x1, y1 = data.bbox
    lon, lat = (x0 + x1) / 2, (y0 + y1) / 2
    c, crs_name = resolve_crs(crs, lon, lat)
    tr = pyproj.Transformer.from_crs("EPSG:4326", c, always_xy=True)
    ox, oy = tr.transform(lon, lat)
    origin = (float(round(ox)), float(round(oy)))
    return build_scene(data, crs_name, tr, origin, name=_scene_name(path), source=str(path),
                       seed=seed)


def cache_dir() -> Path:
    """Where built OSM scenes are cached: $AERIAL_SYNTH_CACHE/osm, else
    $XDG_CACHE_HOME/aerial-synth/osm, else ~/.cache/aerial-synth/osm."""
    env = os.environ.get("AERIAL_SYNTH_CACHE")
    if env:
        return Path(env) / "osm"
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "aerial-synth" / "osm"


def _file_hash(path: Path) -> str:
    h = hashlib.sha256()
    try:
        with open(path, "rb") as fh:  # guard: the OSM file, check_link'ed by load_osm_scene
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
    except FileNotFoundError:
        raise SceneError(f"OSM file {path}: file not found") from None
    except OSError as exc:
        raise SceneError(f"OSM file {path}: cannot read ({exc.strerror or exc})") from None
    return h.hexdigest()


def cache_key(path, bbox=None, crs=None, seed: int = 0) -> str:
    """Hash of the file's bytes and every option that changes the scene."""
    path = Path(path)
    opts = {"file": _file_hash(path), "bbox": parse_bbox(bbox), "crs": crs, "seed": int(seed),
            "builder": BUILDER_VERSION}
    return hashlib.sha256(json.dumps(opts, sort_keys=True).encode()).hexdigest()[:32]


def _current(scene) -> bool:
    """A cached object is a Scene with every field the current Scene class has."""
    from dataclasses import fields


    return isinstance(scene, Scene) and all(f.name in vars(scene) for f in fields(Scene))


def load_osm_scene(path, bbox=None, crs=None, seed: int = 0, cache: Path | str | None = None,
                   use_cache: bool = True):
    """:func:`build_osm_scene` with a cache keyed by the file hash and the options.

    cache : cache folder (default :func:`cache_dir`); a cached scene is a pickle written
            atomically, rebuilt when unreadable. ``use_cache=False`` builds and stores nothing.
    """
    import pickle


    path = Path(path)
    if not path.is_file():
        raise SceneError(f"OSM file {path}: file not found")
    check_link(path, SceneError)  # a FIFO, a device or a link out of an input folder: refused
    bb = parse_bbox(bbox)
    if crs is not None:
        resolve_crs(crs, 0.0, 0.0)
    if not use_cache:
        return build_osm_scene(path, bb, crs, seed)
    folder = Path(cache) if cache is not None else cache_dir()
    key = cache_key(path, bb, crs, seed)
    f = folder / f"{_scene_name(path)}-{key}.pkl"
    if f.is_file():
        try:
            with open(f, "rb") as fh:  # guard: our own cache entry
                scene = pickle.load(fh)  # guard: our own cache entry
            if _current(scene):
                scene.meta["cache"] = str(f)
                return scene
        except Exception:  # a stale or damaged cache entry: rebuild it
            pass
    scene = build_osm_scene(path, bb, crs, seed)
    try:
        atomic_write_bytes(f, pickle.dumps(scene, protocol=pickle.HIGHEST_PROTOCOL))
        scene.meta["cache"] = str(f)
    except Exception:  # a read-only cache must not stop the run  # noqa: BLE001
        scene.meta["cache"] = None
    return scene
