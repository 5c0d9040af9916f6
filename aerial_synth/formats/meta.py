"""Per-image metadata JSON (``meta/<image>.json``): everything needed to reproduce and to
re-export the image's labels.

Top-level keys: ``format`` ("aerial-synth-image-meta"), ``version``, ``image`` (index, name,
file_name, split, width_px, height_px), ``gsd_m``, ``seed`` (dataset seed, image index,
placement group, the SeedSequence entropy of both), ``camera`` (K, pose, tilt, yaw, ...
from ``Camera.to_dict``), ``render`` (sun and influence factors from ``Frame.to_meta``),
``placement`` (scene, scenario, parameters), ``georeference`` (the scene's float64 origin
[x, y, z] in metres and its CRS, or null: original coordinates = local + origin),
``box_config``, ``counts`` (kept / difficult /
dropped) and ``vehicles``: one entry per vehicle in view with its id, model, colour, class,
world pose, visible fraction, truncation, status (kept / difficult / dropped), reasons, the
oriented box, image heading and (kept only) the visible-mask RLE.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..annotate.boxes import VehicleAnnotation
from ..errors import LabelFormatError
from ..io_utils import atomic_write_text, dumps_json
from ._common import read_json

__all__ = ["FORMAT", "VERSION", "ImageRecord", "to_dict", "from_dict", "write", "read"]

FORMAT = "aerial-synth-image-meta"
VERSION = 1


@dataclass(frozen=True)
class ImageRecord:
    """One exported image's metadata and annotations.

    annotations   : one per vehicle in view, sorted by vehicle id
    world         : vehicle id -> ``PlacedVehicle.to_dict()`` (world pose, model, colour)
    segmentations : vehicle id -> compressed RLE {"size": [H, W], "counts": str}, kept only
    georeference  : ``Scene.georeference()``: {"origin": [x, y, z] float64 m, "crs": str|None};
                    world poses are local: original = local + origin
    """

    index: int
    name: str
    file_name: str
    split: str
    width_px: int
    height_px: int
    gsd_m: float
    seed: dict = field(default_factory=dict)
    camera: dict = field(default_factory=dict)
    render: dict = field(default_factory=dict)
    placement: dict = field(default_factory=dict)
    box_config: dict = field(default_factory=dict)
    annotations: tuple[VehicleAnnotation, ...] = ()
    world: dict = field(default_factory=dict)
    segmentations: dict = field(default_factory=dict)
    georeference: dict = field(default_factory=dict)

    def counts(self) -> dict:
        c = {"kept": 0, "difficult": 0, "dropped": 0}
        for a in self.annotations:
            c[a.status] += 1
        return c


def to_dict(r: ImageRecord) -> dict:
    vehicles = []
    for a in r.annotations:
        v = a.to_dict()
        w = dict(r.world.get(a.vehicle_id, {}))
        v["model"] = w.pop("model", None)
        v["color"] = w.pop("color", None)
        w.pop("cls", None)
        w.pop("id", None)
        v["world"] = w
        v["segmentation"] = r.segmentations.get(a.vehicle_id)
        vehicles.append(v)
    return {
        "format": FORMAT,
        "version": VERSION,
        "image": {
            "index": int(r.index),
            "name": r.name,
            "file_name": r.file_name,
            "split": r.split,
            "width_px": int(r.width_px),
            "height_px": int(r.height_px),
        },
        "gsd_m": round(float(r.gsd_m), 6),
        "seed": r.seed,
        "camera": r.camera,
        "render": r.render,
        "placement": r.placement,
        "georeference": r.georeference,
        "box_config": r.box_config,
        "counts": r.counts(),
        "vehicles": vehicles,
    }


def from_dict(d: dict, where: str = "<meta>") -> ImageRecord:
    if not isinstance(d, dict):
        raise LabelFormatError(f"{where}: expected a JSON object, got {type(d).__name__}")
    if d.get("format") != FORMAT:
        raise LabelFormatError(f"{where}: expected format {FORMAT!r}, got {d.get('format')!r}")
    try:
        img = d["image"]
        anns, world, segs = [], {}, {}
        for v in d["vehicles"]:
            v = dict(v)
            w = dict(v.pop("world", {}) or {})
            seg = v.pop("segmentation", None)
            model, color = v.pop("model", None), v.pop("color", None)
            a = VehicleAnnotation.from_dict(v)
            anns.append(a)
            world[a.vehicle_id] = {"id": a.vehicle_id, "model": model, "color": color, "cls": a.cls, **w}
            if seg is not None:
                segs[a.vehicle_id] = seg
        return ImageRecord(
            index=int(img["index"]),
            name=str(img["name"]),
            file_name=str(img["file_name"]),
            split=str(img["split"]),
            width_px=int(img["width_px"]),
            height_px=int(img["height_px"]),
            gsd_m=float(d["gsd_m"]),
            seed=d.get("seed", {}),
            camera=d.get("camera", {}),
            render=d.get("render", {}),
            placement=d.get("placement", {}),
            box_config=d.get("box_config", {}),
            annotations=tuple(anns),
            world=world,
            segmentations=segs,
            georeference=d.get("georeference", {}) or {},
        )
    except (KeyError, TypeError, ValueError, AttributeError, IndexError, OverflowError) as exc:
        raise LabelFormatError(f"{where}: bad image metadata ({type(exc).__name__}: {exc})") from None


def write(path, record: ImageRecord) -> Path:
    return atomic_write_text(path, dumps_json(to_dict(record)))


def read(path) -> ImageRecord:
    return from_dict(read_json(path), where=str(path))
