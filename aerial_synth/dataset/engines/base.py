"""The engine interface (:class:`Engine`) and the task plan (:func:`plan_tasks`); the
registry that chooses an engine is the package's (:mod:`aerial_synth.dataset.engines`)."""

from __future__ import annotations

import math
from collections.abc import Iterator

__all__ = ["Engine", "plan_tasks"]


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
        server was started (see :func:`~aerial_synth.dataset.engines.fork_server.start_pool_server`)."""
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
