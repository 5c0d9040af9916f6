"""CPU test of a ``stream:`` arm in ``sim2real --plan`` (make test-train): 1 stream arm x 1
seed, 1 epoch at imgsz 128, the network cut off. The run trains from the stream (nothing
exported), its images are the ones its stream seed names, the weights are kept and the
report records the arm as a stream (images per epoch, epochs)."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import shutil

import numpy as np
import pytest

pytestmark = pytest.mark.train
pytest.importorskip("ultralytics", reason="needs the [train] extra (Ultralytics, torch): make test-train")

from aerial_synth.dataset.config import ExportConfig  # noqa: E402
from aerial_synth.dataset.sample import render_sample  # noqa: E402
from aerial_synth.sim2real.plan import stream_seed  # noqa: E402
from aerial_synth.sim2real.runs import seen_digest  # noqa: E402
from aerial_synth.stream import epoch_config  # noqa: E402

from ..helpers import write_crossing_obj  # noqa: E402
from .test_plan_train import _run  # noqa: E402

PLAN = """real: real
seeds: [3]
ignore_border: {same: 2}
real_scale: [arm]
train: {epochs: 1, imgsz: 128, batch: 4, workers: 0, threads: 1}
arms:
  S: {stream: {scene: tiny.obj, images: 4, size: 128, gsd: 0.12, seed: 7, images_per_placement: 2,
               vehicles: 10, simple_vehicles: true}}
"""


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    from aerial_synth.camera import CameraConfig
    from aerial_synth.dataset.export import ExportConfig, export_dataset

    root = tmp_path_factory.mktemp("stream-arm")
    scene = write_crossing_obj(root / "tiny.obj", 40)
    cfg = ExportConfig(scene=scene, images=4, formats="dota", split=1.0, seed=9, images_per_placement=2,
                       n_vehicles=10, camera=CameraConfig(width_px=128, height_px=128, gsd_m=0.12),
                       simple_vehicles=True)
    export_dataset(cfg, root / "src", workers=1, progress=False)
    shutil.copytree(root / "src" / "dota" / "train", root / "real" / "same")
    shutil.rmtree(root / "src")
    (root / "plan.yaml").write_text(PLAN)
    _run(root, "--plan", "plan.yaml", "--out", "rep", "--parallel", "1", "--device", "cpu")
    return root / "rep", json.loads((root / "rep" / "report.json").read_text())


def test_stream_arm_trains_from_the_stream_and_keeps_weights(run):
    out, report = run
    (a,) = report["arms"]
    assert a["kind"] == "stream" and a["dirs"] == [] and a["export_seconds"] is None
    assert not (out / "exports").exists()  # nothing exported: the run rendered its images
    assert a["stream"]["images_per_epoch"] == 4 and a["stream"]["epochs"] == [1] and a["stream"]["pool"] is None
    assert a["stream"]["stream_seeds"] == [stream_seed(7, 3)] != [7]
    assert a["training_images"] == 4 and a["gsd_m"] == pytest.approx(0.12)
    (r,) = a["runs"]
    assert r["seed"] == 3 and r["epochs"] == 1 and r["images_per_s"] > 0
    w = out / r["weights"]
    assert 1e6 < w.stat().st_size < 8e6  # kept: half precision, no optimizer state
    assert (out / r["predictions"]["arm"]).is_dir() and 0.0 <= r["real_ap50"] <= 1.0
    res = json.loads((out / "runs" / "S" / "seed3" / "result.json").read_text())
    assert res["spec"]["stream"]["seed"] == stream_seed(7, 3) and res["spec"]["dirs"] == []
    # the images it trained on are the ones (stream seed, epoch 0, index) names
    cfg = ExportConfig.from_dict(res["spec"]["stream"]["config"])  # scene: relative to the run's cwd
    cfg = dataclasses.replace(cfg, seed=stream_seed(7, 3), scene=out.parent / cfg.scene)
    want = []
    for i in range(4):
        s = render_sample(epoch_config(cfg, 0), i)
        bgr = np.ascontiguousarray(s.rgb[..., ::-1].transpose(2, 0, 1))
        want.append((0, f"stream/seed{cfg.seed}/epoch0/{s.meta.name}", hashlib.sha256(bgr.tobytes()).hexdigest()))
    assert res["stream_seen"] == seen_digest(want)
    assert (out / "summary.txt").is_file()
