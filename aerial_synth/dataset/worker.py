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
from .gsd import image_camera_config
from .layout import image_name, image_paths, meta_path, split_of
from .scene_mix import parse_mix

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

_PARENT_PID: int | None = None  # this process's parent when the watch started
_EXPORTER_PID: int | None = None  # the exporting process (the parent, or its fork server's parent)


def _watch_parent(parent_pid: int) -> None:
    """Die with the exporter ``parent_pid``: PR_SET_PDEATHSIG on Linux, and
    :func:`_check_parent` everywhere. A worker forked by the pool's fork server has that
    server as its parent; the server exits when the exporter does, so the death signal
    still follows the exporter, and :func:`_check_parent` also asks after the exporter.

    A worker's results go back through a pipe that only the exporter reads: a worker that
    finishes a task in the milliseconds between the exporter's death and its own (the kill
    chain runs through the fork server) would get a BrokenPipeError and print its traceback
    on the user's terminal. SIGPIPE's default action is restored instead (Python ignores it),
    so that write ends the worker silently, as the death signal would a moment later."""
    import signal

    global _PARENT_PID, _EXPORTER_PID
    if hasattr(signal, "SIGPIPE"):
        signal.signal(signal.SIGPIPE, signal.SIG_DFL)
    _EXPORTER_PID = int(parent_pid)
    _PARENT_PID = os.getppid()
    if _PARENT_PID != _EXPORTER_PID and not _alive(_EXPORTER_PID):
        os._exit(0)
    if hasattr(os, "sched_getaffinity"):  # Linux
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            PR_SET_PDEATHSIG = 1
            libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):  # no prctl: the pid checks still apply
            pass
    _check_parent()  # the parent may have died before prctl took effect


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # exists, but not ours to signal
        return True
    return True


def _check_parent() -> None:
    """Exit at once, quietly and without writing, when this worker's parent is gone (or,
    for a worker of the fork server, the exporter)."""
    if _PARENT_PID is None:
        return
    if os.getppid() != _PARENT_PID or (_EXPORTER_PID != _PARENT_PID and not _alive(_EXPORTER_PID)):
        os._exit(0)


# ------------------------------------------------------------------- worker


def _load_scene(cfg: ExportConfig):
    """The export's scene, with its distractors (drawn once per dataset, so every worker and
    engine builds the same scene). A tiled export (``cfg.tile_m``) gets its TiledWorld."""
    if getattr(cfg, "tile_m", None) is not None:
        from .tiled import load_world

        return load_world(cfg)
    from ..scene import load_scene

    scene = load_scene(cfg.scene, labels=cfg.labels, seed=cfg.scene_seed, bbox=cfg.bbox,
                       crs=cfg.crs)
    if cfg.distractors:
        from ..render.distractors import DISTRACTOR_KEY, add_distractors

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
    """Per-process state: scene, catalog and the current placement group."""

    def __new__(cls, cfg=None, *args, **kwargs):
        """A tiled export (``cfg.tile_m``) gets a :class:`TiledImageWorker`."""
        if cls is ImageWorker and getattr(cfg, "tile_m", None) is not None:
            cls = TiledImageWorker
        return super().__new__(cls)

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
        # our own warnings only (PlacementWarning, SceneWarning): a library's one-time import
        # warning (open3d's "built with CUDA support, but no suitable CUDA devices") reaches
        # only the first placement of a process, and would make the meta depend on which
        # worker placed which group
        self._placement_warnings = sorted({str(w.message) for w in caught
                                           if w.category.__module__.startswith("aerial_synth.")})
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
        from ..camera import sample_pose_targeted

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
        import dataclasses

        from ..render.cull import vehicles_for_views

        kept = vehicles_for_views(pl.vehicles, self._cameras.values(), self.render_config,
                                  z_low=float(rs.scene.bounds()[0, 2]))
        return pl if len(kept) == len(pl.vehicles) else dataclasses.replace(pl, vehicles=kept)

    def record(self, index: int):
        """Render and annotate image ``index``: (ImageRecord, RGB (H, W, 3) uint8)."""
        from ..annotate.boxes import annotate_frame
        from ..formats import coco, meta
        from ..render import render_frame

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
        _check_parent()
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
        out, seen = [], self.written
        try:
            for i in indices:
                _check_parent()
                out.append((int(i), self.render(int(i), wait=False)))
                if progress is not None and self.written != seen:
                    progress(self.written - seen)
                    seen = self.written
        except BaseException as exc:
            if self._writer is not None:  # nothing keeps writing after a failure
                try:
                    self._writer.drain()
                except BaseException as werr:  # both failed: report both
                    if exc.__context__ is None:
                        exc.__context__ = werr
            raise
        self.drain()
        if progress is not None and self.written != seen:
            progress(self.written - seen)
        return out

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
        from ..render import add_placement
        from ..scene.raycast import RayScene
        from .tiled import _GroupPlacer, _grow, group_placement

        world, grid = self.scene, self.grid
        if self._placer is None:
            self._placer = _GroupPlacer(world, grid, self.cfg, self.catalog)
        tile, within, area, pl, warned = group_placement(world, grid, self.cfg, group, self.catalog,
                                                         self._placer)
        if not pl.vehicles:
            raise ExportError(f"placement group {group}: scenario {self.cfg.scenario!r} placed no "
                              f"vehicles near tile {list(tile.key)} of scene {self.cfg.scene!r}")
        rect = _grow(within, self._placer.pads.render_m, grid.bounds)
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
        w = _CACHE[key] = ImageWorker(cfg, Path(out_dir))
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
        import queue
        import threading

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
        from ..png import encode_png

        return encode_png(a)
    import cv2

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
        atomic_write_bytes(dst, src.read_bytes())


def write_image_files(cfg: ExportConfig, out: Path, record, rgb: np.ndarray) -> None:
    """The image (once, hard-linked into every other format's folder), every format's
    per-image label file, then the metadata (the image's "done" mark), each atomically."""
    _write_files(cfg, out, record, encode_image(rgb, cfg.image_ext))


def _write_files(cfg: ExportConfig, out: Path, record, data: bytes) -> None:
    from ..formats import meta
    from ..formats.registry import get

    out = Path(out)
    paths = image_paths(cfg, out, record.index)
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
_STOPPING = False  # SIGTERM came: no further task starts
_SIGTERM_EXIT = 128 + 15  # the shell's status of a process ended by SIGTERM (15 on every POSIX)


def _exit_on_sigterm(signum, frame):
    global _STOPPING
    _STOPPING = True
    raise SystemExit(128 + signum)


def init_pool_worker(cfg: ExportConfig, out: str, nthreads: int, parent_pid: int,
                     extra_formats=(), slots=None, pool_size: int = 0, scene=None, catalog=None) -> None:
    """Pool initializer: watch the parent, share the cores, register run-time formats.

    Cores: the ``pool_size`` workers of the pool take the slots 0, 1, ... of the shared
    counter ``slots`` (a ``multiprocessing.Value``) in start order, and worker ``k`` pins
    itself to its share of the cores (:func:`.affinity.pin_share`) before open3d or numba
    start a thread; its numba/OpenMP threads follow the share. Without a counter (or where
    pinning is refused) it only sets ``nthreads`` threads.

    ``scene``/``catalog``: the parent's (already loaded and validated) objects, pickled
    to the worker in a few milliseconds instead of loading the scene again (seconds).

    Ctrl-C is the parent's to handle (it stops the pool): workers ignore SIGINT, so an
    interrupted export prints no worker tracebacks. The pool then stops its workers with
    SIGTERM, which a worker turns into a normal exit: its exit handlers release what it
    registered with multiprocessing's resource tracker (numba's lock of its threading
    layer), which would otherwise report leaked semaphores after "interrupted". A
    ``ProcessPoolExecutor`` worker catches the SystemExit of its task and reads the next
    one from its queue: :func:`run_group` then ends at once, so the few tasks queued
    ahead do not run after Ctrl-C."""
    import signal

    from .affinity import limit_threads, pin_share

    global _POOL_WORKER
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _exit_on_sigterm)
    _watch_parent(parent_pid)
    share = None
    if slots is not None and int(pool_size) > 1:
        with slots.get_lock():
            k = slots.value
            slots.value += 1
        share = pin_share(k % int(pool_size), int(pool_size))
    if share is None:
        limit_threads(nthreads)
    else:
        nthreads = len(share)
    from ..formats.registry import names, register

    for fmt in extra_formats:  # formats registered at run time in the parent
        if fmt.name not in names():
            register(fmt)
    _POOL_WORKER = ImageWorker(cfg, Path(out), nthreads=nthreads, scene=scene, catalog=catalog)


def run_group(indices: list[int]) -> list[tuple[int, dict]]:
    """Pool task: the images of one run of a placement group, in order; returns once every
    one of their files is on disk."""
    assert _POOL_WORKER is not None
    if _STOPPING:
        raise SystemExit(_SIGTERM_EXIT)
    return _POOL_WORKER.render_run(indices)
