"""The render backend interface (:class:`RenderBackend`) and its result (:class:`Shaded`);
the registry that chooses a backend is the package's (:mod:`aerial_synth.render.backends`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # numpy is not imported here: --help start-up time
    import numpy as np

__all__ = ["RenderBackend", "Shaded"]


@dataclass
class Shaded:
    """What a backend makes of one frame's buffers.

    rgb          : (H, W, 3) uint8, RGB order
    visibility   : {id: VehicleVisibility}, from :func:`~aerial_synth.render.visibility.compute_visibility`
    amodal       : :class:`~aerial_synth.render.visibility.AmodalMasks`
    visibility_s : seconds of the visibility pass
    overlapped   : True when visibility ran beside the shading (its time is then not
                   subtracted from the RGB time)
    stages_s     : seconds per shading stage (``rgb_<stage>`` in the frame's timings)
    """

    rgb: np.ndarray
    visibility: dict
    amodal: object
    visibility_s: float
    overlapped: bool = False
    stages_s: dict = field(default_factory=dict)


class RenderBackend:
    """Base class of a render backend; instances are stateless (worker processes share them)."""

    #: ``RenderConfig.backend`` / ``--backend`` value
    name: str = ""
    #: one line for ``--help`` and docs
    description: str = ""
    #: True for a backend that casts the frame's buffers itself (:meth:`render_whole`), so
    #: its labels come from its own instance buffer; False: it shades the ray-cast
    #: :class:`~aerial_synth.render.buffers.Buffers` it is given (:meth:`render`)
    whole_frame: bool = False
    #: True for a backend that runs on ``--device`` (cpu or cuda[:N]); False: the CPU only
    devices: bool = False

    def check(self, device: str = "cpu") -> None:
        """Raise :class:`~aerial_synth.errors.RenderError` when the backend cannot run here
        (on ``device``, ``RenderConfig.device``: ``cpu`` or ``cuda[:N]``)."""

    def render(self, rayscene, camera, buffers, vehicles, factors: dict, rng, config) -> Shaded:
        """RGB and visibility of one frame whose ``buffers`` were cast from ``rayscene``."""
        raise NotImplementedError

    def render_whole(self, rayscene, camera, vehicles, factors: dict, rng, config):
        """A whole-frame backend's frame: (Buffers, :class:`Shaded`, seconds of the buffers,
        {name: device array} of the buffers it keeps on its device, or {})."""
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"<render backend {self.name!r}>"
