"""The default render backend: the ray-traced shader (:func:`aerial_synth.render.shading.shade`).

Visibility (labels) and shading (RGB) read the same buffers and nothing of each other:
visibility runs in a second thread beside the shader's stages after its ray casts
(compose, tone, sensor), so its serial parts fill the cores those leave idle (the same
results either way).
"""

from __future__ import annotations

import threading
import time

from ..shading import shade
from ..visibility import compute_visibility
from .base import RenderBackend, Shaded

__all__ = ["BACKEND", "RaycastBackend", "OVERLAP_VISIBILITY"]

#: run visibility in a second thread while shading (False: one after the other)
OVERLAP_VISIBILITY = True


class RaycastBackend(RenderBackend):
    name = "raycast"
    description = "ray-traced shading: shadows, ambient occlusion, sky, wet-road reflections, sensor"

    def render(self, rayscene, camera, buffers, vehicles, factors, rng, config) -> Shaded:
        t1 = time.perf_counter()
        overlap = OVERLAP_VISIBILITY and _thread_safe_kernels()
        sides: list = []

        def start_visibility():
            sides.append(_Side(compute_visibility, rayscene, camera, buffers.instance, vehicles,
                               depth=buffers.depth))

        if not overlap:
            vis, amodal = compute_visibility(rayscene, camera, buffers.instance, vehicles,
                                             depth=buffers.depth)
            t_vis = time.perf_counter() - t1
        stages: dict = {}
        rgb = shade(rayscene, camera, buffers, factors, rng, timings=stages,
                    before_compose=start_visibility if overlap else None)
        if overlap:
            if not sides:  # pragma: no cover - shade always calls it
                start_visibility()
            (vis, amodal), t_vis = sides[0].result()
        return Shaded(rgb, vis, amodal, t_vis, overlapped=overlap, stages_s=stages)


def _thread_safe_kernels() -> bool:
    """Whether numba's threading layer lets two threads run parallel kernels at once (the
    OpenMP and TBB layers do; the fallback work queue does not)."""
    try:
        import numba  # lazy: the layer is known only once a parallel kernel ran

        return numba.threading_layer() in ("omp", "tbb")
    except (ImportError, ValueError):  # no parallel kernel has run yet
        return False


class _Side:
    """``fn(*args, **kw)`` in a thread of its own, started at once; :meth:`result` joins it
    and returns (its value, its seconds) or raises its exception. A thread per frame (not a
    pool) so that forked export workers never inherit a pool without its thread."""

    def __init__(self, fn, *args, **kw):
        self._out: dict = {}

        def run():
            t = time.perf_counter()
            try:
                self._out["value"] = fn(*args, **kw)
            except BaseException as e:  # noqa: BLE001 - re-raised in the caller's thread
                self._out["error"] = e
            self._out["seconds"] = time.perf_counter() - t

        self._thread = threading.Thread(target=run, name="aerial-synth-visibility",
                                        daemon=True)
        self._thread.start()

    def result(self):
        self._thread.join()
        if "error" in self._out:
            raise self._out["error"]
        return self._out["value"], self._out["seconds"]


BACKEND = RaycastBackend()
