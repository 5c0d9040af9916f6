"""``aerial-synth mix``: real + synthetic training sets with an exact real share.

- **Counts.** ``real_fraction`` F: all synthetic training images (or ``synthetic_images``)
  plus ``round(F * S / (1 - F))`` real ones, so real / (real + synthetic) = F up to rounding
  (F = 1: real images only, all of them). ``real_images`` N: N real images added. Counts are
  of images as written: tiles when tiling.
- **Determinism.** Source images are shuffled with ``numpy.random.default_rng(seed)``; the
  real training images are the first N tiles of the shuffled real images (tiles of one image
  in raster order). Same inputs and seed -> identical folder.
- **Validation.** Real only by default: the real folder's ``val`` split, or, when it has
  none, ``val_fraction`` of the real source images (whole images, so no tile leaks).
- **GSD rescale** (``gsd``): each real image is resized by its ``gsd:`` header / target GSD
  (``INTER_AREA`` when shrinking, ``INTER_CUBIC`` when enlarging), boxes scaled by the
  exact pixel ratio new size / old size.
- **Tiles** (``tile``, ``overlap``), as the DOTA devkit's ``ImgSplit``: tile origins every
  ``tile - overlap`` px, the last tile flush with the right / bottom edge; a box wholly
  inside a tile is kept unchanged; a cut box is kept when at least ``keep_threshold`` of its
  area is inside, clipped to the tile (the clipped polygon reduced to four corners: merge the
  shortest edge of a pentagon as the devkit does, else the minimum rotated rectangle clamped
  to the tile; corner order rotated to fit the original box) and marked difficult; otherwise
  dropped (the devkit writes those as difficult ``2``; we leave them out).
- **Formats.** ``dota``, ``yolo-obb`` or both (``dota,yolo-obb``: the second folder links
  to the first's image files), laid out as ``aerial-synth export`` lays them out.
- **Files.** Untouched images are hard-linked (copied when linking fails, e.g. across
  devices; each copy is recorded in the manifest); tiles and rescaled images are written as
  PNG. Labels are rewritten (class filter, DOTA v1 or YOLO-OBB). The mix is built in a
  temporary sibling folder and renamed into place, so a failing run writes nothing.
"""

from __future__ import annotations

import errno
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import EvaluationError
from ..formats import CATEGORIES, dota, yolo_obb
from ..formats.labels import ImageLabels
from ..io_utils import check_output_dir, dumps_json, is_inside, replace_dir
from ..safe_input import image_file_complete, quote, read_bytes, read_image, shown
from .ap import to_polygons
from .labels import (
    IMAGE_EXTS,
    find_data_yaml,
    image_size,
    parse_names,
    read_dota_folder,
    read_yolo_labels,
)
from .tiling import check_scaled_plan, tile_origins

__all__ = ["MixConfig", "make_mix", "tile_origins", "clip_to_tile", "rescale_polygons",
           "mix_counts"]

MANIFEST_FORMAT = "aerial-synth-mix"


@dataclass(frozen=True)
class MixConfig:
    real: Path
    synthetic: Path
    out: Path
    real_fraction: float | None = None
    real_images: int | None = None
    synthetic_images: int | None = None
    format: str = "dota"
    seed: int = 0
    val: str = "real"
    val_fraction: float = 0.2
    tile: int | None = None
    overlap: int = 200
    keep_threshold: float = 0.7
    gsd: float | None = None
    gsd_missing: str = "error"
    real_gsd: float | None = None
    classes: list[str] | None = CATEGORIES  # type: ignore[assignment]
    force: bool = False
    formats: tuple[str, ...] = ()  # derived from ``format`` (a comma list)

    def __post_init__(self):
        if (self.real_fraction is None) == (self.real_images is None):
            raise EvaluationError("mix: expected exactly one of --real-fraction or --real-images")
        if self.real_fraction is not None and not (0.0 <= self.real_fraction <= 1.0):
            raise EvaluationError(f"--real-fraction: expected a number in [0, 1], got {self.real_fraction!r}")
        if self.real_images is not None and self.real_images < 0:
            raise EvaluationError(f"--real-images: expected a non-negative integer, got {self.real_images!r}")
        fmts = tuple(f.strip() for f in str(self.format).split(","))
        if not fmts or any(f not in ("dota", "yolo-obb") for f in fmts) or len(set(fmts)) != len(fmts):
            raise EvaluationError(f"--format: expected dota, yolo-obb or dota,yolo-obb, got {self.format!r}")
        object.__setattr__(self, "formats", fmts)
        if self.val not in ("real", "synthetic", "both"):
            raise EvaluationError(f"--val: expected real, synthetic or both, got {self.val!r}")
        if not (0.0 <= self.val_fraction < 1.0):
            raise EvaluationError(f"--val-fraction: expected a number in [0, 1), got {self.val_fraction!r}")
        if self.tile is not None and self.tile < 1:
            raise EvaluationError(f"--tile: expected a positive integer, got {self.tile!r}")
        if self.tile is not None and not (0 <= self.overlap < self.tile):
            raise EvaluationError(f"--overlap: expected 0 <= overlap < --tile ({self.tile}), got {self.overlap!r}")
        if not (0.0 < self.keep_threshold <= 1.0):
            raise EvaluationError(f"--keep-threshold: expected a number in (0, 1], got {self.keep_threshold!r}")
        if self.gsd is not None and not (self.gsd > 0 and np.isfinite(self.gsd)):
            raise EvaluationError(f"--gsd: expected a number > 0, got {self.gsd!r}")
        if self.real_gsd is not None and not (self.real_gsd > 0 and np.isfinite(self.real_gsd)):
            raise EvaluationError(f"--real-gsd: expected a number > 0, got {self.real_gsd!r}")
        if self.gsd_missing not in ("error", "keep", "skip"):
            raise EvaluationError(f"--gsd-missing: expected error, keep or skip, got {self.gsd_missing!r}")


# -- geometry (pure) ----------------------------------------------------------------------------


def rescale_polygons(polygons_xy_px, sx: float, sy: float) -> np.ndarray:
    """Pixel-edge coordinates scale with the image: (x, y) -> (x * sx, y * sy)."""
    return np.asarray(polygons_xy_px, float).reshape(-1, 4, 2) * (sx, sy)


def _four_corners(poly, original: np.ndarray) -> np.ndarray | None:
    """A clipped polygon -> 4 corners (devkit: pentagon -> merge the shortest edge)."""
    import shapely

    g = shapely.orient_polygons(shapely.simplify(poly, 1e-9)) if hasattr(shapely, "orient_polygons") \
        else shapely.geometry.polygon.orient(shapely.simplify(poly, 1e-9), 1.0)
    if g.geom_type != "Polygon" or g.is_empty:
        return None
    pts = np.asarray(g.exterior.coords)[:-1]
    if len(pts) == 5:
        d = np.linalg.norm(np.roll(pts, -1, 0) - pts, axis=1)
        k = int(np.argmin(d))
        merged = (pts[k] + pts[(k + 1) % 5]) / 2
        pts = np.array([merged if i == k else pts[i] for i in range(5) if i != (k + 1) % 5])
    elif len(pts) != 4:
        r = shapely.minimum_rotated_rectangle(g)
        if r.geom_type != "Polygon":
            return None
        pts = np.asarray(r.exterior.coords)[:-1]
    if len(pts) != 4:
        return None
    if np.sign(_shoelace(pts)) != np.sign(_shoelace(original)):
        pts = pts[::-1]
    # the cyclic rotation that best fits the original corners (devkit choose_best_pointorder)
    rots = [np.roll(pts, -i, axis=0) for i in range(4)]
    k = int(np.argmin([np.sum((r - original) ** 2) for r in rots]))
    return rots[k]


def _shoelace(p: np.ndarray) -> float:
    x, y = p[:, 0], p[:, 1]
    return float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) / 2)


def clip_to_tile(polygons_xy_px, difficult, tile_xywh, keep_threshold: float = 0.7):
    """Boxes of a whole image -> boxes of one tile, in tile pixels.

    Returns (kept indices, polygons (k, 4, 2) in tile px, difficult (k,) bool, clipped (k,)
    bool). Wholly inside: unchanged (shifted). Cut with inside area / area >= threshold:
    clipped to the tile, four corners, difficult. Otherwise dropped."""
    import shapely

    x0, y0, w, h = tile_xywh
    P = np.asarray(polygons_xy_px, float).reshape(-1, 4, 2)
    diff = np.asarray(difficult, bool)
    if len(P) == 0:
        return np.zeros(0, int), np.zeros((0, 4, 2)), np.zeros(0, bool), np.zeros(0, bool)
    polys = to_polygons(P)
    box = shapely.box(x0, y0, x0 + w, y0 + h)
    area = shapely.area(polys)
    inter = shapely.intersection(polys, box)
    frac = np.where(area > 0, shapely.area(inter) / np.where(area > 0, area, 1), 0.0)
    inside = shapely.covers(box, polys) & (area > 0)
    keep, out, dout, cout = [], [], [], []
    for i in np.nonzero(inside | (frac >= keep_threshold))[0]:
        if inside[i]:
            q = P[i]
            d, c = bool(diff[i]), False
        else:
            q = _four_corners(inter[i], P[i])
            if q is None:
                continue
            q = np.clip(q, (x0, y0), (x0 + w, y0 + h))
            d, c = True, True
        keep.append(i)
        out.append(q - (x0, y0))
        dout.append(d)
        cout.append(c)
    return (np.asarray(keep, int), np.asarray(out, float).reshape(-1, 4, 2),
            np.asarray(dout, bool), np.asarray(cout, bool))


def mix_counts(n_syn_avail: int, n_real_avail: int, real_fraction: float | None,
               real_images: int | None, synthetic_images: int | None) -> tuple[int, int]:
    """(synthetic, real) training image counts; raises when there are too few images."""
    n_syn = n_syn_avail if synthetic_images is None else synthetic_images
    if n_syn > n_syn_avail:
        raise EvaluationError(f"--synthetic-images: expected at most {n_syn_avail} (the synthetic "
                              f"training images), got {n_syn}")
    if real_images is not None:
        n_real = real_images
    elif real_fraction >= 1.0:
        n_syn, n_real = 0, n_real_avail
    else:
        n_real = int(round(real_fraction * n_syn / (1.0 - real_fraction)))
    if n_real > n_real_avail:
        raise EvaluationError(
            f"--real-{'images' if real_images is not None else 'fraction'}: needs {n_real} real "
            f"training images with {n_syn} synthetic ones, only {n_real_avail} available "
            f"(use --synthetic-images to take fewer synthetic images)")
    if n_real + n_syn == 0:
        raise EvaluationError("mix: the mix would hold no training image")
    return n_syn, n_real


# -- sources ----------------------------------------------------------------------------------


def _dota_splits(root: Path, option: str) -> dict[str, tuple]:
    """split -> a reader spec: ("dota", labelTxt, images) of a DOTA root, an export or one
    split folder, or ("yolo", labels, images, names) of a YOLO-OBB folder (images/,
    labels/ and a data YAML, like Ultralytics' DOTA8)."""
    if not root.exists():
        raise EvaluationError(f"{option} {root}: no such folder")
    if not root.is_dir():
        raise EvaluationError(f"{option} {root}: expected a folder, found a file")
    for base in (root / "dota", root):
        if (base / "labelTxt").is_dir():
            return {"train": ("dota", base / "labelTxt", base / "images")}
        found = {s.name: ("dota", s / "labelTxt", s / "images")
                 for s in sorted(p for p in base.iterdir() if p.is_dir()) if (s / "labelTxt").is_dir()} \
            if base.is_dir() else {}
        if found:
            return found
    for base in (root / "yolo-obb", root):
        if (base / "images").is_dir() and (base / "labels").is_dir():
            yaml_path = find_data_yaml(base)
            if yaml_path is None:
                raise EvaluationError(f"{option} {base}: expected a data YAML (data.yaml) with class names")
            names = parse_names(str(yaml_path), option=f"{option} {yaml_path.name}")
            subs = sorted(p.name for p in (base / "images").iterdir() if p.is_dir())
            if subs:
                return {s: ("yolo", base / "labels" / s, base / "images" / s, names) for s in subs}
            return {"train": ("yolo", base / "labels", base / "images", names)}
    raise EvaluationError(f"{option} {root}: expected a DOTA folder (labelTxt/ and images/, "
                          f"<split>/labelTxt/, an export with dota/) or a YOLO-OBB folder "
                          f"(images/, labels/, data.yaml), found none")


def _read_split(spec: tuple, option: str) -> list[ImageLabels]:
    kind, lab, img = spec[:3]
    if not img.is_dir():
        raise EvaluationError(f"{option} {lab.parent}: expected an images/ folder beside {lab.name}/")
    if kind == "dota":
        return read_dota_folder(lab, img, option=option, need_images=True)
    names = spec[3]
    items = []
    for p in sorted(q for q in img.iterdir() if q.suffix.lower() in IMAGE_EXTS and q.is_file()):
        items.append(read_yolo_labels(lab / (p.stem + ".txt"), p, names, image_size(p)))
    if not items:
        raise EvaluationError(f"{option} {img}: no images found")
    return items


@dataclass
class _Item:
    """One output image: a whole source image or a tile of it, possibly rescaled."""

    origin: str  # real | synthetic
    src: ImageLabels
    scale: tuple[float, float]  # (sx, sy); (1, 1) = unscaled
    size_wh: tuple[int, int]  # after scaling
    tile: tuple[int, int, int, int] | None  # x, y, w, h in scaled pixels
    out_stem: str


def _plan_real(items: list[ImageLabels], cfg: MixConfig) -> list[list[_Item]]:
    """Per source image, the output images it gives (tiles in raster order)."""
    plans = []
    for it in items:
        w, h = image_size(it.image_path)
        sx = sy = 1.0
        if it.gsd_m is None and cfg.real_gsd is not None:
            it.gsd_m = cfg.real_gsd
        gsd = it.gsd_m
        if cfg.gsd is not None:
            if it.gsd_m is None:
                if cfg.gsd_missing == "error":
                    raise EvaluationError(f"{it.label_path or it.image_path}: expected a 'gsd:' header to "
                                          f"rescale to --gsd {cfg.gsd:g}, found none (see "
                                          f"--real-gsd and --gsd-missing)")
                if cfg.gsd_missing == "skip":
                    plans.append([])
                    continue
            else:
                f = it.gsd_m / cfg.gsd
                if abs(f - 1.0) > 1e-9:
                    least = cfg.tile or 1
                    if w * f < least or h * f < least:
                        raise EvaluationError(
                            f"--gsd {cfg.gsd:g}: {shown(it.image_path)} ({w} x {h} px at {it.gsd_m:g} "
                            f"m/px) would shrink to {w * f:.3g} x {h * f:.3g} px, less than "
                            + (f"one --tile ({cfg.tile} px)" if cfg.tile else "1 px")
                            + "; choose a smaller --gsd")
                    nw, nh = check_scaled_plan(shown(it.image_path), w, h, f, cfg.tile, cfg.overlap)
                    sx, sy = nw / w, nh / h
                    w, h = nw, nh
                    # the GSD the rounded size gives (the labels' gsd: header must be true)
                    gsd = it.gsd_m / ((sx + sy) / 2)
        scale_tag = "" if (sx, sy) == (1.0, 1.0) else f"__{sx:.4g}"
        out = []
        if cfg.tile is None:
            out.append(_Item("real", it, (sx, sy), (w, h), None, f"real-{it.name}{scale_tag}"))
        else:
            check_scaled_plan(shown(it.image_path), w, h, 1.0, cfg.tile, cfg.overlap)
            for y in tile_origins(h, cfg.tile, cfg.overlap):
                for x in tile_origins(w, cfg.tile, cfg.overlap):
                    tw, th = min(cfg.tile, w - x), min(cfg.tile, h - y)
                    out.append(_Item("real", it, (sx, sy), (w, h), (x, y, tw, th),
                                     f"real-{it.name}__{sx:.4g}__{x}___{y}"))
        for o in out:
            o.src.extra["gsd_out"] = gsd
        plans.append(out)
    return plans


def _head(path: Path) -> str:
    """The first 4 KiB of one of our own files, as text ('' when it cannot be read)."""
    try:
        return read_bytes(path, str(path), EvaluationError, max_bytes=1 << 30)[:4096].decode(
            "utf-8", "replace")
    except EvaluationError:
        return ""


def _link(src: Path, dst: Path) -> str:
    try:
        os.link(src, dst)
        return "hardlink"
    except OSError as exc:
        if exc.errno in (errno.EXDEV, errno.EPERM, errno.EMLINK, errno.ENOTSUP, errno.EACCES):
            shutil.copyfile(src, dst)
            return "copy"
        raise


def _load(path: Path):
    return read_image(path, error=EvaluationError)


class _Writer:
    def __init__(self, root: Path, fmts: tuple[str, ...], classes: list[str], keep_threshold: float):
        self.root, self.fmts, self.classes = root, fmts, classes
        self._keep_threshold = keep_threshold
        self._cache: tuple[Path, tuple, np.ndarray] | None = None

    def dirs(self, fmt: str, split: str) -> tuple[Path, Path]:
        if fmt == "dota":
            return self.root / "dota" / split / "images", self.root / "dota" / split / "labelTxt"
        return self.root / "yolo-obb" / "images" / split, self.root / "yolo-obb" / "labels" / split

    def image(self, item: _Item) -> np.ndarray:
        key = (item.src.image_path, item.scale)
        if self._cache is None or self._cache[:2] != key:
            import cv2

            img = _load(item.src.image_path)
            if item.scale != (1.0, 1.0):
                w, h = item.size_wh
                interp = cv2.INTER_AREA if item.scale[0] < 1 else cv2.INTER_CUBIC
                img = cv2.resize(img, (w, h), interpolation=interp)
            self._cache = (key[0], key[1], img)
        return self._cache[2]

    def write(self, item: _Item, split: str) -> dict:
        import cv2

        src = item.src
        keep_cls = np.array([self.classes is None or c in self.classes for c in src.classes], bool)
        P = rescale_polygons(src.polygons_xy_px, *item.scale)[keep_cls]
        C = [c for c, k in zip(src.classes, keep_cls) if k]
        D = np.asarray(src.difficult, bool)[keep_cls]
        clipped = np.zeros(len(C), bool)
        if item.tile is not None:
            idx, P, D, clipped = clip_to_tile(P, D, item.tile, self._keep_threshold)
            C = [C[i] for i in idx]
            w, h = item.tile[2], item.tile[3]
        else:
            w, h = item.size_wh if item.size_wh != (0, 0) else image_size(src.image_path)
        gsd = src.extra.get("gsd_out", src.gsd_m)
        first: Path | None = None
        how = ""
        images = []
        for fmt in self.fmts:
            img_dir, lab_dir = self.dirs(fmt, split)
            img_dir.mkdir(parents=True, exist_ok=True)
            lab_dir.mkdir(parents=True, exist_ok=True)
            untouched = item.tile is None and item.scale == (1.0, 1.0)
            dst = img_dir / (item.out_stem + (src.image_path.suffix.lower() if untouched else ".png"))
            if first is not None:  # the other format's folder: a link to the file just made
                how_here = _link(first, dst)
                how = "copy" if "copy" in (how, how_here) else how
            elif untouched:
                if not image_file_complete(src.image_path):  # linked as is: check it first
                    raise EvaluationError(f"{shown(src.image_path)}: truncated or damaged image "
                                          "(its header or end is missing)")
                how = _link(src.image_path, dst)
            else:
                arr = self.image(item)
                if item.tile is not None:
                    x, y, tw, th = item.tile
                    arr = arr[y:y + th, x:x + tw]
                ok, buf = cv2.imencode(".png", arr)
                if not ok:  # pragma: no cover
                    raise EvaluationError(f"{src.image_path}: cannot encode a tile as PNG")
                dst.write_bytes(buf.tobytes())  # guard: inside the staged build
                how = "written"
            first = first or dst
            images.append(str(dst.relative_to(self.root)))
            if fmt == "dota":
                out = ImageLabels(item.out_stem, P, C, D)
                text = dota.text(dota.from_labels(out), gsd, src.image_source or item.origin)
            else:
                text = yolo_obb.text(
                    yolo_obb.YoloObbObject(self.classes.index(c) if self.classes else 0,
                                           tuple(map(tuple, np.clip(p / (w, h), 0.0, 1.0))))
                    for p, c in zip(P, C))
            (lab_dir / (item.out_stem + ".txt")).write_text(text, encoding="utf-8")  # guard: inside the staged build
        return {
            "split": split, "origin": item.origin, "image": images[0], "images": images,
            "file": how, "objects": len(C), "clipped": int(clipped.sum()),
            "dropped_by_class": int((~keep_cls).sum()),
            "tile_xywh": list(item.tile) if item.tile else None,
            "scale": [round(item.scale[0], 8), round(item.scale[1], 8)],
        }


def _shuffle(items: list, rng: np.random.Generator) -> list:
    order = rng.permutation(len(items))
    return [items[i] for i in order]


def _check_out(cfg: MixConfig) -> Path:
    """``--out``: not inside an input nor holding one, and new, empty or a mix (with --force)."""
    out = Path(cfg.out)
    for opt, p in (("--real", cfg.real), ("--synthetic", cfg.synthetic)):
        if not Path(p).exists():
            raise EvaluationError(f"{opt} {p}: no such folder")
        if is_inside(out, p) or is_inside(p, out):
            raise EvaluationError(f"--out {out}: overlaps the input folder {opt} {p}; choose another folder")
    check_output_dir(out, "--out")
    if out.exists() and any(out.iterdir()):
        man = out / "manifest.json"
        is_mix = man.is_file() and f'"{MANIFEST_FORMAT}"' in _head(man)
        if not is_mix:
            raise EvaluationError(f"--out {out}: exists, is not empty and is not a mix; choose a new folder")
        if not cfg.force:
            raise EvaluationError(f"--out {out}: holds a mix already (use --force to replace it)")
    return out


def _counts(entries: list[dict]) -> dict:
    """The manifest's counts of the written images."""
    tr = [e for e in entries if e["split"] == "train"]
    va = [e for e in entries if e["split"] == "val"]
    n_r = sum(e["origin"] == "real" for e in tr)
    counts = {
        "train_real": n_r, "train_synthetic": len(tr) - n_r,
        "real_share": (n_r / len(tr)) if tr else 0.0,
        "val_real": sum(e["origin"] == "real" for e in va),
        "val_synthetic": sum(e["origin"] == "synthetic" for e in va),
        "objects": sum(e["objects"] for e in entries),
        "clipped": sum(e["clipped"] for e in entries),
        "copied": sum(e["file"] == "copy" for e in entries),
    }
    return counts


def _check_out_names(group) -> None:
    """The output names of one split: each within the file system's 255 bytes (the source
    name + tile suffix), no two alike."""
    names = [i.out_stem for i in group]
    for i in group:
        if len(os.fsencode(i.out_stem)) + len(".png") > 255:
            raise EvaluationError(f"{shown(i.src.image_path)}: the mix would name it "
                                  f"{quote(i.out_stem)}.png, over 255 bytes; rename the source")
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})[0]
        raise EvaluationError(f"mix: two source images give the output name {dup!r}; rename one")


def make_mix(cfg: MixConfig) -> dict:
    """Build the mix (see the module docstring); returns the manifest."""
    out = _check_out(cfg)

    real_splits = _dota_splits(Path(cfg.real), "--real")
    syn_splits = _dota_splits(Path(cfg.synthetic), "--synthetic")
    rng = np.random.default_rng(cfg.seed)

    val_names = ("val", "valid", "validation")
    real_val_src = [s for s in real_splits if s in val_names]
    train_keys = ["train"] if "train" in real_splits else [s for s in real_splits if s not in val_names]
    if not train_keys:  # only a validation split: it is the source, and val is held out of it
        train_keys, real_val_src = real_val_src[:1], []
    real_train = _read_split(real_splits[train_keys[0]], "--real")
    if real_val_src:
        real_val = _read_split(real_splits[real_val_src[0]], "--real")
        real_train = _shuffle(real_train, rng)
    else:
        real_train = _shuffle(real_train, rng)
        n_val = int(round(cfg.val_fraction * len(real_train))) if cfg.val in ("real", "both") else 0
        real_val, real_train = real_train[:n_val], real_train[n_val:]
    syn_key = "train" if "train" in syn_splits else next(iter(syn_splits))
    syn_train = _shuffle(_read_split(syn_splits[syn_key], "--synthetic"), rng)
    syn_val = _read_split(syn_splits["val"], "--synthetic") if ("val" in syn_splits and cfg.val != "real") else []

    train_plans = [t for p in _plan_real(real_train, cfg) for t in p]
    n_syn, n_real = mix_counts(len(syn_train), len(train_plans), cfg.real_fraction, cfg.real_images,
                               cfg.synthetic_images)
    chosen = train_plans[:n_real] + [
        _Item("synthetic", s, (1.0, 1.0), (0, 0), None, f"syn-{s.name}") for s in syn_train[:n_syn]]
    val_items: list[_Item] = []
    if cfg.val in ("real", "both"):
        val_items += [t for p in _plan_real(real_val, cfg) for t in p]
    if cfg.val in ("synthetic", "both"):
        val_items += [_Item("synthetic", s, (1.0, 1.0), (0, 0), None, f"syn-{s.name}") for s in syn_val]
    for group in (chosen, val_items):
        _check_out_names(group)

    classes = list(cfg.classes) if cfg.classes is not None else sorted(
        {c for it in real_train + real_val + syn_train + syn_val for c in it.classes})

    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent))
    try:
        w = _Writer(tmp, cfg.formats, classes, cfg.keep_threshold)
        entries = []
        for split, items in (("train", chosen), ("val", val_items)):
            for it in items:
                e = w.write(it, split)
                e["source_image"] = str(it.src.image_path)
                e["source_label"] = str(it.src.label_path)
                entries.append(e)
        if "yolo-obb" in cfg.formats:
            import yaml

            val_dir = "images/val" if val_items else "images/train"
            (tmp / "yolo-obb").mkdir(parents=True, exist_ok=True)
            (tmp / "yolo-obb" / "images" / "train").mkdir(parents=True, exist_ok=True)
            (tmp / "yolo-obb" / "data.yaml").write_text(yaml.safe_dump(  # guard: inside the staged build
                {"train": "images/train", "val": val_dir, "nc": len(classes),
                 "names": dict(enumerate(classes))}, sort_keys=False), encoding="utf-8")
        counts = _counts(entries)
        used = {}
        for e in entries:
            used.setdefault(e["source_image"], []).append(e["image"])
        manifest = {
            "format": MANIFEST_FORMAT, "version": 1,
            "parameters": {
                "real": str(cfg.real), "synthetic": str(cfg.synthetic), "real_fraction": cfg.real_fraction,
                "real_images": cfg.real_images, "synthetic_images": cfg.synthetic_images,
                "format": cfg.format, "seed": cfg.seed, "val": cfg.val, "val_fraction": cfg.val_fraction,
                "tile": cfg.tile, "overlap": cfg.overlap, "keep_threshold": cfg.keep_threshold,
                "gsd": cfg.gsd, "gsd_missing": cfg.gsd_missing, "real_gsd": cfg.real_gsd,
                "classes": classes,
            },
            "counts": counts,
            "available": {"real_train_images": len(real_train), "real_val_images": len(real_val),
                          "real_train_outputs": len(train_plans), "synthetic_train_images": len(syn_train),
                          "synthetic_val_images": len(syn_val)},
            "sources": [{"source_image": k, "outputs": v} for k, v in used.items()],
            "images": entries,
        }
        (tmp / "manifest.json").write_text(dumps_json(manifest), encoding="utf-8")  # guard: inside the staged build
        os.chmod(tmp, 0o777 & ~_umask())
        replace_dir(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return manifest


def _umask() -> int:
    m = os.umask(0)
    os.umask(m)
    return m
