"""The stream (aerial_synth.stream) against export: the same pixels before encoding and the
same labels in every format, for every index; shards cover each index once; epochs are the
exports their seeds name; and the ``render`` command shows export's images."""

import dataclasses
import json

import numpy as np
import pytest

from aerial_synth.camera import CameraConfig
from aerial_synth.dataset.export import ExportConfig, export_dataset
from aerial_synth.dataset.layout import image_paths, meta_path
from aerial_synth.dataset.plan import build_plan
from aerial_synth.dataset.sample import render_sample
from aerial_synth.errors import ConfigError
from aerial_synth.formats import meta as meta_fmt
from aerial_synth.formats.registry import get as get_format
from aerial_synth.render.config import RenderOptions
from aerial_synth.stream import epoch_config, epoch_seed, iter_samples, shard_indices

FORMATS = ("dota", "eagle", "yolo-obb", "coco")


def decode_png(data: bytes) -> np.ndarray:
    """A PNG's pixels, RGB order."""
    import cv2

    bgr = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    return np.ascontiguousarray(bgr[..., ::-1])


def _check_equal(cfg, out, samples):
    """Every sample equals export's files of its index: PNG pixels, per-image label files
    of every format, the metadata file."""
    n = 0
    for s in samples:
        png = image_paths(cfg, out, s.index)[0]
        assert np.array_equal(decode_png(png.read_bytes()), s.rgb), s.index
        assert s.rgb.dtype == np.uint8 and s.rgb.shape == (cfg.camera.height_px, cfg.camera.width_px, 3)
        for name in cfg.formats:
            rel = get_format(name).label_path(s.meta.split, s.meta.name)
            if rel is None:
                continue
            assert (out / rel).read_text(encoding="utf-8") == s.label_text(name), (s.index, name)
        d = json.loads(meta_path(out, s.index).read_text(encoding="utf-8"))
        assert d == json.loads(json.dumps(meta_fmt.to_dict(s.meta))), s.index
        kept = [v for v in d["vehicles"] if v["status"] != "dropped"]
        assert len(s.labels) == len(kept) and s.labels.classes == [v["cls"] for v in kept]
        n += len(s.labels)
    return n


def _pair_cfg(scene, scenario, images, **kw):
    return ExportConfig(scene=scene, scenario=scenario, images=images, formats=FORMATS, seed=11,
                        images_per_placement=5, split=0.5,
                        camera=CameraConfig(width_px=128, height_px=128, altitude_m=40.0),
                        render=RenderOptions(preset="fast"), **kw)


def test_stream_equals_export_on_a_tiny_scene(tiny_scene, tmp_path):
    cfg = ExportConfig(scene=tiny_scene, images=6, formats=FORMATS, split=0.5, seed=3,
                       images_per_placement=2, n_vehicles=10, simple_vehicles=True,
                       camera=CameraConfig(width_px=96, height_px=96))
    out = tmp_path / "ds"
    export_dataset(cfg, out, workers=1, progress=False)
    assert _check_equal(cfg, out, iter_samples(cfg)) >= 6
    # any order, any slice: the same samples (the group memo is not observable)
    back = list(iter_samples(cfg, indices=[5, 2, 3, 0]))
    assert [s.index for s in back] == [5, 2, 3, 0]
    _check_equal(cfg, out, back)
    assert [s.index for s in iter_samples(cfg, 2, 4)] == [2, 3]
    s = render_sample(build_plan(cfg), 4)
    assert np.array_equal(s.rgb, next(iter_samples(cfg, 4, 5)).rgb)


@pytest.mark.slow  # about 1 min on a busy machine; make test has the tiny scene's version
@pytest.mark.parametrize("scene, scenario", [("city_park", "jam")])
def test_stream_equals_export_bundled(scene, scenario, tmp_path):
    """One bundled scene x scenario pair, 4 indices, 2 export workers."""
    cfg = _pair_cfg(scene, scenario, 4, n_vehicles=60)
    out = tmp_path / "ds"
    export_dataset(cfg, out, workers=2, progress=False)
    assert _check_equal(cfg, out, iter_samples(cfg)) >= 4


@pytest.mark.slow
@pytest.mark.parametrize("scene, scenario", [("city_park", "jam"), ("suburb", "parking"),
                                             ("highway", "sparse")])
def test_stream_equals_export_3_pairs_20_indices(scene, scenario, tmp_path):
    cfg = _pair_cfg(scene, scenario, 20)
    out = tmp_path / "ds"
    export_dataset(cfg, out, workers=2, progress=False)
    assert _check_equal(cfg, out, iter_samples(cfg)) >= 20


@pytest.mark.parametrize("n, K, ipp", [(10, 1, 1), (10, 2, 1), (11, 3, 2), (7, 4, 5), (0, 2, 1)])
def test_shards_cover_every_index_once(n, K, ipp):
    shards = [shard_indices(n, k, K, ipp) for k in range(K)]
    flat = sorted(i for s in shards for i in s)
    assert flat == list(range(n))
    for s in shards:  # whole placement groups
        groups = {i // ipp for i in s}
        assert all(i in s for g in groups for i in range(g * ipp, min(n, (g + 1) * ipp)))


def test_bad_shards_and_ranges_are_refused(tiny_scene):
    with pytest.raises(ConfigError, match="shard"):
        shard_indices(10, 2, 2)
    cfg = ExportConfig(scene=tiny_scene, images=2)
    with pytest.raises(ConfigError, match="stop"):
        list(iter_samples(cfg, 0, 3))
    with pytest.raises(ConfigError, match="index"):
        list(iter_samples(cfg, indices=[2]))


def test_epochs_are_the_exports_their_seeds_name(tiny_scene):
    cfg = ExportConfig(scene=tiny_scene, images=2, seed=5, images_per_placement=2, n_vehicles=10,
                       simple_vehicles=True, camera=CameraConfig(width_px=64, height_px=64))
    assert epoch_config(cfg, 0) == cfg
    seeds = [epoch_seed(5, e) for e in range(4)]
    assert seeds[0] == 5 and len(set(seeds)) == 4 and seeds == [epoch_seed(5, e) for e in range(4)]
    e1 = epoch_config(cfg, 1)
    assert e1 == dataclasses.replace(cfg, seed=seeds[1])
    a = list(iter_samples(cfg))
    b = list(iter_samples(e1))
    assert all(not np.array_equal(x.rgb, y.rgb) for x, y in zip(a, b))
    assert b[1].meta.seed["dataset_seed"] == seeds[1]


def test_render_cli_shows_exports_images(tiny_scene, tmp_path):
    """``render`` and ``export`` with the same scene, scenario, seed and camera (one
    placement per run = one placement group): the same RGB, and the render's instance
    buffer holds the exported vehicles."""
    from aerial_synth.cli import main

    args = ["--scene", tiny_scene, "--seed", "4", "--images", "2", "--vehicles", "6",
            "--width", "64", "--height", "64", "--preset", "fast"]
    assert main(["render", *args, "--distractors", "0", "--out", str(tmp_path / "r")]) == 0
    assert main(["export", *args, "--images-per-placement", "2", "--format", "dota", "--no-progress",
                 "--out", str(tmp_path / "e")]) == 0
    for i in range(2):
        r = decode_png((tmp_path / "r" / f"{i:06d}" / "rgb.png").read_bytes())
        e = decode_png(next((tmp_path / "e").glob(f"dota/*/images/{i:06d}.png")).read_bytes())
        assert np.array_equal(r, e), i


def test_pool_naming_without_torch(tiny_scene):
    """Pool mode: epoch 0 renders every slot; each later epoch refreshes round(refresh * P)
    slots, drawn from the seed; a slot shows the image of its last refresh."""
    from aerial_synth.stream.dataset import EpochSampler, StreamDataset

    cfg = ExportConfig(scene=tiny_scene, images=10, seed=2)
    ds = StreamDataset(cfg, pool=8, refresh=0.25)
    assert len(ds) == 8 and ds.refreshed(0).tolist() == list(range(8))
    fresh = [set(ds.refreshed(e).tolist()) for e in range(1, 6)]
    assert all(len(f) == 2 for f in fresh) and len({frozenset(f) for f in fresh}) > 1
    for e in range(6):
        for j in range(8):
            b = ds.born(e, j)
            assert b <= e and (b == 0 or j in fresh[b - 1])
            assert all(j not in fresh[k - 1] for k in range(b + 1, e + 1))
            assert ds.image_of((e, j)) == (b, j)
    with pytest.raises(ConfigError, match="pool"):
        StreamDataset(cfg, pool=11)
    with pytest.raises(IndexError):
        ds.split_key((0, 8))
    s = EpochSampler(StreamDataset(cfg), shuffle=True, start_epoch=3)
    a, b = list(s), list(s)
    assert {e for e, _ in a} == {3} and {e for e, _ in b} == {4}
    assert sorted(i for _, i in a) == list(range(10)) and [i for _, i in a] != list(range(10))
    fixed = EpochSampler(StreamDataset(cfg), shuffle=False, advance=False)
    assert list(fixed) == list(fixed) == [(0, i) for i in range(10)]
