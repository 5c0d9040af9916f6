"""One home per default: the camera's defaults and bounds are CameraConfig's, the render and
export commands share one camera option group, and the choices the CLI offers are the values
of the render options' enums."""

import argparse

import pytest

from aerial_synth.annotate.boxes import BoxConfig
from aerial_synth.camera import MAX_ALTITUDE_M, MAX_GSD_M, CameraConfig
from aerial_synth.dataset import cli as dataset_cli
from aerial_synth.dataset.config import ExportConfig
from aerial_synth.errors import CameraError
from aerial_synth.render import backends
from aerial_synth.render import cli as render_cli
from aerial_synth.render.config import (
    RANDOMISE,
    RENDER_PRESETS,
    Backend,
    Preset,
    Randomise,
    RenderConfig,
)


def _parser():
    p = argparse.ArgumentParser(exit_on_error=False)
    sub = p.add_subparsers()
    render_cli.register(sub)
    dataset_cli.register(sub)
    return p, sub


def _choices(sub, command, option):
    for a in sub.choices[command]._actions:
        if option in a.option_strings:
            return a
    raise AssertionError(option)


def test_enums_are_what_the_cli_accepts():
    assert RENDER_PRESETS == ("full", "fast") == tuple(p.value for p in Preset)
    assert RANDOMISE == ("none", "textures") == tuple(r.value for r in Randomise)
    assert tuple(b.value for b in Backend) == tuple(backends.BUILTIN) == ("raycast", "pyrender")
    cfg = RenderConfig.preset(Preset.FAST, randomise=Randomise.TEXTURES, backend=Backend.RAYCAST)
    assert type(cfg.randomise) is str and cfg.randomise == "textures" and cfg.shadow_step == 4
    _, sub = _parser()
    for command in ("render", "export"):
        assert _choices(sub, command, "--preset").type("fast") == "fast"
        with pytest.raises(argparse.ArgumentTypeError, match="full, fast"):
            _choices(sub, command, "--preset").type("medium")
        with pytest.raises(argparse.ArgumentTypeError, match="none, textures"):
            _choices(sub, command, "--randomise").type("colours")


def test_one_camera_default_and_one_set_of_bounds():
    d = CameraConfig()
    e = ExportConfig()
    assert (e.width_px, e.height_px, e.altitude_m, e.gsd_m, e.max_tilt_deg) == (
        d.width_px, d.height_px, d.altitude_m, d.gsd_m, d.max_tilt_deg)
    with pytest.raises(CameraError, match="altitude_m"):
        CameraConfig(altitude_m=MAX_ALTITUDE_M * 2)
    with pytest.raises(CameraError, match="gsd_m"):
        CameraConfig(gsd_m=MAX_GSD_M * 2)
    _, sub = _parser()
    for command in ("render", "export"):  # the same group: the same bounds and defaults
        alt, gsd = _choices(sub, command, "--altitude"), _choices(sub, command, "--gsd")
        assert alt.default == d.altitude_m and _choices(sub, command, "--max-tilt").default == d.max_tilt_deg
        with pytest.raises(argparse.ArgumentTypeError, match="--altitude"):
            alt.type(str(MAX_ALTITUDE_M * 2))
        with pytest.raises(argparse.ArgumentTypeError, match="--gsd"):
            gsd.type(str(MAX_GSD_M * 2))
        assert alt.type(str(MAX_ALTITUDE_M)) == MAX_ALTITUDE_M


def test_export_options_become_the_config():
    p, sub = _parser()
    args = p.parse_args(["export", "--out", "x", "--size", "256", "--height", "128", "--gsd", "0.2"])
    cfg = dataset_cli.config_from_args(args)
    assert (cfg.width_px, cfg.height_px, cfg.gsd_m, cfg.altitude_m) == (256, 128, 0.2, 60.0)
    assert cfg.box == BoxConfig()  # the thresholds' defaults are BoxConfig's
    args = p.parse_args(["render", "--out", "x", "--fov", "70"])
    cam = render_cli.camera_config_from_args(args)
    assert (cam.width_px, cam.fov_deg, cam.gsd_m) == (1024, 70.0, None)
