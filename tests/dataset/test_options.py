"""One home per default: the camera's defaults and bounds are CameraConfig's, the render
options' RenderOptions', and ExportConfig nests both (as it nests BoxConfig); the render and
export commands share one camera option group and one render option group, built from those
dataclasses; the choices the CLI offers are the values of the enums. The manifest keeps its
flat parameter names, so its bytes and the resume of older exports are unchanged."""

import argparse

import pytest

from aerial_synth.annotate.boxes import BoxConfig
from aerial_synth.camera import MAX_ALTITUDE_M, MAX_GSD_M, CameraConfig
from aerial_synth.dataset import cli as dataset_cli
from aerial_synth.dataset.config import CAMERA_KEYS, RENDER_KEYS, ExportConfig
from aerial_synth.dataset.output import _param_diff
from aerial_synth.errors import CameraError, ConfigError, ExportError
from aerial_synth.render import backends
from aerial_synth.render import cli as render_cli
from aerial_synth.render.config import (
    RANDOMISE,
    RENDER_PRESETS,
    Backend,
    Preset,
    Randomise,
    RenderConfig,
    RenderOptions,
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
    assert tuple(b.value for b in Backend) == tuple(backends.BUILTIN) == ("raycast", "pyrender", "warp")
    cfg = RenderConfig.preset(Preset.FAST, randomise=Randomise.TEXTURES, backend=Backend.RAYCAST)
    assert type(cfg.randomise) is str and cfg.randomise == "textures" and cfg.shadow_step == 4
    _, sub = _parser()
    for command in ("render", "export"):
        assert _choices(sub, command, "--preset").type("fast") == "fast"
        with pytest.raises(argparse.ArgumentTypeError, match="full, fast"):
            _choices(sub, command, "--preset").type("medium")
        with pytest.raises(argparse.ArgumentTypeError, match="none, textures"):
            _choices(sub, command, "--randomise").type("colours")


def test_box_enums_are_what_the_cli_accepts():
    from aerial_synth.annotate.boxes import BOX_FITS, BOX_MODES, BoxConfig, BoxFit, BoxMode

    assert BOX_MODES == ("visible", "amodal") == tuple(m.value for m in BoxMode)
    assert BOX_FITS == ("pixels", "dilated") == tuple(f.value for f in BoxFit)
    assert BoxConfig(box=BoxMode.AMODAL, fit=BoxFit.DILATED).to_dict()["box"] == "amodal"
    _, sub = _parser()
    assert _choices(sub, "export", "--box").type("amodal") == "amodal"
    assert _choices(sub, "export", "--box-fit").type("dilated") == "dilated"
    with pytest.raises(argparse.ArgumentTypeError, match="visible, amodal"):
        _choices(sub, "export", "--box").type("tight")
    with pytest.raises(argparse.ArgumentTypeError, match="pixels, dilated"):
        _choices(sub, "export", "--box-fit").type("hull")


def test_one_camera_default_and_one_set_of_bounds():
    d = CameraConfig()
    e = ExportConfig()
    assert e.camera == d and e.render == RenderOptions() and e.camera_config() is e.camera
    with pytest.raises(CameraError, match="width_px"):  # checked once, by CameraConfig
        CameraConfig(width_px=0)
    with pytest.raises(ConfigError, match="camera: expected a CameraConfig"):
        ExportConfig(camera={"width_px": 64})
    with pytest.raises(ConfigError, match="render: expected a RenderOptions"):
        ExportConfig(render="fast")
    with pytest.raises(ExportError, match="lens is set by gsd_m"):  # the manifest has no focal_px
        ExportConfig(camera=CameraConfig(focal_px=500.0))
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
    assert cfg.camera == CameraConfig(width_px=256, height_px=128, gsd_m=0.2)
    assert cfg.box == BoxConfig()  # the thresholds' defaults are BoxConfig's
    assert cfg.render == RenderOptions()
    args = p.parse_args(["export", "--out", "x", "--preset", "fast", "--randomise", "textures"])
    assert dataset_cli.config_from_args(args).render == RenderOptions(Preset.FAST, Randomise.TEXTURES)
    args = p.parse_args(["render", "--out", "x", "--fov", "70"])
    cam = render_cli.camera_config_from_args(args)
    assert (cam.width_px, cam.fov_deg, cam.gsd_m) == (1024, 70.0, None)


def test_render_option_defaults_are_render_options():
    d = RenderOptions()
    assert (d.preset, d.randomise) == ("full", RenderConfig().randomise)
    assert RenderOptions().config() == RenderConfig()
    assert RenderOptions("fast", "textures").config(shadows=False) == RenderConfig.preset(
        "fast", randomise="textures", shadows=False)
    _, sub = _parser()
    for command in ("render", "export"):  # the same group: the same defaults
        assert _choices(sub, command, "--preset").default == d.preset
        assert _choices(sub, command, "--randomise").default == d.randomise


#: the manifest's parameters, in order: the names and order of every earlier version
MANIFEST_KEYS = ["scene", "labels", "scene_seed", "scenario", "images", "formats", "split", "seed",
                 "images_per_placement", "n_vehicles", "n_lines", "width_px", "height_px",
                 "altitude_m", "gsd_m", "max_tilt_deg", "box", "image_ext", "simple_vehicles",
                 "render_preset", "randomise", "distractors", "gsd_range"]


def test_manifest_parameters_stay_flat():
    cfg = ExportConfig(camera=CameraConfig(width_px=256, height_px=128, max_tilt_deg=5.0, altitude_m=45.0),
                       render=RenderOptions("fast", "textures"), distractors=2.0,
                       gsd_range=(0.05, 0.3), images=3, n_vehicles=4)
    d = cfg.to_dict()
    assert list(d) == MANIFEST_KEYS  # as the previous version wrote it, byte for byte
    assert [d[k] for k in CAMERA_KEYS] == [256, 128, 45.0, None, 5.0]
    assert (d["render_preset"], d["randomise"], d["gsd_range"]) == ("fast", "textures", [0.05, 0.3])
    assert ExportConfig.from_dict(d) == cfg
    plain = ExportConfig().to_dict()  # defaults and unset options stay out, as before
    assert not set(RENDER_KEYS) & set(plain) and "camera" not in plain and "render" not in plain
    assert ExportConfig.from_dict(plain) == ExportConfig()


def test_resume_accepts_render_options_an_older_version_wrote_at_their_default():
    """``ExportConfig(render_preset="full")`` (the flat API) wrote the default into the
    manifest; this version leaves defaults out. Resuming such an export is no change."""
    old = {**ExportConfig().to_dict(), "render_preset": "full", "randomise": "none"}
    assert ExportConfig.from_dict(old) == ExportConfig()
    assert _param_diff(old, ExportConfig().to_dict()) == []
    fast = ExportConfig(render=RenderOptions("fast"))
    assert _param_diff(old, fast.to_dict()) == ["render_preset"]
    assert _param_diff({**old, "render_preset": "fast"}, fast.to_dict()) == []
