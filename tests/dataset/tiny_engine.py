"""A toy export engine, registered at run time by the engine tests: it runs the tasks in
reverse order, a fresh ImageWorker per task, in this process. Adding an engine is this one
class plus one registry line (``engines.register`` here, :data:`BUILTIN` for a built-in)."""

from aerial_synth.dataset.engines.base import Engine
from aerial_synth.dataset.worker import ImageWorker


class ReverseEngine(Engine):
    name = "toy-reverse"
    seen: list = []  # the tasks, in the order they ran (for the test)

    def run(self, tasks):
        for task in reversed(tasks):
            w = ImageWorker.for_config(self.cfg, self.build)  # its own scene: nothing shared
            try:
                ReverseEngine.seen.append(list(task))
                yield len(w.render_run(task))
            finally:
                w.close()
