"""``render_frame``: one camera view of a world -> buffers, visibility, factors and RGB.

The buffers are ray cast (:mod:`.buffers`) and the backend named by
``RenderConfig.backend`` (:mod:`.backends`) makes the RGB and the visibility from them; a
whole-frame backend (``warp``) casts the buffers itself, on ``RenderConfig.device``."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from . import backends
from .buffers import cast_buffers
from .config import RenderConfig, sample_factors
from .visibility import AmodalMasks, VehicleVisibility
from .warm import ensure_compiled

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
    #: a whole-frame backend's device arrays of the buffers ({} otherwise), for
    #: :func:`aerial_synth.render.backends.warp.to_torch`
    device_buffers: dict = field(default_factory=dict, repr=False)

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
    ensure_compiled(render_frame)  # first frame of a process: the kernels, compiled once per machine
    cfg = config or RenderConfig()
    backend = backends.get(cfg.backend)
    t0 = time.perf_counter()
    factors = sample_factors(cfg, rng)
    vehicles = placement.vehicles if placement is not None else []
    dev: dict = {}
    if backend.whole_frame:  # its own buffers: every label from its instance buffer
        buf, out, t_buf, dev = backend.render_whole(rayscene, camera, vehicles, factors, rng,
                                                    cfg)
        t1 = t0 + t_buf
    else:
        buf = cast_buffers(rayscene, camera)
        t1 = time.perf_counter()
        out = backend.render(rayscene, camera, buf, vehicles, factors, rng, cfg)
    t3 = time.perf_counter()
    t_vis = out.visibility_s
    return Frame(
        instance=buf.instance,
        semantic=buf.semantic,
        depth=buf.depth,
        rgb=out.rgb,
        visibility=out.visibility,
        factors=factors,
        camera=camera,
        amodal=out.amodal,
        timings_s={"buffers": t1 - t0, "visibility": t_vis, "rgb": t3 - t1 - (
            0.0 if out.overlapped else t_vis), "total": t3 - t0,
                   **{f"rgb_{k}": v for k, v in out.stages_s.items()}},
        device_buffers=dev,
    )
