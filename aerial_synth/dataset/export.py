"""Dataset export orchestration: validate, plan the output, run the image tasks, aggregate.

Folder layout (``OUT``)::

    manifest.json                 tool, version, every output-affecting parameter, status,
                                  the scene's georeference
    summary.json                  images, vehicles per class, difficult, dropped (+ reasons)
    meta/<name>.json              per-image metadata (written last: the image's "done" mark)
    <format>/...                  each requested format's images and labels, where the format
                                  registry (aerial_synth.formats.registry) says

Images are written once and hard-linked into the other formats' folders (copied where
links are not possible).

The pieces: :mod:`.config` (parameters), :mod:`.layout` (paths), :mod:`.manifest`,
:mod:`.worker` (one image: the engine-agnostic task), :mod:`.engines` (who runs the tasks:
serial, a process pool, Dask), :mod:`.aggregate` (per-dataset files), :mod:`.output` (the
``--out`` folder, the partial build and the final swap). This module only sequences them
and never looks at a format's or an engine's name.

Seeds: image ``i`` draws its camera and rendering from ``SeedSequence([seed, i])``;
placement group ``g = i // images_per_placement`` draws its placement from
``SeedSequence([seed, g, 1])`` on a fresh RayScene, so an image's bytes depend only on
(parameters, seed, i), never on worker count or order. Aggregate files are rebuilt from the
per-image metadata at the end, so ``--resume`` finishes a killed export byte-identical to an
uninterrupted one.
"""

from __future__ import annotations

import time
import warnings
from contextlib import closing
from pathlib import Path

from tqdm import tqdm

from .. import validators as v
from ..errors import ExportError
from ..io_utils import atomic_write_json
from ..placement import load_scenario
from ..render.budget import check_frame_memory
from ..safe_input import shown
from ..vehicles import load_catalog
from . import engines
from .aggregate import aggregate_pool, write_aggregates
from .config import IMAGE_EXTS, PLACEMENT_STREAM, SPLITS, ExportConfig, ExportResult
from .engines.fork_server import check_entry_point, pool_context, start_pool_server
from .layout import image_name, image_paths, is_done, label_paths, meta_path, split_of
from .manifest import MANIFEST_FORMAT, is_dataset, manifest, read_manifest
from .output import (
    discard_build,
    finish_output,
    output_lock,
    plan_output,
    prepare_build,
    remove_stray_temps,
)
from .plan import build_plan
from .scene_mix import check_names
from .scenes import scene_georeference
from .tiled import export_pads
from .worker import ImageWorker, encode_image, record_counts, render_image

__all__ = [
    "IMAGE_EXTS",
    "MANIFEST_FORMAT",
    "PLACEMENT_STREAM",
    "SPLITS",
    "ExportConfig",
    "ExportResult",
    "ImageWorker",
    "encode_image",
    "export_dataset",
    "image_name",
    "image_paths",
    "is_dataset",
    "is_done",
    "label_paths",
    "meta_path",
    "pool_context",
    "read_manifest",
    "record_counts",
    "render_image",
    "split_of",
    "start_pool_server",
    "validate_inputs",
    "write_aggregates",
]

def validate_inputs(cfg: ExportConfig):
    """Load and check everything that can only be checked by loading it (camera, scenario,
    catalog, scene) before anything is written. Returns (scene, catalog)."""
    plan = build_plan(cfg)
    if plan.scenes.kind == "mix":  # every entry's names; the first group's scene is loaded
        check_names(plan.scenes.mix, cfg.scenario)
        return plan.scenes.scene_for_group(0), load_catalog()
    load_scenario(cfg.scenario)
    catalog = load_catalog()
    scene = plan.scenes.scene_for_group(0)
    if plan.scenes.kind == "tiled":  # a capped render pad: said once, here
        cut = export_pads(scene, cfg.render.config(), cfg.camera_config(), catalog).warning
        if cut is not None:
            warnings.warn(cut, stacklevel=2)
    return scene, catalog


def export_dataset(
    cfg: ExportConfig,
    out_dir,
    workers: int | None = None,
    resume: bool = False,
    force: bool = False,
    progress: bool | None = None,
    dask: str | None = None,
    engine: str | None = None,
) -> ExportResult:
    """Export ``cfg.images`` images to ``out_dir``. Validates everything (parameters, output
    folder, scene, catalog, scenario, camera) before writing anything; builds a new dataset
    beside ``out_dir`` and moves it into place at the end (see :mod:`.output`).

    workers  : processes (forked from a fork server, spawned where there is none); output
               is byte-identical for any count (None or 1: this process)
    resume   : finish an interrupted export with the same parameters
    force    : replace an existing dataset (only once the new one is complete), or write
               into a folder that is not a dataset (keeping its files)
    progress : tqdm bar (None = only on a terminal)
    dask     : run on Dask instead: "tcp://HOST:PORT" or "local:K" (see .engines.dask)
    engine   : an engine by name (:mod:`.engines`); default chosen from workers and dask
    """
    t0 = time.perf_counter()
    check_entry_point()
    if workers is not None:
        workers = v.integer("--workers", workers, 1, error=ExportError)
    plan = plan_output(cfg, out_dir, resume, force)
    cfg.render.check()  # --backend warp without its extra, --device cuda without CUDA
    eng = engines.choose(workers, dask, engine)
    eng.check()  # a bad or unreachable --dask is reported before the slow checks
    _check_frame_memory(cfg, eng.local_processes)
    if not eng.warm_up() and aggregate_pool(cfg):
        start_pool_server()  # ready when the aggregate files are made, at the end
    eng.start()  # --dask local:K: the cluster starts while the scene loads
    try:
        scene, catalog = validate_inputs(cfg)
    except BaseException:
        eng.close()
        raise
    geo = scene_georeference(scene)

    # --- from here on, files are written (only into plan.build until the final swap), under
    # a lock on --out; the plan is made again under it (another export may have finished).
    with closing(eng), output_lock(out_dir):
        plan = plan_output(cfg, out_dir, resume, force)
        eng.connect()  # before any write: an unreachable scheduler writes nothing
        build = plan.build
        try:
            prepare_build(plan)
            if plan.mode == "resume":
                remove_stray_temps(build)
            atomic_write_json(build / "manifest.json", manifest(cfg, "incomplete", geo))
        except BaseException:
            discard_build(plan)  # a fresh build with nothing in it (a full disk): no trace
            raise

        todo = [i for i in range(cfg.images) if not (plan.mode == "resume" and is_done(cfg, build, i))]
        skipped = cfg.images - len(todo)
        bar = tqdm(total=cfg.images, initial=skipped, unit="img", desc="export",
                   disable=(None if progress is None else not progress), dynamic_ncols=True)
        done = 0
        try:
            eng.open(cfg, build, scene, catalog)
            # runs of images: a small export still uses every worker
            with closing(eng.run(eng.plan(todo))) as finished:
                for n in finished:  # images newly on disk
                    done += n
                    bar.update(n)
            summary = write_aggregates(cfg, build, geo)
            atomic_write_json(build / "manifest.json", manifest(cfg, "complete", geo))
        except Exception as exc:
            # pool and Dask workers report only at the end: look at the disk too
            if done == 0 and skipped == 0 and not any(is_done(cfg, build, i) for i in todo):
                discard_build(plan)  # nothing worth resuming: leave no trace
                raise
            if isinstance(exc, OSError) and build != Path(out_dir):  # a full disk, mostly
                where = f" ({shown(exc.filename)})" if exc.filename else ""
                raise ExportError(
                    f"--out {shown(out_dir)}: {exc.strerror or type(exc).__name__}{where}; the "
                    f"images made so far are kept in {shown(build)}: make room, then run the same "
                    "command with --resume to finish (or --force to start over)") from None
            raise
        finally:
            bar.close()
            eng.close()
        finish_output(plan)
        return ExportResult(Path(out_dir), summary, time.perf_counter() - t0, len(todo), skipped)


def _check_frame_memory(cfg: ExportConfig, processes: int | None) -> None:
    """Refuse images whose frames cannot fit in this machine's memory, one per local worker
    (``processes`` None: a cluster's workers run elsewhere, not checked here)."""
    if processes is None:
        return
    check_frame_memory(cfg.camera.width_px, cfg.camera.height_px, max(1, min(int(processes), int(cfg.images))),
                       error=ExportError)
