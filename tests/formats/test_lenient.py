"""The lenient readers of real-world files and the one label model they return."""

import numpy as np
import pytest

from aerial_synth.errors import EvaluationError, ExportError, LabelFormatError
from aerial_synth.formats import ImageLabels, dota, vedai, yolo_obb

BOX = "10 20 30 20 30 30 10 30"


@pytest.mark.parametrize("header", [[], ["imagesource:GoogleEarth", "gsd:0.146343590398"],
                                    ["gsd:null"], ["imagesource:x"]])
@pytest.mark.parametrize("fast", [True, False])
def test_dota_lenient_headers_difficult_two_unknown_classes(header, fast):
    body = [f"{BOX} plane 0", "", f"{BOX} small-vehicle 2", f"{BOX} ship 1"]
    if not fast:
        body.append(f"{BOX} harbor")  # 9 fields: the line-by-line reader
    lab = dota.labels_from_lines(header + body, "x.txt", "img")
    assert lab.name == "img" and len(lab) == len(body) - 1
    assert lab.classes[:3] == ["plane", "small-vehicle", "ship"]
    assert lab.difficult.tolist()[:3] == [False, True, True]
    assert lab.polygons_xy_px.shape == (len(body) - 1, 4, 2) and lab.polygons_xy_px.dtype == np.float64
    np.testing.assert_array_equal(lab.polygons_xy_px[0], [[10, 20], [30, 20], [30, 30], [10, 30]])
    assert lab.gsd_m == (pytest.approx(0.146343590398) if "gsd:0.146343590398" in header else None)
    assert lab.image_source == ("GoogleEarth" if "imagesource:GoogleEarth" in header
                                else "x" if "imagesource:x" in header else None)


def test_dota_lenient_empty_file_and_what_we_write(tmp_path):
    p = tmp_path / "e.txt"
    p.write_text("")
    lab = dota.read_labels(p)
    assert len(lab) == 0 and lab.polygons_xy_px.shape == (0, 4, 2) and lab.label_path == p
    # what the strict writer writes, the lenient reader reads back (one writer, two readers)
    objs = [dota.DotaObject(((1.5, 2.0), (3.0, 2.0), (3.0, 4.0), (1.5, 4.0)), "large-vehicle", 1)]
    p.write_text(dota.text(objs, 0.12))
    back = dota.read_labels(p)
    assert dota.from_labels(back) == objs and back.gsd_m == 0.12
    assert dota.text(dota.from_labels(back), back.gsd_m) == p.read_text()


@pytest.mark.parametrize("line, msg", [
    (f"{BOX}", "x.txt:1: expected 'x1 y1 x2 y2 x3 y3 x4 y4 category"),
    (f"{BOX} car yes", "x.txt:1: expected difficult as an integer"),
    ("10 20 30 nan 30 30 10 30 car 0", "x.txt:1: expected coordinate 4 as a finite number"),
    ("gsd:-1", "x.txt:1: expected gsd in 0.0001..1000 metres per pixel, got '-1'"),
    ("gsd:1e300", "x.txt:1: expected gsd in 0.0001..1000 metres per pixel"),
])
def test_dota_lenient_errors_name_the_line(line, msg):
    with pytest.raises(LabelFormatError, match=msg) as e:
        dota.labels_from_lines([line], "x.txt")
    # one error type for a bad label file, caught by the exporter's and evaluation's handlers
    assert isinstance(e.value, ExportError) and isinstance(e.value, EvaluationError)


def test_dota_lenient_reader_refuses_bytes(tmp_path):
    p = tmp_path / "b.txt"
    p.write_bytes(b"\xff\xfe\x00bad")
    with pytest.raises(LabelFormatError, match="expected UTF-8"):
        dota.read_labels(p)


def test_yolo_lenient_labels_and_predictions():
    lines = ["1 0.1 0.2 0.3 0.2 0.3 0.4 0.1 0.4 0.9", "", "0 0 0 1 0 1 1 0 1 0.5"]
    pred = yolo_obb.labels_from_lines(lines, "p.txt", ["a", "b"], (200, 100), with_conf=True)
    assert pred.classes == ["b", "a"] and pred.scores.tolist() == [0.9, 0.5]
    np.testing.assert_allclose(pred.polygons_xy_px[0], [[20, 20], [60, 20], [60, 40], [20, 40]])
    assert pred.size_wh == (200, 100) and not pred.difficult.any()
    gt = yolo_obb.labels_from_lines([ln.rsplit(" ", 1)[0] for ln in lines if ln], "g.txt", ["a", "b"], (200, 100))
    assert gt.scores is None and np.array_equal(gt.polygons_xy_px, pred.polygons_xy_px)
    with pytest.raises(LabelFormatError, match="g.txt:1: expected a class index in 0..1"):
        yolo_obb.labels_from_lines(["2 0 0 1 0 1 1 0 1"], "g.txt", ["a", "b"], (10, 10))


def test_vedai_reader():
    line = "50 60 0.3 1 1 0 40 60 60 40 55 55 65 65"
    lab = vedai.labels_from_lines([line, "50 60 0.3 31 0 0 40 60 60 40 55 55 65 65"], "v.txt")
    assert lab.classes == ["small-vehicle", "plane"] and lab.difficult.tolist() == [False, True]
    np.testing.assert_array_equal(lab.polygons_xy_px[0], [[40, 55], [60, 55], [60, 65], [40, 65]])
    with pytest.raises(LabelFormatError, match="v.txt:1: expected VEDAI"):
        vedai.labels_from_lines(["1 2 3"], "v.txt")


@pytest.mark.parametrize("kwargs, msg", [
    (dict(polygons_xy_px=np.zeros((2, 8))), r"polygons_xy_px must be \(n, 4, 2\)"),
    (dict(classes=["a"]), "2 polygons but 1 classes"),
    (dict(difficult=np.zeros(3, bool)), r"difficult must be \(2,\)"),
    (dict(scores=np.zeros((2, 1))), r"scores must be \(2,\)"),
])
def test_image_labels_checks_shapes_when_made(kwargs, msg):
    good = dict(polygons_xy_px=np.zeros((2, 4, 2)), classes=["a", "b"], difficult=np.zeros(2, bool))
    ImageLabels("ok", **good)
    with pytest.raises(ValueError, match=msg):
        ImageLabels("bad", **{**good, **kwargs})


def test_image_labels_normalises_empty_and_lists():
    lab = ImageLabels("e", [], [], [])
    assert lab.polygons_xy_px.shape == (0, 4, 2) and lab.difficult.dtype == bool and len(lab) == 0
    lab = ImageLabels("l", [[[0, 0], [1, 0], [1, 1], [0, 1]]], ("a",), [1])
    assert lab.polygons_xy_px.dtype == np.float64 and lab.classes == ["a"] and lab.difficult.tolist() == [True]
