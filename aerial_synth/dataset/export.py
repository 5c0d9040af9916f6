"""Dataset export orchestration: seeds, placements, workers, resume, manifest, summary.

Folder layout (``OUT``)::

    manifest.json                 tool, version, every output-affecting parameter, status
    summary.json                  images, vehicles per class, difficult, dropped (+ reasons)
    meta/<name>.json              per-image metadata (written last: the image's "done" mark)
    dota/{train,val}/images/<name>.png, dota/{train,val}/labelTxt/<name>.txt
    eagle/{train,val}/images/<name>.png, eagle/{train,val}/labels/<name>.txt
    yolo-obb/images/{train,val}/<name>.png, yolo-obb/labels/{train,val}/<name>.txt, data.yaml
    coco/images/{train,val}/<name>.png, coco/annotations/instances_{train,val}.json

Images are written once and hard-linked into the other formats' folders (copied where
links are not possible).

Seeds: image ``i`` draws its camera and rendering from ``SeedSequence([seed, i])`` (spawned
into a camera and a render stream); placement group ``g = i // images_per_placement`` draws
its placement from ``SeedSequence([seed, g, 1])``. Every placement group starts from a fresh
RayScene, so an image's bytes depend only on (parameters, seed, i), never on worker count or
order. Per-image files are written first; aggregate files (COCO JSON, data.yaml, summary)
are rebuilt from the per-image metadata at the end, so ``--resume`` finishes a killed export
byte-identical to an uninterrupted one.
"""

from __future__ import annotations

import functools
import math
import os
import shutil
import time
import warnings
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from .. import __version__
from ..annotate.boxes import BoxConfig
from ..errors import ConfigError, ExportError
from ..formats import FORMATS
from ..io_utils import atomic_write_bytes, atomic_write_json, atomic_write_text

__all__ = [
    "MANIFEST_FORMAT",
    "SPLITS",
    "ExportConfig",
    "ExportResult",
    "export_dataset",
    "image_name",
    "split_of",
    "image_paths",
    "label_paths",
    "is_dataset",
]

MANIFEST_FORMAT = "aerial-synth-dataset"
MANIFEST_VERSION = 1
SPLITS = ("train", "val")
PLACEMENT_STREAM = 1
IMAGE_EXTS = ("png", "jpg")


@dataclass(frozen=True)
class ExportConfig:
    """Every parameter that affects the exported bytes (all go into the manifest).

    scene / labels / scene_seed : as ``load_scene`` takes them
    scenario            : traffic scenario name or YAML path
    images              : number of images (>= 1)
    formats             : subset of FORMATS, in any order (stored sorted)
    split               : fraction of images in train, in (0, 1]; the first
                          round(split * images) indices (at least one) are train
    seed                : dataset seed (0 is a seed like any other)
    images_per_placement: a fresh placement every K images (K >= 1)
    n_vehicles / n_lines: how much to place per placement (default: the scenario's)
    width_px, height_px, altitude_m, gsd_m, max_tilt_deg : camera (see CameraConfig)
    box                 : box extraction and flag thresholds (BoxConfig)
    image_ext           : "png" (lossless) or "jpg" (quality 95)
    simple_vehicles     : box meshes instead of catalog meshes (fast tests)
    """

    scene: str = "city_park"
    labels: str | None = None
    scene_seed: int | None = None
    scenario: str = "jam"
    images: int = 10
    formats: tuple[str, ...] = ("dota",)
    split: float = 0.8
    seed: int = 0
    images_per_placement: int = 10
    n_vehicles: int | None = None
    n_lines: int | None = None
    width_px: int = 1024
    height_px: int = 1024
    altitude_m: float = 60.0
    gsd_m: float | None = None
    max_tilt_deg: float = 15.0
    box: BoxConfig = field(default_factory=BoxConfig)
    image_ext: str = "png"
    simple_vehicles: bool = False

    def __post_init__(self):
        fm = self.formats
        if isinstance(fm, str):
            fm = tuple(f.strip() for f in fm.split(",") if f.strip())
        fm = tuple(str(f).strip().lower() for f in fm)
        if not fm:
            raise ExportError(f"--format: expected one or more of {', '.join(FORMATS)}, got nothing")
        unknown = [f for f in fm if f not in FORMATS]
        if unknown:
            raise ExportError(
                f"--format: unknown format {unknown[0]!r}; expected a comma list of {', '.join(FORMATS)}"
            )
        object.__setattr__(self, "formats", tuple(f for f in FORMATS if f in fm))
        if isinstance(self.images, bool) or int(self.images) != self.images or self.images < 1:
            raise ExportError(f"--images: expected a positive number of images, got {self.images}")
        try:
            split = float(self.split)
        except (TypeError, ValueError):
            raise ExportError(f"--split: expected a fraction in (0, 1], got {self.split!r}") from None
        if not (math.isfinite(split) and 0.0 < split <= 1.0):
            raise ExportError(f"--split: expected a fraction in (0, 1], got {self.split!r}")
        object.__setattr__(self, "split", split)
        k = self.images_per_placement
        if isinstance(k, bool) or int(k) != k or k < 1:
            raise ExportError(f"--images-per-placement: expected an integer >= 1, got {k}")
        if isinstance(self.seed, bool) or int(self.seed) != self.seed or self.seed < 0:
            raise ExportError(f"--seed: expected an integer >= 0, got {self.seed}")
        if self.image_ext not in IMAGE_EXTS:
            raise ExportError(f"--image-ext: expected one of {', '.join(IMAGE_EXTS)}, got {self.image_ext!r}")
        if not isinstance(self.box, BoxConfig):
            raise ConfigError(f"box: expected a BoxConfig, got {type(self.box).__name__}")

    # --------------------------------------------------------------- derived
    @property
    def n_train(self) -> int:
        return max(1, min(self.images, int(round(self.split * self.images))))

    def camera_config(self):
        from ..camera import CameraConfig

        return CameraConfig(
            altitude_m=self.altitude_m,
            width_px=self.width_px,
            height_px=self.height_px,
            gsd_m=self.gsd_m,
            max_tilt_deg=self.max_tilt_deg,
        )

    def to_dict(self) -> dict:
        d = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "box":
                v = v.to_dict()
            elif f.name == "formats":
                v = list(v)
            d[f.name] = v
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "ExportConfig":
        kw = dict(d)
        kw["box"] = BoxConfig(**kw.get("box", {}))
        kw["formats"] = tuple(kw.get("formats", ()))
        return cls(**kw)


@dataclass(frozen=True)
class ExportResult:
    out_dir: Path
    summary: dict
    elapsed_s: float
    rendered: int
    skipped: int

    def text(self) -> str:
        s = self.summary
        cls = ", ".join(f"{k} {v}" for k, v in s["vehicles_per_class"].items())
        drop = ", ".join(f"{k} {v}" for k, v in s["dropped_reasons"].items()) or "none"
        return (
            f"exported {s['images']} images (train {s['splits']['train']}, val {s['splits']['val']}) "
            f"to {self.out_dir} in {self.elapsed_s:.1f} s ({self.rendered} rendered, "
            f"{self.skipped} resumed): vehicles {cls}; difficult {s['difficult']}; "
            f"dropped {s['dropped']} ({drop})"
        )


# ------------------------------------------------------------------- layout


def image_name(index: int) -> str:
    return f"{index:06d}"


def split_of(cfg: ExportConfig, index: int) -> str:
    return "train" if index < cfg.n_train else "val"


def image_paths(cfg: ExportConfig, out: Path, index: int) -> list[Path]:
    """Where image ``index`` lives, one path per format (first = the one written)."""
    name, sp = image_name(index), split_of(cfg, index)
    f = f"{name}.{cfg.image_ext}"
    loc = {
        "dota": out / "dota" / sp / "images" / f,
        "eagle": out / "eagle" / sp / "images" / f,
        "yolo-obb": out / "yolo-obb" / "images" / sp / f,
        "coco": out / "coco" / "images" / sp / f,
    }
    return [loc[k] for k in cfg.formats]


def label_paths(cfg: ExportConfig, out: Path, index: int) -> dict[str, Path]:
    """Per-image label files by format (COCO has none: it is aggregated)."""
    name, sp = image_name(index), split_of(cfg, index)
    loc = {
        "dota": out / "dota" / sp / "labelTxt" / f"{name}.txt",
        "eagle": out / "eagle" / sp / "labels" / f"{name}.txt",
        "yolo-obb": out / "yolo-obb" / "labels" / sp / f"{name}.txt",
    }
    return {k: loc[k] for k in cfg.formats if k in loc}


def meta_path(out: Path, index: int) -> Path:
    return out / "meta" / f"{image_name(index)}.json"


_OWNED = ("manifest.json", "summary.json", "meta", "dota", "eagle", "yolo-obb", "coco")


def _read_manifest(out: Path) -> dict | None:
    import json

    p = out / "manifest.json"
    if not p.is_file():
        return None
    try:
        d = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return d if isinstance(d, dict) and d.get("format") == MANIFEST_FORMAT else None


def is_dataset(path) -> bool:
    """True when ``path`` holds an aerial-synth dataset (its manifest)."""
    return _read_manifest(Path(path)) is not None


def _manifest(cfg: ExportConfig, status: str) -> dict:
    return {
        "format": MANIFEST_FORMAT,
        "version": MANIFEST_VERSION,
        "tool": "aerial-synth",
        "tool_version": __version__,
        "status": status,
        "parameters": cfg.to_dict(),
        "seeding": {
            "image": "numpy SeedSequence([seed, index]).spawn(2) -> camera, render",
            "placement": f"numpy SeedSequence([seed, index // images_per_placement, {PLACEMENT_STREAM}])",
        },
    }


# ------------------------------------------------------------------ workers


class _Worker:
    """Per-process state: scene, catalog and the current placement group."""

    def __init__(self, cfg: ExportConfig, out: Path, nthreads: int = 0, scene=None):
        self.cfg = cfg
        self.out = Path(out)
        self.nthreads = nthreads
        self._scene = scene
        self._catalog = None
        self._group = None
        self._rayscene = None
        self._placement = None
        self._placement_warnings: list[str] = []

    @property
    def scene(self):
        if self._scene is None:
            self._scene = _load_scene(self.cfg)
        return self._scene

    @functools.cached_property
    def scene_xy_bounds(self) -> np.ndarray:
        """[[xmin, ymin], [xmax, ymax]]: camera footprints stay inside the scene."""
        return self.scene.bounds()[:, :2]

    @property
    def catalog(self):
        if self._catalog is None:
            from ..vehicles import load_catalog

            self._catalog = load_catalog()
        return self._catalog

    def _ensure_group(self, group: int):
        if self._group == group:
            return
        from ..placement import place
        from ..render import add_placement
        from ..scene.raycast import RayScene

        rs = RayScene(self.scene, nthreads=self.nthreads)  # fresh: independent of history
        rng = np.random.default_rng(np.random.SeedSequence([self.cfg.seed, group, PLACEMENT_STREAM]))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            pl = place(
                rs,
                self.cfg.scenario,
                rng,
                n_vehicles=self.cfg.n_vehicles,
                n_lines=self.cfg.n_lines,
                catalog=self.catalog,
                scene_name=self.scene.name,
            )
        if not pl.vehicles:
            raise ExportError(
                f"placement group {group}: scenario {self.cfg.scenario!r} placed no vehicles "
                f"on scene {self.cfg.scene!r} (no road found?)"
            )
        add_placement(rs, pl, self.catalog, simple_boxes=self.cfg.simple_vehicles)
        self._placement_warnings = sorted({str(w.message) for w in caught})
        self._group, self._rayscene, self._placement = group, rs, pl

    def render(self, index: int) -> dict:
        """Render, annotate and write image ``index``; returns its summary counts."""
        from ..annotate.boxes import annotate_frame
        from ..camera import sample_pose_targeted
        from ..formats import coco, meta
        from ..render import RenderConfig, render_frame

        cfg = self.cfg
        group = index // cfg.images_per_placement
        self._ensure_group(group)
        pl, rs = self._placement, self._rayscene
        ss = np.random.SeedSequence([cfg.seed, index])
        cam_ss, render_ss = ss.spawn(2)
        cam = sample_pose_targeted(cfg.camera_config(), pl, np.random.default_rng(cam_ss),
                                   within_xy=self.scene_xy_bounds)
        frame = render_frame(rs, cam, pl, np.random.default_rng(render_ss), config=RenderConfig())
        H, W = frame.instance.shape
        segs = {}

        def sink(vid, crop, off):
            segs[vid] = coco.rle_from_crop(crop, off, H, W)

        anns = annotate_frame(frame, cam, pl, cfg.box, mask_sink=sink)
        by_id = pl.by_id()
        name = image_name(index)
        render_meta = frame.to_meta()
        render_meta.pop("vehicles", None)  # per-vehicle visibility is in ``vehicles``
        render_meta.pop("camera", None)
        record = meta.ImageRecord(
            index=index,
            name=name,
            file_name=f"{name}.{cfg.image_ext}",
            split=split_of(cfg, index),
            width_px=W,
            height_px=H,
            gsd_m=float(getattr(cam, "gsd_m", cfg.camera_config().nadir_gsd_m)),
            seed={
                "dataset_seed": cfg.seed,
                "image_index": index,
                "image_entropy": [cfg.seed, index],
                "placement_group": group,
                "placement_entropy": [cfg.seed, group, PLACEMENT_STREAM],
            },
            camera=cam.to_dict(),
            render=render_meta,
            placement={
                "scene": pl.scene,
                "scenario": pl.scenario,
                "parameters": pl.parameters,
                "n_vehicles": len(pl.vehicles),
                "warnings": self._placement_warnings,
            },
            box_config=cfg.box.to_dict(),
            annotations=tuple(anns),
            world={a.vehicle_id: by_id[a.vehicle_id].to_dict() for a in anns},
            segmentations=segs,
        )
        write_image_files(cfg, self.out, record, frame.rgb)
        return _record_counts(record)


_WORKER: _Worker | None = None


def _init_worker(cfg: ExportConfig, out: str, nthreads: int):
    global _WORKER
    os.environ.setdefault("OMP_NUM_THREADS", str(max(1, nthreads)))
    import numba  # the shading kernels' threads: share the cores among the workers

    numba.set_num_threads(max(1, min(int(nthreads), numba.config.NUMBA_NUM_THREADS)))
    _WORKER = _Worker(cfg, Path(out), nthreads=nthreads)


def _run_group(indices: list[int]) -> list[tuple[int, dict]]:
    assert _WORKER is not None
    return [(i, _WORKER.render(i)) for i in indices]


def _load_scene(cfg: ExportConfig):
    from ..scene import load_scene

    return load_scene(cfg.scene, labels=cfg.labels, seed=cfg.scene_seed)


# ------------------------------------------------------------------ writing


def encode_image(rgb: np.ndarray, ext: str) -> bytes:
    """(H, W, 3) uint8 RGB -> PNG (zlib level 1) or JPEG (quality 95) bytes."""
    import cv2

    bgr = np.ascontiguousarray(np.asarray(rgb, dtype=np.uint8)[..., ::-1])
    if ext == "png":
        ok, buf = cv2.imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, 1])
    else:
        ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 95])
    if not ok:
        raise ExportError(f"could not encode an image as {ext}")
    return buf.tobytes()


def _link_or_copy(src: Path, dst: Path) -> None:
    dst.parent.mkdir(parents=True, exist_ok=True)
    tmp = dst.with_name(f".{dst.name}.{os.getpid()}.lnk")
    try:
        if tmp.exists():
            tmp.unlink()
        os.link(src, tmp)
        os.replace(tmp, dst)
    except OSError:
        try:
            tmp.unlink()
        except OSError:
            pass
        atomic_write_bytes(dst, src.read_bytes())


def write_image_files(cfg: ExportConfig, out: Path, record, rgb: np.ndarray) -> None:
    """Image, per-image labels, then metadata (the done mark), each atomically."""
    from ..formats import dota, eagle, meta, yolo_obb

    paths = image_paths(cfg, out, record.index)
    atomic_write_bytes(paths[0], encode_image(rgb, cfg.image_ext))
    for p in paths[1:]:
        _link_or_copy(paths[0], p)
    anns = record.annotations
    for fmt, p in label_paths(cfg, out, record.index).items():
        if fmt == "dota":
            dota.write(p, dota.from_annotations(anns), record.gsd_m)
        elif fmt == "eagle":
            eagle.write(p, eagle.from_annotations(anns))
        elif fmt == "yolo-obb":
            yolo_obb.write(p, yolo_obb.from_annotations(anns, record.width_px, record.height_px))
    meta.write(meta_path(out, record.index), record)


def _record_counts(record) -> dict:
    c = {"classes": {}, "difficult": 0, "dropped": 0, "dropped_reasons": {}, "kept": 0}
    for a in record.annotations:
        if a.status == "dropped":
            c["dropped"] += 1
            for r in a.reasons:
                c["dropped_reasons"][r] = c["dropped_reasons"].get(r, 0) + 1
            continue
        c["kept"] += 1
        c["classes"][a.cls] = c["classes"].get(a.cls, 0) + 1
        if a.status == "difficult":
            c["difficult"] += 1
    return c


def _is_done(cfg: ExportConfig, out: Path, index: int) -> bool:
    if not meta_path(out, index).is_file():
        return False
    return all(p.is_file() for p in image_paths(cfg, out, index)) and all(
        p.is_file() for p in label_paths(cfg, out, index).values()
    )


def write_aggregates(cfg: ExportConfig, out: Path) -> dict:
    """COCO JSON per split, YOLO data.yaml and summary.json, from the per-image metadata."""
    from ..formats import CATEGORIES, coco, meta, yolo_obb

    records = [meta.read(meta_path(out, i)) for i in range(cfg.images)]
    if "yolo-obb" in cfg.formats:
        atomic_write_text(
            out / "yolo-obb" / "data.yaml", yolo_obb.data_yaml_text(CATEGORIES, cfg.n_train < cfg.images)
        )
    if "coco" in cfg.formats:
        for sp in SPLITS:
            recs = [r for r in records if r.split == sp]
            if not recs:
                continue
            images = [coco.CocoImage(r.index + 1, r.file_name, r.width_px, r.height_px) for r in recs]
            objs = [
                coco.object_from_annotation(a, r.index + 1, r.segmentations[a.vehicle_id])
                for r in recs
                for a in r.annotations
                if a.kept and a.box is not None
            ]
            info = {
                "description": f"aerial-synth {cfg.scene} {cfg.scenario} ({sp})",
                "version": __version__,
                "seed": cfg.seed,
            }
            coco.write(out / "coco" / "annotations" / f"instances_{sp}.json", coco.to_dict(images, objs, CATEGORIES, info))
    total = {"classes": {c: 0 for c in CATEGORIES}, "difficult": 0, "dropped": 0, "dropped_reasons": {}, "kept": 0}
    unclear = 0
    for r in records:
        c = _record_counts(r)
        for k, v in c["classes"].items():
            total["classes"][k] = total["classes"].get(k, 0) + v
        for k, v in c["dropped_reasons"].items():
            total["dropped_reasons"][k] = total["dropped_reasons"].get(k, 0) + v
        for k in ("difficult", "dropped", "kept"):
            total[k] += c[k]
        unclear += sum(1 for a in r.annotations if a.kept and a.orientation_unclear)
    summary = {
        "images": cfg.images,
        "splits": {"train": cfg.n_train, "val": cfg.images - cfg.n_train},
        "placements": math.ceil(cfg.images / cfg.images_per_placement),
        "vehicles_kept": total["kept"],
        "vehicles_per_class": total["classes"],
        "difficult": total["difficult"],
        "orientation_unclear": unclear,
        "dropped": total["dropped"],
        "dropped_reasons": dict(sorted(total["dropped_reasons"].items())),
        "formats": list(cfg.formats),
    }
    atomic_write_json(out / "summary.json", summary)
    return summary


# ------------------------------------------------------------------ driver


def _remove_stray_temps(out: Path) -> None:
    """Delete temporary files a killed export left behind (``.<name>.*.tmp`` / ``.lnk``)."""
    for name in _OWNED:
        p = out / name
        if p.is_dir():
            for f in p.rglob(".*"):
                if f.is_file() and f.name.endswith((".tmp", ".lnk")):
                    f.unlink()
    for f in out.glob(".*.tmp"):
        f.unlink()


def _check_out_dir(cfg: ExportConfig, out: Path, resume: bool, force: bool) -> str:
    """'new', 'resume' or 'overwrite'; raises ExportError on a refused folder."""
    if out.exists() and not out.is_dir():
        raise ExportError(f"--out {out}: exists and is not a folder")
    if not out.exists() or not any(out.iterdir()):
        return "new"
    man = _read_manifest(out)
    if man is None:
        if force:
            return "new"
        raise ExportError(
            f"--out {out}: folder exists, is not empty and is not an aerial-synth dataset "
            "(no manifest.json); choose another folder or pass --force"
        )
    if resume:
        old = man.get("parameters")
        if old != cfg.to_dict():
            if force:
                return "overwrite"
            diff = sorted(k for k in set(old or {}) | set(cfg.to_dict())
                          if (old or {}).get(k) != cfg.to_dict().get(k))
            raise ExportError(
                f"--resume {out}: the dataset was made with other parameters ({', '.join(diff)}); "
                "give the same parameters or pass --force to overwrite"
            )
        return "resume"
    if force:
        return "overwrite"
    raise ExportError(
        f"--out {out}: an aerial-synth dataset already exists there; pass --resume to finish "
        "it or --force to overwrite it"
    )


def export_dataset(
    cfg: ExportConfig,
    out_dir,
    workers: int = 1,
    resume: bool = False,
    force: bool = False,
    progress: bool | None = None,
) -> ExportResult:
    """Export ``cfg.images`` images to ``out_dir``. Validates everything (parameters, folder,
    scene, scenario, camera) before writing anything.

    workers  : processes (spawn); output is byte-identical for any count
    resume   : finish an interrupted export with the same parameters
    force    : overwrite an existing dataset, or write into a non-dataset folder
    progress : tqdm bar (None = only on a terminal)
    """
    t0 = time.perf_counter()
    if isinstance(workers, bool) or int(workers) != workers or workers < 1:
        raise ExportError(f"--workers: expected an integer >= 1, got {workers}")
    out = Path(out_dir)
    mode = _check_out_dir(cfg, out, resume, force)
    # Validate the inputs that can only be checked by loading them.
    cfg.camera_config()
    from ..placement import load_scenario

    load_scenario(cfg.scenario)
    scene = _load_scene(cfg)
    if mode == "overwrite":
        for name in _OWNED:
            p = out / name
            if p.is_dir():
                shutil.rmtree(p)
            elif p.exists():
                p.unlink()
    if mode == "resume":
        _remove_stray_temps(out)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(out / "manifest.json", _manifest(cfg, "incomplete"))

    todo = [i for i in range(cfg.images) if not (mode == "resume" and _is_done(cfg, out, i))]
    skipped = cfg.images - len(todo)
    groups: dict[int, list[int]] = {}
    for i in todo:
        groups.setdefault(i // cfg.images_per_placement, []).append(i)
    tasks = [groups[g] for g in sorted(groups)]

    from tqdm import tqdm

    bar = tqdm(total=cfg.images, initial=skipped, unit="img", desc="export",
               disable=(None if progress is None else not progress), dynamic_ncols=True)
    try:
        if workers == 1 or len(tasks) <= 1:
            w = _Worker(cfg, out, nthreads=0, scene=scene)
            for task in tasks:
                for i in task:
                    w.render(i)
                    bar.update(1)
        else:
            import multiprocessing as mp

            ncpu = os.cpu_count() or 1
            nthreads = max(1, ncpu // int(workers))
            ctx = mp.get_context("spawn")
            with ctx.Pool(min(int(workers), len(tasks)), initializer=_init_worker,
                          initargs=(cfg, str(out), nthreads)) as pool:
                for res in pool.imap_unordered(_run_group, tasks):
                    bar.update(len(res))
    finally:
        bar.close()
    summary = write_aggregates(cfg, out)
    atomic_write_json(out / "manifest.json", _manifest(cfg, "complete"))
    return ExportResult(out, summary, time.perf_counter() - t0, len(todo), skipped)
