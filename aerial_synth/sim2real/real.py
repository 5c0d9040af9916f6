"""The real images of ``sim2real``: read, rescale to the synthetic GSD, cut into tiles, and
map predictions back; the merge of tile predictions (rotated NMS, as the DOTA devkit's
``ResultMerge``).

Frames: *original* pixels of a real image (its labels' frame); *scaled* pixels after the
resize to the synthetic GSD (``sx = new width / old width``, ``sy`` likewise, as ``mix``);
*tile* pixels, offset by the tile's origin in scaled pixels. All polygons (n, 4, 2) float64.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..evaluate.ap import candidate_pairs, quad_pair_iou, quads
from ..evaluate.labels import IMAGE_EXTS, ImageLabels, image_size
from ..evaluate.scoring import read_gt
from ..evaluate.tiling import check_scaled_plan, tile_origins
from ..safe_input import read_image
from .config import Sim2RealError

__all__ = ["RealImage", "read_real", "plan_image", "load_scaled", "tiles_of", "tile_to_original",
           "rotated_nms", "merge_tiles"]


@dataclass
class RealImage:
    """One real image: its labels (original frame), scale to the synthetic GSD, scaled size
    and tiles (x, y, w, h in scaled pixels)."""

    labels: ImageLabels
    gsd_m: float | None
    scale: tuple[float, float]
    size_wh: tuple[int, int]
    scaled_wh: tuple[int, int]
    tiles: list[tuple[int, int, int, int]]


def read_real(path: Path, classes: tuple[str, ...] | None) -> list[ImageLabels]:
    """A DOTA folder or a collection of them; every image needs its label file and every
    label file its image. Truth boxes of other classes than ``classes`` are dropped."""
    path = Path(path)
    if not path.exists():
        raise Sim2RealError(f"--real {path}: no such folder")
    if not path.is_dir():
        raise Sim2RealError(f"--real {path}: expected a folder, found a file")
    items = read_gt(path, option="--real")
    by_folder: dict[Path, set[str]] = {}
    for g in items:
        if g.label_path is not None:
            by_folder.setdefault(g.label_path.parent, set()).add(g.label_path.stem)
        if g.image_path is None:
            raise Sim2RealError(f"--real: label file {g.label_path} has no image "
                                f"({g.label_path.stem}.png/.jpg/... in images/ beside labelTxt/)")
    for lab_dir, stems in by_folder.items():
        img_dir = lab_dir.parent / "images"
        if img_dir.is_dir():
            for p in sorted(img_dir.iterdir()):
                if p.suffix.lower() in IMAGE_EXTS and p.is_file() and p.stem not in stems:
                    raise Sim2RealError(f"--real: image {p} has no label file "
                                        f"({lab_dir / (p.stem + '.txt')}); label it or move it out")
    if classes is not None:
        found = sorted({c for g in items for c in g.classes})
        if found and not set(found) & set(classes):
            raise Sim2RealError(f"--real {path}: no truth box of the classes {','.join(classes)} "
                                f"(found {','.join(found[:8])}); give --real-classes LIST or all")
        for g in items:
            g.keep_classes(classes)
    return items


def plan_image(g: ImageLabels, target_gsd: float | None, real_gsd: float | None, tile: int,
               overlap: int) -> RealImage:
    """Scale and tiles of one image. Rescaling needs the image's GSD (``gsd:`` header, else
    ``real_gsd``); ``target_gsd`` None keeps the image as it is."""
    w, h = g.size_wh or image_size(g.image_path)
    g.size_wh = (w, h)
    gsd = g.gsd_m if g.gsd_m is not None else real_gsd
    sx = sy = 1.0
    nw, nh = w, h
    if target_gsd is not None:
        if gsd is None:
            raise Sim2RealError(f"{g.label_path}: expected a 'gsd:' header (metres per pixel) to rescale "
                                f"to the synthetic GSD {target_gsd:g} m, found none; give --real-gsd M "
                                f"for images without one")
        f = gsd / target_gsd
        if abs(f - 1.0) > 1e-9:
            nw, nh = check_scaled_plan(str(g.label_path), w, h, f, tile, overlap, Sim2RealError)
            sx, sy = nw / w, nh / h
    else:
        check_scaled_plan(str(g.label_path), w, h, 1.0, tile, overlap, Sim2RealError)
    tiles = [(x, y, min(tile, nw - x), min(tile, nh - y))
             for y in tile_origins(nh, tile, overlap) for x in tile_origins(nw, tile, overlap)]
    return RealImage(g, gsd, (sx, sy), (w, h), (nw, nh), tiles)


def load_scaled(r: RealImage) -> np.ndarray:
    """The image (BGR, uint8) at the synthetic GSD (INTER_AREA to shrink, INTER_CUBIC to
    enlarge, as ``mix``)."""
    import cv2

    img = read_image(r.labels.image_path, cv2.IMREAD_COLOR, Sim2RealError)  # checked, then decoded
    if r.scale != (1.0, 1.0):
        interp = cv2.INTER_AREA if r.scale[0] < 1 else cv2.INTER_CUBIC
        img = cv2.resize(img, r.scaled_wh, interpolation=interp)
    return img


def tiles_of(img: np.ndarray, r: RealImage) -> list[np.ndarray]:
    return [np.ascontiguousarray(img[y:y + th, x:x + tw]) for x, y, tw, th in r.tiles]


def tile_to_original(xy_tile_px, tile_xywh, scale) -> np.ndarray:
    """Tile pixels -> original pixels: add the tile origin, undo the scale."""
    xy = np.asarray(xy_tile_px, np.float64).reshape(-1, 4, 2)
    x0, y0 = tile_xywh[0], tile_xywh[1]
    return (xy + (x0, y0)) / np.asarray(scale, np.float64)


def rotated_nms(xy, scores, classes, iou_threshold: float) -> np.ndarray:
    """Greedy NMS per class (the DOTA devkit's ``py_cpu_nms_poly``): by score, highest first
    (ties keep input order), a box is dropped when its polygon IoU with a kept box of the
    same class is above ``iou_threshold``. Returns the kept indices in score order."""
    xy = np.asarray(xy, np.float64).reshape(-1, 4, 2)
    scores = np.asarray(scores, np.float64)
    n = len(xy)
    if n == 0:
        return np.zeros(0, np.int64)
    names = sorted(set(classes))
    key = np.array([names.index(c) for c in classes], np.int64)
    order = np.argsort(-scores, kind="stable")
    rank = np.empty(n, np.int64)
    rank[order] = np.arange(n)
    i, j = candidate_pairs(xy, key, xy, key)
    m = i != j
    i, j = i[m], j[m]
    q = quads(xy)
    iou = quad_pair_iou(q, i, q, j)
    hit = iou > iou_threshold
    i, j = i[hit], j[hit]
    nbrs: dict[int, list[int]] = {}
    for a, b in zip(i.tolist(), j.tolist()):
        if rank[b] > rank[a]:
            nbrs.setdefault(a, []).append(b)
    dropped = np.zeros(n, bool)
    keep = []
    for k in order.tolist():
        if dropped[k]:
            continue
        keep.append(k)
        for b in nbrs.get(k, ()):
            dropped[b] = True
    return np.asarray(keep, np.int64)


def merge_tiles(r: RealImage, per_tile, iou_threshold: float):
    """Tile predictions [(xy tile px, scores, classes)] of one image -> (xy original px,
    scores, classes) after rotated NMS across the tiles."""
    xs, ss, cs = [], [], []
    for t, (xy, sc, cl) in zip(r.tiles, per_tile):
        if len(sc):
            xs.append(tile_to_original(xy, t, r.scale))
            ss.append(np.asarray(sc, np.float64))
            cs += list(cl)
    if not ss:
        return np.zeros((0, 4, 2)), np.zeros(0), []
    xy, sc = np.concatenate(xs), np.concatenate(ss)
    keep = rotated_nms(xy, sc, cs, iou_threshold)
    return xy[keep], sc[keep], [cs[k] for k in keep]
