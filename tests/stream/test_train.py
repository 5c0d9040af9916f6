"""Ultralytics trains from the stream (make test-train): 2 epochs at imgsz 128 on the CPU,
the images rendered in 2 DataLoader workers. The two epochs see different images, and each
image is the one (seed, epoch, index) names. Marked ``train``; skipped without Ultralytics."""

from __future__ import annotations

import hashlib
import re

import numpy as np
import pytest

pytestmark = pytest.mark.train
pytest.importorskip("ultralytics", reason="needs the [train] extra (Ultralytics, torch): make test-train")

from aerial_synth.camera import CameraConfig  # noqa: E402
from aerial_synth.dataset.export import ExportConfig  # noqa: E402
from aerial_synth.dataset.sample import render_sample  # noqa: E402
from aerial_synth.sim2real import ultra  # noqa: E402
from aerial_synth.stream import epoch_config  # noqa: E402
from aerial_synth.stream.dataset import EpochSampler, StreamDataset  # noqa: E402
from aerial_synth.stream.train import train_from_stream  # noqa: E402

N = 8


def _cfg(scene):
    return ExportConfig(scene=scene, images=N, seed=9, images_per_placement=4, n_vehicles=10,
                        simple_vehicles=True, camera=CameraConfig(width_px=128, height_px=128, gsd_m=0.12))


def _digest(cfg, epoch, index):
    rgb = render_sample(epoch_config(cfg, epoch), index).rgb
    return hashlib.sha256(np.ascontiguousarray(rgb[..., ::-1].transpose(2, 0, 1)).tobytes()).hexdigest()


def test_ultralytics_trains_two_epochs_from_the_stream(tiny_scene, tmp_path):
    cfg = _cfg(tiny_scene)
    # sim2real's offline Ultralytics (settings, fonts, AMP check) and its trainer as the base
    ultra._offline_ultralytics()
    res = train_from_stream(cfg, tmp_path / "run", epochs=2, imgsz=128, batch=4, workers=2, device="cpu",
                            trainer_base=ultra._trainer_class(), amp_check=ultra._patched_amp_check())
    assert res.epochs == 2 and res.weights.is_file()
    by_epoch: dict[int, dict[int, str]] = {}
    for epoch, name, digest in res.seen:
        m = re.fullmatch(r"stream/seed9/epoch(\d+)/(\d{6})", name)
        assert m, name
        assert int(m.group(1)) == epoch  # the loader's pass is the trainer's epoch
        by_epoch.setdefault(epoch, {})[int(m.group(2))] = digest
    assert sorted(by_epoch) == [0, 1]
    for e, seen in by_epoch.items():
        assert sorted(seen) == list(range(N))  # every index once an epoch
        for i, d in seen.items():
            assert d == _digest(cfg, e, i), (e, i)  # the image (seed, epoch, index) names
    assert not set(by_epoch[0].values()) & set(by_epoch[1].values())  # new images


def test_items_and_pool_mode(tiny_scene):
    cfg = _cfg(tiny_scene)
    ds = StreamDataset(cfg, imgsz=128, pool=4, refresh=0.5)
    keys = list(EpochSampler(ds, shuffle=False, start_epoch=2))
    assert keys == [(2, i) for i in range(4)]
    for e, i in keys:
        item = ds[(e, i)]
        born = ds.born(e, i)
        s = render_sample(epoch_config(cfg, born), i)
        assert np.array_equal(item["img"].numpy(), s.rgb[..., ::-1].transpose(2, 0, 1))
        assert item["bboxes"].shape == (len(s.labels), 5) and item["cls"].shape == (len(s.labels), 1)
        if len(s.labels):
            b = item["bboxes"].numpy()
            assert ((b[:, :4] >= -0.5) & (b[:, :4] <= 1.5)).all()
            c = s.labels.polygons_xy_px.mean(axis=1) / 128.0  # box centres
            assert np.allclose(np.sort(b[:, 0]), np.sort(c[:, 0]), atol=1e-4)
    batch = StreamDataset.collate_fn([ds[(0, 0)], ds[(0, 1)]])
    assert batch["img"].shape == (2, 3, 128, 128)
    assert batch["batch_idx"].tolist() == [0.0] * len(ds[(0, 0)]["cls"]) + [1.0] * len(ds[(0, 1)]["cls"])
