"""Adding a format is one module plus one registry line: a tiny test format registered at
run time is exported beside the built-ins, by one worker or two, with no change to the
exporter."""

import json

import pytest

from aerial_synth.camera import CameraConfig
from aerial_synth.dataset.export import ExportConfig, export_dataset
from aerial_synth.errors import ExportError
from aerial_synth.formats import registry
from aerial_synth.formats.registry import LabelFormat

from .conftest import tree_bytes
from .tiny_format import CountFormat


@pytest.fixture
def count_format():
    fmt = registry.register(CountFormat())
    yield fmt
    registry.unregister(fmt.name)


def test_registry_lists_builtins_in_order():
    assert registry.names() == ("dota", "eagle", "yolo-obb", "coco")
    assert registry.parse_names("coco, DOTA,dota") == ("dota", "coco")
    with pytest.raises(ExportError, match="unknown format 'kitti'; expected a comma list of dota, eagle"):
        registry.parse_names("dota,kitti")
    with pytest.raises(ExportError, match="--format"):
        registry.parse_names(" , ")


def test_register_refuses_bad_names_and_duplicates(count_format):
    assert registry.names()[-1] == "count" and registry.get("count") is count_format
    with pytest.raises(ExportError, match="already registered"):
        registry.register(CountFormat())

    class Bad(LabelFormat):
        name = "has space"

    with pytest.raises(ExportError, match="lower-case format name"):
        registry.register(Bad())
    with pytest.raises(ExportError, match="expected a LabelFormat"):
        registry.register("dota")


@pytest.mark.parametrize("workers", [1, pytest.param(2, marks=pytest.mark.slow)])
def test_export_with_a_registered_test_format(count_format, tiny_scene, tmp_path, workers):
    cfg = ExportConfig(scene=tiny_scene, images=3, formats="count,dota", split=0.7, seed=2,
                       images_per_placement=2, n_vehicles=8,
                       camera=CameraConfig(width_px=160, height_px=120),
                       simple_vehicles=True)
    assert cfg.formats == ("dota", "count")
    out = tmp_path / "ds"
    res = export_dataset(cfg, out, workers=workers, progress=False)
    man = json.loads((out / "manifest.json").read_text())
    assert man["parameters"]["formats"] == ["dota", "count"]
    total = 0
    for i, sp in enumerate(["train", "train", "val"]):
        meta = json.loads((out / "meta" / f"{i:06d}.json").read_text())
        kept = sum(1 for v in meta["vehicles"] if v["status"] != "dropped")
        assert (out / "count" / sp / f"{i:06d}.count").read_text() == f"{kept}\n"
        assert (out / "count" / "pictures" / f"{i:06d}.png").read_bytes() == \
            (out / "dota" / sp / "images" / f"{i:06d}.png").read_bytes()
        total += kept
    assert (out / "count" / "total.txt").read_text() == f"images 3 vehicles {total}\n"
    assert res.summary["vehicles_kept"] == total and res.summary["formats"] == ["dota", "count"]
    if workers == 2:
        one = tmp_path / "one"
        export_dataset(cfg, one, workers=1, progress=False)
        assert tree_bytes(one) == tree_bytes(out)


def test_unregistered_format_refused(tiny_scene):
    with pytest.raises(ExportError, match="unknown format 'count'"):
        ExportConfig(scene=tiny_scene, formats="count")


@pytest.mark.parametrize("kw, msg", [
    (dict(images=0), "--images: expected an integer >= 1 and <= 1000000, got 0"),
    (dict(images="abc"), "--images"),
    (dict(images=True), "--images"),
    (dict(scene=""), "--scene"),
    (dict(labels=3), "--labels"),
    (dict(formats=""), "--format"),
    (dict(formats=("dota", "kitti")), "unknown format 'kitti'"),
    (dict(split=0), "--split"),
    (dict(split=float("nan")), "--split"),
    (dict(n_vehicles=0), "--vehicles"),
    (dict(n_lines=-1), "--lines"),
    (dict(seed=-1), "--seed"),
    (dict(scene_seed=-5), "--scene-seed"),
    (dict(images_per_placement=0), "--images-per-placement"),
    (dict(image_ext="gif"), "--image-ext"),
])
def test_export_config_refuses_bad_values(kw, msg):
    with pytest.raises(ExportError, match=msg.replace("(", r"\(")) as exc:
        ExportConfig(**kw)
    assert "\n" not in str(exc.value)


def test_export_config_paths_and_order():
    from pathlib import Path

    c = ExportConfig(scene=Path("/x/scene.obj"), formats="coco,dota")
    assert c.scene == "/x/scene.obj" and c.formats == ("dota", "coco")
    assert ExportConfig.from_dict(c.to_dict()) == c


def test_one_module_plus_one_registry_line(monkeypatch, tiny_scene, tmp_path):
    """The documented way to add a format: a module defining FORMAT, and its line in
    registry.BUILTIN (imported lazily on first use)."""
    monkeypatch.setitem(registry.BUILTIN, "count", "tests.dataset.tiny_format")
    monkeypatch.setattr(registry.REGISTRY, "loaded", dict(registry.REGISTRY.loaded))
    assert "count" in registry.names()
    assert isinstance(registry.get("count"), CountFormat)
    cfg = ExportConfig(scene=tiny_scene, images=1, formats="count", seed=1, n_vehicles=6,
                       camera=CameraConfig(width_px=96, height_px=96),
                       simple_vehicles=True)
    out = tmp_path / "ds"
    export_dataset(cfg, out, progress=False)
    assert sorted(p.name for p in out.iterdir()) == ["count", "manifest.json", "meta", "summary.json"]
    assert (out / "count" / "total.txt").read_text().startswith("images 1 vehicles ")


def test_builtin_module_must_define_its_format(monkeypatch):
    monkeypatch.setitem(registry.BUILTIN, "broken", "aerial_synth.formats._common")
    monkeypatch.setattr(registry.REGISTRY, "loaded", dict(registry.REGISTRY.loaded))
    with pytest.raises(ExportError, match="expected FORMAT = a LabelFormat named 'broken', got None"):
        registry.get("broken")


def test_manifest_parameters_omit_unset_osm_fields():
    """bbox / crs (OSM cuts) appear in the manifest only when set: exports without them keep
    the manifest of earlier versions, so those datasets still resume."""
    d = ExportConfig().to_dict()
    assert "bbox" not in d and "crs" not in d
    c = ExportConfig(bbox="1,2,3,4", crs="EPSG:32633")
    assert c.to_dict()["bbox"] == "1,2,3,4" and ExportConfig.from_dict(c.to_dict()) == c
    assert ExportConfig.from_dict(d) == ExportConfig()
