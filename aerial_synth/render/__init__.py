"""Renderer: frame buffers, visibility and shaded RGB from the RayScene.

Public API::

    from aerial_synth.render import render_frame, Frame, RenderConfig, VehicleVisibility
    from aerial_synth.render import add_placement
    frame = render_frame(rayscene, camera, placement, rng, config=RenderConfig())
    frame.instance (H, W) uint32   # 0 = background, ids = placement ids
    frame.semantic (H, W) uint8    # aerial_synth.scene.model.LABEL_IDS
    frame.depth    (H, W) float32  # z-depth along the optical axis, metres (0 = no hit)
    frame.rgb      (H, W, 3) uint8 # RGB order
    frame.visibility {id: VehicleVisibility}; frame.amodal_mask(id) -> (mask, (x0, y0))
    frame.factors dict; frame.to_meta() -> dict

Submodules: ``buffers`` (the ray-cast frame buffers), ``visibility`` (visible and amodal
pixels per vehicle), ``backends`` (who makes the RGB: ``raycast`` with ``shading``, the
optional EGL rasteriser ``pyrender``), ``shading`` (RGB, RenderConfig), ``world`` (placement
-> vehicle meshes in the RayScene), ``io`` (writing a frame's files), ``cli``
(``aerial-synth render``).
Names are imported lazily so ``aerial-synth --help`` stays fast.
"""

from __future__ import annotations

from ..lazy import lazy_module_attrs

__all__ = [
    "render_frame",
    "Frame",
    "RenderConfig",
    "VehicleVisibility",
    "add_placement",
    "write_frame",
    "instance_colors",
]

_LAZY = {
    "render_frame": "frame",
    "Frame": "frame",
    "RenderConfig": "config",
    "VehicleVisibility": "visibility",
    "add_placement": "world",
    "write_frame": "io",
    "instance_colors": "io",
}


__getattr__, __dir__ = lazy_module_attrs(__name__, _LAZY, __all__)
