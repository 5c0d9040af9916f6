"""Render, annotate and write one image: the export's unit of work.

:func:`render_image` ``(cfg, out_dir, index)`` is engine-agnostic and deterministic: it
renders image ``index`` of the export described by ``cfg`` into ``out_dir`` and returns its
counts. The bytes it writes depend only on (cfg, index), never on which process runs it or
in which order, so a process pool (:mod:`.export`) or a Dask cluster can call it.

Seeds: image ``i`` draws its camera and rendering from ``SeedSequence([seed, i])`` (spawned
into a camera and a render stream); placement group ``g = i // images_per_placement`` draws
its placement from ``SeedSequence([seed, g, 1])`` on a fresh RayScene.

Pool workers watch their parent: on Linux they ask the kernel to kill them when the parent
dies (``prctl(PR_SET_PDEATHSIG, SIGKILL)``), and everywhere they check the parent pid
between images and before every file they write; an orphaned worker exits at once, quietly,
without writing.
"""

from __future__ import annotations

import functools
import os
import warnings
from pathlib import Path

import numpy as np

from ..errors import ExportError
from ..io_utils import atomic_write_bytes, atomic_write_text
from .config import PLACEMENT_STREAM, ExportConfig
from .layout import image_name, image_paths, meta_path, split_of

__all__ = [
    "ImageWorker",
    "render_image",
    "encode_image",
    "write_image_files",
    "record_counts",
    "init_pool_worker",
    "run_group",
]


# ------------------------------------------------------------- parent watch

_PARENT_PID: int | None = None


def _watch_parent(parent_pid: int) -> None:
    """Die with the parent: PR_SET_PDEATHSIG on Linux, and :func:`_check_parent` elsewhere."""
    global _PARENT_PID
    _PARENT_PID = int(parent_pid)
    if hasattr(os, "sched_getaffinity"):  # Linux
        try:
            import ctypes
            import signal

            libc = ctypes.CDLL(None, use_errno=True)
            PR_SET_PDEATHSIG = 1
            libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):  # no prctl: the pid checks still apply
            pass
    _check_parent()  # the parent may have died before prctl took effect


def _check_parent() -> None:
    """Exit at once, quietly and without writing, when this worker's parent is gone."""
    if _PARENT_PID is not None and os.getppid() != _PARENT_PID:
        os._exit(0)


# ------------------------------------------------------------------- worker


def _load_scene(cfg: ExportConfig):
    """The export's scene, with its distractors (drawn once per dataset, so every worker and
    engine builds the same scene)."""
    from ..scene import load_scene

    scene = load_scene(cfg.scene, labels=cfg.labels, seed=cfg.scene_seed, bbox=cfg.bbox,
                       crs=cfg.crs)
    if cfg.distractors:
        from ..render.distractors import DISTRACTOR_KEY, add_distractors

        rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, DISTRACTOR_KEY]))
        scene, _ = add_distractors(scene, rng, per_hectare=cfg.distractors)
    return scene


class ImageWorker:
    """Per-process state: scene, catalog and the current placement group."""

    def __init__(self, cfg: ExportConfig, out: Path, nthreads: int = 0, scene=None, catalog=None):
        self.cfg = cfg
        self.out = Path(out)
        self.nthreads = nthreads
        self._scene = scene
        self._catalog = catalog
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

    @functools.cached_property
    def georeference(self) -> dict:
        geo = getattr(self.scene, "georeference", None)
        return geo() if callable(geo) else {"origin": [0.0, 0.0, 0.0], "crs": None}

    @functools.cached_property
    def render_config(self):
        return self.cfg.render_config()

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

    def record(self, index: int):
        """Render and annotate image ``index``: (ImageRecord, RGB (H, W, 3) uint8)."""
        from ..annotate.boxes import annotate_frame
        from ..camera import sample_pose_targeted
        from ..formats import coco, meta
        from ..render import render_frame

        cfg = self.cfg
        group = index // cfg.images_per_placement
        self._ensure_group(group)
        pl, rs = self._placement, self._rayscene
        ss = np.random.SeedSequence([cfg.seed, index])
        cam_ss, render_ss = ss.spawn(2)
        cam = sample_pose_targeted(cfg.camera_config(), pl, np.random.default_rng(cam_ss),
                                   within_xy=self.scene_xy_bounds)
        frame = render_frame(rs, cam, pl, np.random.default_rng(render_ss), config=self.render_config)
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
        rec = meta.ImageRecord(
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
            georeference=self.georeference,
        )
        return rec, frame.rgb

    def render(self, index: int) -> dict:
        """Render, annotate and write image ``index``; returns its summary counts."""
        _check_parent()
        rec, rgb = self.record(index)
        write_image_files(self.cfg, self.out, rec, rgb)
        return record_counts(rec)


# Engine-agnostic entry point -------------------------------------------------------------

_CACHE: dict = {}


def render_image(cfg: ExportConfig, out_dir, index: int) -> dict:
    """Render image ``index`` of the export ``cfg`` into ``out_dir`` (deterministic; the
    scene, catalog and current placement are cached per process). Returns its counts."""
    key = (cfg, str(out_dir))
    w = _CACHE.get(key)
    if w is None:
        _CACHE.clear()
        w = _CACHE[key] = ImageWorker(cfg, Path(out_dir))
    return w.render(int(index))


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
    """The image (once, hard-linked into every other format's folder), every format's
    per-image label file, then the metadata (the image's "done" mark), each atomically."""
    from ..formats import meta
    from ..formats.registry import get

    out = Path(out)
    paths = image_paths(cfg, out, record.index)
    data = encode_image(rgb, cfg.image_ext)
    _check_parent()
    atomic_write_bytes(paths[0], data)
    for p in paths[1:]:
        _check_parent()
        _link_or_copy(paths[0], p)
    for name in cfg.formats:
        fmt = get(name)
        rel = fmt.label_path(record.split, record.name)
        if rel is None:
            continue
        body = fmt.label_text(record)
        _check_parent()
        atomic_write_text(out / rel, body)
    _check_parent()
    meta.write(meta_path(out, record.index), record)


def record_counts(record) -> dict:
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


# --------------------------------------------------------------- pool glue

_POOL_WORKER: ImageWorker | None = None


def init_pool_worker(cfg: ExportConfig, out: str, nthreads: int, parent_pid: int,
                     extra_formats=()) -> None:
    """Pool initializer: watch the parent, share the cores, register run-time formats.
    Ctrl-C is the parent's to handle (it stops the pool): workers ignore SIGINT, so an
    interrupted export prints no worker tracebacks."""
    import signal

    global _POOL_WORKER
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _watch_parent(parent_pid)
    from ..formats.registry import names, register

    for fmt in extra_formats:  # formats registered at run time in the parent
        if fmt.name not in names():
            register(fmt)
    os.environ.setdefault("OMP_NUM_THREADS", str(max(1, nthreads)))
    import numba  # the shading kernels' threads: share the cores among the workers

    numba.set_num_threads(max(1, min(int(nthreads), numba.config.NUMBA_NUM_THREADS)))
    _POOL_WORKER = ImageWorker(cfg, Path(out), nthreads=nthreads)


def run_group(indices: list[int]) -> list[tuple[int, dict]]:
    """Pool task: the images of one placement group, in order."""
    assert _POOL_WORKER is not None
    out = []
    for i in indices:
        _check_parent()
        out.append((i, _POOL_WORKER.render(i)))
    return out
