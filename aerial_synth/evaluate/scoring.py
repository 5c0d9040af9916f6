"""Scoring options of ``aerial-synth eval`` for real sets: merged classes, axis-aligned IoU,
an ignored border, and scores per group of images.

Each option is a pure transformation of the ground truth and the detections before
:func:`~aerial_synth.evaluate.ap.evaluate` runs, so the AP itself stays the devkit's:

- **merged classes** (``vehicle`` or ``vehicle=small-vehicle,large-vehicle``): every class
  (or the listed ones; the others are dropped from both sides) becomes one class, so AP is
  class-agnostic;
- **IoU type** ``obb`` (oriented polygons, the default), ``hbb`` (both the detection and the
  truth are replaced by their axis-aligned hull: min/max of the four corners, so an oriented
  prediction is scored against an axis-aligned label by its hull) or ``auto`` (``hbb`` for a
  group whose truth boxes are all axis-aligned, else ``obb``);
- **ignored border** PX (for every image, or per group with ``GROUP=PX``): a truth box whose
  centre lies less than PX from the image border is made difficult (a detection on it is
  neither a true nor a false positive); a detection whose centre lies there is removed;
- **groups**: one per sub-folder of a collection (``--gt`` holding DOTA folders), or the
  first capture group that took part in the match (else the whole match) of ``--group
  REGEX`` searched in each image name; images that do not match form the group ``(other)``.

Geometry: (n, 4, 2) float64 pixels, image frame. Image names of a collection are
``<sub-folder>/<stem>``, the names prediction files use.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..errors import EvaluationError
from ..safe_input import user_regex
from .ap import Detections, EvalResult, evaluate
from .labels import ImageLabels, find_image, image_size, read_dota_folder, resolve_dota_folder

__all__ = [
    "IOU_TYPES",
    "OTHER_GROUP",
    "ScoringOptions",
    "ScoreResult",
    "parse_merge_classes",
    "parse_ignore_border",
    "merge_classes",
    "hbb_hull",
    "is_axis_aligned",
    "ignore_border",
    "image_groups",
    "is_dota_folder",
    "read_gt",
    "score",
]

IOU_TYPES = ("obb", "hbb", "auto")
OTHER_GROUP = "(other)"


def parse_merge_classes(text: str | None) -> tuple[str, tuple[str, ...] | None] | None:
    """``NAME`` (every class) or ``NAME=C1,C2`` (those classes; others dropped)."""
    if text is None:
        return None
    name, sep, rest = str(text).partition("=")
    name = name.strip()
    members = tuple(c.strip() for c in rest.split(",") if c.strip()) if sep else None
    if not name or " " in name or (sep and not members):
        raise EvaluationError(f"--merge-classes: expected NAME or NAME=CLASS1,CLASS2, got {text!r}")
    return name, members


def parse_ignore_border(values) -> dict[str | None, float]:
    """``PX`` (every image) or ``GROUP=PX`` items -> {group or None: px}."""
    out: dict[str | None, float] = {}
    for v in values or ():
        group, sep, px = str(v).rpartition("=")
        key = group.strip() if sep else None
        try:
            val = float(px)
        except ValueError:
            val = float("nan")
        if not (np.isfinite(val) and val >= 0) or (sep and not key):
            raise EvaluationError(f"--ignore-border: expected PX or GROUP=PX with PX >= 0, got {v!r}")
        if key in out:
            raise EvaluationError(f"--ignore-border: {'every image' if key is None else key!r} given twice")
        out[key] = val
    return out


@dataclass(frozen=True)
class ScoringOptions:
    """What :func:`score` does besides the plain AP (see the module docstring)."""

    merge_classes: tuple[str, tuple[str, ...] | None] | None = None
    iou_type: str = "obb"
    ignore_border: dict = field(default_factory=dict)
    group: str | None = None

    def __post_init__(self):
        if self.iou_type not in IOU_TYPES:
            raise EvaluationError(f"--iou-type: expected one of {', '.join(IOU_TYPES)}, got {self.iou_type!r}")
        if self.group is not None:
            user_regex(self.group, "--group", EvaluationError)  # RE2: no backtracking

    @classmethod
    def from_text(cls, merge: str | None = None, iou_type: str = "obb", border=(), group=None):
        return cls(parse_merge_classes(merge), iou_type, parse_ignore_border(border), group)

    def to_dict(self) -> dict:
        m = self.merge_classes
        return {
            "merge_classes": None if m is None else (m[0] if m[1] is None else f"{m[0]}={','.join(m[1])}"),
            "iou_type": self.iou_type,
            "ignore_border_px": {("*" if k is None else k): v for k, v in self.ignore_border.items()},
            "group": self.group,
        }


# -- pure transformations ---------------------------------------------------------------------


def _copy(g: ImageLabels, polys, classes, diff) -> ImageLabels:
    return replace(g, polygons_xy_px=np.asarray(polys, np.float64).reshape(-1, 4, 2),
                   classes=list(classes), difficult=np.asarray(diff, bool), extra=dict(g.extra))


def _select(dets: Detections, keep: np.ndarray, classes=None) -> Detections:
    keep = np.asarray(keep, bool)
    cls = [c for c, k in zip(classes if classes is not None else dets.classes, keep) if k]
    return Detections(np.asarray(dets.image)[keep], cls, np.asarray(dets.scores)[keep],
                      np.asarray(dets.polygons_xy_px, np.float64).reshape(-1, 4, 2)[keep])


def merge_classes(gt: list[ImageLabels], dets: Detections, name: str,
                  members: tuple[str, ...] | None = None) -> tuple[list[ImageLabels], Detections]:
    """Every class (or ``members``; the rest dropped on both sides) renamed ``name``."""
    out = []
    for g in gt:
        k = np.array([members is None or c in members for c in g.classes], bool)
        out.append(_copy(g, g.polygons_xy_px.reshape(-1, 4, 2)[k], [name] * int(k.sum()),
                         np.asarray(g.difficult, bool)[k]))
    keep = np.array([members is None or c in members for c in dets.classes], bool)
    return out, _select(dets, keep, [name] * len(dets))


def hbb_hull(polygons_xy_px) -> np.ndarray:
    """(n, 4, 2) -> the axis-aligned hull of each box as four corners (x0,y0) (x1,y0)
    (x1,y1) (x0,y1), px."""
    p = np.asarray(polygons_xy_px, np.float64).reshape(-1, 4, 2)
    x0, y0 = p[..., 0].min(1), p[..., 1].min(1)
    x1, y1 = p[..., 0].max(1), p[..., 1].max(1)
    return np.stack([np.stack([x0, y0], 1), np.stack([x1, y0], 1),
                     np.stack([x1, y1], 1), np.stack([x0, y1], 1)], 1)


def is_axis_aligned(polygons_xy_px, tol_px: float = 1e-3) -> bool:
    """True when every box equals its axis-aligned hull (corners in any order)."""
    p = np.asarray(polygons_xy_px, np.float64).reshape(-1, 4, 2)
    if len(p) == 0:
        return True
    h = hbb_hull(p)
    xs_ok = np.all(np.minimum(np.abs(p[..., 0] - h[:, :1, 0]), np.abs(p[..., 0] - h[:, 1:2, 0])) <= tol_px)
    ys_ok = np.all(np.minimum(np.abs(p[..., 1] - h[:, :1, 1]), np.abs(p[..., 1] - h[:, 2:3, 1])) <= tol_px)
    return bool(xs_ok and ys_ok)


def _size(g: ImageLabels) -> tuple[int, int]:
    if g.size_wh is None:
        if g.image_path is None:
            raise EvaluationError(f"--ignore-border: no image for {g.name!r} (needed for its size); "
                                  f"expected images/ beside labelTxt/")
        g.size_wh = image_size(g.image_path)
    return g.size_wh


def _near_border(xy: np.ndarray, size_wh, px: float) -> np.ndarray:
    c = xy.reshape(-1, 4, 2).mean(1)
    w, h = size_wh
    return (c[:, 0] < px) | (c[:, 1] < px) | (c[:, 0] > w - px) | (c[:, 1] > h - px)


def ignore_border(gt: list[ImageLabels], dets: Detections, px_per_image) -> tuple[list[ImageLabels], Detections]:
    """Truth boxes whose centre is within ``px_per_image[i]`` px of image i's border become
    difficult; detections whose centre is there are removed. 0 px changes nothing."""
    px = np.asarray(px_per_image, np.float64)
    out = []
    for i, g in enumerate(gt):
        if px[i] <= 0 or len(g) == 0:
            out.append(g)
            continue
        near = _near_border(g.polygons_xy_px, _size(g), px[i])
        out.append(_copy(g, g.polygons_xy_px, g.classes, np.asarray(g.difficult, bool) | near))
    keep = np.ones(len(dets), bool)
    img = np.asarray(dets.image, np.int64)
    xy = np.asarray(dets.polygons_xy_px, np.float64).reshape(-1, 4, 2)
    for i in np.unique(img):
        if px[i] > 0:
            sel = np.nonzero(img == i)[0]
            keep[sel] = ~_near_border(xy[sel], _size(gt[i]), px[i])
    return out, _select(dets, keep)


def image_groups(gt: list[ImageLabels], regex: str | None = None) -> list[str]:
    """The group of each image: ``regex`` (first matched capture group, else the whole match), else
    the collection's sub-folder (``extra['group']``), else ``all``."""
    if regex is not None:
        pat = user_regex(regex, "--group", EvaluationError)
        out = []
        for g in gt:
            m = pat.search(g.name)
            if m is None:
                out.append(OTHER_GROUP)
                continue
            found = next((x for x in m.groups() if x is not None), None)
            out.append((found if found is not None else m.group(0)) or OTHER_GROUP)
        return out
    return [g.extra.get("group", "all") for g in gt]


# -- reading ----------------------------------------------------------------------------------


def is_dota_folder(p: Path) -> bool:
    return (p / "labelTxt").is_dir() or (p / "dota").is_dir() or any(
        (p / s / "labelTxt").is_dir() for s in ("train", "val", "test"))


def read_gt(path, split: str | None = None, option: str = "--gt") -> list[ImageLabels]:
    """A DOTA folder (see :func:`resolve_dota_folder`), or a collection: a folder whose
    sub-folders are DOTA folders; its images are named ``<sub-folder>/<stem>`` and carry
    ``extra['group']`` = the sub-folder."""
    p = Path(path)
    if p.is_dir() and not is_dota_folder(p) and not any(q.suffix == ".txt" for q in p.iterdir()):
        subs = sorted(q for q in p.iterdir() if q.is_dir() and not q.name.startswith(".") and is_dota_folder(q))
        if subs:
            items = []
            for s in subs:
                lab, img = resolve_dota_folder(s, split, option=f"{option} {s.name}/")
                for g in read_dota_folder(lab, img, option=f"{option} {s.name}/"):
                    g.name = f"{s.name}/{g.name}"
                    g.extra["group"] = s.name
                    items.append(g)
            return items
    lab, img = resolve_dota_folder(p, split, option=option)
    items = read_dota_folder(lab, img, option=option)
    for g in items:
        g.image_path = g.image_path or find_image(img, g.name)
    return items


# -- scoring ----------------------------------------------------------------------------------


@dataclass
class ScoreResult:
    """``overall``: all images; ``groups``: per group (empty with a single group);
    ``iou_type`` and ``border_px`` per group as applied."""

    overall: EvalResult
    groups: dict[str, EvalResult]
    iou_type: dict[str, str]
    border_px: dict[str, float]
    options: ScoringOptions

    def to_dict(self) -> dict:
        return {
            "options": self.options.to_dict(),
            "overall": self.overall.to_dict(),
            "groups": {k: dict(v.to_dict(), iou_type=self.iou_type[k], ignore_border_px=self.border_px[k])
                       for k, v in self.groups.items()},
            "iou_type_by_group": dict(self.iou_type),
            "ignore_border_px_by_group": dict(self.border_px),
        }


def _subset(gt, dets: Detections, idx: np.ndarray):
    remap = np.full(len(gt), -1, np.int64)
    remap[idx] = np.arange(len(idx))
    img = np.asarray(dets.image, np.int64)
    keep = remap[img] >= 0 if len(img) else np.zeros(0, bool)
    d = _select(dets, keep)
    d.image = remap[np.asarray(d.image, np.int64)]
    return [gt[i] for i in idx], d


def score(gt: list[ImageLabels], dets: Detections, opts: ScoringOptions, *, iou: float = 0.5,
          metric: str = "voc07", classes: list[str] | None = None) -> ScoreResult:
    """Apply ``opts`` (merge, border, IoU type) and evaluate all images and each group."""
    groups = image_groups(gt, opts.group)
    names = sorted(set(groups))
    unknown = [k for k in opts.ignore_border if k is not None and k not in names]
    if unknown:
        raise EvaluationError(f"--ignore-border: no group {unknown[0]!r} (groups: {', '.join(names)})")
    if opts.merge_classes is not None:
        gt, dets = merge_classes(gt, dets, *opts.merge_classes)
    border = {k: float(opts.ignore_border.get(k, opts.ignore_border.get(None, 0.0))) for k in names}
    gt, dets = ignore_border(gt, dets, [border[k] for k in groups])
    iou_type = {}
    for k in names:
        if opts.iou_type == "auto":
            boxes = [g.polygons_xy_px for g, gk in zip(gt, groups) if gk == k]
            iou_type[k] = "hbb" if is_axis_aligned(np.concatenate(boxes or [np.zeros((0, 4, 2))])) else "obb"
        else:
            iou_type[k] = opts.iou_type
    hbb_img = np.array([iou_type[k] == "hbb" for k in groups], bool)
    if hbb_img.any():
        gt = [_copy(g, hbb_hull(g.polygons_xy_px), g.classes, g.difficult) if h else g
              for g, h in zip(gt, hbb_img)]
        xy = np.asarray(dets.polygons_xy_px, np.float64).reshape(-1, 4, 2).copy()
        m = hbb_img[np.asarray(dets.image, np.int64)] if len(dets) else np.zeros(0, bool)
        xy[m] = hbb_hull(xy[m])
        dets = Detections(dets.image, dets.classes, dets.scores, xy)
    overall = evaluate(gt, dets, iou_threshold=iou, metric=metric, classes=classes)
    per = {}
    if len(names) > 1:
        garr = np.array(groups)
        for k in names:
            sg, sd = _subset(gt, dets, np.nonzero(garr == k)[0])
            per[k] = evaluate(sg, sd, iou_threshold=iou, metric=metric, classes=classes or overall.classes)
    return ScoreResult(overall, per, iou_type, border, opts)
