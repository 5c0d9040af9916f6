"""aerial-synth mix: exact ratios, tiles covering images, devkit-style clipping, GSD rescale."""

from __future__ import annotations

import json
import os

import cv2
import numpy as np
import pytest
import shapely

from aerial_synth.cli import main
from aerial_synth.errors import EvaluationError
from aerial_synth.evaluate.mix import MixConfig, clip_to_tile, make_mix, mix_counts, tile_origins
from aerial_synth.formats import dota, yolo_obb

from .conftest import make_dota, rect, write_dota_image


def labels_of(folder):
    out = {}
    for p in sorted(folder.glob("*.txt")):
        lab = dota.labels_from_lines(p.read_text().splitlines(), str(p))
        out[p.stem] = (lab.polygons_xy_px, lab.classes, lab.difficult, lab.gsd_m, lab.image_source)
    return out


def test_ratio_is_exact_and_deterministic(tmp_path):
    syn = make_dota(tmp_path / "syn" / "dota" / "train", 30, "s", seed=1)
    make_dota(tmp_path / "syn" / "dota" / "val", 5, "sv", seed=2)
    make_dota(tmp_path / "real" / "train", 20, "r", seed=3)
    make_dota(tmp_path / "real" / "val", 4, "rv", seed=4)
    assert syn.exists()
    man = make_mix(MixConfig(real=tmp_path / "real", synthetic=tmp_path / "syn",
                             out=tmp_path / "mix", real_fraction=0.25, seed=7))
    c = man["counts"]
    assert (c["train_real"], c["train_synthetic"]) == (10, 30)
    assert c["real_share"] == 0.25
    assert (c["val_real"], c["val_synthetic"]) == (4, 0)  # validation: real only
    train = sorted(p.name for p in (tmp_path / "mix/dota/train/images").iterdir())
    assert len(train) == 40 and sum(n.startswith("real-") for n in train) == 10
    val = sorted(p.name for p in (tmp_path / "mix/dota/val/images").iterdir())
    assert val == [f"real-rv{i:03d}.png" for i in range(4)]
    # hard links, not copies
    src = tmp_path / "real/val/images/rv000.png"
    assert os.stat(tmp_path / "mix/dota/val/images/real-rv000.png").st_ino == os.stat(src).st_ino
    # every source image is in the manifest
    assert len(man["sources"]) == 44 and all(e["file"] == "hardlink" for e in man["images"])
    # same seed -> same choice; another seed -> another choice
    man2 = make_mix(MixConfig(real=tmp_path / "real", synthetic=tmp_path / "syn",
                              out=tmp_path / "mix2", real_fraction=0.25, seed=7))
    assert [e["image"] for e in man2["images"]] == [e["image"] for e in man["images"]]

    def tree(root):
        return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}

    assert tree(tmp_path / "mix2") == tree(tmp_path / "mix")  # byte-identical, manifest included
    man3 = make_mix(MixConfig(real=tmp_path / "real", synthetic=tmp_path / "syn",
                              out=tmp_path / "mix3", real_fraction=0.25, seed=8))
    assert {e["image"] for e in man3["images"]} != {e["image"] for e in man["images"]}
    # --real-images N adds exactly N
    man4 = make_mix(MixConfig(real=tmp_path / "real", synthetic=tmp_path / "syn",
                              out=tmp_path / "mix4", real_images=7, synthetic_images=12))
    assert (man4["counts"]["train_real"], man4["counts"]["train_synthetic"]) == (7, 12)


def test_counts_for_fractions():
    assert mix_counts(88, 100, 0.12, None, None) == (88, 12)
    assert mix_counts(50, 50, 0.5, None, None) == (50, 50)
    assert mix_counts(40, 9, 0.0, None, None) == (40, 0)
    assert mix_counts(40, 9, 1.0, None, None) == (0, 9)
    with pytest.raises(EvaluationError, match="needs 40 real .* only 9 available"):
        mix_counts(40, 9, 0.5, None, None)


def test_tile_origins_cover_the_image():
    assert tile_origins(3000, 1024, 200) == [0, 824, 1648, 1976]
    assert tile_origins(1024, 1024, 200) == [0]
    assert tile_origins(500, 1024, 200) == [0]
    for size in (1, 50, 1023, 1025, 2047, 4000):
        o = tile_origins(size, 1024, 200)
        cover = np.zeros(size, bool)
        for x in o:
            cover[x:x + 1024] = True
        assert cover.all()
        assert o[-1] + min(1024, size) == size  # the last tile ends at the edge
        assert all(b - a == 824 for a, b in zip(o[:-2], o[1:-1]))


def test_box_cut_by_tile_border_is_clipped_and_flagged():
    tile = (0, 0, 100, 100)
    inside = rect(50, 50, 20, 10, 30)
    mostly = np.array([[85, 40], [110, 40], [110, 50], [85, 50]], float)  # 15/25 = 0.6 inside
    big = np.array([[80, 60], [105, 60], [105, 70], [80, 70]], float)  # 20/25 = 0.8 inside
    idx, P, D, C = clip_to_tile([inside, mostly, big], [0, 0, 0], tile, 0.7)
    assert idx.tolist() == [0, 2]  # 0.6 < 0.7: dropped
    np.testing.assert_allclose(P[0], inside)  # untouched
    assert D.tolist() == [False, True] and C.tolist() == [False, True]
    np.testing.assert_allclose(P[1], [[80, 60], [100, 60], [100, 70], [80, 70]])
    # a rotated box cut by the corner of a tile at an offset: the clipped polygon lies in the
    # tile, keeps >= threshold of the area and starts at the corner nearest the original head
    b = rect(195, 105, 30, 12, 20)
    tile2 = (100, 100, 100, 100)
    idx, P, D, C = clip_to_tile([b], [0], tile2, 0.5)
    assert idx.tolist() == [0] and D.tolist() == [True]
    assert P.min() >= 0 and P.max() <= 100
    inter = shapely.Polygon(b).intersection(shapely.box(100, 100, 200, 200)).area
    assert shapely.Polygon(P[0] + (100, 100)).area == pytest.approx(inter, rel=0.15)
    assert np.linalg.norm(P[0][0] + (100, 100) - b[0]) < np.linalg.norm(P[0][2] + (100, 100) - b[0])


def test_tiled_mix_covers_each_real_image_and_clips_labels(tmp_path):
    real = tmp_path / "real"
    cut = np.array([[230, 100], [265, 100], [265, 115], [230, 115]], float)  # crosses x = 256
    write_dota_image(real / "train", "r0", [rect(60, 60, 30, 12, 10), cut], size=(400, 300))
    write_dota_image(real / "val", "rv", [rect(30, 30, 20, 10)], size=(120, 90))
    make_dota(tmp_path / "syn/dota/train", 3, "s")
    man = make_mix(MixConfig(real=real, synthetic=tmp_path / "syn", out=tmp_path / "mix",
                             real_images=4, tile=256, overlap=64, seed=0))
    tiles = [e for e in man["images"] if e["split"] == "train" and e["origin"] == "real"]
    # x in {0, 144}, y in {0, 44}: the last tiles are flush with the right and bottom edges
    assert sorted(tuple(e["tile_xywh"]) for e in tiles) == [
        (0, 0, 256, 256), (0, 44, 256, 256), (144, 0, 256, 256), (144, 44, 256, 256)]
    src = cv2.imread(str(real / "train/images/r0.png"))
    cover = np.zeros(src.shape[:2], bool)
    labels = labels_of(tmp_path / "mix/dota/train/labelTxt")
    for e in tiles:
        x, y, w, h = e["tile_xywh"]
        cover[y:y + h, x:x + w] = True
        tile_img = cv2.imread(str(tmp_path / "mix" / e["image"]))
        np.testing.assert_array_equal(tile_img, src[y:y + h, x:x + w])  # pixels are the crop
    assert cover.all()
    # the cut box: wholly inside the right tiles (unchanged, shifted), clipped at x = 256 in
    # the left ones (26/35 = 0.74 of it inside >= 0.7: kept, difficult)
    polys, cls, diff, gsd, _ = labels["real-r0__1__144___0"]
    np.testing.assert_allclose(polys[-1], cut - (144, 0), atol=0.01)
    assert not diff[-1] and gsd == 0.12
    polys, cls, diff, _, _ = labels["real-r0__1__0___0"]
    assert len(polys) == 2 and diff.tolist() == [False, True]
    np.testing.assert_allclose(polys[1], [[230, 100], [256, 100], [256, 115], [230, 115]], atol=0.01)
    assert man["counts"]["clipped"] == 2


def test_gsd_rescale_keeps_boxes_on_their_objects(tmp_path):
    real = tmp_path / "real"
    boxes = [rect(50, 40, 24, 10, 30), rect(120, 100, 30, 14, -50)]
    write_dota_image(real / "train", "r0", boxes, size=(200, 160), gsd=0.3, background=20)
    make_dota(tmp_path / "syn/dota/train", 2, "s")
    man = make_mix(MixConfig(real=real, synthetic=tmp_path / "syn", out=tmp_path / "mix",
                             real_images=1, gsd=0.12, val_fraction=0.0, format="dota,yolo-obb"))
    e = [e for e in man["images"] if e["origin"] == "real"][0]
    assert e["scale"] == [2.5, 2.5] and e["file"] == "written"
    dota_img, yolo_img = (tmp_path / "mix" / p for p in e["images"])
    assert os.stat(dota_img).st_ino == os.stat(yolo_img).st_ino  # one file, linked
    assert yolo_img.parent == tmp_path / "mix/yolo-obb/images/train"
    dlab = dota.labels_from_lines(
        (tmp_path / "mix/dota/train/labelTxt" / (dota_img.stem + ".txt")).read_text().splitlines(), "x")
    dpolys, dgsd = dlab.polygons_xy_px, dlab.gsd_m
    assert dgsd == 0.12  # the rescaled image's header says the new GSD
    np.testing.assert_allclose(dpolys, np.array(boxes) * 2.5, atol=0.013)
    img = cv2.imread(str(yolo_img), cv2.IMREAD_GRAYSCALE)
    assert img.shape == (400, 500)
    lab = yolo_img.as_posix().replace("/images/", "/labels/").replace(".png", ".txt")
    polys = yolo_obb.labels_from_lines(open(lab).read().splitlines(), lab,
                                       ["small-vehicle", "large-vehicle"], (500, 400)).polygons_xy_px
    assert len(polys) == 2
    for p, b in zip(polys, boxes):
        np.testing.assert_allclose(p, b * 2.5, atol=0.013)  # labels hold 2 decimals
        mask = np.zeros_like(img)
        cv2.fillPoly(mask, [np.round(p * 16).astype(np.int32)], 1, cv2.LINE_8, shift=4)
        inner = cv2.erode(mask, np.ones((5, 5), np.uint8))
        ring = cv2.dilate(mask, np.ones((7, 7), np.uint8)) - cv2.dilate(mask, np.ones((3, 3), np.uint8))
        assert img[inner > 0].mean() > 220 and img[ring > 0].mean() < 40  # bright car, dark ground
    data = (tmp_path / "mix/yolo-obb/data.yaml").read_text()
    assert "small-vehicle" in data and "val: images/train" in data


def test_failing_mix_writes_nothing_and_cli_errors_are_one_line(tmp_path, capsys):
    make_dota(tmp_path / "real/train", 3, "r")
    make_dota(tmp_path / "syn/dota/train", 10, "s")
    out = tmp_path / "mix"
    rc = main(["mix", "--real", str(tmp_path / "real"), "--synthetic", str(tmp_path / "syn"),
               "--real-fraction", "0.5", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and "needs 10 real training images" in err and err.count("\n") == 1
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["real", "syn"]
    rc = main(["mix", "--real", str(tmp_path / "real"), "--synthetic", str(tmp_path / "syn"),
               "--real-fraction", "1.5", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and "--real-fraction: expected a finite number >= 0 and <= 1, got '1.5'" in err
    # a real image without gsd header when rescaling: named, nothing written
    write_dota_image(tmp_path / "real/train", "nogsd", [rect(20, 20, 10, 5)], gsd=None)
    rc = main(["mix", "--real", str(tmp_path / "real"), "--synthetic", str(tmp_path / "syn"),
               "--real-images", "1", "--gsd", "0.12", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and "nogsd.txt: expected a 'gsd:' header" in err and not out.exists()
    # --out inside an input
    rc = main(["mix", "--real", str(tmp_path / "real"), "--synthetic", str(tmp_path / "syn"),
               "--real-images", "1", "--out", str(tmp_path / "syn" / "m")])
    assert rc == 2 and "overlaps the input folder" in capsys.readouterr().err
    # success, then a second run into the same folder is refused without --force
    args = ["mix", "--real", str(tmp_path / "real"), "--synthetic", str(tmp_path / "syn"),
            "--real-images", "1", "--out", str(out)]
    assert main(args) == 0
    capsys.readouterr()
    assert main(args) == 2 and "use --force" in capsys.readouterr().err
    assert main(args + ["--force"]) == 0
    man = json.loads((out / "manifest.json").read_text())
    assert man["format"] == "aerial-synth-mix"
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temp left


def test_pentagon_cut_merges_its_shortest_edge_as_the_devkit():
    b = rect(90, 50, 30, 12, 30)  # one corner past x = 100: the clipped polygon has 5 corners
    inter = shapely.Polygon(b).intersection(shapely.box(0, 0, 100, 100))
    pts = np.asarray(inter.exterior.coords)[:-1]
    assert len(pts) == 5
    d = np.linalg.norm(np.roll(pts, -1, 0) - pts, axis=1)
    k = int(np.argmin(d))
    merged = (pts[k] + pts[(k + 1) % 5]) / 2
    expected = {tuple(np.round(p, 6)) for i, p in enumerate(pts) if i not in (k, (k + 1) % 5)}
    expected.add(tuple(np.round(merged, 6)))
    idx, P, D, C = clip_to_tile([b], [0], (0, 0, 100, 100), 0.7)
    assert idx.tolist() == [0] and D.tolist() == [True] and C.tolist() == [True]
    assert {tuple(np.round(p, 6)) for p in P[0]} == expected
    # corners stay clockwise on screen and start at the corner nearest the original first one
    x, y = P[0][:, 0], P[0][:, 1]
    assert np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0
    assert np.argmin(np.linalg.norm(P[0] - b[0], axis=1)) == 0


def test_without_a_real_val_split_whole_images_are_held_out(tmp_path):
    make_dota(tmp_path / "real", 10, "r", size=(300, 200))  # images/ + labelTxt/, no splits
    make_dota(tmp_path / "syn/dota/train", 4, "s")
    man = make_mix(MixConfig(real=tmp_path / "real", synthetic=tmp_path / "syn", out=tmp_path / "mix",
                             real_images=16, tile=160, overlap=20, val_fraction=0.2, seed=3))
    src = {"train": set(), "val": set()}
    for e in man["images"]:
        if e["origin"] == "real":
            src[e["split"]].add(e["source_image"])
    assert len(src["val"]) == 2 and not (src["val"] & src["train"])  # no tile of a val image trains
    assert man["available"]["real_train_images"] == 8
    assert man["available"]["real_train_outputs"] == 8 * 4  # 2 x 2 tiles per 300 x 200 image
    assert man["counts"]["train_real"] == 16 and man["counts"]["val_real"] == 2 * 4
    with pytest.raises(EvaluationError, match="needs 33 real training images .* only 32"):
        make_mix(MixConfig(real=tmp_path / "real", synthetic=tmp_path / "syn", out=tmp_path / "m2",
                           real_images=33, tile=160, overlap=20, seed=3))
    assert not (tmp_path / "m2").exists()


def test_real_yolo_obb_folder_with_a_given_gsd(tmp_path):
    real = tmp_path / "dota8like"
    for split in ("train", "val"):
        (real / "images" / split).mkdir(parents=True)
        (real / "labels" / split).mkdir(parents=True)
    boxes = [rect(40, 30, 24, 10, 20), rect(100, 60, 30, 12, -30)]
    for split, name in (("train", "t0"), ("train", "t1"), ("val", "v0")):
        img = np.full((100, 160, 3), 20, np.uint8)
        for b in boxes:
            cv2.fillPoly(img, [np.round(b * 16).astype(np.int32)], (230, 230, 230), cv2.LINE_8, shift=4)
        cv2.imwrite(str(real / "images" / split / f"{name}.jpg"), img)
        lines = [f"{k} " + " ".join(f"{v:.6f}" for v in (b / (160, 100)).reshape(-1))
                 for k, b in zip((1, 0), boxes)]
        (real / "labels" / split / f"{name}.txt").write_text("\n".join(lines) + "\n")
    (real / "data.yaml").write_text("names:\n  0: large vehicle\n  1: small vehicle\n  2: plane\n")
    make_dota(tmp_path / "syn/dota/train", 2, "s")
    man = make_mix(MixConfig(real=real, synthetic=tmp_path / "syn", out=tmp_path / "mix",
                             real_images=2, gsd=0.12, real_gsd=0.24))
    assert man["counts"]["train_real"] == 2 and man["counts"]["val_real"] == 1
    lab = tmp_path / "mix/dota/train/labelTxt/real-t0__2.txt"
    got = dota.read_labels(lab)
    polys, cls, gsd = got.polygons_xy_px, got.classes, got.gsd_m
    assert cls == ["small-vehicle", "large-vehicle"] and gsd == 0.12  # names from the YAML
    np.testing.assert_allclose(polys, np.array(boxes) * 2, atol=0.01)
    img = cv2.imread(str(tmp_path / "mix/dota/train/images/real-t0__2.png"))
    assert img.shape == (200, 320, 3)
    # without --real-gsd, rescaling a YOLO folder (no gsd: headers) is refused, naming a file
    with pytest.raises(EvaluationError, match="expected a 'gsd:' header .* --real-gsd"):
        make_mix(MixConfig(real=real, synthetic=tmp_path / "syn", out=tmp_path / "m2",
                           real_images=2, gsd=0.12))
