"""The COCO annotation text a large export streams (``coco._annotation_json``, formatted
directly for speed) is json.dumps's, byte for byte."""

import json
import math
import random

import pytest

from aerial_synth.formats import coco
from aerial_synth.io_utils import iter_json

_FLOATS = [0.0, -0.0, 1.0, -1.5, 0.1, 1e-7, 1e16, 123456789.123, 5e-324, 1.7976931348623157e308, 359.996]


def _annotation(rng):
    f = lambda: rng.choice(_FLOATS) if rng.random() < 0.3 else rng.uniform(-1e4, 1e4)  # noqa: E731
    counts = "".join(chr(rng.randint(48, 111)) for _ in range(rng.randint(0, 40))) + rng.choice(['', '"', "\\\\"])
    return {"id": rng.randint(1, 10**9), "image_id": rng.randint(1, 10**6), "category_id": rng.randint(1, 2),
            "bbox": [f() for _ in range(4)], "area": rng.randint(0, 10**7), "iscrowd": 0,
            "segmentation": {"size": [rng.randint(1, 4096), rng.randint(1, 4096)], "counts": counts},
            "obb_xyxyxyxy": [f() for _ in range(8)], "heading_img_deg": f(), "difficult": rng.randint(0, 1),
            "orientation_unclear": rng.randint(0, 1), "vehicle_id": rng.randint(0, 2**31),
            "visible_fraction": rng.random(), "truncated": rng.randint(0, 1)}


def test_annotation_text_is_json_dumps():
    rng = random.Random(11)
    for _ in range(2000):
        d = _annotation(rng)
        assert coco._annotation_json(d).text == json.dumps(d, indent=2, sort_keys=True, allow_nan=False)


def test_other_shapes_go_through_json_and_nan_is_refused():
    rng = random.Random(3)
    d = _annotation(rng)
    for changed in ({**d, "extra": [1, {"a": None}]}, {**d, "bbox": []},
                    {**d, "segmentation": {**d["segmentation"], "size": [10.0, 20.0]}}):
        assert coco._annotation_json(changed).text == json.dumps(changed, indent=2, sort_keys=True)
    for bad in ({**d, "visible_fraction": math.nan}, {**d, "bbox": [0.0, math.inf, 1.0, 1.0]}):
        with pytest.raises(ValueError):
            coco._annotation_json(bad)
        with pytest.raises(ValueError):
            json.dumps(bad, allow_nan=False)


def test_streamed_document_with_preformatted_items():
    rng = random.Random(5)
    anns = [_annotation(rng) for _ in range(5)]
    doc = {"annotations": coco.StreamedList(coco._annotation_json(a) for a in anns), "info": {"x": 1}}
    assert "".join(iter_json(doc)) == json.dumps({"annotations": anns, "info": {"x": 1}}, indent=2,
                                                 sort_keys=True) + "\n"


def test_annotation_text_around_its_id():
    """A pool process formats an annotation before its id is known: head + id + tail."""
    rng = random.Random(7)
    cat_id = {"car": 1, "van": 2}
    for j in range(300):
        d = _annotation(rng)
        size = d["segmentation"]["size"] if j % 3 else [float(v) for v in d["segmentation"]["size"]]
        o = coco.CocoObject(image_id=d["image_id"], category=rng.choice(list(cat_id)), bbox_xywh=tuple(d["bbox"]),
                            area=d["area"], segmentation={"size": size, "counts": d["segmentation"]["counts"]},
                            obb_xyxyxyxy=tuple(d["obb_xyxyxyxy"]), heading_img_deg=d["heading_img_deg"],
                            difficult=d["difficult"], orientation_unclear=d["orientation_unclear"],
                            vehicle_id=d["vehicle_id"], visible_fraction=d["visible_fraction"],
                            truncated=d["truncated"])
        head, tail = coco._annotation_parts(o, cat_id)
        for k in (1, 10, rng.randint(1, 10**9)):
            assert head + str(k) + tail == coco._annotation_json(coco._annotation(k, o, cat_id)).text
