"""aerial-synth stats: exact figures on hand-built folders, and the domain-gap report of a
synthetic export against a small DOTA-format folder."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from scipy.stats import ks_2samp

from aerial_synth.cli import main
from aerial_synth.evaluate.stats import box_geometry, compare_stats, dataset_stats

from .conftest import write_dota_image


def car(cx, cy, length, width, heading_deg):
    """Corners front-left, front-right, rear-right, rear-left (clockwise on screen)."""
    t = np.deg2rad(heading_deg)
    f = np.array([np.cos(t), -np.sin(t)])
    r = np.array([np.sin(t), np.cos(t)])
    c = np.array([cx, cy], float)
    return np.array([c + f * length / 2 - r * width / 2, c + f * length / 2 + r * width / 2,
                     c - f * length / 2 + r * width / 2, c - f * length / 2 - r * width / 2])


def test_box_geometry_heading_axis_and_size():
    g = box_geometry([car(0, 0, 40, 16, h) for h in (0, 90, 200, 315)])
    np.testing.assert_allclose(g["heading_deg"], [0, 90, 200, 315], atol=1e-9)
    np.testing.assert_allclose(g["axis_deg"], [0, 90, 20, 135], atol=1e-9)
    np.testing.assert_allclose(g["length_px"], 40)
    np.testing.assert_allclose(g["width_px"], 16)


@pytest.fixture
def real_like(tmp_path):
    """Three 200 x 160 images: axis-aligned integer boxes, 230 gray on 90 gray."""
    d = tmp_path / "real"
    boxes = {
        "a": [car(50, 40, 20, 8, 0), car(120, 40, 20, 8, 0), car(50, 110, 30, 10, 90)],
        "b": [car(100, 80, 20, 8, 180)],
        "c": [car(60, 60, 24, 8, 270), car(69, 60, 24, 8, 270)],  # a plane 1 px beside the car
    }
    cls = {"a": ["small-vehicle", "small-vehicle", "large-vehicle"], "b": ["small-vehicle"],
           "c": ["small-vehicle", "plane"]}
    diff = {"a": [0, 1, 0], "b": [0], "c": [0, 0]}
    for k in boxes:
        write_dota_image(d, k, boxes[k], cls[k], diff[k], gsd=0.25)
    return d, boxes


def test_dataset_stats_exact_on_a_built_folder(real_like):
    d, boxes = real_like
    s, dist, hist = dataset_stats(d)
    assert s["layout"] == "dota" and s["images"] == 3 and s["objects"] == 5
    assert s["classes"] == {"large-vehicle": 1, "small-vehicle": 4}
    assert s["other_classes_left_out"] == {"plane": 1}
    assert s["difficult_fraction"] == 1 / 5 and s["truncated_fraction"] == 0.0
    np.testing.assert_array_equal(np.sort(dist["vehicles_per_image"]), [1, 1, 3])
    np.testing.assert_allclose(np.sort(dist["length_px"]), [20, 20, 20, 24, 30], atol=0.01)
    np.testing.assert_allclose(np.sort(dist["length_m"]), np.array([20, 20, 20, 24, 30]) * 0.25, atol=0.01)
    np.testing.assert_allclose(np.sort(dist["heading_deg"]), [0, 0, 90, 180, 270], atol=0.1)
    # nearest neighbours: image a has centres (50,40), (120,40), (50,110)
    np.testing.assert_allclose(np.sort(dist["nn_distance_px"]), [70, 70, 70], atol=0.01)
    # pixels: 230 inside every box, 90 around it -> contrast (230 - 90) / the image's gray sd
    np.testing.assert_allclose(dist["box_gray_mean"], 230.0)
    np.testing.assert_allclose(dist["ring_gray_mean"], 90.0)
    sds = {}
    for k in "abc":
        g = cv2.imread(str(d / "images" / f"{k}.png"), cv2.IMREAD_GRAYSCALE)
        sds[k] = g.std()
    expected = [140 / sds["a"]] * 3 + [140 / sds["b"]] + [140 / sds["c"]]
    np.testing.assert_allclose(np.sort(dist["vehicle_contrast"]), np.sort(expected), rtol=1e-9)
    assert s["vehicle_contrast_median"] == pytest.approx(np.median(expected))
    # the ring of a vehicle leaves out the plane beside it (a labelled object, not ground)
    assert s["distributions"]["image_gray_mean"]["n"] == 3
    assert hist["inside"].sum() > 0 and hist["ring"].sum() > 0
    # the inside histogram is one bin (230 // 8 = 28) per channel
    assert hist["inside"][:, 28].sum() == hist["inside"].sum()


def test_compare_identical_is_zero_and_shifted_is_found(real_like):
    d, _ = real_like
    _, da, ha = dataset_stats(d)
    gaps = compare_stats(da, da, ha, ha)
    assert gaps and all(g["ks"] == 0 and g["wasserstein"] == pytest.approx(0, abs=1e-9) for g in gaps)
    shifted = {k: v * 2 for k, v in da.items()}
    gaps = compare_stats(da, shifted)
    assert [g["ks"] for g in gaps] == sorted((g["ks"] for g in gaps), reverse=True)
    g = {x["name"]: x for x in gaps}["length_px"]
    assert g["ks"] == pytest.approx(ks_2samp(da["length_px"], shifted["length_px"]).statistic)
    assert g["wasserstein"] == pytest.approx(np.mean(da["length_px"]))  # W of x vs 2x = mean(x)


def test_yolo_obb_and_image_only_folders(tmp_path):
    root = tmp_path / "dota8like"
    (root / "images" / "train").mkdir(parents=True)
    (root / "labels" / "train").mkdir(parents=True)
    img = np.full((100, 200, 3), 60, np.uint8)
    cv2.imwrite(str(root / "images/train/x.jpg"), img)
    b = car(100, 50, 40, 10, 0) / (200, 100)
    (root / "labels/train/x.txt").write_text("1 " + " ".join(f"{v:.6f}" for v in b.reshape(-1)) + "\n")
    (root / "data.yaml").write_text("train: images/train\nnames:\n  0: large vehicle\n  1: small vehicle\n")
    s, dist, _ = dataset_stats(root)
    assert s["layout"] == "yolo-obb" and s["classes"] == {"small-vehicle": 1}
    np.testing.assert_allclose(dist["length_px"], [40], atol=1e-3)
    assert s["gsd_m"] is None and len(dist["length_m"]) == 0
    s2, dist2, _ = dataset_stats(root, gsd=0.5)
    np.testing.assert_allclose(dist2["length_m"], [20], atol=1e-3)
    only = tmp_path / "only"
    only.mkdir()
    cv2.imwrite(str(only / "p.png"), img)
    s3, dist3, _ = dataset_stats(only)
    assert s3["layout"] == "images" and s3["objects"] == 0
    np.testing.assert_allclose(dist3["image_gray_mean"], [60.0])


def test_report_synthetic_export_vs_dota_folder(tiny_export, real_like, tmp_path, capsys):
    d, _ = real_like
    out = tmp_path / "report"
    rc = main(["stats", str(tiny_export), "--compare", str(d), "--out", str(out)])
    text = capsys.readouterr().out
    assert rc == 0, text
    assert "domain gap, largest first" in text
    rep = json.loads((out / "stats.json").read_text())
    a, b = rep["datasets"]["A"], rep["datasets"]["B"]
    assert a["layout"] == "dota" and a["objects"] > 0 and b["objects"] == 5
    assert a["gsd_m"]["median"] == pytest.approx(0.12, rel=0.05)  # the export's gsd: headers
    ks = [g["ks"] for g in rep["gaps"]]
    assert ks == sorted(ks, reverse=True) and all(0 <= k <= 1 for k in ks)
    names = {g["name"] for g in rep["gaps"]}
    assert {"vehicles_per_image", "length_m", "vehicle_contrast", "image_gray_mean", "image_gray_sd"} <= names
    assert rep["realism"]["vehicle_contrast_median"]["B"] == pytest.approx(b["vehicle_contrast_median"])
    assert rep["realism"]["image_gray_sd"]["ks"] is not None
    for p in rep["plots"]:
        img = cv2.imread(str(out / p))
        assert img is not None and img.shape[0] >= 380 and (img < 250).mean() > 0.01
    assert "overview.png" in rep["plots"] and "colour_histograms.png" in rep["plots"]
    # bad input: one line, exit 2, nothing written
    for argv, msg in (
        (["stats", str(tmp_path / "nope"), "--out", str(tmp_path / "r2")], "no such folder"),
        (["stats", str(d), "--out", str(d / "r")], "inside the input folder DIR"),
        (["stats", str(d), "--compare", str(d / "labelTxt" / "a.txt"), "--out", str(tmp_path / "r2")],
         "expected a folder, found a file"),
        (["stats", str(d), "--max-images", "0", "--out", str(tmp_path / "r2")], "--max-images"),
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and msg in err, err
        assert not (tmp_path / "r2").exists()


def test_vedai_folder_with_and_without_annotations(tmp_path):
    root = tmp_path / "vedai"
    (root / "images").mkdir(parents=True)
    (root / "annotations512").mkdir()
    co = np.full((64, 64, 3), 120, np.uint8)
    cv2.imwrite(str(root / "images/00000001_co.png"), co)
    cv2.imwrite(str(root / "images/00000001_ir.png"), np.zeros((64, 64), np.uint8))
    # xc yc angle class contained occluded x1..x4 y1..y4: a car (1) and a truck (2, occluded)
    (root / "annotations512/00000001.txt").write_text(
        "20 20 0.0 1 1 0 14 26 26 14 17 17 23 23\n"
        "40 40 0.0 2 1 1 30 50 50 30 36 36 44 44\n")
    s, dist, _ = dataset_stats(root, gsd=0.25)
    assert s["layout"] == "vedai" and s["classes"] == {"large-vehicle": 1, "small-vehicle": 1}
    assert s["difficult_fraction"] == 0.5
    np.testing.assert_allclose(np.sort(dist["length_m"]), [12 * 0.25, 20 * 0.25])
    # the same images without annotations: pixel statistics of the colour images only
    import shutil

    shutil.rmtree(root / "annotations512")
    s2, dist2, _ = dataset_stats(root)
    assert s2["layout"] == "images" and s2["images"] == 1
    np.testing.assert_allclose(dist2["image_gray_mean"], [120.0])


def test_inside_means_pixel_centres_inside_the_box():
    from aerial_synth.evaluate.stats import vehicle_pixels

    gray = np.full((40, 40), 50, np.uint8)
    gray[10:16, 10:20] = 230  # pixels (j, i) covering [10, 20] x [10, 16]
    box = np.array([[10, 10], [20, 10], [20, 16], [10, 16]], float)
    m_in, m_ring, inside, ring = vehicle_pixels(gray, [box])
    assert inside.sum() == 60 and m_in[0] == 230.0  # exactly the 10 x 6 pixels
    assert m_ring[0] == 50.0 and not (ring & inside).any()
    # the ring reaches 4 px out: pixel columns 6..9 and 20..23 on the box's rows
    assert ring[12, 6] and ring[12, 23] and not ring[12, 5] and not ring[12, 24]


def test_collection_of_datasets_and_abs_contrast(tmp_path):
    """A folder holding a VEDAI folder and a DOTA folder is read as one collection; the
    |contrast| median and the brighter share are exact on drawn boxes."""
    root = tmp_path / "real"
    vedai = root / "vedai"
    (vedai / "images").mkdir(parents=True)
    (vedai / "annotations512").mkdir()
    co = np.full((64, 64, 3), 100, np.uint8)
    co[17:23, 14:26] = 40  # a dark car on a 100 background
    cv2.imwrite(str(vedai / "images/00000001_co.png"), co)
    (vedai / "annotations512/00000001.txt").write_text("20 20 0.0 1 1 0 14 26 26 14 17 17 23 23\n")
    # two bright cars (drawn 230 by the helper) on a 90 background
    write_dota_image(root / "dota_crops", "p1", [[[20, 20], [40, 20], [40, 30], [20, 30]],
                                           [[80, 60], [100, 60], [100, 70], [80, 70]]])
    (root / "notes").mkdir()  # an unlabelled, image-less folder is ignored
    s, dist, _ = dataset_stats(root)
    assert s["layout"] == "collection" and s["images"] == 2 and s["objects"] == 3
    c = dist["vehicle_contrast"]
    assert len(c) == 3 and (c > 0).sum() == 2
    assert s["vehicle_brighter_fraction"] == pytest.approx(2 / 3)
    assert s["vehicle_abs_contrast_median"] == pytest.approx(float(np.median(np.abs(c))))
    # the dark VEDAI car: (40 - 100) / sd of its image, exactly
    g = cv2.cvtColor(co, cv2.COLOR_BGR2GRAY).astype(float)
    assert c.min() == pytest.approx((40 - 100) / g.std())
