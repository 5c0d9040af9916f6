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
:mod:`.worker` (one image: the engine-agnostic task), :mod:`.aggregate` (per-dataset files),
:mod:`.output` (the ``--out`` folder, the partial build and the final swap). This module
only sequences them and never looks at a format's name.

Seeds: image ``i`` draws its camera and rendering from ``SeedSequence([seed, i])``;
placement group ``g = i // images_per_placement`` draws its placement from
``SeedSequence([seed, g, 1])`` on a fresh RayScene, so an image's bytes depend only on
(parameters, seed, i), never on worker count or order. Aggregate files are rebuilt from the
per-image metadata at the end, so ``--resume`` finishes a killed export byte-identical to an
uninterrupted one.
"""

from __future__ import annotations

import os
import time
import warnings
from pathlib import Path

from .. import validators as v
from ..errors import ExportError
from ..io_utils import atomic_write_json
from .aggregate import aggregate_pool, write_aggregates
from .config import IMAGE_EXTS, PLACEMENT_STREAM, SPLITS, ExportConfig, ExportResult
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
from .pool import _WORKER_MODULES, check_entry_point, pool_context, start_pool_server  # noqa: F401 (re-exported)
from .scene_mix import check_names, parse_mix
from .worker import (
    ImageWorker,
    encode_image,
    init_pool_worker,
    mix_scene,
    record_counts,
    render_image,
    run_group,
)

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
    "read_manifest",
    "record_counts",
    "render_image",
    "split_of",
    "validate_inputs",
    "write_aggregates",
]

# Backward-compatible name (tests and tools re-render through it).
_Worker = ImageWorker


def validate_inputs(cfg: ExportConfig):
    """Load and check everything that can only be checked by loading it (camera, scenario,
    catalog, scene) before anything is written. Returns (scene, catalog)."""
    cfg.camera_config()
    from ..placement import load_scenario
    from ..vehicles import load_catalog

    if cfg.scene_mix is not None:  # every entry's names; the first group's scene is loaded
        mix = parse_mix(cfg.scene_mix)
        check_names(mix, cfg.scenario)
        catalog = load_catalog()
        scene = mix_scene(cfg, mix.entries[mix.index_for_group(cfg.seed, 0)].scene)
        return scene, catalog
    load_scenario(cfg.scenario)
    catalog = load_catalog()
    scene = ImageWorker(cfg, Path(".")).scene
    if getattr(cfg, "tile_m", None) is not None:  # a capped render pad: said once, here
        from .tiled import export_pads

        cut = export_pads(scene, cfg.render_config(), cfg.camera_config(), catalog).warning
        if cut is not None:
            warnings.warn(cut, stacklevel=2)
    return scene, catalog


def _georeference(scene) -> dict:
    geo = getattr(scene, "georeference", None)
    return geo() if callable(geo) else {"origin": [0.0, 0.0, 0.0], "crs": None}


def export_dataset(
    cfg: ExportConfig,
    out_dir,
    workers: int = 1,
    resume: bool = False,
    force: bool = False,
    progress: bool | None = None,
    dask: str | None = None,
) -> ExportResult:
    """Export ``cfg.images`` images to ``out_dir``. Validates everything (parameters, output
    folder, scene, catalog, scenario, camera) before writing anything; builds a new dataset
    beside ``out_dir`` and moves it into place at the end (see :mod:`.output`).

    workers  : processes (forked from a fork server, spawned where there is none); output
               is byte-identical for any count
    resume   : finish an interrupted export with the same parameters
    force    : replace an existing dataset (only once the new one is complete), or write
               into a folder that is not a dataset (keeping its files)
    progress : tqdm bar (None = only on a terminal)
    dask     : run on Dask instead: "tcp://HOST:PORT" or "local:K" (see .engine_dask)
    """
    t0 = time.perf_counter()
    check_entry_point()
    workers = v.integer("--workers", workers, 1, error=ExportError)
    plan = plan_output(cfg, out_dir, resume, force)
    _check_dask(dask, workers)  # a bad or unreachable --dask is reported before the slow checks
    _check_frame_memory(cfg, dask, workers)
    if dask is None and workers > 1:
        start_pool_server()  # imports the workers' modules while the scene loads here
    elif dask is not None and str(dask).strip().startswith("local:"):
        start_pool_server(dask=True)  # the LocalCluster's workers fork from it too
    elif aggregate_pool(cfg):
        start_pool_server()  # ready when the aggregate files are made, at the end
    starting = _start_dask(dask)  # --dask local:K: the cluster starts while the scene loads
    try:
        scene, catalog = validate_inputs(cfg)
    except BaseException:
        starting.close()
        raise
    geo = _georeference(scene)

    # --- from here on, files are written (only into plan.build until the final swap), under
    # a lock on --out; the plan is made again under it (another export may have finished).
    with starting, output_lock(out_dir):  # (closes a cluster not handed over to the engine)
        plan = plan_output(cfg, out_dir, resume, force)
        engine = _dask_engine(dask, workers, starting)  # before any write: an unreachable scheduler writes nothing
        try:
            prepare_build(plan)
        except BaseException:
            if engine is not None:
                engine.close()
            raise
        build = plan.build
        if plan.mode == "resume":
            remove_stray_temps(build)
        atomic_write_json(build / "manifest.json", manifest(cfg, "incomplete", geo))

        todo = [i for i in range(cfg.images) if not (plan.mode == "resume" and is_done(cfg, build, i))]
        skipped = cfg.images - len(todo)
        # runs of images: a small export still uses every worker
        from .engine_dask import plan_tasks

        tasks = plan_tasks(todo, cfg.images_per_placement, workers)

        from tqdm import tqdm

        bar = tqdm(total=cfg.images, initial=skipped, unit="img", desc="export",
                   disable=(None if progress is None else not progress), dynamic_ncols=True)
        done = 0
        try:
            if engine is not None:
                done += engine.run(cfg, build, todo, bar, *_shareable(cfg, scene, catalog))
            elif workers == 1 or len(tasks) <= 1:
                w = ImageWorker(cfg, build, nthreads=0, scene=scene, catalog=catalog)

                def step(n):
                    nonlocal done
                    done += n
                    bar.update(n)

                try:
                    for task in tasks:  # images encode and write while the next renders
                        w.render_run(task, progress=step)
                finally:
                    w.close()
            else:
                done += _run_pool(cfg, build, tasks, workers, bar, scene, catalog)
            summary = write_aggregates(cfg, build, geo)
            atomic_write_json(build / "manifest.json", manifest(cfg, "complete", geo))
        except Exception:
            # pool and Dask workers report only at the end: look at the disk too
            if done == 0 and skipped == 0 and not any(is_done(cfg, build, i) for i in todo):
                discard_build(plan)  # nothing worth resuming: leave no trace
            raise
        finally:
            bar.close()
            if engine is not None:
                engine.close()
        finish_output(plan)
        return ExportResult(Path(out_dir), summary, time.perf_counter() - t0, len(todo), skipped)


def _check_dask(dask, workers):
    if dask is None:
        return
    if workers != 1:
        raise ExportError(f"--dask and --workers: choose one engine (Dask workers are the cluster's), got --workers {workers}")
    from .engine_dask import probe_scheduler

    probe_scheduler(dask)


def _check_frame_memory(cfg: ExportConfig, dask, workers: int) -> None:
    """Refuse images whose frames cannot fit in this machine's memory, one per local worker
    (a ``tcp://`` cluster's workers run elsewhere: not checked here)."""
    from ..render.budget import check_frame_memory

    processes = int(workers)
    if dask is not None:
        from .engine_dask import parse_dask_address

        kind, arg = parse_dask_address(dask)
        if kind != "local":
            return
        processes = int(arg)
    check_frame_memory(cfg.width_px, cfg.height_px, max(1, min(processes, int(cfg.images))),
                       error=ExportError)


def _start_dask(dask):
    """``--dask local:K``: the LocalCluster starting in the background; else nothing starts
    (see :class:`.engine_dask.LocalStart`)."""
    from .engine_dask import LocalStart

    return LocalStart(dask)


def _dask_engine(dask, workers, starting=None):
    if dask is None:
        return None
    from .engine_dask import DaskEngine

    engine = starting.engine() if starting is not None else None
    return engine if engine is not None else DaskEngine.connect(dask)


#: How often the local pool is started again after one of its workers died (killed by the
#: OOM killer, say) before the export gives up, as Dask gives up on a task after 3 deaths.
MAX_POOL_RESTARTS = 3


def _run_pool(cfg: ExportConfig, build: Path, tasks, workers: int, bar, scene=None, catalog=None) -> int:
    """Run the placement-group tasks on a process pool (:func:`pool_context`); returns
    images finished.

    Worker k of the pool pins itself to the k-th share of the cores (see
    :func:`.worker.init_pool_worker`). An untiled export hands its loaded scene and
    catalog to the workers (pickled: milliseconds, against seconds to load the scene
    again in every worker); a tiled one lets each worker build its own tiles.

    A worker that dies (SIGKILL from the OOM killer, a crash) breaks the pool: the tasks
    not yet returned are run again on a new pool, less the images already on disk (an
    image's bytes do not depend on who renders it), up to :data:`MAX_POOL_RESTARTS` times;
    then one ExportError. (``multiprocessing.Pool``, used before, waited forever for the
    task of a killed worker.)"""
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    from ..formats.registry import BUILTIN, get

    extra = [get(n) for n in cfg.formats if n not in BUILTIN]  # run-time formats travel along
    from .affinity import allowed_cores

    ctx = pool_context()
    shared = _shareable(cfg, scene, catalog)
    remaining = [list(t) for t in tasks]
    done = 0
    restarts = 0
    while remaining:
        size = min(int(workers), len(remaining))
        nthreads = max(1, len(allowed_cores()) // size)
        slots = ctx.Value("i", 0)  # worker k of the pool takes the k-th share of the cores
        pool = ProcessPoolExecutor(size, mp_context=ctx, initializer=init_pool_worker,
                                   initargs=(cfg, str(build), nthreads, os.getpid(), extra, slots, size,
                                             *shared))
        broken = None
        pending = {}
        try:
            try:
                for t in remaining:  # (the pool starts its processes here)
                    pending[pool.submit(run_group, t)] = t
            except BrokenProcessPool as exc:  # a worker died while the tasks were handed out
                broken = exc
            except (BrokenPipeError, EOFError) as exc:  # a child died while it was starting
                raise _not_started(workers, f" ({type(exc).__name__})") from None
            while pending:
                finished, _ = wait(pending, return_when=FIRST_COMPLETED)
                for fut in finished:
                    t = pending.pop(fut)
                    try:
                        res = fut.result()
                    except BrokenProcessPool as exc:
                        broken = exc
                        continue
                    remaining.remove(t)
                    done += len(res)
                    bar.update(len(res))
                if broken is not None:
                    break
        except BaseException:
            _stop_pool(pool)  # Ctrl-C, an error in a task: the workers stop now
            raise
        if broken is None:
            pool.shutdown(wait=True)  # workers exit normally (their exit handlers run)
            break
        codes = _stop_pool(pool)
        from ._server_guard import ENTRY_POINT_EXIT

        if ENTRY_POINT_EXIT in codes:  # a worker ran an unguarded script again and stopped
            raise _not_started(workers)
        restarts += 1
        remove_stray_temps(build)  # the dead worker's temporaries
        before = sum(len(t) for t in remaining)
        remaining = [r for r in ([i for i in t if not is_done(cfg, build, i)] for t in remaining) if r]
        written = before - sum(len(t) for t in remaining)  # finished before the pool broke
        done += written
        bar.update(written)
        how = _death(codes)
        if restarts > MAX_POOL_RESTARTS:
            from ..render.budget import frame_gb

            raise ExportError(
                f"--workers {workers}: a worker process died {restarts} times ({how}; out of memory? one "
                f"{cfg.width_px} x {cfg.height_px} px frame needs about {frame_gb(cfg.width_px, cfg.height_px):.1f} GB per "
                "worker); the images done are kept: rerun with --resume, with fewer workers or smaller "
                "images"
            )
        if remaining:
            warnings.warn(f"a worker process died ({how}); its pool's {sum(len(t) for t in remaining)} "
                          f"unfinished images (the first: image {remaining[0][0]}) are rendered again on a "
                          f"new pool (restart {restarts} of at most {MAX_POOL_RESTARTS})", RuntimeWarning,
                          stacklevel=2)
    return done


def _not_started(workers, why: str = "") -> ExportError:
    return ExportError(f"--workers {workers}: the worker processes did not start{why}; a script that "
                       "exports must guard its entry point with if __name__ == '__main__'")


def _stop_pool(pool) -> list:
    """Stop a ProcessPoolExecutor's workers now: cancel what has not started, terminate the
    workers (SIGTERM: they exit normally, see :func:`.worker.init_pool_worker`), reap them;
    returns their exit codes (None: unknown). Python 3.14 has ``terminate_workers()``;
    before it the processes are only in the executor's ``_processes`` (which ``shutdown``
    drops, and which a broken pool keeps: the first death's code is there, the others
    were terminated by the pool). Exit codes are read only once the pool's manager thread
    has ended: a fork-server process's code can be read once, and a second reader at the
    same time gets 255."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    for p in procs:
        try:
            p.terminate()  # sends SIGTERM unless the code is known (does not read it)
        except (OSError, AttributeError, ValueError):
            pass
    pool.shutdown(wait=True, cancel_futures=True)
    codes = []
    for p in procs:
        try:
            p.join(timeout=5)
            codes.append(p.exitcode)
        except (OSError, AttributeError, ValueError, AssertionError):
            codes.append(None)
    return codes


def _death(codes) -> str:
    """How the first dead worker of a broken pool ended, in words."""
    import signal

    for c in codes:
        if c is not None and c < 0 and -c != signal.SIGTERM:
            try:
                return f"killed by {signal.Signals(-c).name}"
            except ValueError:
                return f"killed by signal {-c}"
    for c in codes:
        if c not in (None, 0, 128 + signal.SIGTERM, -signal.SIGTERM):
            return f"exit status {c}"
    return "ended abruptly"


def _shareable(cfg: ExportConfig, scene, catalog) -> tuple:
    """(scene, catalog) to hand to the workers of an untiled export, else (None, None)."""
    if getattr(cfg, "tile_m", None) is not None or scene is None:
        return None, None
    from ..scene.model import Scene

    return (scene, catalog) if isinstance(scene, Scene) else (None, None)
