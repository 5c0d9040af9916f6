"""Compile the render kernels once per machine, saying so, and once for all the processes
that start together.

numba compiles a kernel on its first call and keeps the machine code in its disk cache
(``cache=True``; ``NUMBA_CACHE_DIR`` or ``__pycache__`` beside the sources). On an empty
cache the first frame of a process took a minute with nothing printed, and every export
worker (or Dask worker) that started before the cache existed compiled the same kernels
again. :func:`ensure_compiled` runs before the first frame of a process
(:func:`aerial_synth.render.frame.render_frame`):

- when every render kernel has a cache entry for this CPU, it returns at once;
- otherwise it takes an exclusive file lock in the cache folder, prints one line
  (``compiling render kernels, once per machine...``) and renders a tiny frame of a
  hand-built street with the full and the fast preset (that compiles and caches the
  kernels). A process that finds the lock taken waits, silently, then loads the cache that
  the other one filled instead of compiling.

``make demo`` warms the cache (``ensure_compiled(render_frame)``).
"""

from __future__ import annotations

import os
import sys

__all__ = ["ensure_compiled", "kernels", "missing_kernels"]

_MESSAGE = "aerial-synth: compiling render kernels, once per machine..."
_LOCK_NAME = "aerial_synth_compile.lock"
_done = False


def kernels() -> list:
    """Every numba dispatcher of the render path (the modules the first frame compiles)."""
    from numba.core.registry import CPUDispatcher

    from .. import camera_rays
    from . import _kernels, _tone, _vis_kernels, raster

    out = []
    for mod in (_kernels, raster, _vis_kernels, _tone, camera_rays):
        for name in sorted(vars(mod)):
            obj = getattr(mod, name)
            if (isinstance(obj, CPUDispatcher) and getattr(obj, "py_func", None) is not None
                    and obj.py_func.__module__ == mod.__name__ and obj._cache is not None
                    and getattr(obj._cache, "_cache_file", None) is not None):
                out.append(obj)
    return out


def _cached_here(disp) -> bool:
    """True when ``disp`` has at least one disk-cache entry for this CPU (numba's index,
    read as numba reads it: a stale index, from an older source, counts as empty)."""
    try:
        index = disp._cache._cache_file._load_index()
        magic = disp.targetctx.codegen().magic_tuple()
    except Exception:  # numba internals moved: assume cached, compile lazily as before
        return True
    return any(isinstance(k, tuple) and len(k) > 1 and k[1] == magic for k in index)


def missing_kernels() -> list[str]:
    """Names of the render kernels without a cache entry for this CPU."""
    return [d.py_func.__qualname__ for d in kernels() if not _cached_here(d)]


def _lock_path(ks) -> str | None:
    for d in ks:
        try:
            path = d._cache._cache_path
            os.makedirs(path, exist_ok=True)
            return os.path.join(path, _LOCK_NAME)
        except (AttributeError, OSError):
            continue
    return None


def _tiny_frame(render, preset: str) -> None:
    """Render a 48 px frame of a street with a house, a tree and two cars: every kernel of
    the default stages runs once."""
    import numpy as np
    import shapely

    from ..camera import Camera, CameraConfig
    from ..placement.model import PlacedVehicle, Placement
    from ..scene import build
    from ..scene.model import Scene, SceneObject
    from ..scene.raycast import RayScene
    from .config import RenderConfig
    from .world import add_placement

    road = shapely.box(-40, -4, 40, 4)
    objs = [build.polygon_object("grass", "ground", shapely.box(-40, -40, 40, 40).difference(road), 0.0),
            build.polygon_object("road", "road", road, 0.0),
            build.polygon_object("mark", "lane_marking", shapely.box(-40, -0.06, 40, 0.06), 0.005)]
    v, f = build.prism(shapely.box(6, 6, 14, 12), 0.0, 6.0)
    objs.append(SceneObject("house", "building", v, f))
    v, f = build.ellipsoid((-8.0, 7.0, 6.0), (3.0, 3.0, 2.0), 1)
    objs.append(SceneObject("crown", "tree", v, f))
    rs = RayScene(Scene("warm", objs))
    cars = [PlacedVehicle(id=i + 1, model="sedan", color="white", cls="small-vehicle",
                          length_m=4.5, width_m=1.8, height_m=1.5, x_m=x, y_m=y, z_m=0.0,
                          heading_rad=0.0) for i, (x, y) in enumerate([(-3.0, -2.0), (2.5, -1.9)])]
    pl = Placement(scene="warm", scenario="manual", seed=0, vehicles=cars)
    add_placement(rs, pl, simple_boxes=True)
    cam = Camera.look_at_ground(CameraConfig(altitude_m=40.0, width_px=48, height_px=48,
                                             gsd_m=0.4, max_tilt_deg=0.0), (0.0, 0.0, 0.0))
    render(rs, cam, pl, np.random.default_rng(0), RenderConfig.preset(preset))


def ensure_compiled(render, presets=("full", "fast"), quiet: bool = False) -> bool:
    """Compile the render kernels if this machine's cache lacks any (see the module doc),
    by rendering tiny frames with ``render`` (:func:`aerial_synth.render.frame.render_frame`,
    passed in: it calls this function). Returns True when this process compiled (or waited
    for another that did)."""
    global _done
    if _done:
        return False
    _done = True  # also guards the tiny frame's own render_frame call
    ks = kernels()
    if all(_cached_here(d) for d in ks):
        return False
    lock = _lock_path(ks)
    fd = None
    first = True  # this process compiles (and says so); False: another one is compiling
    if lock is not None:
        import fcntl

        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                first = False
                fcntl.flock(fd, fcntl.LOCK_EX)  # wait for it, then load what it cached
        except OSError:
            fd = None
    if first and not quiet:
        print(_MESSAGE, file=sys.stderr, flush=True)
    try:
        for preset in presets:
            _tiny_frame(render, preset)
    finally:
        if fd is not None:
            os.close(fd)  # releases the lock
    return True
