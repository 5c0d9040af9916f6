"""Export's rendering options (--preset, --randomise, --distractors): recorded in the
manifest only when set, deterministic for any worker count, and never touching labels."""

from __future__ import annotations

import json

import pytest

from aerial_synth.camera import CameraConfig
from aerial_synth.dataset.config import RENDER_KEYS
from aerial_synth.dataset.export import ExportConfig, export_dataset
from aerial_synth.dataset.scenes import load_export_scene
from aerial_synth.errors import ConfigError, ExportError
from aerial_synth.render.config import RenderOptions

from .conftest import tree_bytes


def _cfg(scene, **kw):
    base = dict(scene=scene, images=2, formats="dota,yolo-obb", split=0.5, seed=5,
                images_per_placement=2, n_vehicles=8,
                camera=CameraConfig(width_px=192, height_px=192),
                simple_vehicles=True)
    base.update(kw)
    return ExportConfig(**base)


def _labels(out):
    return {k: v for k, v in tree_bytes(out).items() if k.startswith(("dota/", "yolo-obb/"))
            and k.endswith(".txt")}


def _images(out):
    return {k: v for k, v in tree_bytes(out).items() if k.endswith(".png")}


@pytest.fixture(scope="module")
def plain(tiny_scene, tmp_path_factory):
    out = tmp_path_factory.mktemp("plain") / "ds"
    export_dataset(_cfg(tiny_scene), out, workers=1, progress=False)
    return out


def test_unset_options_stay_out_of_the_manifest(plain):
    cfg = json.loads((plain / "manifest.json").read_text())["parameters"]
    assert not {"render_preset", "randomise", "distractors"} & set(cfg)


def test_fast_preset_and_randomised_textures_change_pixels_not_labels(plain, tiny_scene, tmp_path):
    for key, render in (("render_preset", RenderOptions(preset="fast")),
                        ("randomise", RenderOptions(randomise="textures"))):
        out = tmp_path / key
        export_dataset(_cfg(tiny_scene, render=render), out, workers=1, progress=False)
        assert _labels(out) == _labels(plain)
        assert _images(out) != _images(plain)
        cfg = json.loads((out / "manifest.json").read_text())["parameters"]
        assert cfg[key] == getattr(render, RENDER_KEYS[key])  # the manifest's flat name
        assert [k for k in cfg if k in RENDER_KEYS] == [key]  # the other one at its default


def test_distractors_are_in_the_scene_and_never_labelled(tiny_scene, tmp_path):
    cfg = _cfg(tiny_scene, distractors=400.0)
    scene = load_export_scene(cfg, fresh=True)
    base = load_export_scene(_cfg(tiny_scene), fresh=True)
    added = [o for o in scene.objects if o.name not in {b.name for b in base.objects}]
    assert added, "400 per hectare on 0.64 ha drew no distractor"
    assert all(o.label != "vehicle" for o in added)
    assert load_export_scene(cfg, fresh=True).vertex_hash() == scene.vertex_hash()  # same draw every time
    one, two = tmp_path / "one", tmp_path / "two"
    export_dataset(cfg, one, workers=1, progress=False)
    export_dataset(cfg, two, workers=2, progress=False)
    assert tree_bytes(one) == tree_bytes(two)
    # every DOTA line is a vehicle class: distractors never become labels
    for name, data in _labels(one).items():
        if name.startswith("dota/"):
            for line in data.decode().splitlines():
                if line and not line.startswith(("imagesource", "gsd")):
                    assert line.split()[8] in ("small-vehicle", "large-vehicle"), line


@pytest.mark.parametrize("kw, field", [
    ({"distractors": -1}, "--distractors"), ({"distractors": float("nan")}, "--distractors"),
    ({"images": 1_000_001}, "--images"), ({"images": 10**20}, "--images"),
])
def test_bad_render_options_are_one_line(tiny_scene, kw, field):
    with pytest.raises(ExportError, match=f"^{field}: expected"):
        _cfg(tiny_scene, **kw)


@pytest.mark.parametrize("kw, field", [({"preset": "slow"}, "render preset"),
                                       ({"randomise": "all"}, "render randomise")])
def test_bad_render_choices_are_refused_by_render_options(kw, field):
    """The checks live in RenderOptions, once (ExportConfig nests it)."""
    with pytest.raises(ConfigError, match=f"^{field}: expected one of") as exc:
        RenderOptions(**kw)
    assert "\n" not in str(exc.value)
