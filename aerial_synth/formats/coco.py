"""COCO instances JSON (one file per split), with the oriented box and heading as extra fields.

Standard fields: ``images`` (id, file_name, width, height), ``categories`` (id from 1,
name, supercategory "vehicle"), ``annotations`` (id, image_id, category_id, bbox [x, y, w, h]
of the visible mask in px, area = visible mask pixels, iscrowd 0, segmentation = compressed
RLE of the visible mask as made by pycocotools, counts as ASCII text).
Extra annotation fields: ``obb_xyxyxyxy`` (8 floats, px, front-left first, clockwise on
screen), ``heading_img_deg``, ``difficult``, ``orientation_unclear``, ``vehicle_id``,
``visible_fraction``, ``truncated``.
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import LabelFormatError
from ..io_utils import RawJson, StreamedList, atomic_write_text, dumps_json, iter_json
from ._common import CATEGORIES, read_json
from .registry import DatasetInfo, LabelFormat

_json_str = json.encoder.encode_basestring_ascii  # how json.dumps prints a str

__all__ = [
    "FORMAT",
    "CocoFormat",
    "CocoImage",
    "CocoObject",
    "rle_from_crop",
    "object_from_annotation",
    "to_dict",
    "from_dict",
    "write",
    "read",
]


@dataclass(frozen=True)
class CocoImage:
    id: int
    file_name: str
    width: int
    height: int


@dataclass(frozen=True)
class CocoObject:
    """One annotation; ``segmentation`` is a compressed RLE dict {"size": [h, w], "counts": str}."""

    image_id: int
    category: str
    bbox_xywh: tuple[float, float, float, float]
    area: int
    segmentation: dict
    obb_xyxyxyxy: tuple[float, ...]
    heading_img_deg: float
    difficult: int = 0
    orientation_unclear: int = 0
    vehicle_id: int = 0
    visible_fraction: float = 1.0
    truncated: int = 0
    iscrowd: int = 0


def rle_from_crop(crop: np.ndarray, offset_xy_px, height_px: int, width_px: int) -> dict:
    """Compressed COCO RLE of a full (height, width) mask that is ``crop`` at ``offset``
    and empty elsewhere, built from the crop alone (column-major runs).

    crop : (h, w) bool; offset_xy_px : (x0, y0) int
    """
    from pycocotools import mask as mask_utils

    rows, cols = np.nonzero(np.asarray(crop, dtype=bool))
    x0, y0 = int(offset_xy_px[0]), int(offset_xy_px[1])
    flat = np.sort((cols.astype(np.int64) + x0) * height_px + (rows.astype(np.int64) + y0))
    total = int(height_px) * int(width_px)
    if len(flat) == 0:
        counts = [total]
    else:
        brk = np.nonzero(np.diff(flat) != 1)[0]
        starts = flat[np.r_[0, brk + 1]]
        ends = flat[np.r_[brk, len(flat) - 1]] + 1
        counts = np.empty(2 * len(starts) + 1, dtype=np.int64)
        counts[0] = starts[0]
        counts[1::2] = ends - starts
        counts[2:-1:2] = starts[1:] - ends[:-1]
        counts[-1] = total - ends[-1]
        counts = counts.tolist()
        if counts[-1] == 0:
            counts = counts[:-1]
    rle = mask_utils.frPyObjects({"size": [int(height_px), int(width_px)], "counts": counts},
                                 int(height_px), int(width_px))
    return {"size": [int(height_px), int(width_px)], "counts": rle["counts"].decode("ascii")}


def object_from_annotation(annotation, image_id: int, rle: dict) -> CocoObject:
    """A kept :class:`~aerial_synth.annotate.VehicleAnnotation` and its visible-mask RLE."""
    from pycocotools import mask as mask_utils

    enc = {"size": rle["size"], "counts": rle["counts"].encode("ascii")}
    x, y, w, h = (float(v) for v in mask_utils.toBbox(enc))
    return CocoObject(
        image_id=int(image_id),
        category=annotation.cls,
        bbox_xywh=(x, y, w, h),
        area=int(mask_utils.area(enc)),
        segmentation=dict(rle),
        obb_xyxyxyxy=tuple(round(float(v), 3) for v in annotation.box.xyxyxyxy),
        heading_img_deg=round(float(annotation.heading_img_deg) % 360.0, 3),
        difficult=int(annotation.difficult),
        orientation_unclear=int(annotation.orientation_unclear),
        vehicle_id=int(annotation.vehicle_id),
        visible_fraction=round(float(annotation.visible_fraction), 4),
        truncated=int(annotation.truncated),
    )


def to_dict(images, objects, categories=CATEGORIES, info: dict | None = None) -> dict:
    """COCO instances dict; annotation ids 1.. in the given order, category ids 1.. in
    ``categories`` order. (The exporter streams its files instead: :meth:`CocoFormat._instances`.)"""
    cat_id = _category_ids(categories)
    anns = [_annotation(k, o, cat_id) for k, o in enumerate(objects, start=1)]
    return _document([_image(i) for i in images], anns, categories, info)


def _category_ids(categories) -> dict:
    return {name: i + 1 for i, name in enumerate(categories)}


def _document(images, annotations, categories, info: dict | None) -> dict:
    cat_id = _category_ids(categories)
    return {
        "info": dict(info or {"description": "aerial-synth"}),
        "licenses": [],
        "categories": [
            {"id": cat_id[n], "name": n, "supercategory": "vehicle"} for n in categories
        ],
        "images": images,
        "annotations": annotations,
    }


#: the keys of :func:`_annotation`'s dict, sorted (the order ``json`` prints them in)
_ANN_KEYS = ("area", "bbox", "category_id", "difficult", "heading_img_deg", "id", "image_id",
             "iscrowd", "obb_xyxyxyxy", "orientation_unclear", "segmentation", "truncated",
             "vehicle_id", "visible_fraction")


_frepr, _irepr = float.__repr__, int.__repr__  # how json prints a float, an int


def _finite(values) -> None:
    if not all(map(math.isfinite, values)):
        raise ValueError(f"Out of range float values are not JSON compliant: {values!r}")


def _list(values, pad: str, fmt) -> str:
    if not values:
        return "[]"
    inner = pad + "  "
    return "[" + inner + ("," + inner).join(map(fmt, values)) + pad + "]"


def _annotation_json(d: dict) -> RawJson:
    """:func:`_annotation`'s dict (its values cast as there: ints, floats, a str) as
    :func:`~aerial_synth.io_utils.dumps_json` prints it (without the newline), formatted
    directly, several times faster than ``json`` with indentation (pure Python), which was a
    third of a large export's COCO time. A dict of another shape (a key added to :func:`_annotation` and not here)
    goes through ``json``; the bytes are the same either way (tests/formats compare them)."""
    seg = d.get("segmentation")
    if (tuple(sorted(d)) != _ANN_KEYS or not isinstance(seg, dict) or tuple(sorted(seg)) != ("counts", "size")
            or not all(type(v) is int for v in seg["size"])):
        return RawJson(json.dumps(d, indent=2, sort_keys=True, allow_nan=False))
    floats = (*d["bbox"], d["heading_img_deg"], *d["obb_xyxyxyxy"], d["visible_fraction"])
    _finite(floats)
    p1, p2 = "\n  ", "\n    "
    return RawJson("".join((
        "{", p1, '"area": ', _irepr(d["area"]),
        ",", p1, '"bbox": ', _list(d["bbox"], p1, _frepr),
        ",", p1, '"category_id": ', _irepr(d["category_id"]),
        ",", p1, '"difficult": ', _irepr(d["difficult"]),
        ",", p1, '"heading_img_deg": ', _frepr(d["heading_img_deg"]),
        ",", p1, '"id": ', _irepr(d["id"]),
        ",", p1, '"image_id": ', _irepr(d["image_id"]),
        ",", p1, '"iscrowd": ', _irepr(d["iscrowd"]),
        ",", p1, '"obb_xyxyxyxy": ', _list(d["obb_xyxyxyxy"], p1, _frepr),
        ",", p1, '"orientation_unclear": ', _irepr(d["orientation_unclear"]),
        ",", p1, '"segmentation": {', p2, '"counts": ', _json_str(seg["counts"]),
        ",", p2, '"size": ', _list(seg["size"], p2, _irepr), p1, "}",
        ",", p1, '"truncated": ', _irepr(d["truncated"]),
        ",", p1, '"vehicle_id": ', _irepr(d["vehicle_id"]),
        ",", p1, '"visible_fraction": ', _frepr(d["visible_fraction"]),
        "\n}",
    )))


_ID0 = '\n  "id": 0'  # the id line of an annotation numbered 0 (two spaces: top-level keys only)


def _annotation_parts(o: CocoObject, cat_id: dict) -> tuple[str, str]:
    """The JSON text of ``o``'s annotation around its id: ``head + str(k) + tail`` is
    ``_annotation_json(_annotation(k, o, cat_id)).text`` for every id ``k``, so a process
    can format an annotation before the one that numbers them has counted it."""
    text = _annotation_json(_annotation(0, o, cat_id)).text
    head, sep, tail = text.partition(_ID0)
    if not sep or tail[:1] not in (",", "\n"):  # pragma: no cover - every shape has a top-level id
        raise RuntimeError("COCO annotation text without its id line")
    return head + _ID0[:-1], tail


def _record_items(categories: tuple, record) -> tuple[tuple, list[tuple[str, str]]]:
    """A record's share of its split's COCO file: its image (id, file_name, width, height)
    and the text of each kept annotation around its id (:func:`_annotation_parts`), in
    annotation order. Module-level: :meth:`CocoFormat._instances` runs it on the
    aggregation's process pool (``records.map``), where most of a large export's COCO time
    goes (decoding the RLE's bbox and area, formatting the text)."""
    cat_id = _category_ids(categories)
    image_id = record.index + 1
    anns = [_annotation_parts(object_from_annotation(a, image_id, record.segmentations[a.vehicle_id]), cat_id)
            for a in record.annotations if a.kept and a.box is not None]
    return (image_id, record.file_name, record.width_px, record.height_px), anns


def _image(i: CocoImage) -> dict:
    return {"id": int(i.id), "file_name": i.file_name, "width": int(i.width), "height": int(i.height)}


def _annotation(k: int, o: CocoObject, cat_id: dict) -> dict:
    if o.category not in cat_id:
        raise LabelFormatError(f"COCO category: expected one of {', '.join(cat_id)}, got {o.category!r}")
    return {
        "id": k,
        "image_id": int(o.image_id),
        "category_id": cat_id[o.category],
        "bbox": [float(v) for v in o.bbox_xywh],
        "area": int(o.area),
        "iscrowd": int(o.iscrowd),
        "segmentation": {"size": list(o.segmentation["size"]), "counts": o.segmentation["counts"]},
        "obb_xyxyxyxy": [float(v) for v in o.obb_xyxyxyxy],
        "heading_img_deg": float(o.heading_img_deg),
        "difficult": int(o.difficult),
        "orientation_unclear": int(o.orientation_unclear),
        "vehicle_id": int(o.vehicle_id),
        "visible_fraction": float(o.visible_fraction),
        "truncated": int(o.truncated),
    }


def from_dict(d: dict, where: str = "<coco>") -> tuple[list[CocoImage], list[CocoObject]]:
    try:
        names = {int(c["id"]): str(c["name"]) for c in d["categories"]}
        images = [CocoImage(int(i["id"]), str(i["file_name"]), int(i["width"]), int(i["height"]))
                  for i in d["images"]]
        objects = [
            CocoObject(
                image_id=int(a["image_id"]),
                category=names[int(a["category_id"])],
                bbox_xywh=tuple(float(v) for v in a["bbox"]),
                area=int(a["area"]),
                segmentation=dict(a["segmentation"]),
                obb_xyxyxyxy=tuple(float(v) for v in a.get("obb_xyxyxyxy", ())),
                heading_img_deg=float(a.get("heading_img_deg", float("nan"))),
                difficult=int(a.get("difficult", 0)),
                orientation_unclear=int(a.get("orientation_unclear", 0)),
                vehicle_id=int(a.get("vehicle_id", 0)),
                visible_fraction=float(a.get("visible_fraction", 1.0)),
                truncated=int(a.get("truncated", 0)),
                iscrowd=int(a.get("iscrowd", 0)),
            )
            for a in d["annotations"]
        ]
    except (KeyError, TypeError, ValueError, AttributeError, IndexError, OverflowError) as exc:
        raise LabelFormatError(f"{where}: not a COCO instances file ({type(exc).__name__}: {exc})") from None
    return images, objects


def write(path, d: dict) -> Path:
    return atomic_write_text(path, dumps_json(d))


def read(path) -> tuple[list[CocoImage], list[CocoObject]]:
    return from_dict(read_json(path), where=str(path))


class CocoFormat(LabelFormat):
    """``coco/images/<split>/<name>.png`` + ``coco/annotations/instances_<split>.json`` (one
    file per split that has images; no per-image label files)."""

    name = "coco"
    description = "COCO instances JSON per split (visible-mask RLE, bbox, oriented box extras)"

    def image_path(self, split: str, file_name: str) -> str:
        return f"{self.folder}/images/{split}/{file_name}"

    def aggregate_files(self, records, info: DatasetInfo) -> dict:
        """One ``instances_<split>.json`` per split with images, each streamed (its text
        made record by record while it is written: a 100,000-image export's JSON is never
        held in memory). ``records``: every image's record in index order (a list, or the
        exporter's lazy sequence, :class:`~aerial_synth.dataset.aggregate.MetaRecords`,
        whose ``map`` reads only that split's records and does the per-record work,
        :func:`_record_items`, on a process pool for a large export; numbering the
        annotations and writing the text stay in this process)."""
        out = {}
        for sp in info.splits:
            if not info.splits[sp]:
                continue
            out[f"{self.folder}/annotations/instances_{sp}.json"] = self._instances(records, sp, info)
        return out

    def _instances(self, records, sp: str, info: DatasetInfo):
        categories = tuple(info.categories)
        per_record = functools.partial(_record_items, categories)
        mapper = getattr(records, "map", None)
        if mapper is not None:  # the exporter's records: a large export's on a process pool
            items = mapper(per_record, split=sp)
        else:
            of_split = getattr(records, "of_split", None)
            recs = of_split(sp) if of_split is not None else (r for r in records if r.split == sp)
            items = map(per_record, recs)
        images: list[CocoImage] = []  # filled while the annotations stream (written after them)

        def annotations():
            k = 0
            for image, anns in items:
                images.append(CocoImage(*image))
                for head, tail in anns:  # ids 1.. in index order, numbered here
                    k += 1
                    yield RawJson(f"{head}{k}{tail}")

        meta = {"description": f"aerial-synth {info.scene} {info.scenario} ({sp})",
                "version": info.tool_version, "seed": info.seed}
        d = _document(StreamedList(_image(i) for i in images), StreamedList(annotations()), categories, meta)
        if sorted(d).index("annotations") > sorted(d).index("images"):  # pragma: no cover
            raise RuntimeError("COCO streaming: the images must be written after the annotations")
        return iter_json(d)


FORMAT = CocoFormat()
