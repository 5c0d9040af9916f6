"""Tiny DOTA / YOLO-OBB folders built in tmp folders."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest


def rect(cx, cy, w, h, angle_deg=0.0):
    """(4, 2) corners of a w x h rectangle centred at (cx, cy), clockwise on screen."""
    a = np.deg2rad(angle_deg)
    c, s = np.cos(a), np.sin(a)
    pts = np.array([[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [-w / 2, h / 2]])
    return pts @ np.array([[c, s], [-s, c]]) + (cx, cy)


def write_dota_image(folder: Path, name: str, boxes, classes=None, difficult=None, *,
                     size=(200, 160), gsd=0.12, header=True, draw=True, ext=".png",
                     background=90) -> Path:
    """folder/images/name.png (boxes drawn bright on a grey background) + folder/labelTxt/name.txt."""
    (folder / "images").mkdir(parents=True, exist_ok=True)
    (folder / "labelTxt").mkdir(parents=True, exist_ok=True)
    w, h = size
    img = np.full((h, w, 3), background, np.uint8)
    boxes = [np.asarray(b, float) for b in boxes]
    if draw:
        for b in boxes:
            lo, hi = b.min(0), b.max(0)
            axis_aligned = np.all(np.isin(b[:, 0], (lo[0], hi[0])) & np.isin(b[:, 1], (lo[1], hi[1])))
            if axis_aligned and np.all(b == np.round(b)):  # exactly the pixels inside
                img[int(lo[1]):int(hi[1]), int(lo[0]):int(hi[0])] = 230
            else:
                cv2.fillPoly(img, [np.round(b * 16).astype(np.int32)], (230, 230, 230), cv2.LINE_8, shift=4)
    cv2.imwrite(str(folder / "images" / f"{name}{ext}"), img)
    lines = []
    if header:
        lines += ["imagesource:test", f"gsd:{gsd}" if gsd is not None else "gsd:null"]
    classes = classes or ["small-vehicle"] * len(boxes)
    difficult = difficult or [0] * len(boxes)
    for b, c, d in zip(boxes, classes, difficult):
        lines.append(" ".join(f"{v:.2f}" for v in b.reshape(-1)) + f" {c} {d}")
    p = folder / "labelTxt" / f"{name}.txt"
    p.write_text("\n".join(lines) + "\n")
    return p


def make_dota(folder: Path, n: int, prefix="img", *, seed=0, size=(200, 160), gsd=0.12,
              per_image=3) -> Path:
    rng = np.random.default_rng(seed)
    for i in range(n):
        boxes = [rect(rng.uniform(30, size[0] - 30), rng.uniform(30, size[1] - 30), 20, 9,
                      rng.uniform(0, 180)) for _ in range(per_image)]
        cls = ["small-vehicle" if rng.random() < 0.7 else "large-vehicle" for _ in boxes]
        write_dota_image(folder, f"{prefix}{i:03d}", boxes, cls, size=size, gsd=gsd)
    return folder


@pytest.fixture
def tiny_dota(tmp_path):
    return make_dota(tmp_path / "gt", 4)


@pytest.fixture(scope="session")
def tiny_export(tmp_path_factory) -> Path:
    """A 2-image synthetic export (DOTA + YOLO-OBB, 256 px, box vehicles) on an 80 m scene."""
    from aerial_synth.camera import CameraConfig
    from aerial_synth.dataset.export import ExportConfig, export_dataset

    lines = []
    off = 0
    for name, (x0, y0, x1, y1, z) in {"ground": (-40, -40, 40, 40, 0.0),
                                      "road_ew": (-40, -4, 40, 4, 0.05),
                                      "road_ns": (-4, -40, 4, 40, 0.051)}.items():
        lines.append(f"o {name}")
        lines += [f"v {x} {y} {z}" for x, y in ((x0, y0), (x1, y0), (x1, y1), (x0, y1))]
        lines += [f"f {off + 1} {off + 2} {off + 3}", f"f {off + 1} {off + 3} {off + 4}"]
        off += 4
    root = tmp_path_factory.mktemp("export")
    scene = root / "tiny.obj"
    scene.write_text("\n".join(lines) + "\n")
    out = root / "ds"
    export_dataset(ExportConfig(scene=str(scene), images=2, formats="dota,yolo-obb", split=0.5,
                                seed=1, images_per_placement=2, n_vehicles=10,
                                camera=CameraConfig(width_px=256, height_px=256),
                                simple_vehicles=True), out, workers=1, progress=False)
    return out
