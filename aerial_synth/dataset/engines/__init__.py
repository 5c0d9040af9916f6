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

from ...errors import ExportError
from ...registry import Registry
from .base import Engine, plan_tasks

__all__ = ["BUILTIN", "Engine", "choose", "get", "names", "plan_tasks", "register", "unregister"]

#: Built-in engines: name -> module defining ENGINE.
BUILTIN: dict[str, str] = {
    "serial": "aerial_synth.dataset.engines.serial",
    "pool": "aerial_synth.dataset.engines.pool",
    "dask": "aerial_synth.dataset.engines.dask",
}


REGISTRY = Registry(BUILTIN, attr="ENGINE", noun="engine", option="engine", kind="an Engine",
                    is_entry=lambda o: isinstance(o, type) and issubclass(o, Engine), error=ExportError)
names = REGISTRY.names
get = REGISTRY.get
register = REGISTRY.register
unregister = REGISTRY.unregister


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
