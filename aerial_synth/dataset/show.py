"""``aerial-synth show``: draw labels over images, and a contact sheet.

Reads an aerial-synth dataset (``meta/*.json`` plus any format's images) or a plain DOTA
folder (``images/`` + ``labelTxt/``). Previews are drawn into a temporary folder inside
``--out`` and moved into place only when every image has been read and drawn, so a bad input
(a truncated image, a broken label file) leaves ``--out`` as it was; ``--out`` inside the
dataset is refused. Draws each box's polygon, a heading arrow from the box
centre to the middle of its front edge (corner 1 -> corner 2), the class, kept boxes in green
(small vehicles) / cyan (large vehicles) and difficult ones in orange.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from itertools import islice
from pathlib import Path

import numpy as np

from ..errors import ExportError, OutputError
from ..formats import dota, meta
from ..formats.registry import get, names
from ..io_utils import atomic_write_bytes, check_output_dir, is_inside
from ..out_guard import staged_dir
from ..safe_input import MAX_IMAGE_FILE_BYTES, check_image_pixels, cv_text, decode_image, read_bytes
from ..vehicles.model import CLASSES

__all__ = ["Drawn", "draw_labels", "contact_sheet", "show_dataset"]

# BGR
COLOURS = dict(zip(CLASSES, ((80, 220, 80), (230, 200, 40))))
DIFFICULT = (0, 140, 255)
SHORT = {c: "".join(w[0] for w in c.split("-")).upper() for c in CLASSES}  # SV, LV


@dataclass(frozen=True)
class Drawn:
    """One box to draw: polygon (4, 2) px, front-left first; class; difficult."""

    polygon_xy_px: tuple
    category: str
    difficult: bool


def draw_labels(bgr: np.ndarray, boxes, label: bool = True) -> np.ndarray:
    """A copy of ``bgr`` (H, W, 3) uint8 with the boxes drawn."""
    import cv2

    img = np.ascontiguousarray(bgr.copy())
    scale = max(1, round(max(img.shape[:2]) / 1024))
    for b in boxes:
        p = np.asarray(b.polygon_xy_px, dtype=float).reshape(4, 2)
        col = DIFFICULT if b.difficult else COLOURS.get(b.category, (255, 0, 255))
        pts = np.round(p * 4).astype(np.int32)  # 2 fractional bits
        cv2.polylines(img, [pts], True, col, scale, cv2.LINE_AA, shift=2)
        centre = p.mean(axis=0)
        front = (p[0] + p[1]) / 2.0
        tip = centre + 1.4 * (front - centre)
        cv2.arrowedLine(img, tuple(np.round(centre * 4).astype(int)), tuple(np.round(tip * 4).astype(int)),
                        col, scale, cv2.LINE_AA, shift=2, tipLength=0.3)
        cv2.circle(img, tuple(np.round(p[0] * 4).astype(int)), 2 * scale, col, -1, cv2.LINE_AA, shift=2)
        if label:
            text = cv_text(SHORT.get(b.category, b.category) + ("*" if b.difficult else ""))
            org = (int(p[:, 0].min()), max(int(p[:, 1].min()) - 3, 10))
            cv2.putText(img, text, org, cv2.FONT_HERSHEY_SIMPLEX, 0.35 * scale, col, scale, cv2.LINE_AA)
    return img


def contact_sheet(images: list[np.ndarray], thumb_px: int = 256, cols: int | None = None) -> np.ndarray:
    """Grid of thumbnails (BGR uint8), ``cols`` per row (default ~square)."""
    import cv2

    if not images:
        raise ExportError("contact sheet: no images to draw")
    n = len(images)
    cols = cols or max(1, math.ceil(math.sqrt(n)))
    rows = math.ceil(n / cols)
    sheet = np.full((rows * thumb_px, cols * thumb_px, 3), 32, np.uint8)
    for k, im in enumerate(images):
        h, w = im.shape[:2]
        s = thumb_px / max(h, w)
        t = cv2.resize(im, (max(1, round(w * s)), max(1, round(h * s))), interpolation=cv2.INTER_AREA)
        r, c = divmod(k, cols)
        sheet[r * thumb_px: r * thumb_px + t.shape[0], c * thumb_px: c * thumb_px + t.shape[1]] = t
    return sheet


def _items_from_dataset(root: Path):
    fmts = [get(n) for n in names()]
    for mp in sorted((root / "meta").glob("*.json")):
        try:
            rec = meta.read(mp)
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ExportError(f"show {mp}: cannot read the metadata ({type(exc).__name__})") from None
        sp, fn = rec.split, rec.file_name
        cands = [root / f.image_path(sp, fn) for f in fmts]
        img = next((c for c in cands if c.is_file()), None)
        boxes = [
            Drawn(a.box.corners_xy_px, a.cls, a.difficult)
            for a in rec.annotations
            if a.kept and a.box is not None
        ]
        yield rec.name, img, boxes


def _items_from_dota(root: Path):
    for lp in sorted((root / "labelTxt").glob("*.txt")):
        lab = dota.read_labels(lp)
        img = None
        for ext in ("png", "jpg", "jpeg", "tif", "bmp"):
            cand = root / "images" / f"{lp.stem}.{ext}"
            if cand.is_file():
                img = cand
                break
        yield lp.stem, img, [Drawn(p, c, bool(d))
                             for p, c, d in zip(lab.polygons_xy_px, lab.classes, lab.difficult)]


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_END = b"IEND\xaeB`\x82"


def _decode(path: Path) -> np.ndarray:
    """Read and decode one image (BGR); a truncated or unreadable file raises ExportError."""
    import cv2

    check_image_pixels(path, ExportError, f"show {path}")  # over OpenCV's limit: refused first
    data = read_bytes(path, f"show {path}", ExportError, max_bytes=MAX_IMAGE_FILE_BYTES)
    ext = path.suffix.lower()
    # Check the container's end first: libpng/libjpeg would print their own messages, and a
    # truncated JPEG decodes "successfully" with grey rows.
    if ext == ".png" and (not data.startswith(_PNG_SIGNATURE) or not data.endswith(_PNG_END)):
        raise ExportError(f"show {path}: truncated or damaged PNG (no IEND chunk at its end)")
    if ext in (".jpg", ".jpeg") and (not data.startswith(b"\xff\xd8")
                                     or not data.rstrip(b"\x00").endswith(b"\xff\xd9")):
        raise ExportError(f"show {path}: truncated or damaged JPEG (no end-of-image marker)")
    bgr = decode_image(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)  # libpng silenced
    if bgr is None:
        raise ExportError(f"show {path}: cannot decode the image")
    return bgr


def show_dataset(root, out_dir, limit: int | None = None, thumb_px: int = 256) -> list[Path]:
    """Draw every labelled image of ``root`` into ``out_dir`` plus ``contact_sheet.jpg``.
    Returns the written paths (sheet last). Writes nothing unless every image was read."""
    import cv2

    root, out = Path(root), Path(out_dir)
    if not root.is_dir():
        raise ExportError(f"show {root}: no such folder")
    check_output_dir(out, "--out")
    if is_inside(out, root):
        raise OutputError(f"--out {out}: is inside the dataset {root}; write the previews elsewhere")
    if (root / "meta").is_dir():
        items = _items_from_dataset(root)
    elif (root / "labelTxt").is_dir():
        items = _items_from_dota(root)
    else:
        raise ExportError(
            f"show {root}: expected an aerial-synth dataset (meta/) or a DOTA folder (labelTxt/)"
        )
    items = list(islice(items, limit))  # parses every label / metadata file first
    if not items:
        raise ExportError(f"show {root}: no labelled images found")
    for name, img_path, _ in items:
        if img_path is None:
            raise ExportError(f"show {root}: no image found for {name}")
    names, thumbs = [], []
    with staged_dir(out) as tmp:  # nothing half-written, files already in --out kept
        for name, img_path, boxes in items:
            drawn = draw_labels(_decode(img_path), boxes)
            ok, buf = cv2.imencode(".jpg", drawn, [cv2.IMWRITE_JPEG_QUALITY, 90])
            atomic_write_bytes(tmp / f"{name}.jpg", buf.tobytes())
            names.append(f"{name}.jpg")
            h, w = drawn.shape[:2]
            f = thumb_px / max(h, w)
            thumbs.append(cv2.resize(drawn, (max(1, round(w * f)), max(1, round(h * f))),
                                     interpolation=cv2.INTER_AREA))
        ok, buf = cv2.imencode(".jpg", contact_sheet(thumbs, thumb_px), [cv2.IMWRITE_JPEG_QUALITY, 90])
        atomic_write_bytes(tmp / "contact_sheet.jpg", buf.tobytes())
        names.append("contact_sheet.jpg")
    return [out / n for n in names]
