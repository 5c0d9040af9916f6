"""tools/make_dev_set.py: a collection of DOTA, YOLO-OBB and VEDAI folders becomes the DOTA
collection ``sim2real --real`` reads (vehicles only, GSD headers where known), made here from
small hand-written folders."""

import importlib.util
import subprocess
import sys

import cv2
import numpy as np
import pytest

from aerial_synth.evaluate.labels import read_dataset

from ..helpers import REPO, tree_bytes

TOOL = REPO / "tools" / "make_dev_set.py"


def _image(path, w=200, h=100):
    path.parent.mkdir(parents=True, exist_ok=True)
    img = np.zeros((h, w, 3), np.uint8)
    img[:, :, 1] = np.arange(w, dtype=np.uint8)[None, :]
    assert cv2.imwrite(str(path), img)


def _source(root):
    # DOTA with a GSD header, a vehicle, a plane and a difficult vehicle
    _image(root / "uav" / "images" / "a.png")
    (root / "uav" / "labelTxt").mkdir(parents=True)
    (root / "uav" / "labelTxt" / "a.txt").write_text(
        "imagesource:drone\ngsd:0.05\n10 10 50 10 50 30 10 30 small-vehicle 0\n"
        "60 10 90 10 90 40 60 40 plane 0\n100 50 140 50 140 70 100 70 large-vehicle 1\n")
    # YOLO-OBB with DOTA8's class names (spaces), no GSD
    _image(root / "yolo" / "images" / "train" / "b.jpg")
    (root / "yolo" / "labels" / "train").mkdir(parents=True)
    (root / "yolo" / "data.yaml").write_text("names:\n  0: small vehicle\n  1: harbor\n")
    (root / "yolo" / "labels" / "train" / "b.txt").write_text(
        "0 0.1 0.1 0.3 0.1 0.3 0.3 0.1 0.3\n1 0.5 0.5 0.9 0.5 0.9 0.9 0.5 0.9\n")
    # VEDAI: a car (1), a boat (23) and an occluded pick-up (11)
    _image(root / "vedai" / "images" / "00000001_co.png")
    (root / "vedai" / "annotations512").mkdir(parents=True)
    (root / "vedai" / "annotations512" / "00000001.txt").write_text(
        "30 20 0 1 1 0 20 40 40 20 10 10 30 30\n"
        "80 20 0 23 1 0 70 90 90 70 10 10 30 30\n"
        "130 20 0 11 1 1 120 140 140 120 10 10 30 30\n")
    return root


def _run(*args):
    return subprocess.run([sys.executable, str(TOOL), *map(str, args)], capture_output=True, text=True,
                          timeout=120)


def test_collection_becomes_dota_with_vehicles_and_gsd(tmp_path):
    src = _source(tmp_path / "src")
    out = tmp_path / "dev"
    r = _run(src, out, "--gsd", "vedai=0.25")
    assert r.returncode == 0, r.stderr
    assert "uav: 1 images, 2 vehicles" in r.stdout and "yolo: 1 images, 1 vehicles" in r.stdout
    assert "vedai: 1 images, 2 vehicles" in r.stdout and "total: 3 images, 5 vehicles" in r.stdout
    layout, items = read_dataset(out)
    assert layout == "collection"
    by = {it.name: it for it in items}
    assert set(by) == {"uav/a", "yolo/b", "vedai/00000001"}
    assert by["uav/a"].classes == ["small-vehicle", "large-vehicle"]
    assert by["uav/a"].difficult.tolist() == [False, True] and by["uav/a"].gsd_m == 0.05
    assert by["yolo/b"].classes == ["small-vehicle"] and by["yolo/b"].gsd_m is None
    assert np.allclose(by["yolo/b"].polygons_xy_px[0], [[20, 10], [60, 10], [60, 30], [20, 30]])
    assert by["vedai/00000001"].classes == ["small-vehicle", "small-vehicle"]
    assert by["vedai/00000001"].difficult.tolist() == [False, True]
    assert by["vedai/00000001"].gsd_m == 0.25
    # images copied byte for byte
    assert (out / "yolo" / "images" / "b.jpg").read_bytes() == (src / "yolo" / "images" / "train" / "b.jpg").read_bytes()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".dev.")], "temporary folder left"
    # deterministic: a second run gives the same bytes
    r = _run(src, tmp_path / "dev2", "--gsd", "vedai=0.25")
    assert r.returncode == 0 and tree_bytes(out) == tree_bytes(tmp_path / "dev2")


def test_known_sources_print_their_scoring_keys(tmp_path):
    """A ucas_aod group (cars only, part-labelled border cars) gets its plan keys printed."""
    src = tmp_path / "src"
    _image(src / "ucas_aod" / "images" / "u.png")
    (src / "ucas_aod" / "labelTxt").mkdir(parents=True)
    (src / "ucas_aod" / "labelTxt" / "u.txt").write_text("gsd:0.08\n10 10 50 10 50 30 10 30 small-vehicle 0\n")
    _image(src / "other" / "images" / "o.png")
    (src / "other" / "labelTxt").mkdir(parents=True)
    (src / "other" / "labelTxt" / "o.txt").write_text("gsd:0.1\n10 10 50 10 50 30 10 30 small-vehicle 0\n")
    r = _run(src, tmp_path / "dev")
    assert r.returncode == 0, r.stderr
    assert "ucas_aod: 1 images, 1 vehicles" in r.stdout
    assert "ignore_border: {ucas_aod: 20}" in r.stdout
    assert "ignore_classes: {ucas_aod: [large-vehicle]}" in r.stdout
    r = _run(tmp_path / "dev", tmp_path / "dev3")  # a collection made by the tool, made again
    assert r.returncode == 0 and "ignore_classes" in r.stdout


def test_jpeg_reencodes_lossless_images_only(tmp_path):
    src = _source(tmp_path / "src")
    r = _run(src, tmp_path / "dev", "--gsd", "vedai=0.25", "--jpeg", "90")
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in (tmp_path / "dev" / "uav" / "images").iterdir()) == ["a.jpg"]
    a = cv2.imread(str(tmp_path / "dev" / "uav" / "images" / "a.jpg"))
    ref = cv2.imread(str(src / "uav" / "images" / "a.png"))
    assert a.shape == ref.shape and np.abs(a.astype(int) - ref).mean() < 3
    assert (tmp_path / "dev" / "yolo" / "images" / "b.jpg").read_bytes() == \
        (src / "yolo" / "images" / "train" / "b.jpg").read_bytes()  # a JPEG stays as it is
    layout, items = read_dataset(tmp_path / "dev")
    assert {it.name for it in items} == {"uav/a", "yolo/b", "vedai/00000001"}
    assert _run(src, tmp_path / "dev2", "--jpeg", "0").returncode == 2 and not (tmp_path / "dev2").exists()


@pytest.mark.parametrize("args, msg", [
    (("--gsd", "vedai"), "--gsd: expected GROUP=M"),
    (("--gsd", "vedai=-1"), "--gsd: expected GROUP=M"),
    (("--gsd", "nosuch=0.2"), "--gsd: no group nosuch"),
    (("--gsd", "vedai=1e400"), "--gsd: expected GROUP=M"),
])
def test_bad_options_write_nothing(tmp_path, args, msg):
    src = _source(tmp_path / "src")
    r = _run(src, tmp_path / "dev", *args)
    assert r.returncode != 0 and msg in r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["src"]


def test_bad_source_is_one_line(tmp_path):
    r = _run(tmp_path / "nosuch", tmp_path / "dev")
    assert r.returncode == 2 and r.stderr.strip().count("\n") == 0 and "no such folder" in r.stderr
    src = _source(tmp_path / "src")
    (src / "uav" / "labelTxt" / "a.txt").write_text("10 10 50 10 50 x 10 30 small-vehicle 0\n")
    r = _run(src, tmp_path / "dev")
    assert r.returncode == 2 and r.stderr.strip().count("\n") == 0 and "a.txt" in r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["src"]


@pytest.mark.parametrize("out", ["/dev/null", "afile", "afile/sub", "src", "src/uav/dev"])
def test_out_that_is_no_new_folder_or_overlaps_src_is_refused(tmp_path, out):
    """A device, a file, a path below a file, SRC itself or a folder inside it (with --force
    too): one line, SRC and the file untouched."""
    src = _source(tmp_path / "src")
    (tmp_path / "afile").write_text("x")
    before = tree_bytes(src)
    target = out if out.startswith("/") else tmp_path / out
    r = _run(src, target, "--force")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 + r.stderr.count("usage:"), r.stderr
    assert tree_bytes(src) == before and (tmp_path / "afile").read_text() == "x"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "src"]


def test_existing_out_needs_force(tmp_path):
    src = _source(tmp_path / "src")
    (tmp_path / "dev").mkdir()
    (tmp_path / "dev" / "keep.txt").write_text("x")
    r = _run(src, tmp_path / "dev")
    assert r.returncode == 2 and "exists" in r.stderr and (tmp_path / "dev" / "keep.txt").is_file()
    # --force replaces only this tool's own collections (issue 37 L1): a user's folder stays
    r = _run(src, tmp_path / "dev", "--force")
    assert r.returncode == 2 and "not a collection made by make_dev_set.py" in r.stderr
    assert (tmp_path / "dev" / "keep.txt").read_text() == "x"
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr


def test_force_replaces_own_collection_and_empty_folder(tmp_path):
    src = _source(tmp_path / "src")
    (tmp_path / "empty").mkdir()
    assert _run(src, tmp_path / "empty", "--force").returncode == 0
    assert (tmp_path / "empty" / "dev_set.json").is_file()
    (tmp_path / "empty" / "uav" / "stale.txt").write_text("old")
    r = _run(src, tmp_path / "empty", "--force")
    assert r.returncode == 0, r.stderr
    assert not (tmp_path / "empty" / "uav" / "stale.txt").exists()


def test_label_linked_out_of_src_is_refused_unread(tmp_path):
    # issue 37 D2: the CLI's link guard now covers the tool
    src = _source(tmp_path / "src")
    secret = tmp_path / "secret.txt"
    secret.write_text("root:$6$secretpassword:19000\n")
    lab = src / "uav" / "labelTxt" / "a.txt"
    lab.unlink()
    lab.symlink_to(secret)
    r = _run(src, tmp_path / "dev")
    assert r.returncode == 2 and "outside the input folder" in r.stderr, r.stderr
    assert "secretpassword" not in r.stderr and "root:" not in r.stderr
    assert r.stderr.count("\n") == 1 and not (tmp_path / "dev").exists()


def test_image_linked_out_of_src_is_not_copied(tmp_path):
    src = _source(tmp_path / "src")
    img = src / "uav" / "images" / "a.png"
    outside = tmp_path / "private.png"
    img.rename(outside)
    img.symlink_to(outside)
    r = _run(src, tmp_path / "dev")
    assert r.returncode == 2 and "outside the input folder" in r.stderr, r.stderr
    assert not (tmp_path / "dev").exists()


def test_out_is_current_folder_is_one_line(tmp_path):
    # issue 37 T4: 'SRC . --force' raised OSError EBUSY (a folder renamed while one stands in it)
    src = _source(tmp_path / "src")
    here = tmp_path / "here"
    here.mkdir()
    r = subprocess.run([sys.executable, str(TOOL), str(src), ".", "--force"], cwd=here,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "current folder" in r.stderr and "Traceback" not in r.stderr
    assert r.stderr.count("\n") == 1 and here.is_dir()


def test_refusals_exit_2(tmp_path):
    # issue 37 T4: a single dataset instead of a collection was SystemExit (status 1)
    src = _source(tmp_path / "src")
    r = _run(src / "uav", tmp_path / "dev")
    assert r.returncode == 2 and "expected a folder of datasets" in r.stderr
    r = _run(src, tmp_path / "dev", "--gsd", "nosuch=0.1")
    assert r.returncode == 2 and "no group nosuch" in r.stderr
    assert not (tmp_path / "dev").exists()


def test_full_disk_is_one_line_and_leaves_nothing(tmp_path, monkeypatch, capsys):
    # issue 37 T4: ENOSPC while copying an image was a traceback
    import errno
    import shutil

    mod = _module()
    src = _source(tmp_path / "src")

    def full(a, b, *args, **kw):
        raise OSError(errno.ENOSPC, "No space left on device", str(b))

    monkeypatch.setattr(shutil, "copyfile", full)
    assert mod.main([str(src), str(tmp_path / "dev")]) == 2
    err = capsys.readouterr().err
    assert "No space left on device" in err and err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["src"]  # no OUT, no temporary, no lock


def _module():
    spec = importlib.util.spec_from_file_location("make_dev_set", TOOL)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_tool_module_imports_cleanly():
    mod = _module()
    assert mod.VEHICLES == ("small-vehicle", "large-vehicle")
