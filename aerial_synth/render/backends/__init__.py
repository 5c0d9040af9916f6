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

import importlib

from ...errors import RenderError
from .base import RenderBackend, Shaded

__all__ = ["BUILTIN", "RenderBackend", "Shaded", "get", "names", "register", "unregister"]

#: Built-in backends: name -> module defining BACKEND.
BUILTIN: dict[str, str] = {
    "raycast": "aerial_synth.render.backends.raycast",
    "pyrender": "aerial_synth.render.backends.pyrender",
    "warp": "aerial_synth.render.backends.warp",
}


_LOADED: dict[str, RenderBackend] = {}
_EXTRA: dict[str, RenderBackend] = {}  # registered at run time (plugins, tests)


def names() -> tuple[str, ...]:
    """Every backend name: built-ins first, then those registered at run time."""
    return tuple(BUILTIN) + tuple(n for n in _EXTRA if n not in BUILTIN)


def get(name: str) -> RenderBackend:
    """The backend called ``name``; an unknown name raises RenderError listing the valid ones."""
    if name in _EXTRA:
        return _EXTRA[name]
    if name in _LOADED:
        return _LOADED[name]
    if name not in BUILTIN:
        raise RenderError(f"--backend: unknown backend {name!r}; expected one of {', '.join(names())}")
    backend = getattr(importlib.import_module(BUILTIN[name]), "BACKEND", None)
    if not isinstance(backend, RenderBackend) or backend.name != name:
        raise RenderError(f"backend module {BUILTIN[name]}: expected BACKEND = a RenderBackend named "
                          f"{name!r}, got {backend!r}")
    _LOADED[name] = backend
    return backend


def register(backend: RenderBackend, *, replace: bool = False) -> RenderBackend:
    """Add a backend at run time (a plugin, a test)."""
    if not isinstance(backend, RenderBackend) or not backend.name:
        raise RenderError(f"register: expected a RenderBackend with a name, got {backend!r}")
    if backend.name in names() and not replace:
        raise RenderError(f"register: backend {backend.name!r} is already registered")
    _EXTRA[backend.name] = backend
    return backend


def unregister(name: str) -> None:
    """Remove a backend registered at run time (built-ins stay)."""
    _EXTRA.pop(name, None)
