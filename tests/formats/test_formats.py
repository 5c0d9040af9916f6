import json

import numpy as np
import pytest

from aerial_synth.annotate import BoxConfig, annotate_instances
from aerial_synth.formats import LabelFormatError, coco, dota, eagle, meta, yolo_obb
from aerial_synth.placement.model import PlacedVehicle

from ..annotate.synthetic import NadirCamera, render_instance, vehicle

W = H = 320


@pytest.fixture(scope="module")
def scene():
    """A 320 x 320 frame with 12 vehicles at random poses, one cut by the border."""
    cam = NadirCamera(width_px=W, height_px=H)
    rng = np.random.default_rng(7)
    vs = []
    for i in range(1, 12):
        big = i % 4 == 0
        vs.append(vehicle(i, *rng.uniform(-14, 14, 2), heading_deg=rng.uniform(0, 360),
                          length=9.0 if big else 4.5, width=2.5 if big else 1.8,
                          height=3.0 if big else 1.5, cls="large-vehicle" if big else "small-vehicle"))
    vs.append(vehicle(12, x=19.0, y=0.0, heading_deg=10))  # cut by the right border
    inst = render_instance(cam, vs)
    crops = {}
    anns = annotate_instances(inst, {v.id: v for v in vs}, cam.project,
                              mask_sink=lambda vid, c, off: crops.__setitem__(vid, (c.copy(), off)))
    kept = [a for a in anns if a.kept]
    assert len(kept) >= 8
    return cam, inst, anns, kept, crops, vs


def _assert_same_polys(a, b, tol=0.5):
    a, b = np.asarray(a, float), np.asarray(b, float)
    assert a.shape == b.shape
    assert np.max(np.abs(a - b)) <= tol


def test_dota_round_trip_and_strict(scene, tmp_path):
    cam, inst, anns, kept, _, _ = scene
    objs = dota.from_annotations(anns)
    assert len(objs) == len(kept)
    p = dota.write(tmp_path / "x.txt", objs, gsd_m=cam.gsd_m)
    text = p.read_text()
    lines = text.splitlines()
    assert lines[0] == "imagesource:aerial-synth" and lines[1] == "gsd:0.12"
    assert all(len(ln.split(" ")) == 10 for ln in lines[2:])
    back = dota.read(p)
    assert back.gsd_m == pytest.approx(0.12) and back.image_source == "aerial-synth"
    assert len(back.objects) == len(kept) == len(lines) - 2
    for a, o in zip(kept, back.objects, strict=True):
        _assert_same_polys(a.box.corners, o.polygon_xy_px)
        assert o.category == a.cls and o.difficult == int(a.difficult)
    assert any(o.difficult for o in back.objects)  # the truncated one


@pytest.mark.parametrize(
    "lines, msg",
    [
        (["imagesource:x"], "2 header lines"),
        (["gsd:0.1", "imagesource:x"], "imagesource"),
        (["imagesource:x", "gsd:abc"], "number"),
        (["imagesource:x", "gsd:0.1", "1 2 3 4 5 6 7 8 small-vehicle"], "10 fields"),
        (["imagesource:x", "gsd:0.1", "1 2 3 4 5 6 7 8 small-vehicle 0 extra"], "10 fields"),
        (["imagesource:x", "gsd:0.1", "1 2 3 4 5 6 7 x small-vehicle 0"], "number"),
        (["imagesource:x", "gsd:0.1", "1 2 3 4 5 6 7 8 plane 0"], "category"),
        (["imagesource:x", "gsd:0.1", "1 2 3 4 5 6 7 8 small-vehicle 2"], "difficult"),
        (["imagesource:x", "gsd:0.1", "1  2 3 4 5 6 7 8 small-vehicle 0"], "10 fields"),
    ],
)
def test_dota_strict_parser_rejects(lines, msg):
    with pytest.raises(LabelFormatError, match=msg):
        dota.from_lines(lines)


def test_dota_empty_image():
    lines = dota.to_lines([], gsd_m=0.12)
    assert lines == ["imagesource:aerial-synth", "gsd:0.12"]
    assert dota.from_lines(lines).objects == ()


def test_eagle_round_trip(scene, tmp_path):
    _, _, anns, kept, _, _ = scene
    objs = eagle.from_annotations(anns)
    p = eagle.write(tmp_path / "e.txt", objs)
    lines = p.read_text().splitlines()
    assert lines[0] == eagle.HEADER
    assert all(len(ln.split(" ")) == 12 for ln in lines[1:])
    back = eagle.read(p)
    assert len(back) == len(kept) == len(lines) - 1
    for a, o in zip(kept, back, strict=True):
        _assert_same_polys(a.box.corners, o.polygon_xy_px)
        assert abs((o.orientation_deg - a.heading_img_deg + 180) % 360 - 180) < 0.01
        assert o.category == a.cls
        assert o.visibility_difficult == int(a.difficult)
        assert o.orientation_unclear == int(a.orientation_unclear)


@pytest.mark.parametrize("line", ["1 2 3 4 5 6 7 8 9 small-vehicle 0", "1 2 3 4 5 6 7 8 361 small-vehicle 0 0",
                                  "1 2 3 4 5 6 7 8 9 small-vehicle 0 2"])
def test_eagle_rejects(line):
    with pytest.raises(LabelFormatError):
        eagle.from_lines([line])


def _assert_rectangle(px, tol_px):
    """(4, 2) corners: opposite sides equal and every angle right, within tol_px."""
    e = np.roll(px, -1, axis=0) - px  # the four edges
    lens = np.linalg.norm(e, axis=1)
    assert abs(lens[0] - lens[2]) <= tol_px and abs(lens[1] - lens[3]) <= tol_px
    for k in range(4):  # |cos| of each corner angle, as a length: |e_k . e_k+1| / |e_k+1|
        assert abs(float(e[k] @ e[(k + 1) % 4])) / lens[(k + 1) % 4] <= tol_px
    assert np.linalg.norm(px[0] - px[2]) == pytest.approx(np.linalg.norm(px[1] - px[3]), abs=tol_px)


def test_yolo_obb_round_trip_true_rectangles(scene, tmp_path):
    """Every written box is the annotation's rectangle, unclipped: corners may lie past
    [0, 1] for a border-cut vehicle, and the box is still a rectangle in pixels."""
    _, _, anns, kept, _, _ = scene
    objs = yolo_obb.from_annotations(anns, W, H)
    p = yolo_obb.write(tmp_path / "y.txt", objs)
    lines = p.read_text().splitlines()
    back = yolo_obb.read(p)
    assert len(back) == len(kept) == len(lines)
    tol = 2 * 0.5e-6 * max(W, H) * 2  # two 6-decimal roundings per coordinate
    outside = 0
    for a, o, ln in zip(kept, back, lines, strict=True):
        assert len(ln.split(" ")) == 9
        assert o.class_index == ("small-vehicle", "large-vehicle").index(a.cls)
        px = yolo_obb.denormalize_xy(o.polygon_xy_norm, W, H)
        _assert_same_polys(a.box.corners, px, tol=1e-3)
        _assert_rectangle(px, tol + 1e-3 * max(1.0, np.abs(a.box.corners).max() / 1000))
        outside += int(np.any((np.asarray(o.polygon_xy_norm) < 0) | (np.asarray(o.polygon_xy_norm) > 1)))
    assert outside >= 1, "the border-cut vehicle should reach past the image edge"


def test_yolo_obb_border_rectangle_not_clipped():
    """A rectangle hanging over the right border keeps its shape (clipping each corner would
    make an irregular quadrilateral)."""
    corners = np.array([(300.0, 100.0), (340.0, 130.0), (328.0, 146.0), (288.0, 116.0)])  # 50 x 20
    norm = yolo_obb.normalize_xy(corners, 320, 240)
    assert norm[:, 0].max() == pytest.approx(340 / 320)
    line = yolo_obb.to_lines([yolo_obb.YoloObbObject(0, yolo_obb.polygon4(norm))])[0]
    assert line == "0 0.937500 0.416667 1.062500 0.541667 1.025000 0.608333 0.900000 0.483333"
    back = yolo_obb.denormalize_xy(yolo_obb.from_lines([line])[0].polygon_xy_norm, 320, 240)
    _assert_rectangle(back, 1e-3)


def test_yolo_data_yaml():
    import yaml

    d = yaml.safe_load(yolo_obb.data_yaml_text())
    assert d["train"] == "images/train" and d["val"] == "images/val"
    assert d["names"] == {0: "small-vehicle", 1: "large-vehicle"} and d["nc"] == 2
    assert "path" not in d
    assert yaml.safe_load(yolo_obb.data_yaml_text(has_val=False))["val"] == "images/train"


@pytest.mark.parametrize("line", ["0 0.1 0.2 0.3", "2 0 0 0 0 0 0 0 0", "0 0 0 0 0 0 0 0 nan",
                                  "0 0 0 0 0 0 0 0 inf", "a 0 0 0 0 0 0 0 0", "-1 0 0 0 0 0 0 0 0",
                                  "0 0 0 0 0 0 0 0 0 0", "0 0 0 0 0 0 0 0 x"])
def test_yolo_rejects(line):
    with pytest.raises(LabelFormatError):
        yolo_obb.from_lines([line])


def test_coco_loads_with_pycocotools_and_masks_match(scene, tmp_path):
    from pycocotools.coco import COCO

    _, inst, anns, kept, crops, _ = scene
    objs = [coco.object_from_annotation(a, 1, coco.rle_from_crop(*crops[a.vehicle_id], H, W)) for a in kept]
    d = coco.to_dict([coco.CocoImage(1, "000000.png", W, H)], objs)
    p = coco.write(tmp_path / "instances_train.json", d)
    c = COCO(str(p))
    assert sorted(c.getCatIds()) == [1, 2]
    assert [c.cats[i]["name"] for i in (1, 2)] == ["small-vehicle", "large-vehicle"]
    ann_ids = c.getAnnIds(imgIds=[1])
    assert len(ann_ids) == len(kept)
    for aid, a in zip(ann_ids, kept, strict=True):
        ann = c.anns[aid]
        m = c.annToMask(ann).astype(bool)
        np.testing.assert_array_equal(m, inst == a.vehicle_id)
        ys, xs = np.nonzero(m)
        assert ann["bbox"] == [xs.min(), ys.min(), xs.max() - xs.min() + 1, ys.max() - ys.min() + 1]
        assert ann["area"] == m.sum() and ann["iscrowd"] == 0
    images, back = coco.read(p)
    assert images[0].file_name == "000000.png"
    assert len(back) == len(kept)
    for a, o in zip(kept, back, strict=True):
        _assert_same_polys(a.box.corners, np.reshape(o.obb_xyxyxyxy, (4, 2)))
        assert o.category == a.cls and o.vehicle_id == a.vehicle_id


def test_rle_from_crop_edge_cases():
    from pycocotools import mask as mu

    for crop, off in [(np.ones((3, 4), bool), (0, 0)), (np.ones((2, 2), bool), (8, 8)),
                      (np.zeros((2, 2), bool), (1, 1)), (np.eye(3, dtype=bool), (2, 5))]:
        full = np.zeros((10, 10), bool)
        full[off[1]:off[1] + crop.shape[0], off[0]:off[0] + crop.shape[1]] = crop
        rle = coco.rle_from_crop(crop, off, 10, 10)
        ref = mu.encode(np.asfortranarray(full.astype(np.uint8)))
        assert rle["counts"] == ref["counts"].decode()


def test_meta_round_trip(scene, tmp_path):
    cam, inst, anns, kept, crops, vs = scene
    world = {v.id: v.to_dict() for v in vs}
    segs = {a.vehicle_id: coco.rle_from_crop(*crops[a.vehicle_id], H, W) for a in kept}
    r = meta.ImageRecord(index=3, name="000003", file_name="000003.png", split="val", width_px=W,
                         height_px=H, gsd_m=cam.gsd_m, seed={"dataset_seed": 0, "image_index": 3},
                         camera={"K": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}, box_config=BoxConfig().to_dict(),
                         annotations=tuple(anns), world=world, segmentations=segs)
    p = meta.write(tmp_path / "m.json", r)
    d = json.loads(p.read_text())
    assert d["counts"] == r.counts() and d["vehicles"][0]["world"]["x_m"] is not None
    back = meta.read(p)
    assert back.counts() == r.counts() and back.split == "val"
    assert len(back.annotations) == len(anns)
    for a, b in zip(anns, back.annotations, strict=True):
        assert a.status == b.status and a.reasons == b.reasons
        if a.box is not None:
            _assert_same_polys(a.box.corners, b.box.corners, 0.01)
    assert PlacedVehicle.from_dict(back.world[1]).x_m == pytest.approx(vs[0].x_m, abs=1e-5)
    # serialising again gives the same bytes
    assert meta.write(tmp_path / "m2.json", back).read_bytes() == p.read_bytes()
    with pytest.raises(LabelFormatError):
        meta.from_dict({"format": "other"})
