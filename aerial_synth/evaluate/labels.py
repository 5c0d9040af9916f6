"""Reading labelled image folders for evaluation, mixing and statistics.

The folder readers find the files of a DOTA, YOLO-OBB or VEDAI dataset and parse each one
with the lenient readers of :mod:`aerial_synth.formats` (DOTA files without the two header
lines, ``difficult`` 2 as the devkit splitter writes, any one-word category), which return
the one label model, :class:`~aerial_synth.formats.labels.ImageLabels`. Every error names the
file and line.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import EvaluationError
from ..formats import dota, vedai, yolo_obb
from ..formats.labels import ImageLabels, read_lines
from ..safe_input import (
    check_image_pixels,
    class_name,
    load_yaml_file,
    quote,
    read_image,
    shown,
)

__all__ = [
    "IMAGE_EXTS",
    "ImageLabels",
    "read_lines",
    "parse_names",
    "image_size",
    "find_image",
    "find_data_yaml",
    "read_yolo_labels",
    "resolve_dota_folder",
    "read_dota_folder",
    "detect_layout",
    "read_dataset",
]

IMAGE_EXTS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")

def parse_names(text: str, option: str = "--names") -> list[str]:
    """Class names from a data YAML (``names:`` list or {index: name}) or a comma list."""
    p = Path(text)
    if text.endswith((".yaml", ".yml")) or p.is_file():
        # nesting and alias budgets, duplicate keys, a regular file inside the input folder
        data = load_yaml_file(p, f"{option} {shown(text)}", EvaluationError)
        names = data.get("names") if isinstance(data, dict) else None
        if isinstance(names, dict):
            try:
                keys = sorted(int(k) for k in names)
            except (TypeError, ValueError):
                keys = None
            if keys is None or keys != list(range(len(keys))):
                raise EvaluationError(f"{option} {text}: expected names with indices 0..n-1, got {list(names)[:5]}")
            out = [names[k] for k in keys]
        elif isinstance(names, list):
            out = list(names)
        else:
            raise EvaluationError(f"{option} {text}: expected a 'names:' list or mapping in the YAML")
    else:
        out = [t.strip() for t in text.split(",")]
    if not out or any(n is None or n == "" for n in out):
        raise EvaluationError(f"{option}: expected class names (a data YAML or a comma list), "
                              f"got {quote(text)}")
    # a name is a word or a number (YAML reads 1 as an int); a list or mapping is no name
    out = [class_name(n.replace(" ", "-") if isinstance(n, str) else
                      (str(n) if isinstance(n, (int, float)) and not isinstance(n, bool) else n),
                      f"{option} {shown(text)}: names[{i}]", EvaluationError)
           for i, n in enumerate(out)]
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
    if split:  # the split asked for is not there: say so, not "found none"
        have = sorted({s.name for base in (path, path / "dota") if base.is_dir()
                       for s in base.iterdir() if (s / "labelTxt").is_dir()})
        raise EvaluationError(
            f"--split {quote(split)}: {shown(path)} has no {shown(split)}/labelTxt/ (nor "
            f"dota/{shown(split)}/labelTxt/); its splits: {', '.join(have) or 'none'}")
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
        lab = dota.read_labels(f)
        lab.image_path = images.get(f.stem)
        if need_images and lab.image_path is None:
            raise EvaluationError(f"{f}: no image {f.stem}.* in {images_dir}")
        out.append(lab)
    return out


def read_yolo_labels(label_path: Path, image_path: Path, names: list[str],
                     size_wh: tuple[int, int]) -> ImageLabels:
    """One YOLO-OBB image's labels (none when ``label_path`` is missing), in pixels."""
    if label_path.is_file():
        lab = yolo_obb.labels_from_lines(read_lines(label_path), str(label_path), names, size_wh,
                                         name=image_path.stem)
        lab.label_path = label_path
    else:
        lab = ImageLabels(image_path.stem, np.zeros((0, 4, 2)), [], np.zeros(0, bool), size_wh=size_wh)
    lab.image_path = image_path
    return lab


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
            items.append(read_yolo_labels(lab, img, names, size))
    elif layout == "vedai":
        ann = sorted(p for p in path.iterdir() if p.is_dir() and p.name.startswith("annotations"))[0]
        img_dir = path / "images" if (path / "images").is_dir() else path
        for img in sorted(p for p in img_dir.iterdir() if p.name.endswith(("_co.png", "_co.jpg"))):
            stem = img.name.rsplit("_co.", 1)[0]
            lab = ann / f"{stem}.txt"
            if lab.is_file():
                item = vedai.labels_from_lines(read_lines(lab), str(lab), stem)
                item.label_path = lab
            else:
                item = ImageLabels(stem, np.zeros((0, 4, 2)), [], np.zeros(0, bool))
            item.image_path = img
            items.append(item)
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
