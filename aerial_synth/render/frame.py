"""``render_frame``: one camera view of a world -> buffers, visibility, factors and RGB."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .raycast import AmodalMasks, VehicleVisibility, cast_buffers, compute_visibility
from .shading import RenderConfig, sample_factors, shade

__all__ = ["Frame", "render_frame"]


@dataclass
class Frame:
    """One rendered frame.

    instance : (H, W) uint32 vehicle ids (placement ids; 0 = background)
    semantic : (H, W) uint8 semantic ids (``aerial_synth.scene.model.LABEL_IDS``)
    depth    : (H, W) float32 z-depth along the optical axis, metres (0 = nothing hit)
    rgb      : (H, W, 3) uint8, RGB order
    visibility : {id: VehicleVisibility} for every vehicle with amodal pixels in the image
    factors  : influence factors drawn for this frame (sun, haze, overcast, wet, sensor)
    camera   : the :class:`aerial_synth.camera.Camera`
    timings_s: seconds per stage (not part of the metadata: not deterministic); visibility
               runs alongside the shading stages ("rgb"), so the stages can sum to more
               than "total"
    """

    instance: np.ndarray
    semantic: np.ndarray
    depth: np.ndarray
    rgb: np.ndarray
    visibility: dict[int, VehicleVisibility]
    factors: dict
    camera: object
    amodal: AmodalMasks
    timings_s: dict = field(default_factory=dict)

    @property
    def height_px(self) -> int:
        return int(self.instance.shape[0])

    @property
    def width_px(self) -> int:
        return int(self.instance.shape[1])

    def amodal_mask(self, vehicle_id: int) -> tuple[np.ndarray, tuple[int, int]]:
        """(mask (h, w) bool, (x0, y0)): crop of the vehicle's unoccluded silhouette,
        clipped to the image; ``mask[r, c]`` is pixel (row y0 + r, column x0 + c).
        A vehicle not in view gives an empty (0, 0) mask."""
        return self.amodal.crop(vehicle_id)

    def visible_mask(self, vehicle_id: int) -> np.ndarray:
        """(H, W) bool visible pixels of one vehicle."""
        return self.instance == np.uint32(vehicle_id)

    def to_meta(self) -> dict:
        """JSON-ready metadata: image size, camera, factors, visible vehicles."""
        return {
            "image": {"width_px": self.width_px, "height_px": self.height_px},
            "camera": self.camera.to_dict(),
            "factors": dict(self.factors),
            "depth": "z-depth along the optical axis, metres; 0 = nothing hit",
            "vehicles": [v.to_dict() for v in self.visibility.values()],
        }


def render_frame(
    rayscene, camera, placement, rng: np.random.Generator, config: RenderConfig | None = None
) -> Frame:
    """Render one frame of ``rayscene`` (which must already hold the placement's vehicles,
    see :func:`aerial_synth.render.world.add_placement`) seen by ``camera``.

    placement : the Placement (its vehicles give ids, boxes and classes for visibility);
                None skips visibility.
    rng       : draws the influence factors and sensor noise (deterministic per seed).
    """
    cfg = config or RenderConfig()
    t0 = time.perf_counter()
    factors = sample_factors(cfg, rng)
    buf = cast_buffers(rayscene, camera)
    t1 = time.perf_counter()
    vehicles = placement.vehicles if placement is not None else []
    shade_t: dict = {}
    side = None
    if cfg.backend == "pyrender":
        from .pyrender_backend import render_rgb

        vis, amodal = compute_visibility(rayscene, camera, buf.instance, vehicles,
                                         depth=buf.depth)
        t_vis = time.perf_counter() - t1
        rgb = render_rgb(rayscene, camera, factors)
    else:
        # visibility (labels) and shading (RGB) read the same buffers and nothing of each
        # other: visibility runs in a second thread beside the shader's stages after its
        # ray casts (compose, tone, sensor), so its serial parts fill the cores those leave
        # idle (the same results either way)
        overlap = OVERLAP_VISIBILITY and _thread_safe_kernels()
        sides: list = []

        def start_visibility():
            sides.append(_Side(compute_visibility, rayscene, camera, buf.instance, vehicles,
                               depth=buf.depth))

        if not overlap:
            vis, amodal = compute_visibility(rayscene, camera, buf.instance, vehicles,
                                             depth=buf.depth)
            t_vis = time.perf_counter() - t1
        rgb = shade(rayscene, camera, buf, factors, rng, timings=shade_t,
                    before_compose=start_visibility if overlap else None)
        if overlap:
            if not sides:  # pragma: no cover - shade always calls it
                start_visibility()
            side = sides[0]
            (vis, amodal), t_vis = side.result()
    t3 = time.perf_counter()
    return Frame(
        instance=buf.instance,
        semantic=buf.semantic,
        depth=buf.depth,
        rgb=rgb,
        visibility=vis,
        factors=factors,
        camera=camera,
        amodal=amodal,
        timings_s={"buffers": t1 - t0, "visibility": t_vis, "rgb": t3 - t1 - (
            0.0 if side is not None else t_vis), "total": t3 - t0,
                   **{f"rgb_{k}": v for k, v in shade_t.items()}},
    )


#: run visibility in a second thread while shading (False: one after the other)
OVERLAP_VISIBILITY = True


def _thread_safe_kernels() -> bool:
    """Whether numba's threading layer lets two threads run parallel kernels at once (the
    OpenMP and TBB layers do; the fallback work queue does not)."""
    try:
        import numba

        return numba.threading_layer() in ("omp", "tbb")
    except (ImportError, ValueError):  # no parallel kernel has run yet
        return False


class _Side:
    """``fn(*args, **kw)`` in a thread of its own, started at once; :meth:`result` joins it
    and returns (its value, its seconds) or raises its exception. A thread per frame (not a
    pool) so that forked export workers never inherit a pool without its thread."""

    def __init__(self, fn, *args, **kw):
        import threading

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
