"""Execution engines of an export: who renders the image tasks.

An engine is one module here that defines ``ENGINE``, a subclass of :class:`Engine`, and one
line in :data:`BUILTIN`. The exporter (:mod:`..export`) chooses it in one place
(:func:`choose`) and then only calls the interface:

- before the scene loads: :meth:`Engine.check` (e.g. probe a scheduler),
  :attr:`Engine.local_processes` (for the frame-memory check), :meth:`Engine.warm_up`
  (start the fork server) and :meth:`Engine.start` (start a cluster in the background);
- before anything is written: :meth:`Engine.connect` (an unreachable cluster writes nothing);
- :meth:`Engine.open` hands it the job (config, build folder, loaded scene and catalog),
  :meth:`Engine.plan` cuts the images to render into tasks (:func:`plan_tasks`),
  :meth:`Engine.run` runs them, yielding the number of images newly on disk as they land;
- :meth:`Engine.close` on every way out (idempotent).

Every engine renders a task with an :class:`~aerial_synth.dataset.worker.ImageWorker`
(``ImageWorker.for_config``), whose bytes depend only on (parameters, image index): the
output is byte-identical whatever the engine, the number of its workers or the order of its
tasks. Adding an engine (Ray, say) is one module plus one line in :data:`BUILTIN`; a test
may :func:`register` one at run time.
"""

from __future__ import annotations

import importlib

from ...errors import ExportError
from .base import Engine, plan_tasks

__all__ = ["BUILTIN", "Engine", "choose", "get", "names", "plan_tasks", "register", "unregister"]

#: Built-in engines: name -> module defining ENGINE.
BUILTIN: dict[str, str] = {
    "serial": "aerial_synth.dataset.engines.serial",
    "pool": "aerial_synth.dataset.engines.pool",
    "dask": "aerial_synth.dataset.engines.dask",
}


_LOADED: dict[str, type[Engine]] = {}
_EXTRA: dict[str, type[Engine]] = {}  # registered at run time (plugins, tests)


def names() -> tuple[str, ...]:
    """Every engine name: built-ins first, then those registered at run time."""
    return tuple(BUILTIN) + tuple(n for n in _EXTRA if n not in BUILTIN)


def get(name: str) -> type[Engine]:
    """The engine class called ``name``; an unknown name raises ExportError."""
    if name in _EXTRA:
        return _EXTRA[name]
    if name in _LOADED:
        return _LOADED[name]
    if name not in BUILTIN:
        raise ExportError(f"engine: unknown engine {name!r}; expected one of {', '.join(names())}")
    cls = getattr(importlib.import_module(BUILTIN[name]), "ENGINE", None)
    if not (isinstance(cls, type) and issubclass(cls, Engine)) or cls.name != name:
        raise ExportError(f"engine module {BUILTIN[name]}: expected ENGINE = an Engine named {name!r}, got {cls!r}")
    _LOADED[name] = cls
    return cls


def register(cls: type[Engine], *, replace: bool = False) -> type[Engine]:
    """Add an engine class at run time (a plugin, a test)."""
    if not (isinstance(cls, type) and issubclass(cls, Engine)) or not cls.name:
        raise ExportError(f"register: expected an Engine subclass with a name, got {cls!r}")
    if cls.name in names() and not replace:
        raise ExportError(f"register: engine {cls.name!r} is already registered")
    _EXTRA[cls.name] = cls
    return cls


def unregister(name: str) -> None:
    """Remove an engine registered at run time (built-ins stay)."""
    _EXTRA.pop(name, None)


def choose(workers: int | None = None, dask: str | None = None, engine: str | None = None) -> Engine:
    """The one place an export's engine is chosen: ``engine`` by name when given, else Dask
    for ``dask`` (``tcp://HOST:PORT`` or ``local:K``), the process pool for ``workers`` > 1,
    else serial. ``--dask`` and ``--workers`` together are refused (the cluster's workers do
    the work)."""
    if dask is not None and workers is not None:
        raise ExportError(f"--dask and --workers: choose one engine (the cluster's workers do the work), "
                          f"got --dask {dask} --workers {workers}")
    if engine is None:
        engine = "dask" if dask is not None else "pool" if (workers or 1) > 1 else "serial"
    return get(engine)(workers, dask)
