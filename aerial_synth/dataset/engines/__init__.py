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
import math
from collections.abc import Iterator

from ...errors import ExportError

__all__ = ["BUILTIN", "Engine", "choose", "get", "names", "plan_tasks", "register", "unregister"]

#: Built-in engines: name -> module defining ENGINE.
BUILTIN: dict[str, str] = {
    "serial": "aerial_synth.dataset.engines.serial",
    "pool": "aerial_synth.dataset.engines.pool",
    "dask": "aerial_synth.dataset.engines.dask",
}


def plan_tasks(indices, images_per_placement: int, workers: int) -> list[list[int]]:
    """Split the images to render into tasks: contiguous runs of one placement group each.

    Whole groups when there are at least ``2 * workers`` of them (each placement is then
    computed once); otherwise each group is cut into equal runs so that there are about
    ``2 * workers`` tasks and every worker has work. Deterministic; image order kept."""
    groups: dict[int, list[int]] = {}
    for i in sorted(int(i) for i in indices):
        groups.setdefault(i // int(images_per_placement), []).append(i)
    if not groups:
        return []
    target = 2 * max(1, int(workers))
    pieces = 1 if len(groups) >= target else math.ceil(target / len(groups))
    tasks = []
    for g in sorted(groups):
        imgs = groups[g]
        k = min(pieces, len(imgs))
        size = math.ceil(len(imgs) / k)
        tasks += [imgs[s:s + size] for s in range(0, len(imgs), size)]
    return tasks


class Engine:
    """Base class of an execution engine (see the module's text for the call order).

    ``workers``: local worker processes (None: not given); ``address``: where a cluster is
    (``--dask``), None for a local engine."""

    #: registry name
    name: str = ""

    def __init__(self, workers: int | None = None, address: str | None = None):
        self.workers = 1 if workers is None else int(workers)
        self.address = address
        self.cfg = self.build = self.scene = self.catalog = None

    # -- before the scene loads -----------------------------------------------------------
    def check(self) -> None:
        """Refuse a bad engine setting before any slow work (one-line ExportError)."""

    @property
    def local_processes(self) -> int | None:
        """Processes that render on this machine (each holds a frame); None: not known here."""
        return self.workers

    def warm_up(self) -> bool:
        """Start what the workers need while the scene loads; True when the export's fork
        server was started (see :func:`~aerial_synth.dataset.pool.start_pool_server`)."""
        return False

    def start(self) -> None:
        """Start a cluster in the background (it starts while the scene loads)."""

    def connect(self) -> None:
        """Be ready to run (wait for the start, reach the cluster); before anything is written."""

    # -- the work ------------------------------------------------------------------------
    def open(self, cfg, build, scene=None, catalog=None) -> None:
        """The job: the export ``cfg``, its ``build`` folder, the loaded scene and catalog."""
        self.cfg, self.build, self.scene, self.catalog = cfg, build, scene, catalog

    def plan(self, indices) -> list[list[int]]:
        """The images ``indices`` cut into tasks (:func:`plan_tasks`)."""
        return plan_tasks(indices, self.cfg.images_per_placement, self.workers)

    def run(self, tasks) -> Iterator[int]:
        """Render every task; yields the number of images newly on disk, as they land."""
        raise NotImplementedError

    def close(self) -> None:
        """Release workers, threads and clusters (idempotent; called on every way out)."""

    def __repr__(self) -> str:
        return f"<export engine {self.name!r}>"


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
