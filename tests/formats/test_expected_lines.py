"""Exact expected label lines for every format, written out by hand (not produced by the
code under test): non-square images (1024 x 768 landscape, 480 x 640 portrait), an empty
image, a vehicle cut by the right border, one reaching above the top border, a heading that
rounds to 360, a difficult and an orientation-unclear flag, and a dropped vehicle that
appears in no label file.

Geometry of the hand-made boxes (image px, y down; corners front-left, front-right,
rear-right, rear-left = clockwise on screen):
- v1 small car heading ~0 deg (right): x 100.3..140.3, y 200.7..218.7.
- v2 truck, heading 36.87 deg (a 3-4-5 direction (0.8, -0.6)), centre (1010.5, 500),
  length 50, width 20: FL (1024.5, 477), FR (1036.5, 493), RR (996.5, 523), RL (984.5, 507);
  FR lies past the right border (x / 1024 = 1.012207).
- v3 small car heading 270 deg (down) near the top: x 295..305, y -5.5..14.5.
- v4 dropped.
- portrait v5 heading 90 (up): x 232.5..248.5, y 300..340.
"""

import json

import numpy as np
import pytest

from aerial_synth.annotate.boxes import OrientedBox, VehicleAnnotation
from aerial_synth.formats import CATEGORIES, coco, dota, eagle, meta, yolo_obb
from aerial_synth.formats.registry import DatasetInfo, get

GSD = 0.12


def ann(vid, cls, status, corners, heading, unclear=False, reasons=()):
    box = None if corners is None else OrientedBox.from_corners(corners)
    return VehicleAnnotation(vehicle_id=vid, cls=cls, status=status, reasons=tuple(reasons), box=box,
                             heading_img_deg=heading, orientation_unclear=unclear, visible_px=100,
                             amodal_px=120, visible_fraction=0.8333, truncated=status == "difficult")


V1 = ann(1, "small-vehicle", "kept", [(140.3, 200.7), (140.3, 218.7), (100.3, 218.7), (100.3, 200.7)], 359.996)
V2 = ann(2, "large-vehicle", "difficult",
         [(1024.5, 477), (1036.5, 493), (996.5, 523), (984.5, 507)], 36.869897645844, reasons=("truncated",))
V3 = ann(3, "small-vehicle", "kept", [(305, 14.5), (295, 14.5), (295, -5.5), (305, -5.5)], 270.0, unclear=True)
V4 = ann(4, "small-vehicle", "dropped", None, 10.0, reasons=("too_few_pixels",))
V5 = ann(5, "small-vehicle", "kept", [(232.5, 300), (248.5, 300), (248.5, 340), (232.5, 340)], 90.0)

# visible masks as (rows, cols) ranges -> COCO bbox and area
MASKS = {1: (slice(201, 219), slice(100, 140)), 2: (slice(480, 520), slice(990, 1024)),
         3: (slice(0, 15), slice(296, 305)), 5: (slice(301, 340), slice(233, 248))}


def record(index, anns, w, h, split="train"):
    segs = {}
    for a in anns:
        if a.kept:
            rows, cols = MASKS[a.vehicle_id]
            crop = np.ones((rows.stop - rows.start, cols.stop - cols.start), bool)
            segs[a.vehicle_id] = coco.rle_from_crop(crop, (cols.start, rows.start), h, w)
    name = f"{index:06d}"
    return meta.ImageRecord(index=index, name=name, file_name=f"{name}.png", split=split, width_px=w,
                            height_px=h, gsd_m=GSD, annotations=tuple(anns), segmentations=segs)


LANDSCAPE = record(0, [V1, V2, V3, V4], 1024, 768)
EMPTY = record(1, [V4], 1024, 768)
PORTRAIT = record(2, [V5], 480, 640, split="val")

EXPECTED = {
    "dota": {
        0: ["imagesource:aerial-synth", "gsd:0.12",
            "140.30 200.70 140.30 218.70 100.30 218.70 100.30 200.70 small-vehicle 0",
            "1024.50 477.00 1036.50 493.00 996.50 523.00 984.50 507.00 large-vehicle 1",
            "305.00 14.50 295.00 14.50 295.00 -5.50 305.00 -5.50 small-vehicle 0"],
        1: ["imagesource:aerial-synth", "gsd:0.12"],
        2: ["imagesource:aerial-synth", "gsd:0.12",
            "232.50 300.00 248.50 300.00 248.50 340.00 232.50 340.00 small-vehicle 0"],
    },
    "eagle": {
        0: [eagle.HEADER,
            "140.30 200.70 140.30 218.70 100.30 218.70 100.30 200.70 0.00 small-vehicle 0 0",
            "1024.50 477.00 1036.50 493.00 996.50 523.00 984.50 507.00 36.87 large-vehicle 1 0",
            "305.00 14.50 295.00 14.50 295.00 -5.50 305.00 -5.50 270.00 small-vehicle 0 1"],
        1: [eagle.HEADER],
        2: [eagle.HEADER,
            "232.50 300.00 248.50 300.00 248.50 340.00 232.50 340.00 90.00 small-vehicle 0 0"],
    },
    "yolo-obb": {
        # x / 1024, y / 768 (landscape), x / 480, y / 640 (portrait); not clipped
        0: ["0 0.137012 0.261328 0.137012 0.284766 0.097949 0.284766 0.097949 0.261328",
            "1 1.000488 0.621094 1.012207 0.641927 0.973145 0.680990 0.961426 0.660156",
            "0 0.297852 0.018880 0.288086 0.018880 0.288086 -0.007161 0.297852 -0.007161"],
        1: [],
        2: ["0 0.484375 0.468750 0.517708 0.468750 0.517708 0.531250 0.484375 0.531250"],
    },
}
RECORDS = {0: LANDSCAPE, 1: EMPTY, 2: PORTRAIT}
PATHS = {
    "dota": ("dota/train/labelTxt/000000.txt", "dota/val/images/000002.png"),
    "eagle": ("eagle/train/labels/000000.txt", "eagle/val/images/000002.png"),
    "yolo-obb": ("yolo-obb/labels/train/000000.txt", "yolo-obb/images/val/000002.png"),
}


@pytest.mark.parametrize("fmt", ["dota", "eagle", "yolo-obb"])
@pytest.mark.parametrize("index", [0, 1, 2])
def test_label_text_is_exactly_the_expected_lines(fmt, index):
    text = get(fmt).label_text(RECORDS[index])
    want = EXPECTED[fmt][index]
    assert text == "".join(ln + "\n" for ln in want)
    assert text.splitlines() == want


@pytest.mark.parametrize("fmt", ["dota", "eagle", "yolo-obb"])
def test_registry_paths(fmt):
    label, image = PATHS[fmt]
    f = get(fmt)
    assert f.label_path("train", "000000") == label
    assert f.image_path("val", "000002.png") == image


def test_coco_paths_and_no_per_image_file():
    f = get("coco")
    assert f.image_path("val", "000002.png") == "coco/images/val/000002.png"
    assert f.label_path("train", "000000") is None and f.label_text(LANDSCAPE) is None


def test_readers_give_back_the_table(tmp_path):
    """Each reader returns as many objects as the table has lines, with the table's values."""
    for index, rec in RECORDS.items():
        lab = dota.from_lines(EXPECTED["dota"][index])
        kept = [a for a in rec.annotations if a.kept]
        assert len(lab.objects) == len(kept)
        for a, o in zip(kept, lab.objects, strict=True):
            np.testing.assert_allclose(o.polygon_xy_px, a.box.corners, atol=0.005)
            assert (o.category, o.difficult) == (a.cls, int(a.difficult))
        eg = eagle.from_lines(EXPECTED["eagle"][index])
        assert len(eg) == len(kept)
        yl = yolo_obb.from_lines(EXPECTED["yolo-obb"][index])
        assert len(yl) == len(kept)
        for a, o in zip(kept, yl, strict=True):
            px = yolo_obb.denormalize_xy(o.polygon_xy_norm, rec.width_px, rec.height_px)
            np.testing.assert_allclose(px, a.box.corners, atol=0.5e-6 * max(rec.width_px, rec.height_px) + 1e-9)


def test_coco_fragments():
    info = DatasetInfo(scene="s", scenario="jam", seed=7, tool_version="9.9", splits={"train": 2, "val": 1},
                       categories=CATEGORIES)
    files = get("coco").aggregate_files([LANDSCAPE, EMPTY, PORTRAIT], info)
    assert sorted(files) == ["coco/annotations/instances_train.json", "coco/annotations/instances_val.json"]
    files = {k: "".join(v) for k, v in files.items()}  # streamed: text chunks
    tr = json.loads(files["coco/annotations/instances_train.json"])
    assert tr["info"] == {"description": "aerial-synth s jam (train)", "version": "9.9", "seed": 7}
    assert tr["categories"] == [{"id": 1, "name": "small-vehicle", "supercategory": "vehicle"},
                                {"id": 2, "name": "large-vehicle", "supercategory": "vehicle"}]
    assert tr["images"] == [{"id": 1, "file_name": "000000.png", "width": 1024, "height": 768},
                            {"id": 2, "file_name": "000001.png", "width": 1024, "height": 768}]
    frag = [{k: a[k] for k in ("id", "image_id", "category_id", "bbox", "area", "iscrowd", "obb_xyxyxyxy",
                                 "heading_img_deg", "difficult", "orientation_unclear", "vehicle_id",
                                 "truncated")} for a in tr["annotations"]]
    assert frag == [
        {"id": 1, "image_id": 1, "category_id": 1, "bbox": [100.0, 201.0, 40.0, 18.0], "area": 720,
         "iscrowd": 0, "obb_xyxyxyxy": [140.3, 200.7, 140.3, 218.7, 100.3, 218.7, 100.3, 200.7],
         "heading_img_deg": 359.996, "difficult": 0, "orientation_unclear": 0, "vehicle_id": 1,
         "truncated": 0},
        {"id": 2, "image_id": 1, "category_id": 2, "bbox": [990.0, 480.0, 34.0, 40.0], "area": 1360,
         "iscrowd": 0, "obb_xyxyxyxy": [1024.5, 477.0, 1036.5, 493.0, 996.5, 523.0, 984.5, 507.0],
         "heading_img_deg": 36.87, "difficult": 1, "orientation_unclear": 0, "vehicle_id": 2,
         "truncated": 1},
        {"id": 3, "image_id": 1, "category_id": 1, "bbox": [296.0, 0.0, 9.0, 15.0], "area": 135,
         "iscrowd": 0, "obb_xyxyxyxy": [305.0, 14.5, 295.0, 14.5, 295.0, -5.5, 305.0, -5.5],
         "heading_img_deg": 270.0, "difficult": 0, "orientation_unclear": 1, "vehicle_id": 3,
         "truncated": 0},
    ]
    assert all(a["segmentation"]["size"] == [768, 1024] for a in tr["annotations"])
    va = json.loads(files["coco/annotations/instances_val.json"])
    assert va["images"] == [{"id": 3, "file_name": "000002.png", "width": 480, "height": 640}]
    assert len(va["annotations"]) == 1
    a = va["annotations"][0]
    assert (a["id"], a["image_id"], a["bbox"], a["area"]) == (1, 3, [233.0, 301.0, 15.0, 39.0], 585)
    assert a["segmentation"]["size"] == [640, 480]
    # the empty image is listed and has no annotation
    assert not [x for x in tr["annotations"] if x["image_id"] == 2]


def test_yolo_data_yaml_exact():
    info = DatasetInfo(scene="s", scenario="jam", seed=0, tool_version="1", splits={"train": 3, "val": 0},
                       categories=CATEGORIES)
    assert get("yolo-obb").aggregate_files([], info) == {"yolo-obb/data.yaml": (
        "# aerial-synth YOLO-OBB dataset (Ultralytics). Dataset root = this file's folder.\n"
        "train: images/train\nval: images/train\nnc: 2\nnames:\n  0: small-vehicle\n  1: large-vehicle\n")}


def test_formats_without_aggregates():
    info = DatasetInfo(scene="s", scenario="jam", seed=0, tool_version="1", splits={"train": 1, "val": 0},
                       categories=CATEGORIES)
    assert get("dota").aggregate_files([LANDSCAPE], info) == {}
    assert get("eagle").aggregate_files([LANDSCAPE], info) == {}
