import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from aerial_synth.annotate import shoelace_area
from aerial_synth.dataset.export import ExportConfig, export_dataset
from aerial_synth.errors import ExportError
from aerial_synth.formats import dota, eagle, meta, yolo_obb

from .conftest import REPO, run_cli, tree_bytes

ALL = "dota,eagle,yolo-obb,coco"


def _cfg(scene, **kw):
    base = dict(scene=scene, images=4, formats=ALL, split=0.5, seed=3, images_per_placement=2,
                n_vehicles=10, width_px=256, height_px=256, simple_vehicles=True)
    base.update(kw)
    return ExportConfig(**base)


@pytest.fixture(scope="module")
def exported(tiny_scene, tmp_path_factory):
    out = tmp_path_factory.mktemp("ds") / "one"
    res = export_dataset(_cfg(tiny_scene), out, workers=1, progress=False)
    return out, res


def test_end_to_end_layout_and_formats(exported):
    out, res = exported
    assert res.summary["images"] == 4 and res.summary["splits"] == {"train": 2, "val": 2}
    man = json.loads((out / "manifest.json").read_text())
    assert man["format"] == "aerial-synth-dataset" and man["status"] == "complete"
    assert man["tool_version"] and man["parameters"]["seed"] == 3
    assert "workers" not in man["parameters"]
    kept_total = 0
    for i in range(4):
        sp = "train" if i < 2 else "val"
        rec = meta.read(out / "meta" / f"{i:06d}.json")
        assert rec.split == sp and rec.width_px == 256
        assert rec.seed["image_entropy"] == [3, i] and rec.seed["placement_group"] == i // 2
        assert "K" in rec.camera and "factors" in rec.render
        kept = [a for a in rec.annotations if a.kept]
        kept_total += len(kept)
        # DOTA: strict parse, same boxes
        lab = dota.read(out / "dota" / sp / "labelTxt" / f"{i:06d}.txt")
        assert lab.gsd_m == pytest.approx(rec.gsd_m, rel=1e-4)
        assert len(lab.objects) == len(kept)
        for a, o in zip(kept, lab.objects):
            assert np.abs(np.array(o.polygon_xy_px) - a.box.corners).max() <= 0.5
            assert shoelace_area(o.polygon_xy_px) > 0
        assert len(eagle.read(out / "eagle" / sp / "labels" / f"{i:06d}.txt")) == len(kept)
        yl = yolo_obb.read(out / "yolo-obb" / "labels" / sp / f"{i:06d}.txt")
        assert len(yl) == len(kept)
        assert all(0 <= v <= 1 for o in yl for p in o.polygon_xy_norm for v in p)
        for d in ("dota/%s/images", "eagle/%s/images", "yolo-obb/images/%s", "coco/images/%s"):
            assert (out / (d % sp) / f"{i:06d}.png").is_file()
        # every vehicle in view is accounted for, with reasons for the dropped ones
        for a in rec.annotations:
            assert a.status in ("kept", "difficult", "dropped")
            assert (a.status == "kept") == (a.reasons == ())
    assert kept_total > 0
    cls = res.summary["vehicles_per_class"]
    assert sum(cls.values()) == kept_total == res.summary["vehicles_kept"]
    import yaml

    y = yaml.safe_load((out / "yolo-obb" / "data.yaml").read_text())
    assert y["names"] == {0: "small-vehicle", 1: "large-vehicle"}


def test_coco_masks_decode_to_instance_masks(exported, tiny_scene):
    """COCO RLE = the renderer's instance mask (re-rendered from the recorded seeds)."""
    from pycocotools.coco import COCO

    out, _ = exported
    c = COCO(str(out / "coco" / "annotations" / "instances_train.json"))
    assert sorted(c.getCatIds()) == [1, 2]
    # Re-render image 0 from its recorded parameters and compare masks.
    from aerial_synth.dataset.export import _Worker

    cfg = _cfg(tiny_scene)
    w = _Worker(cfg, out)
    w._ensure_group(0)
    from aerial_synth.camera import sample_pose_targeted
    from aerial_synth.render import RenderConfig, render_frame

    cam_ss, render_ss = np.random.SeedSequence([3, 0]).spawn(2)
    cam = sample_pose_targeted(cfg.camera_config(), w._placement, np.random.default_rng(cam_ss))
    fr = render_frame(w._rayscene, cam, w._placement, np.random.default_rng(render_ss), RenderConfig())
    img_id = 1
    anns = c.loadAnns(c.getAnnIds(imgIds=[img_id]))
    assert anns
    for a in anns:
        np.testing.assert_array_equal(c.annToMask(a).astype(bool), fr.instance == a["vehicle_id"])
        assert len(a["obb_xyxyxyxy"]) == 8 and 0 <= a["heading_img_deg"] < 360


def test_one_and_two_workers_byte_identical(exported, tiny_scene, tmp_path):
    out1, _ = exported
    out2 = tmp_path / "two"
    export_dataset(_cfg(tiny_scene), out2, workers=2, progress=False)
    a, b = tree_bytes(out1), tree_bytes(out2)
    assert a.keys() == b.keys()
    assert [k for k in a if a[k] != b[k]] == []


def test_kill_and_resume_identical(exported, tiny_scene, tmp_path):
    out1, _ = exported
    out = tmp_path / "killed"
    args = ["export", "--scene", tiny_scene, "--images", 4, "--format", ALL, "--split", 0.5,
            "--seed", 3, "--images-per-placement", 2, "--vehicles", 10, "--size", 256,
            "--simple-vehicles", "--no-progress", "--out", out]
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.Popen([sys.executable, "-m", "aerial_synth.cli", *map(str, args)], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t0 = time.time()
    while time.time() - t0 < 60:
        if len(list((out / "meta").glob("*.json"))) >= 1 or proc.poll() is not None:
            break
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    done = len(list((out / "meta").glob("*.json")))
    assert done < 4, "export finished before it could be killed"
    assert json.loads((out / "manifest.json").read_text())["status"] == "incomplete"
    stray = out / "dota" / "val" / "images" / ".000003.png.x1y2.tmp"  # a write cut short
    stray.parent.mkdir(parents=True, exist_ok=True)
    stray.write_bytes(b"partial")
    r = run_cli(*args)  # without --resume: refused
    assert r.returncode == 2 and "--resume" in r.stderr
    r = run_cli(*args, "--resume")
    assert r.returncode == 0, r.stderr
    assert "resumed" in r.stdout
    a, b = tree_bytes(out1), tree_bytes(out)
    assert a.keys() == b.keys()
    assert [k for k in a if a[k] != b[k]] == []


def test_resume_with_other_parameters_refused(exported, tiny_scene):
    out, _ = exported
    with pytest.raises(ExportError, match="other parameters"):
        export_dataset(_cfg(tiny_scene, seed=4), out, resume=True, progress=False)


@pytest.mark.parametrize(
    "extra, msg",
    [
        (["--format", "dota,kitti"], "unknown format"),
        (["--split", "0"], "split"),
        (["--split", "1.01"], "split"),
        (["--images", "0"], "images"),
        (["--box", "tight"], "box"),
        (["--scenario", "no_such_scenario"], ""),
        (["--min-visible-fraction", "2"], "min_visible_fraction"),
        (["--workers", "0"], "workers"),
        (["--scene", "no_such_scene"], "scene"),
    ],
)
def test_bad_input_one_line_exit_2_nothing_written(tiny_scene, tmp_path, extra, msg):
    out = tmp_path / "never"
    r = run_cli("export", "--scene", tiny_scene, "--size", 64, "--images", 1, "--out", out, *extra)
    assert r.returncode == 2, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and r.stderr.startswith("aerial-synth: error:")
    assert msg in r.stderr
    assert not out.exists()


def test_non_dataset_folder_refused_unless_force(tiny_scene, tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("precious")
    r = run_cli("export", "--scene", tiny_scene, "--size", 64, "--images", 1, "--out", out)
    assert r.returncode == 2 and "not an aerial-synth dataset" in r.stderr
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]
    with pytest.raises(ExportError, match="not an aerial-synth"):
        export_dataset(_cfg(tiny_scene), out, progress=False)
    res = export_dataset(_cfg(tiny_scene, images=1, formats="dota"), out, force=True, progress=False)
    assert (out / "notes.txt").read_text() == "precious" and res.summary["images"] == 1


def test_existing_dataset_force_overwrites(tiny_scene, tmp_path):
    out = tmp_path / "ds"
    export_dataset(_cfg(tiny_scene, images=2, formats="dota,coco"), out, progress=False)
    with pytest.raises(ExportError, match="already exists"):
        export_dataset(_cfg(tiny_scene, images=1, formats="yolo-obb"), out, progress=False)
    export_dataset(_cfg(tiny_scene, images=1, formats="yolo-obb"), out, force=True, progress=False)
    assert sorted(p.name for p in out.iterdir()) == ["manifest.json", "meta", "summary.json", "yolo-obb"]
    assert len(list((out / "meta").glob("*.json"))) == 1


def test_show_draws_previews_and_sheet(exported, tmp_path):
    import cv2

    out, _ = exported
    r = run_cli("show", out, "--out", tmp_path / "prev")
    assert r.returncode == 0, r.stderr
    names = sorted(p.name for p in (tmp_path / "prev").iterdir())
    assert names == ["000000.jpg", "000001.jpg", "000002.jpg", "000003.jpg", "contact_sheet.jpg"]
    sheet = cv2.imread(str(tmp_path / "prev" / "contact_sheet.jpg"))
    assert sheet.shape == (512, 512, 3)
    # plain DOTA folder works too
    r = run_cli("show", out / "dota" / "train", "--out", tmp_path / "prev2")
    assert r.returncode == 0, r.stderr
    r = run_cli("show", tmp_path / "nothing", "--out", tmp_path / "prev3")
    assert r.returncode == 2 and not (tmp_path / "prev3").exists()
