"""Small real-like DOTA folders and synthetic YOLO-OBB folders, made here (no torch)."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from aerial_synth.formats import dota


def box(x0, y0, x1, y1):
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)


def rect(cx, cy, w, h, angle_deg=0.0):
    a = np.deg2rad(angle_deg)
    c, s = np.cos(a), np.sin(a)
    pts = np.array([[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [-w / 2, h / 2]])
    return pts @ np.array([[c, s], [-s, c]]) + (cx, cy)


def write_real(folder: Path, name: str, boxes, classes=None, *, size=(300, 200), gsd=0.12,
               header=True) -> Path:
    """folder/images/name.png (boxes drawn) + folder/labelTxt/name.txt (DOTA, gsd header)."""
    (folder / "images").mkdir(parents=True, exist_ok=True)
    (folder / "labelTxt").mkdir(parents=True, exist_ok=True)
    w, h = size
    img = np.full((h, w, 3), 90, np.uint8)
    for b in boxes:
        cv2.fillPoly(img, [np.round(np.asarray(b) * 16).astype(np.int32)], (230, 230, 230), cv2.LINE_8, shift=4)
    cv2.imwrite(str(folder / "images" / f"{name}.png"), img)
    classes = classes or ["small-vehicle"] * len(boxes)
    objects = [dota.DotaObject(np.asarray(b, float).reshape(4, 2), c, 0) for b, c in zip(boxes, classes)]
    lines = dota.to_lines(objects, gsd, image_source="aerial-synth")
    if not header:
        lines = lines[2:]
    (folder / "labelTxt" / f"{name}.txt").write_text("\n".join(lines) + "\n")
    return folder


def write_synthetic(root: Path, n_train=2, n_val=1, gsd=0.12, names=("small-vehicle", "large-vehicle"),
                    manifest=True) -> Path:
    """An export-like folder: yolo-obb/ (data.yaml, images/, labels/) and manifest.json."""
    y = root / "yolo-obb"
    for split, n in (("train", n_train), ("val", n_val)):
        (y / "images" / split).mkdir(parents=True, exist_ok=True)
        (y / "labels" / split).mkdir(parents=True, exist_ok=True)
        for i in range(n):
            cv2.imwrite(str(y / "images" / split / f"{split}{i}.png"), np.full((64, 64, 3), 100, np.uint8))
            (y / "labels" / split / f"{split}{i}.txt").write_text("0 0.1 0.1 0.3 0.1 0.3 0.2 0.1 0.2\n")
    (y / "data.yaml").write_text("train: images/train\nval: images/val\nnames:\n"
                                 + "".join(f"  {i}: {n}\n" for i, n in enumerate(names)))
    if manifest:
        (root / "manifest.json").write_text(json.dumps({"format": "aerial-synth-dataset",
                                                        "parameters": {"gsd_m": gsd}}))
    return root
