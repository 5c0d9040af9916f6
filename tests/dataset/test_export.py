import json
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from aerial_synth.annotate import shoelace_area
from aerial_synth.camera import CameraConfig
from aerial_synth.dataset.export import ExportConfig, export_dataset
from aerial_synth.errors import ExportError
from aerial_synth.formats import dota, eagle, meta, yolo_obb

from .conftest import REPO, run_cli, tree_bytes

ALL = "dota,eagle,yolo-obb,coco"


def _cfg(scene, **kw):
    base = dict(scene=scene, images=4, formats=ALL, split=0.5, seed=3, images_per_placement=2,
                n_vehicles=10,
                camera=CameraConfig(width_px=256, height_px=256), simple_vehicles=True)
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
    import numpy

    assert man["versions"]["numpy"] == numpy.__version__
    assert man["versions"]["aerial-synth"] == man["tool_version"]
    assert "workers" not in man["parameters"]
    from aerial_synth.scene import load_scene

    geo = load_scene(man["parameters"]["scene"]).georeference()
    assert man["georeference"] == geo == res.summary["georeference"]
    assert len(geo["origin"]) == 3 and all(isinstance(c, float) for c in geo["origin"])
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
        for a, o in zip(kept, lab.objects, strict=True):
            assert np.abs(np.array(o.polygon_xy_px) - a.box.corners).max() <= 0.5
            assert shoelace_area(o.polygon_xy_px) > 0
        assert len(eagle.read(out / "eagle" / sp / "labels" / f"{i:06d}.txt")) == len(kept)
        yl = yolo_obb.read(out / "yolo-obb" / "labels" / sp / f"{i:06d}.txt")
        assert len(yl) == len(kept)
        for a, o in zip(kept, yl, strict=True):  # the true rectangle, never clipped corner-wise
            px = yolo_obb.denormalize_xy(o.polygon_xy_norm, 256, 256)
            np.testing.assert_allclose(px, a.box.corners, atol=2e-3)
            e = np.roll(px, -1, axis=0) - px
            assert abs(float(e[0] @ e[1])) <= 2e-3 * np.linalg.norm(e[1]) + 1e-3
            assert abs(np.linalg.norm(e[0]) - np.linalg.norm(e[2])) <= 2e-3
        assert rec.georeference == geo
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
    from aerial_synth.dataset.worker import ImageWorker

    cfg = _cfg(tiny_scene)
    w = ImageWorker.for_config(cfg, out)
    grp = w.renderer.group(0)
    from aerial_synth.camera import sample_pose_targeted
    from aerial_synth.render import RenderConfig, render_frame

    cam_ss, render_ss = np.random.SeedSequence([3, 0]).spawn(2)
    cam = sample_pose_targeted(cfg.camera_config(), grp.placement, np.random.default_rng(cam_ss))
    fr = render_frame(grp.rayscene, cam, grp.placement, np.random.default_rng(render_ss), RenderConfig())
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


def _partial(out):
    return out.parent / f".{out.name}.aerial-synth-partial"


EXPORT_ARGS = ["--images", 4, "--format", ALL, "--split", 0.5, "--seed", 3, "--images-per-placement", 2,
               "--vehicles", 10, "--size", 256, "--simple-vehicles", "--no-progress"]


def _descendants(pid: int) -> set[int]:
    """Every live process below ``pid`` (from /proc)."""
    kids: dict[int, list[int]] = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as fh:
                    ppid = int(fh.read().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            kids.setdefault(ppid, []).append(int(d))
    out, todo = set(), [pid]
    while todo:
        for c in kids.get(todo.pop(), []):
            out.add(c)
            todo.append(c)
    return out


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except OSError:
        return False


def _snapshot(root):
    return {str(p.relative_to(root)): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in sorted(root.rglob("*")) if p.is_file()}


def _start_and_kill(args, watch, min_meta=1, timeout=600):
    """Start ``aerial-synth export ARGS``, SIGKILL it once ``watch/meta`` holds ``min_meta``
    images; returns the pids of its (former) child processes."""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.Popen([sys.executable, "-m", "aerial_synth.cli", *map(str, args)], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    t0, kids = time.time(), set()
    while time.time() - t0 < timeout:
        kids |= _descendants(proc.pid)
        if len(list((watch / "meta").glob("*.json"))) >= min_meta or proc.poll() is not None:
            break
        time.sleep(0.02)
    kids |= _descendants(proc.pid)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    return proc, kids


@pytest.mark.slow  # test_kill_two_workers_force_keeps_old_and_workers_die covers the same in the default run
def test_kill_and_resume_identical(exported, tiny_scene, tmp_path):
    """kill -9 of a fresh export: --out does not appear, the partial build stays for
    --resume, a rerun without --resume is refused, and --resume ends byte-identical."""
    out1, _ = exported
    out = tmp_path / "killed"
    args = ["export", "--scene", tiny_scene, *EXPORT_ARGS, "--out", out]
    proc, _ = _start_and_kill(args, _partial(out))
    part = _partial(out)
    done = len(list((part / "meta").glob("*.json")))
    assert done < 4, "export finished before it could be killed"
    assert not out.exists()
    assert json.loads((part / "manifest.json").read_text())["status"] == "incomplete"
    stray = part / "dota" / "val" / "images" / ".000003.png.x1y2.tmp"  # a write cut short
    stray.parent.mkdir(parents=True, exist_ok=True)
    stray.write_bytes(b"partial")
    r = run_cli(*args)  # without --resume: refused
    assert r.returncode == 2 and "--resume" in r.stderr and len(r.stderr.splitlines()) == 1
    r = run_cli(*args, "--resume", timeout=600)
    assert r.returncode == 0, r.stderr
    assert "resumed" in r.stdout
    assert not part.exists()
    a, b = tree_bytes(out1), tree_bytes(out)
    assert a.keys() == b.keys()
    assert [k for k in a if a[k] != b[k]] == []


_ORPHAN = r"""
import os, sys
from aerial_synth.dataset.engines.parent import watch_parent
r, w = os.pipe()
os.close(r)  # the reader (the exporter's result handler) is gone
if sys.argv[1] == "watched":
    watch_parent(os.getppid())
os.write(w, b"result")  # what a pool worker does with a finished task's result
print("still running", file=sys.stderr)
"""


@pytest.mark.skipif(not hasattr(signal, "SIGPIPE"), reason="no SIGPIPE on this platform")
def test_worker_whose_exporter_died_ends_silently_on_its_result_pipe():
    """A pool worker that writes a result after the exporter died ends by SIGPIPE, without
    the BrokenPipeError traceback Python's default (SIGPIPE ignored) would print; the same
    child without the watcher shows what is avoided."""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    plain = subprocess.run([sys.executable, "-c", _ORPHAN, "plain"], capture_output=True, text=True,
                           env=env, timeout=120)
    assert plain.returncode == 1 and "BrokenPipeError" in plain.stderr
    watched = subprocess.run([sys.executable, "-c", _ORPHAN, "watched"], capture_output=True,
                             text=True, env=env, timeout=120)
    assert watched.returncode == -signal.SIGPIPE
    assert watched.stderr == ""


def test_kill_two_workers_force_keeps_old_and_workers_die(exported, tiny_scene, tmp_path):
    """kill -9 of an export --force --workers 2 over an existing dataset: the old dataset
    stays byte-identical, the orphaned workers stop at once (no file changes afterwards, no
    process left, no traceback), and --resume finishes byte-identical to one clean run."""
    out1, _ = exported
    out = tmp_path / "ds"
    export_dataset(_cfg(tiny_scene, images=1, formats="dota", seed=9), out, progress=False)
    (out / "my_notes.txt").write_text("keep me")
    old = tree_bytes(out)
    args = ["export", "--scene", tiny_scene, *EXPORT_ARGS, "--workers", 2, "--force", "--out", out]
    proc, kids = _start_and_kill(args, _partial(out))
    part = _partial(out)
    assert len(list((part / "meta").glob("*.json"))) < 4, "export finished before it could be killed"
    assert kids, "the export started no worker processes"
    # the kernel kills the fork server with the exporter and the workers with the server: a
    # chain that takes a few milliseconds, in which a worker may still finish a rename
    deadline = time.monotonic() + 2.0
    while any(_alive(k) for k in kids) and time.monotonic() < deadline:
        time.sleep(0.005)
    assert [k for k in kids if _alive(k)] == [], "workers outlived the exporter by 2 s"
    before = _snapshot(part)
    time.sleep(2.0)
    assert _snapshot(part) == before, "files changed after the exporter and its workers died"
    assert "Traceback" not in proc.stderr.read().decode()
    assert tree_bytes(out) == old
    assert json.loads((part / "manifest.json").read_text())["status"] == "incomplete"
    stray = part / "dota" / "val" / "images" / ".000003.png.x1y2.tmp"  # a write cut short
    stray.parent.mkdir(parents=True, exist_ok=True)
    stray.write_bytes(b"partial")
    plain = [a for a in args if a not in ("--force",)]
    r = run_cli(*plain)  # neither --resume nor --force: refused, naming both
    assert r.returncode == 2 and "--resume" in r.stderr and "--force" in r.stderr
    assert len(r.stderr.splitlines()) == 1
    # resume with one worker (any K gives the same bytes; one process starts faster)
    resume_args = [a for a in args if a != "--force"]
    k = resume_args.index("--workers")
    del resume_args[k:k + 2]
    r = run_cli(*resume_args, "--resume", timeout=600)
    assert r.returncode == 0, r.stderr
    new = tree_bytes(out)
    assert new.pop("my_notes.txt") == b"keep me"
    a = tree_bytes(out1)
    assert a.keys() == new.keys()
    assert [k for k in a if a[k] != new[k]] == []
    assert not part.exists()


def test_render_image_is_engine_agnostic(exported, tiny_scene, tmp_path):
    """The task a pool (or Dask) runs: render_image(cfg, out, i) in any order, from a fresh
    process state, writes the same bytes as the export did."""
    from aerial_synth.dataset import worker

    out1, _ = exported
    out = tmp_path / "tasks"
    worker._CACHE.clear()
    for i in (3, 0):  # out of order, a different placement group first
        worker.render_image(_cfg(tiny_scene), out, i)
    ref = tree_bytes(out1)
    got = tree_bytes(out)
    assert got and all(got[k] == ref[k] for k in got)
    assert {k.split("/")[-1] for k in got} >= {"000000.json", "000003.json", "000000.txt", "000003.png"}


def test_resume_with_other_parameters_refused(exported, tiny_scene):
    out, _ = exported
    with pytest.raises(ExportError, match="other parameters"):
        export_dataset(_cfg(tiny_scene, seed=4), out, resume=True, progress=False)


BAD_INPUTS = [
    (["--format", "dota,kitti"], "unknown format"),
    (["--format", ","], "--format"),
    (["--split", "0"], "--split"),
    (["--split", "1.01"], "--split"),
    (["--split", "nan"], "--split"),
    (["--images", "0"], "--images"),
    (["--images", "abc"], "--images: expected an integer >= 1 and <= 1000000, got 'abc'"),
    (["--images", "1.5"], "--images"),
    (["--seed", "-1"], "--seed"),
    (["--seed", "1.5"], "--seed"),
    (["--scene-seed", "-1"], "--scene-seed"),
    (["--workers", "0"], "--workers"),
    (["--images-per-placement", "0"], "--images-per-placement"),
    (["--vehicles", "0"], "--vehicles"),
    (["--lines", "0"], "--lines"),
    (["--size", "0"], "--size"),
    (["--width", "0"], "--width"),
    (["--height", "-5"], "--height"),
    (["--size", "100000"], "--size"),
    (["--altitude", "0"], "--altitude"),
    (["--altitude", "inf"], "--altitude"),
    (["--gsd", "-0.1"], "--gsd"),
    (["--max-tilt", "90"], "--max-tilt"),
    (["--box", "tight"], "--box: expected one of visible, amodal"),
    (["--box-fit", "loose"], "--box-fit: expected one of pixels, dilated"),
    (["--image-ext", "gif"], "--image-ext: expected one of png, jpg"),
    (["--difficult-fraction", "2"], "--difficult-fraction"),
    (["--min-visible-fraction", "2"], "--min-visible-fraction"),
    (["--min-visible-px", "-1"], "--min-visible-px"),
    (["--scenario", "no_such_scenario"], "scenario"),
    (["--scene", "no_such_scene"], "scene"),
]


@pytest.mark.parametrize("extra, msg", BAD_INPUTS)
def test_bad_input_one_line_exit_2_nothing_written(tiny_scene, tmp_path, extra, msg):
    out = tmp_path / "never"
    r = run_cli("export", "--scene", tiny_scene, "--size", 64, "--images", 1, "--out", out, *extra)
    assert r.returncode == 2, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and r.stderr.startswith("aerial-synth")
    assert msg in r.stderr
    assert list(tmp_path.iterdir()) == []  # neither --out nor a partial build


def test_bad_scene_file_writes_nothing(tmp_path):
    bad = tmp_path / "bad.glb"
    bad.write_bytes(b"glTF\x02\x00\x00\x00garbage")
    before = sorted(p.name for p in tmp_path.iterdir())
    r = run_cli("export", "--scene", bad, "--size", 64, "--images", 1, "--out", tmp_path / "never")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_force_with_bad_scene_leaves_dataset_byte_identical(exported, tmp_path):
    src, _ = exported
    out = tmp_path / "existing"
    shutil.copytree(src, out)
    before = tree_bytes(out)
    bad = tmp_path / "BAD.glb"
    bad.write_bytes(b"not a glb at all")
    r = run_cli("export", "--force", "--scene", bad, "--size", 64, "--images", 1, "--out", out)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert tree_bytes(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["BAD.glb", "existing"]


def test_failure_during_run_leaves_nothing(tiny_scene, tmp_path, monkeypatch):
    """An error while rendering (before any image finished) removes the partial build, so a
    corrected rerun is not refused."""
    from aerial_synth.dataset import worker

    def boom(self, index, *args, **kwargs):
        raise ExportError("placement group 0: placed no vehicles")

    monkeypatch.setattr(worker.ImageWorker, "render", boom)
    out = tmp_path / "ds"
    with pytest.raises(ExportError, match="no vehicles"):
        export_dataset(_cfg(tiny_scene, images=1, formats="dota"), out, progress=False)
    assert list(tmp_path.iterdir()) == []


def _chmod_effective() -> bool:
    return hasattr(os, "geteuid") and os.geteuid() != 0


@pytest.mark.parametrize("case", ["file", "below_file", "parent_is_file", "read_only"])
def test_impossible_out_one_line(tiny_scene, tmp_path, case):
    f = tmp_path / "afile"
    f.write_text("x")
    out = {"file": f, "below_file": f / "sub", "parent_is_file": f / "a" / "b"}.get(case)
    if case == "read_only":
        if not _chmod_effective():
            pytest.skip("running as root: root ignores folder permissions, so chmod 555 proves nothing")
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o555)
        out = ro / "ds"
    try:
        r = run_cli("export", "--scene", tiny_scene, "--size", 64, "--images", 1, "--out", out)
    finally:
        if case == "read_only":
            (tmp_path / "ro").chmod(0o755)
    assert r.returncode == 2, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "--out" in r.stderr, r.stderr
    assert f.read_text() == "x"
    assert sorted(p.name for p in tmp_path.iterdir()) == (["afile", "ro"] if case == "read_only" else ["afile"])


def test_read_only_existing_out_refused(tiny_scene, tmp_path):
    if not _chmod_effective():
        pytest.skip("running as root: root ignores folder permissions, so chmod 555 proves nothing")
    out = tmp_path / "ro"
    out.mkdir()
    out.chmod(0o555)
    try:
        r = run_cli("export", "--scene", tiny_scene, "--size", 64, "--images", 1, "--out", out)
    finally:
        out.chmod(0o755)
    assert r.returncode == 2 and "not writable" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert list(out.iterdir()) == []


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
    (out / "notes.txt").write_text("mine")
    export_dataset(_cfg(tiny_scene, images=1, formats="yolo-obb"), out, force=True, progress=False)
    assert sorted(p.name for p in out.iterdir()) == ["manifest.json", "meta", "notes.txt", "summary.json",
                                                      "yolo-obb"]
    assert len(list((out / "meta").glob("*.json"))) == 1
    assert (out / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds"]  # no partial or old folder left


def test_swap_interrupted_between_renames_is_finished_by_resume(tiny_scene, tmp_path):
    """A kill between the swap's two renames: --out missing, the old dataset in -old, the
    complete new one in the partial folder. --resume moves it in and retires the old one."""
    out = tmp_path / "ds"
    new_cfg = _cfg(tiny_scene, images=1, formats="dota", seed=5)
    export_dataset(new_cfg, tmp_path / "ref", progress=False)
    ref = tree_bytes(tmp_path / "ref")
    export_dataset(_cfg(tiny_scene, images=1, formats="eagle", seed=6), out, progress=False)
    (out / "notes.txt").write_text("mine")
    shutil.copytree(tmp_path / "ref", _partial(out))
    out.rename(tmp_path / ".ds.aerial-synth-old")
    with pytest.raises(ExportError, match="--resume"):
        export_dataset(new_cfg, out, progress=False)
    res = export_dataset(new_cfg, out, resume=True, progress=False)
    assert res.rendered == 0 and res.skipped == 1
    got = tree_bytes(out)
    assert got.pop("notes.txt") == b"mine"
    assert got == ref
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds", "ref"]


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


def test_show_truncated_png_writes_nothing(exported, tmp_path):
    src, _ = exported
    ds = tmp_path / "ds"
    shutil.copytree(src, ds)
    img = ds / "dota" / "train" / "images" / "000001.png"
    data = img.read_bytes()
    img.unlink()  # the formats' copies are hard links: cut this one only
    img.write_bytes(data[: len(data) // 2])
    for name in ("eagle/train/images", "yolo-obb/images/train", "coco/images/train"):
        (ds / name / "000001.png").unlink()
    prev = tmp_path / "prev"
    r = run_cli("show", ds, "--out", prev)
    assert r.returncode == 2, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "000001.png" in r.stderr and "truncated" in r.stderr
    assert not prev.exists()
    # an existing preview folder is left exactly as it was
    prev.mkdir()
    (prev / "000000.jpg").write_bytes(b"old")
    r = run_cli("show", ds, "--out", prev)
    assert r.returncode == 2
    assert tree_bytes(prev) == {"000000.jpg": b"old"}


@pytest.mark.parametrize("where", [".", "meta", "previews"])
def test_show_out_inside_dataset_refused(exported, tmp_path, where):
    src, _ = exported
    ds = tmp_path / "ds"
    shutil.copytree(src, ds)
    before = tree_bytes(ds)
    r = run_cli("show", ds, "--out", ds / where)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "inside" in r.stderr, r.stderr
    assert tree_bytes(ds) == before
    assert sorted(p.name for p in ds.iterdir()) == sorted({k.split("/")[0] for k in before})


def test_show_jpeg_dataset_and_truncated_jpeg(tiny_scene, tmp_path):
    ds = tmp_path / "ds"
    export_dataset(_cfg(tiny_scene, images=1, formats="dota", image_ext="jpg",
                   camera=CameraConfig(width_px=96, height_px=96)),
                   ds, progress=False)
    r = run_cli("show", ds, "--out", tmp_path / "prev")
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in (tmp_path / "prev").iterdir()) == ["000000.jpg", "contact_sheet.jpg"]
    img = ds / "dota" / "train" / "images" / "000000.jpg"
    img.write_bytes(img.read_bytes()[:-300])
    r = run_cli("show", ds, "--out", tmp_path / "prev2")
    assert r.returncode == 2 and "truncated or damaged JPEG" in r.stderr and len(r.stderr.splitlines()) == 1
    assert not (tmp_path / "prev2").exists()


def test_export_into_empty_working_folder_keeps_the_folder(tiny_scene, tmp_path):
    """--out . in an empty folder: the folder itself (inode, mode) stays, the dataset moves in."""
    out = tmp_path / "here"
    out.mkdir()
    out.chmod(0o750)
    ino = out.stat().st_ino
    r = run_cli("export", "--scene", tiny_scene, "--size", 64, "--images", 1, "--vehicles", 4,
                "--simple-vehicles", "--no-progress", "--out", ".", cwd=out)
    assert r.returncode == 0, r.stderr
    assert out.stat().st_ino == ino and (out.stat().st_mode & 0o777) == 0o750
    assert sorted(p.name for p in out.iterdir()) == ["dota", "manifest.json", "meta", "summary.json"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["here"]


def test_second_export_into_the_same_folder_refused(tiny_scene, tmp_path):
    """While one export writes --out (it holds the lock), another is refused in one line and
    writes nothing; once the lock is free the export runs and removes the lock file."""
    import fcntl

    out = tmp_path / "ds"
    lock = tmp_path / ".ds.aerial-synth-lock"
    fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
    fcntl.flock(fd, fcntl.LOCK_EX)
    try:
        r = run_cli("export", "--scene", tiny_scene, "--size", 64, "--images", 1, "--vehicles", 4,
                    "--simple-vehicles", "--no-progress", "--force", "--out", out)
    finally:
        os.close(fd)
    assert r.returncode == 2 and "another aerial-synth export" in r.stderr and len(r.stderr.splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == [".ds.aerial-synth-lock"]
    res = export_dataset(_cfg(tiny_scene, images=1, formats="dota"), out, progress=False)
    assert res.summary["images"] == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds"]


def test_pool_workers_fork_from_a_preloading_server():
    """Linux: the pool's workers are forks of a fork server that imported their modules;
    the guard that ties the server to the exporter acts only inside that server."""
    import multiprocessing as mp

    from aerial_synth.dataset.engines import _server_guard
    from aerial_synth.dataset.engines.fork_server import WORKER_MODULES, pool_context

    ctx = pool_context()
    if "forkserver" in mp.get_all_start_methods():
        assert ctx.get_start_method() == "forkserver"
        assert WORKER_MODULES[0] == "aerial_synth.dataset.engines._server_guard"
    else:
        assert ctx.get_start_method() == "spawn"
    assert _server_guard.GUARDED is False  # imported here, in no fork server: no prctl


def test_exported_png_is_the_rendered_pixels():
    """encode_image (what the writer thread runs) gives PNGs that decode to the very pixels
    rendered, through this package's encoder; JPEG stays OpenCV's."""
    import cv2

    from aerial_synth.dataset.worker import encode_image
    from aerial_synth.png import encode_png

    rng = np.random.default_rng(3)
    rgb = rng.integers(0, 256, (64, 80, 3), dtype=np.uint8)
    rgb[:, :40] = rgb[:, :40] // 16 * 16  # some smooth, some noisy
    data = encode_image(rgb, "png")
    assert data == encode_png(rgb)
    back = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    assert np.array_equal(back[:, :, ::-1], rgb)
    smooth = np.zeros((64, 80, 3), np.uint8)
    smooth[..., 0] = np.arange(80, dtype=np.uint8) * 3  # red rises to the right
    smooth[..., 2] = 180
    jpg = cv2.imdecode(np.frombuffer(encode_image(smooth, "jpg"), np.uint8), cv2.IMREAD_COLOR)
    assert jpg.shape == smooth.shape  # OpenCV's channel order: blue first
    assert np.abs(jpg[:, :, ::-1].astype(int) - smooth).max() < 8


def _server_state(_):
    import sys

    import numba.core.registry as reg

    viewer = sys.modules.get("open3d.visualization.draw_plotly")
    return {"stub": viewer is not None and "stub" in (viewer.__doc__ or ""), "dash": "dash" in sys.modules,
            "open3d": "open3d" in sys.modules, "numba_warm": bool(reg.cpu_target.target_context._registries)}


def test_fork_server_workers_are_ready_and_light():
    """A pool worker is a fork of the warmed server: open3d imported without its plotly
    viewer (no Dash), numba's contexts set up, the heap frozen; this process's open3d
    import is untouched and the stub reports itself when called."""
    import multiprocessing as mp
    import sys

    import pytest

    from aerial_synth.dataset.engines import _server_open3d
    from aerial_synth.dataset.export import pool_context

    if "forkserver" not in mp.get_all_start_methods():
        pytest.skip("no fork server on this platform")
    with pool_context().Pool(1) as pool:
        state = pool.map(_server_state, [0])[0]
    assert state == {"stub": True, "dash": False, "open3d": True, "numba_warm": True}
    assert _server_open3d.STUBBED is False  # not in a fork server: nothing stubbed here
    import open3d  # noqa: F401

    viewer = sys.modules.get("open3d.visualization.draw_plotly")
    assert viewer is None or "stub" not in (viewer.__doc__ or "")
    from aerial_synth._open3d import _absent

    with pytest.raises(RuntimeError, match="not loaded"):
        _absent()


def test_meta_records_our_warnings_not_a_library_s(tiny_scene, tmp_path, monkeypatch):
    """A library's one-time warning during placement (open3d 0.18 warns once per process
    that it was built with CUDA) stays out of meta.json: it reached only the first placement
    of a process, so the meta of one image depended on which worker placed its group (a
    killed-and-resumed export differed from a clean one). Our own warnings stay."""
    import warnings

    import aerial_synth.dataset.sample as worker_module
    from aerial_synth.placement.traffic import PlacementWarning

    real = worker_module.place

    def noisy_place(*a, **kw):
        warnings.warn("a third-party library warns once per process", UserWarning, stacklevel=2)
        warnings.warn("ours: a placement warning", PlacementWarning, stacklevel=2)
        return real(*a, **kw)

    monkeypatch.setattr(worker_module, "place", noisy_place)
    out = tmp_path / "ds"
    export_dataset(_cfg(tiny_scene, images=1, formats="dota"), out, workers=1, progress=False)
    metas = list((out / "meta").glob("*.json"))
    assert len(metas) == 1
    recorded = json.loads(metas[0].read_text())["placement"]["warnings"]
    assert recorded == ["ours: a placement warning"]
