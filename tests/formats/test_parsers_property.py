"""Property-based tests (hypothesis) for the label readers: any input either parses or
raises LabelFormatError (an AerialSynthError) with one line; never another exception.
Written labels always read back to the same objects."""

import math

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import example, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from aerial_synth.errors import AerialSynthError  # noqa: E402
from aerial_synth.formats import coco, dota, eagle, meta, yolo_obb  # noqa: E402

TOKENS = st.one_of(
    st.sampled_from(["0", "1", "2", "-1", "0.5", "1.5", "nan", "inf", "-inf", "1e400", "", " ", "x",
                     "small-vehicle", "large-vehicle", "plane", "359.999", "360", "imagesource:a",
                     "gsd:0.1", "gsd:abc", "gsd:null", "#", "\t", "1,5"]),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.text(max_size=6),
)
LINE = st.lists(TOKENS, max_size=13).map(" ".join)
LINES = st.lists(LINE, max_size=5)


def _one_line_error(fn, *args):
    try:
        return fn(*args)
    except AerialSynthError as exc:
        assert "\n" not in str(exc), str(exc)
        return None


@settings(max_examples=300, deadline=None)
@given(LINES)
def test_dota_reader_total(lines):
    _one_line_error(dota.from_lines, ["imagesource:x", "gsd:0.1", *lines])
    _one_line_error(dota.from_lines, lines)


@settings(max_examples=300, deadline=None)
@given(LINES)
def test_eagle_reader_total(lines):
    _one_line_error(eagle.from_lines, lines)


@settings(max_examples=300, deadline=None)
@given(LINES)
def test_yolo_reader_total(lines):
    out = _one_line_error(yolo_obb.from_lines, lines)
    if out is not None:
        assert all(math.isfinite(v) for o in out for p in o.polygon_xy_norm for v in p)


JSONISH = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-3, 3), st.floats(allow_nan=True), st.text(max_size=4)),
    lambda inner: st.one_of(st.lists(inner, max_size=3),
                            st.dictionaries(st.sampled_from(["id", "name", "images", "annotations",
                                                             "categories", "file_name", "width", "height",
                                                             "image_id", "category_id", "bbox", "area",
                                                             "segmentation", "format", "image", "vehicles",
                                                             "index", "split", "gsd_m", "width_px",
                                                             "height_px"]), inner, max_size=6)),
    max_leaves=12,
)


@settings(max_examples=300, deadline=None)
@given(JSONISH)
@example({"id": None, "index": float("inf")})  # int(inf) raised OverflowError (found by hypothesis)
def test_coco_and_meta_readers_total(d):
    _one_line_error(coco.from_dict, d)
    _one_line_error(meta.from_dict, d)
    _one_line_error(coco.from_dict, {"categories": [{"id": 1, "name": "c"}], "images": [], "annotations": d})
    _one_line_error(meta.from_dict, {"format": meta.FORMAT, "image": d, "vehicles": [], "gsd_m": 0.1})


COORD = st.floats(-1e4, 1e4, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.lists(COORD, min_size=8, max_size=8), st.integers(0, 1), st.integers(0, 1)),
                max_size=6))
def test_dota_write_read_round_trip(objs):
    objects = [dota.DotaObject(dota.polygon4(xy), ("small-vehicle", "large-vehicle")[c], d)
               for xy, c, d in objs]
    back = dota.from_lines(dota.text(objects, 0.12).splitlines())
    assert len(back.objects) == len(objects)
    for a, b in zip(objects, back.objects, strict=True):
        assert (a.category, a.difficult) == (b.category, b.difficult)
        assert all(abs(p - q) <= 0.005 + 1e-9 * abs(p) for pa, pb in zip(a.polygon_xy_px, b.polygon_xy_px)
                   for p, q in zip(pa, pb))


@pytest.mark.parametrize("reader", [dota.read, eagle.read, yolo_obb.read, coco.read, meta.read])
@pytest.mark.parametrize("content", [b"\xff\xfe\x00binary", b"{not json", b"[1, 2"])
def test_file_readers_one_line_on_bad_bytes(tmp_path, reader, content):
    p = tmp_path / "label.txt"
    p.write_bytes(content)
    try:
        reader(p)
    except AerialSynthError as exc:
        assert "\n" not in str(exc) and str(p) in str(exc)
