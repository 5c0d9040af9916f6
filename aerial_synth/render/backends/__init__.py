"""Render backends: who turns a frame's buffers into RGB (``RenderConfig.backend``).

In the spirit of trimesh's ``ray`` package: one small interface, several implementations,
chosen by name. Every backend starts from the same :class:`~aerial_synth.render.buffers.Buffers`
(the ray-cast instance / semantic / depth buffers) and returns the same :class:`Shaded`
result, so labels and visibility never depend on the backend; only the RGB differs; a
whole-frame backend makes the buffers too (:meth:`RenderBackend.render_whole`).

- ``raycast`` (default): :func:`aerial_synth.render.shading.shade` (shadows, AO, sky,
  reflections, sensor), visibility computed beside it in a second thread;
- ``pyrender``: an EGL rasteriser for a quick RGB preview (optional dependency);
- ``warp``: a *whole-frame* backend (:attr:`RenderBackend.whole_frame`): NVIDIA Warp casts
  every ray, primary ones included, on CUDA or the CPU, so its labels come from its own
  instance buffer (the ``[gpu]`` extra).

Adding a backend is one module that defines ``BACKEND = MyBackend()`` plus one line in
:data:`BUILTIN` (or :func:`register` at run time, as the tests do). This module imports
nothing heavy: a backend's module is imported the first time it is used.
"""

from __future__ import annotations

from ...errors import RenderError
from ...registry import Registry
from .base import RenderBackend, Shaded

__all__ = ["BUILTIN", "RenderBackend", "Shaded", "get", "names", "register", "unregister"]

#: Built-in backends: name -> module defining BACKEND.
BUILTIN: dict[str, str] = {
    "raycast": "aerial_synth.render.backends.raycast",
    "pyrender": "aerial_synth.render.backends.pyrender",
    "warp": "aerial_synth.render.backends.warp",
}


REGISTRY = Registry(BUILTIN, attr="BACKEND", noun="backend", option="--backend", kind="a RenderBackend",
                    is_entry=lambda o: isinstance(o, RenderBackend), error=RenderError)
names = REGISTRY.names
get = REGISTRY.get
register = REGISTRY.register
unregister = REGISTRY.unregister
