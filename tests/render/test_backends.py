"""Render backends behind one interface: a toy backend registered at run time renders the
very buffers and labels of the default backend, only its RGB is its own."""

import numpy as np
import pytest

from aerial_synth.camera import Camera, CameraConfig
from aerial_synth.errors import ConfigError, RenderError
from aerial_synth.render import RenderConfig, backends, render_frame

from .tiny_backend import PALETTE, FlatBackend
from .worlds import make_world


@pytest.fixture
def flat():
    b = backends.register(FlatBackend())
    yield b
    backends.unregister(b.name)


def test_registry_names_and_errors():
    assert backends.names()[:2] == ("raycast", "pyrender")
    assert backends.get("raycast").name == "raycast"
    with pytest.raises(RenderError, match="unknown backend 'vulkan'; expected one of raycast, pyrender"):
        backends.get("vulkan")
    with pytest.raises(ConfigError, match="backend"):
        RenderConfig(backend="toy-flat")  # not registered: refused like any unknown name
    with pytest.raises(RenderError, match="already registered"):
        backends.register(backends.get("raycast"))


def test_toy_backend_gives_the_same_buffers_and_labels(flat):
    rs, pl = make_world([(1, 0.0, 0.0, 0.3, 4.5, 1.8, 1.5), (2, 6.0, -2.0, 0.0, 9.0, 2.5, 3.5)])
    cam = Camera.look_at_ground(CameraConfig(width_px=128, height_px=128, gsd_m=0.12), (2.0, 0.0, 0.0),
                                yaw_deg=20.0, tilt_deg=8.0)
    ref = render_frame(rs, cam, pl, np.random.default_rng(4), RenderConfig.preset("fast"))
    toy = render_frame(rs, cam, pl, np.random.default_rng(4), RenderConfig.preset("fast", backend="toy-flat"))
    for name in ("instance", "semantic", "depth"):
        assert getattr(toy, name).tobytes() == getattr(ref, name).tobytes(), name
    assert toy.visibility == ref.visibility and len(toy.visibility) == 2
    assert toy.amodal.ids.tobytes() == ref.amodal.ids.tobytes()
    assert toy.factors.items() <= ref.factors.items()  # drawn before the backend (the shader adds its own)
    assert toy.rgb.shape == ref.rgb.shape and toy.rgb.dtype == np.uint8
    assert np.array_equal(toy.rgb, PALETTE[ref.semantic]) and not np.array_equal(toy.rgb, ref.rgb)
