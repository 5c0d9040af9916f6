"""A toy render backend, registered at run time by the backend tests: flat colours per
semantic class, no shading. Adding a backend is this one class plus one registry line
(``backends.register`` here, :data:`BUILTIN` for a built-in)."""

import numpy as np

from aerial_synth.render.backends.base import RenderBackend, Shaded
from aerial_synth.render.visibility import compute_visibility

#: semantic id -> RGB (a colour per id, any id)
PALETTE = np.array([[(37 * i) % 256, (91 * i) % 256, (53 * i + 128) % 256] for i in range(256)], np.uint8)


class FlatBackend(RenderBackend):
    name = "toy-flat"
    description = "flat colour per semantic class (test backend)"

    def render(self, rayscene, camera, buffers, vehicles, factors, rng, config) -> Shaded:
        vis, amodal = compute_visibility(rayscene, camera, buffers.instance, vehicles, depth=buffers.depth)
        return Shaded(PALETTE[buffers.semantic], vis, amodal, 0.0)
