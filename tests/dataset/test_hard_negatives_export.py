"""Hard negatives are never labelled: an export of a residential scene crowded with them
(six times the US densities) writes, in all four formats, exactly the kept vehicles'
boxes, none over a hard negative, and every image's metadata counts the negatives."""

from __future__ import annotations

import json

import numpy as np
import pytest
import shapely
import yaml

from aerial_synth.camera import Camera, CameraConfig
from aerial_synth.dataset.export import ExportConfig, export_dataset
from aerial_synth.scene import load_scene

#: hard negatives that stand up (slabs and road patches are flat; a car may stand on a patch)
STANDING = {"shed", "garden_house", "ac_unit", "container", "dumpster", "bus_shelter",
            "market_stall", "boat"}


@pytest.fixture(scope="module")
def export(tmp_path_factory):
    d = tmp_path_factory.mktemp("negx")
    spec = {"name": "res_neg", "generator": "residential", "variant": "us", "seed": 5,
            "size_m": [200, 160], "streets": {"branches": 2}, "hard_negatives": {"scale": 6.0}}
    f = d / "res_neg.yaml"
    f.write_text(yaml.safe_dump(spec))
    cfg = ExportConfig(scene=str(f), scenario="residential", images=2, formats="dota,eagle,yolo-obb,coco",
                       split=0.5, seed=1, images_per_placement=2,
                       camera=CameraConfig(width_px=256, height_px=256, gsd_m=0.3),
                       simple_vehicles=True)
    out = d / "ds"
    export_dataset(cfg, out, workers=1, progress=False)
    return out, load_scene(f)


def _quads(lines, start, scale=1.0):
    out = []
    for ln in lines:
        p = ln.split()
        if len(p) > start + 7 and not ln.startswith("#") and ":" not in ln:
            out.append(np.array(p[start:start + 8], float).reshape(4, 2) * scale)
    return out


def test_no_hard_negative_in_any_label_file(export):
    out, scene = export
    neg = scene.hints.negatives.to_dict()
    pos = np.array([[x, y, 1.0] for k, x, y in neg["positions"] if k in STANDING])
    assert len(pos) > 20
    coco = {}
    for f in (out / "coco" / "annotations").glob("*.json"):
        d = json.loads(f.read_text())
        names = {im["id"]: im["file_name"].rsplit("/", 1)[-1].split(".")[0] for im in d["images"]}
        for a in d["annotations"]:
            coco.setdefault(names[a["image_id"]], []).append(np.array(a["obb_xyxyxyxy"], float).reshape(4, 2))
    in_view = 0
    for mf in sorted((out / "meta").glob("*.json")):
        m = json.loads(mf.read_text())
        name, split = mf.stem, m["image"]["split"] if "split" in m["image"] else None
        assert m["placement"]["hard_negatives"]["counts"] == neg["counts"]
        assert m["placement"]["hard_negatives"]["labelled"] is False
        kept = [v for v in m["vehicles"] if v["status"] in ("kept", "difficult")]
        want = sorted(tuple(np.round(np.array(v["box"]["corners_xy_px"]), 1).ravel()) for v in kept)
        W, H = m["image"]["width_px"], m["image"]["height_px"]
        files = {
            "dota": (next(out.glob(f"dota/*/labelTxt/{name}.txt")), 0, 1.0),
            "eagle": (next(out.glob(f"eagle/*/labels/{name}.txt")), 0, 1.0),
            "yolo-obb": (next(out.glob(f"yolo-obb/labels/*/{name}.txt")), 1, np.array([W, H])),
        }
        per_format = {k: _quads(p.read_text().splitlines(), s, sc) for k, (p, s, sc) in files.items()}
        per_format["coco"] = coco.get(name, [])
        del split
        cam = Camera.from_dict(m["camera"])
        uv = cam.project(pos)
        vis = np.isfinite(uv).all(axis=1) & (uv[:, 0] >= 0) & (uv[:, 0] < W) & (uv[:, 1] >= 0) & (uv[:, 1] < H)
        in_view += int(vis.sum())
        pts = shapely.points(uv[vis])
        for fmt, quads in per_format.items():
            got = sorted(tuple(np.round(q, 1).ravel()) for q in quads)
            assert len(got) == len(want), (fmt, name)
            assert np.allclose(np.array(got).reshape(-1, 8), np.array(want).reshape(-1, 8), atol=0.11), (fmt, name)
            for q in quads:  # no standing hard negative's centre under any label box
                assert not shapely.contains(shapely.Polygon(q), pts).any(), (fmt, name)
        classes = {ln.split()[8] for ln in files["dota"][0].read_text().splitlines()[2:] if ln.strip()}
        assert classes <= {"small-vehicle", "large-vehicle"}
    assert in_view > 0  # the frames did show hard negatives
