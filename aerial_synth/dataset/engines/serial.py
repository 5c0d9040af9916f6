"""The serial engine: every task in this process, one :class:`ImageWorker` (images encode and
write on its writer thread while the next renders)."""

from __future__ import annotations

from collections.abc import Iterator

from ..worker import ImageWorker
from .base import Engine

__all__ = ["ENGINE", "SerialEngine"]


class SerialEngine(Engine):
    name = "serial"

    _worker: ImageWorker | None = None

    def run(self, tasks) -> Iterator[int]:
        self._worker = ImageWorker.for_config(self.cfg, self.build, nthreads=0, scene=self.scene,
                                              catalog=self.catalog)
        try:
            for task in tasks:
                yield from self._worker.iter_run(task)
        finally:
            self.close()

    def close(self) -> None:
        w, self._worker = self._worker, None
        if w is not None:
            w.close()


ENGINE = SerialEngine
