"""Reading labelled image folders for evaluation, mixing and statistics.

Pure parsers (``parse_dota_lines``, ``parse_yolo_obb_lines``, ``parse_vedai_lines``) take text
lines and return arrays; the folder readers find files and call them. Our own parsers (not
:mod:`aerial_synth.formats`) because they must also read *real* data: DOTA files without the
two header lines, ``difficult`` 2 (the devkit splitter's mark), any one-word category,
Ultralytics YOLO-OBB folders and VEDAI annotation files. Every error names the file and line.

Geometry: ``polygons_xy_px`` is (n, 4, 2) float64, pixels, image frame (x right, y down,
origin at the top-left corner of the image).
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import EvaluationError
from ..safe_input import check_image_pixels, read_image

__all__ = [
    "IMAGE_EXTS",
    "ImageLabels",
    "read_lines",
    "parse_dota_lines",
    "dota_lines",
    "parse_yolo_obb_lines",
    "parse_vedai_lines",
    "parse_names",
    "image_size",
    "find_image",
    "find_data_yaml",
    "resolve_dota_folder",
    "read_dota_folder",
    "detect_layout",
    "read_dataset",
]

IMAGE_EXTS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")

#: VEDAI class codes -> DOTA-style names (cars, vans and pick-ups are small vehicles).
VEDAI_CLASSES = {
    1: "small-vehicle", 2: "large-vehicle", 4: "large-vehicle", 5: "large-vehicle",
    7: "motorcycle", 8: "large-vehicle", 9: "small-vehicle", 10: "other", 11: "small-vehicle",
    23: "boat", 31: "plane",
}


@dataclass
class ImageLabels:
    """Labels of one image. ``polygons_xy_px`` (n, 4, 2) float64 px; ``classes`` n names;
    ``difficult`` (n,) bool; ``gsd_m`` metres per pixel or None; ``size_wh`` or None."""

    name: str
    polygons_xy_px: np.ndarray
    classes: list[str]
    difficult: np.ndarray
    gsd_m: float | None = None
    image_source: str | None = None
    label_path: Path | None = None
    image_path: Path | None = None
    size_wh: tuple[int, int] | None = None
    extra: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.classes)


def read_lines(path) -> list[str]:
    """Text lines of a label or prediction file (UTF-8, a byte-order mark ignored)."""
    try:
        return Path(path).read_text(encoding="utf-8-sig").splitlines()
    except UnicodeDecodeError:
        raise EvaluationError(f"{path}: expected UTF-8 text, got undecodable bytes") from None


def _num(token: str, where: str, what: str) -> float:
    try:
        v = float(token)
    except ValueError:
        raise EvaluationError(f"{where}: expected {what} as a number, got {token!r}") from None
    if not np.isfinite(v):
        raise EvaluationError(f"{where}: expected {what} as a finite number, got {token!r}")
    return v


def parse_dota_lines(lines, where: str = "<labelTxt>"):
    """DOTA v1 label lines -> (polygons (n,4,2), classes, difficult (n,) bool, gsd_m, source).

    Header lines ``imagesource:...`` and ``gsd:...`` are optional (real DOTA has them, the
    devkit skips them); blank lines are skipped. Object lines: ``x1 y1 .. x4 y4 category``
    with an optional ``difficult`` (an integer; anything but 0 is difficult, as the devkit's
    splitter writes 2 for small cut-off parts)."""
    fast = _parse_dota_fast(lines)
    if fast is not None:
        return fast
    polys, classes, diff = [], [], []
    gsd = None
    source = None
    for n, raw in enumerate(lines, start=1):
        ln = raw.strip()
        if not ln:
            continue
        if ln.startswith("imagesource:"):
            source = ln[len("imagesource:"):]
            continue
        if ln.startswith("gsd:"):
            g = ln[4:].strip()
            if g not in ("", "null", "None", "none"):
                gsd = _num(g, f"{where}:{n}", "gsd")
                if gsd <= 0:
                    raise EvaluationError(f"{where}:{n}: expected gsd > 0, got {g!r}")
            continue
        f = ln.split()
        if len(f) not in (9, 10):
            raise EvaluationError(
                f"{where}:{n}: expected 'x1 y1 x2 y2 x3 y3 x4 y4 category [difficult]' "
                f"(9 or 10 fields), got {len(f)} fields: {ln[:80]!r}")
        xy = [_num(t, f"{where}:{n}", f"coordinate {i + 1}") for i, t in enumerate(f[:8])]
        d = 0
        if len(f) == 10:
            try:
                d = int(f[9])
            except ValueError:
                raise EvaluationError(
                    f"{where}:{n}: expected difficult as an integer (0 or 1), got {f[9]!r}") from None
        polys.append(xy)
        classes.append(f[8])
        diff.append(d != 0)
    arr = np.asarray(polys, dtype=np.float64).reshape(-1, 4, 2)
    return arr, classes, np.asarray(diff, dtype=bool), gsd, source


def _parse_dota_fast(lines):
    """The common case in one numpy conversion; None when anything is unusual (the strict
    line-by-line parser then finds and names the line)."""
    body = []
    gsd = source = None
    for raw in lines:
        ln = raw.strip()
        if not ln:
            continue
        if ln.startswith("imagesource:"):
            source = ln[len("imagesource:"):]
        elif ln.startswith("gsd:"):
            g = ln[4:].strip()
            if g not in ("", "null", "None", "none"):
                try:
                    gsd = float(g)
                except ValueError:
                    return None
                if not (np.isfinite(gsd) and gsd > 0):
                    return None
        else:
            body.append(ln.split())
    if any(len(f) != 10 for f in body) or any(f[9] not in ("0", "1", "2") for f in body):
        return None
    try:
        xy = np.array([f[:8] for f in body], dtype=np.float64).reshape(-1, 4, 2)
    except ValueError:
        return None
    if not np.isfinite(xy).all():
        return None
    return xy, [f[8] for f in body], np.array([f[9] != "0" for f in body], bool), gsd, source


def _fmt(x: float) -> str:
    s = f"{float(x):.2f}"
    return s[1:] if s.startswith("-") and float(s) == 0.0 else s


def dota_lines(polygons_xy_px, classes, difficult, gsd_m: float | None,
               image_source: str = "aerial-synth") -> list[str]:
    """DOTA v1 lines (two header lines, then one line per object, 2 decimals)."""
    out = [f"imagesource:{image_source}", "gsd:" + ("null" if gsd_m is None else f"{gsd_m:.6g}")]
    for p, c, d in zip(np.asarray(polygons_xy_px).reshape(-1, 8), classes, difficult):
        out.append(" ".join(_fmt(v) for v in p) + f" {c} {int(bool(d))}")
    return out


def parse_yolo_obb_lines(lines, where: str, names: list[str], size_wh, *, with_conf: bool):
    """Ultralytics YOLO-OBB lines ``cls x1 y1 .. x4 y4 [conf]`` (normalised) -> (polygons px
    (n,4,2), classes, conf (n,) or None)."""
    w, h = size_wh
    nf = 10 if with_conf else 9
    what = "'cls x1 y1 x2 y2 x3 y3 x4 y4 conf'" if with_conf else "'cls x1 y1 x2 y2 x3 y3 x4 y4'"
    polys, classes, conf = [], [], []
    for n, raw in enumerate(lines, start=1):
        ln = raw.strip()
        if not ln:
            continue
        f = ln.split()
        if len(f) != nf:
            raise EvaluationError(f"{where}:{n}: expected {what} ({nf} fields), got {len(f)} fields: {ln[:80]!r}")
        try:
            c = int(f[0])
        except ValueError:
            raise EvaluationError(f"{where}:{n}: expected a class index, got {f[0]!r}") from None
        if not 0 <= c < len(names):
            raise EvaluationError(
                f"{where}:{n}: expected a class index in 0..{len(names) - 1} (--names), got {c}")
        xy = np.array([_num(t, f"{where}:{n}", f"coordinate {i + 1}") for i, t in enumerate(f[1:9])])
        polys.append(xy.reshape(4, 2) * (w, h))
        classes.append(names[c])
        if with_conf:
            s = _num(f[9], f"{where}:{n}", "confidence")
            conf.append(s)
    arr = np.asarray(polys, dtype=np.float64).reshape(-1, 4, 2)
    return arr, classes, (np.asarray(conf, dtype=np.float64) if with_conf else None)


def parse_vedai_lines(lines, where: str):
    """VEDAI annotation lines ``xc yc angle class contained occluded x1..x4 y1..y4`` ->
    (polygons (n,4,2), classes, difficult = occluded or not contained)."""
    polys, classes, diff = [], [], []
    for n, raw in enumerate(lines, start=1):
        ln = raw.strip()
        if not ln:
            continue
        f = ln.split()
        if len(f) != 14:
            raise EvaluationError(
                f"{where}:{n}: expected VEDAI 'xc yc angle class contained occluded x1..x4 y1..y4' "
                f"(14 fields), got {len(f)}")
        v = [_num(t, f"{where}:{n}", f"field {i + 1}") for i, t in enumerate(f)]
        xs, ys = v[6:10], v[10:14]
        polys.append(list(zip(xs, ys)))
        code = int(v[3])
        classes.append(VEDAI_CLASSES.get(code, f"vedai-{code}"))
        diff.append(v[4] == 0 or v[5] != 0)
    return (np.asarray(polys, dtype=np.float64).reshape(-1, 4, 2), classes,
            np.asarray(diff, dtype=bool))


def parse_names(text: str, option: str = "--names") -> list[str]:
    """Class names from a data YAML (``names:`` list or {index: name}) or a comma list."""
    p = Path(text)
    if text.endswith((".yaml", ".yml")) or p.is_file():
        import yaml

        try:
            data = yaml.safe_load(p.read_text(encoding="utf-8-sig"))
        except FileNotFoundError:
            raise EvaluationError(f"{option} {text}: no such file") from None
        except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
            raise EvaluationError(f"{option} {text}: cannot read it as YAML ({type(exc).__name__})") from None
        names = data.get("names") if isinstance(data, dict) else None
        if isinstance(names, dict):
            try:
                keys = sorted(int(k) for k in names)
            except (TypeError, ValueError):
                keys = None
            if keys is None or keys != list(range(len(keys))):
                raise EvaluationError(f"{option} {text}: expected names with indices 0..n-1, got {list(names)[:5]}")
            out = [str(names[k]) for k in keys]
        elif isinstance(names, list):
            out = [str(x) for x in names]
        else:
            raise EvaluationError(f"{option} {text}: expected a 'names:' list or mapping in the YAML")
    else:
        out = [t.strip() for t in text.split(",")]
    out = [n.replace(" ", "-") for n in out]
    if not out or any(not n for n in out):
        raise EvaluationError(f"{option}: expected class names (a data YAML or a comma list), got {text!r}")
    return out


# -- image size from the file header -------------------------------------------------------


def image_size(path) -> tuple[int, int]:
    """(width, height) in pixels, from the image header (PNG, JPEG, BMP, GIF, TIFF, WebP;
    a whole decode for other types); an image over OpenCV's size limit is refused."""
    path = Path(path)
    size = check_image_pixels(path, EvaluationError)
    if size is not None:
        return size
    img = read_image(path, error=EvaluationError)
    return int(img.shape[1]), int(img.shape[0])


def _jpeg_size(fh):
    fh.seek(2)
    while True:
        b = fh.read(1)
        while b and b != b"\xff":
            b = fh.read(1)
        while b == b"\xff":
            b = fh.read(1)
        if not b:
            return None
        marker = b[0]
        if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
            continue
        seg = fh.read(2)
        if len(seg) < 2:
            return None
        n = struct.unpack(">H", seg)[0]
        if marker in (0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF):
            data = fh.read(5)
            if len(data) < 5:
                return None
            h, w = struct.unpack(">HH", data[1:5])
            return int(w), int(h)
        fh.seek(n - 2, os.SEEK_CUR)


def _image_index(folder: Path | None) -> dict[str, Path]:
    if folder is None or not folder.is_dir():
        return {}
    out: dict[str, Path] = {}
    for p in sorted(folder.iterdir()):
        if p.suffix.lower() in IMAGE_EXTS and p.is_file():
            out.setdefault(p.stem, p)
    return out


def find_image(folder: Path | None, stem: str) -> Path | None:
    if folder is None:
        return None
    for ext in IMAGE_EXTS:
        p = folder / (stem + ext)
        if p.is_file():
            return p
    return None


# -- folders --------------------------------------------------------------------------------


def _txt_files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.suffix == ".txt" and p.is_file())


def _must_be_dir(path: Path, option: str) -> None:
    if not path.exists():
        raise EvaluationError(f"{option} {path}: no such folder")
    if not path.is_dir():
        raise EvaluationError(f"{option} {path}: expected a folder, found a file")


def resolve_dota_folder(path, split: str | None = None, option: str = "--gt") -> tuple[Path, Path | None]:
    """A DOTA folder -> (labelTxt folder, images folder or None).

    Accepts a labelTxt folder itself (images in ``../images``), a folder holding ``labelTxt/``
    (and ``images/``), a DOTA root or aerial-synth export with ``<split>/labelTxt`` or
    ``dota/<split>/labelTxt`` (``split`` default ``val``)."""
    path = Path(path)
    _must_be_dir(path, option)
    for base in (path, path / "dota"):
        if (base / "labelTxt").is_dir():
            return base / "labelTxt", (base / "images" if (base / "images").is_dir() else None)
    for base in (path, path / "dota"):
        for s in ([split] if split else ["val", "test", "train"]):
            if (base / s / "labelTxt").is_dir():
                lab = base / s / "labelTxt"
                img = base / s / "images"
                return lab, (img if img.is_dir() else None)
    if path.name == "labelTxt" or any(p.suffix == ".txt" for p in path.iterdir()):
        img = path.parent / "images"
        return path, (img if img.is_dir() else None)
    raise EvaluationError(
        f"{option} {path}: expected a DOTA labelTxt folder (or a folder with labelTxt/, "
        f"<split>/labelTxt/ or dota/<split>/labelTxt/), found none")


def read_dota_folder(labels_dir: Path, images_dir: Path | None, option: str = "--gt",
                     need_images: bool = False) -> list[ImageLabels]:
    files = _txt_files(labels_dir)
    if not files:
        raise EvaluationError(f"{option} {labels_dir}: no label files (*.txt) found")
    images = _image_index(images_dir)
    out = []
    for f in files:
        polys, classes, diff, gsd, src = parse_dota_lines(read_lines(f), str(f))
        img = images.get(f.stem)
        if need_images and img is None:
            raise EvaluationError(f"{f}: no image {f.stem}.* in {images_dir}")
        out.append(ImageLabels(f.stem, polys, classes, diff, gsd, src, f, img))
    return out


def find_data_yaml(path: Path) -> Path | None:
    """The data YAML of a YOLO folder: data.yaml / dataset.yaml, else the only YAML there."""
    cands = sorted(p for p in path.glob("*.y*ml") if p.is_file())
    for p in cands:
        if p.name in ("data.yaml", "dataset.yaml"):
            return p
    return cands[0] if len(cands) == 1 else None


def detect_layout(path, collections: bool = True) -> str:
    """``dota``, ``yolo-obb``, ``vedai``, ``collection`` (a folder whose direct subfolders
    are such datasets; only when ``collections``) or ``images`` for a dataset folder (stats
    input)."""
    path = Path(path)
    if (path / "dota").is_dir() or (path / "labelTxt").is_dir() or any(
            (path / s / "labelTxt").is_dir() for s in ("train", "val", "test")):
        return "dota"
    if (path / "yolo-obb").is_dir() or ((path / "labels").is_dir() and (path / "images").is_dir()):
        return "yolo-obb"
    if any(p.is_dir() and p.name.startswith("annotations") for p in path.iterdir()):
        return "vedai"
    if path.name == "labelTxt":
        return "dota"
    if collections and _sub_datasets(path):
        return "collection"
    return "images"


def _sub_datasets(path: Path) -> list[Path]:
    """Direct subfolders that are datasets of a labelled layout (a folder of several
    datasets, e.g. a VEDAI folder beside a DOTA folder). One level only: no walk of a
    whole tree, no loop through a symlink to a parent."""
    subs = sorted(p for p in path.iterdir() if p.is_dir() and not p.name.startswith("."))
    return [p for p in subs if detect_layout(p, collections=False) != "images"]


def _all_images(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.suffix.lower() in IMAGE_EXTS and p.is_file())


def read_dataset(path, option: str = "DIR") -> tuple[str, list[ImageLabels]]:
    """Any supported dataset folder (all splits) -> (layout, labels per image).

    aerial-synth exports and DOTA folders (labelTxt), YOLO-OBB folders (``images/``,
    ``labels/``, a data YAML with ``names``), VEDAI folders (``images/*_co.png`` with
    ``annotations*/``), a folder of such datasets (``collection``: each labelled subfolder
    is read with its own layout; item names get the subfolder as prefix), or a folder of
    images without labels (``classes`` empty)."""
    path = Path(path)
    _must_be_dir(path, option)
    layout = detect_layout(path)
    items: list[ImageLabels] = []
    if layout == "collection":
        for sub in _sub_datasets(path):
            sub_layout, sub_items = read_dataset(sub, f"{option} {sub.name}/")
            for it in sub_items:
                it.name = f"{sub.name}/{it.name}"
                it.extra["layout"] = sub_layout
            items += sub_items
    elif layout == "dota":
        pairs = []
        for base in (path / "dota", path):
            if (base / "labelTxt").is_dir():
                pairs.append((base / "labelTxt", base / "images"))
            for s in sorted(p for p in base.iterdir() if p.is_dir()) if base.is_dir() else []:
                if (s / "labelTxt").is_dir():
                    pairs.append((s / "labelTxt", s / "images"))
            if pairs:
                break
        if path.name == "labelTxt" and not pairs:
            pairs.append((path, path.parent / "images"))
        for lab, img in pairs:
            if _txt_files(lab):
                items += read_dota_folder(lab, img if img.is_dir() else None, option)
    elif layout == "yolo-obb":
        root = path / "yolo-obb" if (path / "yolo-obb").is_dir() else path
        y = find_data_yaml(root)
        if y is None:
            raise EvaluationError(f"{option} {root}: expected a data YAML (data.yaml) with class names")
        names = parse_names(str(y), option=f"{option} {y.name}")
        for img in _all_images(root / "images"):
            rel = img.relative_to(root / "images")
            lab = root / "labels" / rel.with_suffix(".txt")
            size = image_size(img)
            if lab.is_file():
                polys, classes, _ = parse_yolo_obb_lines(
                    read_lines(lab), str(lab), names, size, with_conf=False)
            else:
                polys, classes = np.zeros((0, 4, 2)), []
            items.append(ImageLabels(img.stem, polys, classes, np.zeros(len(classes), bool),
                                     None, None, lab if lab.is_file() else None, img, size))
    elif layout == "vedai":
        ann = sorted(p for p in path.iterdir() if p.is_dir() and p.name.startswith("annotations"))[0]
        img_dir = path / "images" if (path / "images").is_dir() else path
        for img in sorted(p for p in img_dir.iterdir() if p.name.endswith(("_co.png", "_co.jpg"))):
            stem = img.name.rsplit("_co.", 1)[0]
            lab = ann / f"{stem}.txt"
            if lab.is_file():
                polys, classes, diff = parse_vedai_lines(read_lines(lab), str(lab))
            else:
                polys, classes, diff = np.zeros((0, 4, 2)), [], np.zeros(0, bool)
            items.append(ImageLabels(stem, polys, classes, diff, None, None,
                                     lab if lab.is_file() else None, img))
    else:
        imgs = _all_images(path)
        names = {p.with_suffix("").as_posix() for p in imgs}
        for img in imgs:
            stem = img.with_suffix("").as_posix()
            if stem.endswith("_ir") and stem[:-3] + "_co" in names:
                continue  # VEDAI's near-infrared twin of a colour image
            items.append(ImageLabels(img.stem, np.zeros((0, 4, 2)), [], np.zeros(0, bool),
                                     None, None, None, img, extra={"unlabelled": True}))
    if not items:
        raise EvaluationError(f"{option} {path}: expected images or labels ({layout} layout), found none")
    return layout, items
