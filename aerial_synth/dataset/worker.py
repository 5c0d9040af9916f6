"""Render, annotate and write one image: the export's unit of work.

:func:`render_image` ``(cfg, out_dir, index)`` is engine-agnostic and deterministic: it
renders image ``index`` of the export described by ``cfg`` into ``out_dir`` and returns its
counts. The bytes it writes depend only on (cfg, index), never on which process runs it or
in which order, so any engine (:mod:`.engines`) can call it.

Seeds: image ``i`` draws its camera and rendering from ``SeedSequence([seed, i])`` (spawned
into a camera and a render stream); placement group ``g = i // images_per_placement`` draws
its placement from ``SeedSequence([seed, g, 1])`` on a fresh RayScene.

Pool workers watch their parent (:mod:`.parent`): a worker checks it between images and
before every file it writes, and an orphaned worker exits at once, quietly, without writing.
The engines that run workers are in :mod:`.engines`.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import queue
import threading
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from ..annotate.boxes import annotate_frame
from ..camera import sample_pose_targeted
from ..errors import ExportError, own_warnings
from ..formats import coco, meta
from ..formats.registry import get as get_format
from ..io_utils import atomic_write_bytes, atomic_write_text
from ..placement import place
from ..render import add_placement, render_frame
from ..render.cull import vehicles_for_views
from ..render.distractors import DISTRACTOR_KEY, add_distractors
from ..scene import load_scene
from ..scene.raycast import RayScene
from ..vehicles import load_catalog
from .config import PLACEMENT_STREAM, ExportConfig
from .gsd import image_camera_config
from .layout import image_name, image_paths, meta_path, split_of
from .parent import check_parent
from .scene_mix import parse_mix
from .tiled import GroupPlacer, group_placement, grow_rect, load_world

__all__ = [
    "ImageWorker",
    "render_image",
    "encode_image",
    "write_image_files",
    "record_counts",
]


# ------------------------------------------------------------------- worker


def _load_scene(cfg: ExportConfig):
    """The export's scene, with its distractors (drawn once per dataset, so every worker and
    engine builds the same scene). A tiled export (``cfg.tile_m``) gets its TiledWorld."""
    if getattr(cfg, "tile_m", None) is not None:
        return load_world(cfg)
    scene = load_scene(cfg.scene, labels=cfg.labels, seed=cfg.scene_seed, bbox=cfg.bbox,
                       crs=cfg.crs)
    if cfg.distractors:
        rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, DISTRACTOR_KEY]))
        scene, _ = add_distractors(scene, rng, per_hectare=cfg.distractors)
    return scene


_MIX_SCENES: dict = {}  # (scene, labels, scene_seed, seed, distractors) -> Scene, this process


def mix_scene(cfg: ExportConfig, name: str):
    """Scene ``name`` of a ``--scene-mix`` export, with the export's distractors, loaded
    once per process (a mix switches scenes between placement groups)."""
    import dataclasses

    key = (name, cfg.labels, cfg.scene_seed, cfg.seed, cfg.distractors)
    scene = _MIX_SCENES.get(key)
    if scene is None:
        scene = _MIX_SCENES[key] = _load_scene(dataclasses.replace(cfg, scene=name, scene_mix=None))
    return scene


class ImageWorker:
    """Per-process state: scene, catalog and the current placement group. Make one with
    :meth:`for_config`, which picks the tiled worker for a tiled export."""

    @staticmethod
    def for_config(cfg: ExportConfig, out, nthreads: int = 0, scene=None, catalog=None) -> "ImageWorker":
        """The worker for the export ``cfg``: a :class:`TiledImageWorker` when ``cfg.tile_m``
        is set, else an :class:`ImageWorker`."""
        cls = TiledImageWorker if getattr(cfg, "tile_m", None) is not None else ImageWorker
        return cls(cfg, out, nthreads=nthreads, scene=scene, catalog=catalog)

    def __init__(self, cfg: ExportConfig, out: Path, nthreads: int = 0, scene=None, catalog=None):
        self.cfg = cfg
        self.out = Path(out)
        self.nthreads = nthreads
        self._scene = scene
        self._catalog = catalog
        self._group = None
        self._rayscene = None
        self._placement = None
        self._cameras: dict = {}  # the current group's cameras not yet rendered
        self._sky = None  # the group's RayScene, for the cameras' open-sky test
        self._placement_warnings: list[str] = []
        self._writer: ImageWriter | None = None

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
        return self.cfg.render.config()

    @property
    def catalog(self):
        if self._catalog is None:
            self._catalog = load_catalog()
        return self._catalog

    def _ensure_group(self, group: int):
        if self._group == group:
            return
        scenario = self._use_scene(group)

        rs = RayScene(self.scene, nthreads=self.nthreads)  # fresh: independent of history
        rng = np.random.default_rng(np.random.SeedSequence([self.cfg.seed, group, PLACEMENT_STREAM]))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            pl = place(
                rs,
                scenario,
                rng,
                n_vehicles=self.cfg.n_vehicles,
                n_lines=self.cfg.n_lines,
                catalog=self.catalog,
                scene_name=self.scene.name,
            )
        if not pl.vehicles:
            raise ExportError(
                f"placement group {group}: scenario {scenario!r} placed no vehicles "
                f"on scene {self.scene.name if self._mix else self.cfg.scene!r} (no road found?)"
            )
        self._sky = rs
        self._cameras = self._group_cameras(group, pl)
        add_placement(rs, self._visible_part(rs, pl), self.catalog,
                      simple_boxes=self.cfg.simple_vehicles)
        self._placement_warnings = sorted(set(own_warnings(caught)))  # ours only
        self._group, self._rayscene, self._placement = group, rs, pl

    @functools.cached_property
    def _mix(self):
        """The export's SceneMix (None without ``--scene-mix``)."""
        return None if self.cfg.scene_mix is None else parse_mix(self.cfg.scene_mix)

    def _use_scene(self, group: int) -> str:
        """Make placement group ``group``'s scene current and return its scenario: the
        export's own without a mix, else the group's drawn entry's (scenes are loaded once
        per process and kept, :func:`mix_scene`)."""
        mix = self._mix
        if mix is None:
            return self.cfg.scenario
        k = mix.index_for_group(self.cfg.seed, group)
        entry = mix.entries[k]
        scene = mix_scene(self.cfg, entry.scene)
        if scene is not self._scene:
            self._scene = scene
            self.__dict__.pop("scene_xy_bounds", None)
            self.__dict__.pop("georeference", None)
        self._mix_entry = {"entry": k, "scene": entry.scene,
                           "scenario": mix.scenario_of(entry, self.cfg.scenario)}
        return self._mix_entry["scenario"]

    def _group_cameras(self, group: int, pl) -> dict:
        """{index: Camera} of every image of placement group ``group`` (all of them, not
        only this task's: the group's RayScene must not depend on how its images are split
        into tasks)."""
        first = group * self.cfg.images_per_placement
        last = min(first + self.cfg.images_per_placement, self.cfg.images)
        return {i: self._draw_camera(i, pl) for i in range(first, last)}

    def _draw_camera(self, index: int, pl):
        """Image ``index``'s camera: the first of ``SeedSequence([seed, index])``'s two
        streams (the second draws its rendering)."""
        cam_ss, _ = np.random.SeedSequence([self.cfg.seed, index]).spawn(2)
        cam_cfg = image_camera_config(self.cfg, index, self.scene_xy_bounds)
        return sample_pose_targeted(cam_cfg, pl, np.random.default_rng(cam_ss),
                                    within_xy=self.scene_xy_bounds, clear=self._open_sky)

    def _open_sky(self, cam) -> bool:
        """Whether nothing solid is above ``cam`` in the group's scene
        (:meth:`~aerial_synth.scene.raycast.RayScene.open_above`): a camera inside or under a
        building would render the building's inside, so it is redrawn. Never cast for the
        bundled scenes at the default 60 m, whose poses are those of a sampler without it."""
        return self._sky is None or self._sky.open_above(cam.center)

    def _visible_part(self, rs, pl):
        """``pl`` with only the vehicles some camera of the group (``self._cameras``) can
        see in ``rs``'s scene, directly, in a shadow or a reflection
        (:func:`aerial_synth.render.cull.vehicles_for_views`): the group's Embree scenes
        and meshes are built for those only."""
        kept = vehicles_for_views(pl.vehicles, self._cameras.values(), self.render_config,
                                  z_low=float(rs.scene.bounds()[0, 2]))
        return pl if len(kept) == len(pl.vehicles) else dataclasses.replace(pl, vehicles=kept)

    def record(self, index: int):
        """Render and annotate image ``index``: (ImageRecord, RGB (H, W, 3) uint8)."""
        cfg = self.cfg
        group = index // cfg.images_per_placement
        self._ensure_group(group)
        pl, rs = self._placement, self._rayscene
        _, render_ss = np.random.SeedSequence([cfg.seed, index]).spawn(2)
        cam = self._cameras.pop(index, None)  # drawn with the group (see _ensure_group)
        if cam is None:
            cam = self._draw_camera(index, pl)
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
                # scenes with hard negatives (procedural/negatives.py) count them here
                **({"hard_negatives": rs.scene.meta["hard_negatives"]}
                   if "hard_negatives" in rs.scene.meta else {}),
                **({"scene_mix": dict(self._mix_entry)} if self._mix else {}),
            },
            box_config=cfg.box.to_dict(),
            annotations=tuple(anns),
            world={a.vehicle_id: by_id[a.vehicle_id].to_dict() for a in anns},
            segmentations=segs,
            georeference=self.georeference,
        )
        return rec, frame.rgb

    def render(self, index: int, wait: bool = True) -> dict:
        """Render and annotate image ``index``, and write its files; returns its summary
        counts. The files are encoded and written by this worker's writer thread while the
        next image renders; with ``wait`` (the default) this returns only once they are on
        disk (or raises the writer's error). With ``wait=False`` call :meth:`drain` before
        reporting the image as finished."""
        check_parent()
        self._writer_error()  # a failed write stops the run before more rendering
        rec, rgb = self.record(index)
        self.writer.submit(self.cfg, self.out, rec, rgb)
        if wait:
            self.drain()
        return record_counts(rec)

    @property
    def writer(self) -> "ImageWriter":
        if self._writer is None:
            self._writer = ImageWriter()
        return self._writer

    def _writer_error(self) -> None:
        if self._writer is not None:
            self._writer.raise_error()

    @property
    def written(self) -> int:
        """Images whose files are on disk (written by this worker so far)."""
        return 0 if self._writer is None else self._writer.written

    def drain(self) -> None:
        """Wait until every submitted image's files are on disk; raise the first write error
        (the image that failed has no metadata file, so it is not done)."""
        if self._writer is not None:
            self._writer.drain()

    def render_run(self, indices, progress=None) -> list[tuple[int, dict]]:
        """Render a run of images in order, writing in the background; returns once all
        their files are on disk: [(index, counts)]. ``progress(n)`` is called in this
        thread with the number of images newly on disk."""
        out: list[tuple[int, dict]] = []
        for n in self.iter_run(indices, out):
            if progress is not None:
                progress(n)
        return out

    def iter_run(self, indices, out: list | None = None) -> Iterator[int]:
        """:meth:`render_run` as a generator: yields the number of images newly on disk as
        they land (the last once all are); appends (index, counts) to ``out``."""
        out = [] if out is None else out
        seen = self.written
        try:
            for i in indices:
                check_parent()
                out.append((int(i), self.render(int(i), wait=False)))
                if self.written != seen:
                    n, seen = self.written - seen, self.written
                    yield n
        except BaseException as exc:
            if self._writer is not None:  # nothing keeps writing after a failure
                try:
                    self._writer.drain()
                except BaseException as werr:  # both failed: report both
                    if exc.__context__ is None:
                        exc.__context__ = werr
            raise
        self.drain()
        if self.written != seen:
            yield self.written - seen

    def close(self) -> None:
        """Drain and stop the writer thread."""
        if self._writer is not None:
            w, self._writer = self._writer, None
            w.close()


class TiledImageWorker(ImageWorker):
    """An :class:`~aerial_synth.dataset.worker.ImageWorker` for ``cfg.tile_m``: its ``scene``
    is the :class:`~aerial_synth.scene.tiles.TiledWorld`; a group places and builds only the
    tiles it needs (see the module's text)."""

    _placer = None
    _within = None
    _window_cache = None  # (render window rect, Scene): the last group's window

    @property
    def grid(self):
        g = self.__dict__.get("_grid")
        if g is None:
            g = self.__dict__["_grid"] = self.scene.grid(self.cfg.tile_m, self.cfg.margin_m)
        return g

    @property
    def scene_xy_bounds(self) -> np.ndarray:
        """Where the current group's camera footprints must lie."""
        x0, y0, x1, y1 = self._within
        return np.array([[x0, y0], [x1, y1]])

    @property
    def georeference(self) -> dict:
        return self.scene.georeference()

    def _ensure_group(self, group: int):
        if self._group == group:
            return
        world, grid = self.scene, self.grid
        if self._placer is None:
            self._placer = GroupPlacer(world, grid, self.cfg, self.catalog)
        tile, within, area, pl, warned = group_placement(world, grid, self.cfg, group, self.catalog,
                                                         self._placer)
        if not pl.vehicles:
            raise ExportError(f"placement group {group}: scenario {self.cfg.scenario!r} placed no "
                              f"vehicles near tile {list(tile.key)} of scene {self.cfg.scene!r}")
        rect = grow_rect(within, self._placer.pads.render_m, grid.bounds)
        if self._window_cache is not None and self._window_cache[0] == rect:
            scene = self._window_cache[1]
        else:
            self._window_cache = None  # drop the old window before building the next
            scene = world.scene_for(rect)
            self._window_cache = (rect, scene)
        rs = RayScene(scene, nthreads=self.nthreads)  # fresh: independent of history
        self._within = within  # the cameras' bounds (scene_xy_bounds)
        self._sky = rs
        self._cameras = self._group_cameras(group, pl)
        add_placement(rs, self._visible_part(rs, pl), self.catalog,
                      simple_boxes=self.cfg.simple_vehicles)
        self._placement_warnings = warned
        self._group, self._rayscene, self._placement = group, rs, pl


# Engine-agnostic entry point -------------------------------------------------------------

_CACHE: dict = {}


def render_image(cfg: ExportConfig, out_dir, index: int) -> dict:
    """Render image ``index`` of the export ``cfg`` into ``out_dir`` (deterministic; the
    scene, catalog and current placement are cached per process). Returns its counts."""
    key = (cfg, str(out_dir))
    w = _CACHE.get(key)
    if w is None:
        for old in _CACHE.values():
            old.close()
        _CACHE.clear()
        w = _CACHE[key] = ImageWorker.for_config(cfg, Path(out_dir))
    return w.render(int(index))  # waits: the files are on disk when this returns


# ------------------------------------------------------------------ writing


class ImageWriter:
    """One background thread that encodes and writes images, one at a time, in the order
    they were submitted (PNG/JPEG encoding and file writes release the GIL, so the next
    frame renders meanwhile).

    At most ``depth`` images wait in the queue (``submit`` blocks beyond that), so memory
    stays bounded. The first error raised while writing is kept and raised in the
    submitting thread by the next :meth:`submit`, :meth:`drain` or :meth:`raise_error`;
    images queued after a failure are not written (until the next :meth:`drain`). Every write is atomic and the
    metadata is written last (see :func:`write_image_files`), so an image whose write
    failed or was cut short is simply not done."""

    def __init__(self, depth: int = 1):
        self._q: queue.Queue = queue.Queue(maxsize=max(1, int(depth)))
        self._error: BaseException | None = None  # to raise in the submitting thread
        self._failed = False  # a write failed: skip the queued images until drained
        self.written = 0
        self._thread = threading.Thread(target=self._loop, name="aerial-synth-writer", daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        while True:
            job = self._q.get()
            if job is None:
                self._q.task_done()
                return
            try:
                if not self._failed:
                    cfg, out, rec, rgb = job
                    _write_files(cfg, out, rec, encode_image(rgb, cfg.image_ext))
                    self.written += 1
            except BaseException as exc:  # kept for the submitting thread
                self._failed = True
                if self._error is None:
                    self._error = exc
            finally:
                self._q.task_done()

    def raise_error(self) -> None:
        """Raise the first write error, once (the writer writes again after a drain)."""
        if self._error is not None:
            err, self._error = self._error, None
            raise err

    def submit(self, cfg: ExportConfig, out: Path, record, rgb: np.ndarray) -> None:
        """Queue one image (its RGB pixels, which the caller no longer changes)."""
        self.raise_error()
        if not self._thread.is_alive():
            raise ExportError("the image writer thread has stopped")
        # The queue counts the image as unfinished in the same step that queues it: a put
        # cut short (SIGTERM's SystemExit or Ctrl-C while the queue is full) counts nothing,
        # where a count of our own, raised before the put, stayed up and drain() waited
        # forever (an interrupted export hung).
        self._q.put((cfg, Path(out), record, rgb))

    def drain(self, raise_error: bool = True) -> None:
        """Wait until every submitted image is written (or failed)."""
        done = self._q.all_tasks_done  # queue.Queue's condition for its unfinished_tasks
        with done:
            while self._q.unfinished_tasks > 0 and self._thread.is_alive():
                done.wait(0.5)
            if self._q.unfinished_tasks == 0:
                self._failed = False  # the images after a failure were all skipped
        if raise_error:
            self.raise_error()

    def close(self) -> None:
        try:
            self.drain()
        finally:
            self._q.put(None)
            self._thread.join()


def encode_image(rgb: np.ndarray, ext: str) -> bytes:
    """(H, W, 3) uint8 RGB -> PNG (:func:`aerial_synth.png.encode_png`, lossless) or JPEG
    (OpenCV, quality 95) bytes."""
    a = np.ascontiguousarray(rgb, dtype=np.uint8)
    if ext == "png":
        from ..png import encode_png  # lazy: numba kernels cached on disk (checked --out first)

        return encode_png(a)
    import cv2  # lazy: OpenCV only for JPEG (start-up time)

    ok, buf = cv2.imencode(".jpg", cv2.cvtColor(a, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 95])
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
        atomic_write_bytes(dst, src.read_bytes())  # guard: an image file of its own build


def write_image_files(cfg: ExportConfig, out: Path, record, rgb: np.ndarray) -> None:
    """The image (once, hard-linked into every other format's folder), every format's
    per-image label file, then the metadata (the image's "done" mark), each atomically."""
    _write_files(cfg, out, record, encode_image(rgb, cfg.image_ext))


def _write_files(cfg: ExportConfig, out: Path, record, data: bytes) -> None:
    out = Path(out)
    paths = image_paths(cfg, out, record.index)
    check_parent()
    atomic_write_bytes(paths[0], data)
    for p in paths[1:]:
        check_parent()
        _link_or_copy(paths[0], p)
    for name in cfg.formats:
        fmt = get_format(name)
        rel = fmt.label_path(record.split, record.name)
        if rel is None:
            continue
        body = fmt.label_text(record)
        check_parent()
        atomic_write_text(out / rel, body)
    check_parent()
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
