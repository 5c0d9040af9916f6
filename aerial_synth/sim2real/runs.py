"""The runs of a plan (one arm x one seed each) and how several share one device.

Each run is a process of its own (``python -m aerial_synth.sim2real.runs SPEC.json``):
train, keep the weights (half precision, no optimizer state), predict the real images with
those weights and write ``result.json`` last. A run's output depends only on its spec
(data, seed, device, loader workers, torch threads), never on what runs beside it, so N at
once give the predictions of N one after the other (tested on the CPU).

``--parallel auto`` (:func:`auto_parallel`) takes the smallest of: the runs; the CPU cores
/ 2 (each run needs its main process and at least one loader worker's core); and, on a
GPU, (free memory - 2 GiB) / an estimate per run of 0.8 GiB + 0.3 GiB x batch x
(imgsz / 640)^2 (the report records each run's measured peak, to check the estimate);
on the CPU, cores / 4 (training there is bound by its own threads).
Loader workers and torch threads not given per run in the plan are shared out: the
cores / N threads each, and (cores - N) / N loader workers each, at most 8.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

from ..io_utils import atomic_write_json
from ..safe_input import load_json_file
from .config import Sim2RealError

__all__ = ["auto_parallel", "share_out", "run_all", "run_one", "predict_real", "cores"]

_GPU_RESERVE_GIB = 2.0


def cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def gpu_estimate_gib(batch: int, imgsz: int) -> float:
    return 0.8 + 0.3 * batch * (imgsz / 640.0) ** 2


def auto_parallel(n_runs: int, device: str, trains) -> tuple[int, str]:
    """(runs at once, the reason in words) for ``--parallel auto``."""
    from . import ultra

    c = cores()
    if str(device).startswith("cuda"):
        by_cpu = max(1, c // 2)
        free, total = ultra.free_gpu_gib(device)
        per = max(gpu_estimate_gib(t.batch, t.imgsz) for t in trains)
        by_mem = max(1, int((free - _GPU_RESERVE_GIB) // per))
        n = max(1, min(n_runs, by_cpu, by_mem))
        why = (f"min({n_runs} runs, {c} cores / 2 = {by_cpu}, ({free:.1f} GiB free - "
               f"{_GPU_RESERVE_GIB:g}) / {per:.1f} GiB per run = {by_mem})")
    else:
        by_cpu = max(1, c // 4)
        n = max(1, min(n_runs, by_cpu))
        why = f"min({n_runs} runs, {c} cores / 4 = {by_cpu}) on the CPU"
    return n, why


def share_out(parallel: int, workers: int | None, threads: int | None) -> tuple[int, int]:
    """(loader workers, torch threads) per run for ``parallel`` runs at once; a value the
    plan gives is kept."""
    c = cores()
    t = threads if threads is not None else max(1, c // parallel)
    w = workers if workers is not None else min(8, max(0, (c - parallel) // parallel))
    return w, t


# -- in the run's own process ------------------------------------------------------------------------

def predict_real(weights: Path, real: dict, targets: dict, folder: Path, device: str,
                 names: list[str]) -> dict:
    """Predict the real set with ``weights`` once per scale in ``targets`` ({scale: GSD or
    None}); DOTA task-1 files into ``folder/predictions[_scale]`` (the first scale has no
    suffix). ``real``: dir, classes, real_gsd, tile, overlap, imgsz, conf, merge_iou, batch.
    Returns {scale: folder relative to ``folder``}."""
    from . import ultra
    from .pipeline import predict_plans, write_task1
    from .real import plan_image, read_real

    items = read_real(Path(real["dir"]), None if real["classes"] is None else tuple(real["classes"]))
    predictor = ultra.Predictor(weights, imgsz=real["imgsz"], device=device, conf=real["conf"])
    out = {}
    for k, (scale, gsd) in enumerate(targets.items()):
        plans = [plan_image(it, gsd, real["real_gsd"], real["tile"], real["overlap"]) for it in items]
        merged = predict_plans(predictor, plans, real["batch"], real["merge_iou"])
        img_names = [g.name for g, (_, sc, _) in zip(items, merged) for _ in range(len(sc))]
        xy = np.concatenate([m[0] for m in merged] or [np.zeros((0, 4, 2))])
        sc = np.concatenate([m[1] for m in merged] or [np.zeros(0)])
        cl = [c for m in merged for c in m[2]]
        rel = "predictions" if k == 0 else f"predictions_{scale}"
        write_task1(folder / rel, img_names, xy, sc, cl, list(names))
        out[scale] = rel
    return out


def run_one(spec: dict) -> dict:
    """Train, keep the weights, predict; returns result.json's content (written last)."""
    from . import ultra
    from .config import inspect_synthetic
    from .pipeline import prepare_training_set

    run_dir = Path(spec["run_dir"])
    os.environ["OMP_NUM_THREADS"] = str(spec["threads"])
    import torch

    torch.set_num_threads(int(spec["threads"]))
    seen = None
    if spec.get("stream") is not None:
        tr, names, n_train, n_val = _train_stream(spec, run_dir)
        val_is_train = False
        seen = seen_digest(tr.seen)
    else:
        sets = [inspect_synthetic(Path(d), f"arm {spec['arm']}: ") for d in spec["dirs"]]
        names = list(sets[0].names)
        data_yaml, n_train, n_val, val_is_train = prepare_training_set(run_dir / "data", sets)
        tr = ultra.train(data_yaml, run_dir / "train", model=spec["model"],
                         weights=None if spec["weights"] is None else Path(spec["weights"]),
                         epochs=spec["epochs"], minutes=spec["minutes"], imgsz=spec["imgsz"],
                         device=spec["device"], seed=spec["seed"], batch=spec["batch"], workers=spec["workers"])
    peak = ultra.gpu_peak_mib(spec["device"])
    meta = {"arm": spec["arm"], "seed": spec["seed"], "imgsz": spec["imgsz"], "gsd_m": spec["gsd_m"],
            "tile": spec["real"]["tile"], "overlap": spec["real"]["overlap"], "classes": names,
            "epochs": tr.epochs, "training_images": n_train, "plan": spec.get("plan")}
    weights = ultra.save_weights(tr.weights, run_dir / "weights.pt", meta)
    shutil.rmtree(run_dir / "data", ignore_errors=True)  # the mirror (links) is not output
    shutil.rmtree(run_dir / "train" / "stream-data", ignore_errors=True)  # a stream run's empty folder
    for f in (run_dir / "train" / "weights").glob("*.pt"):  # kept once, small, as weights.pt
        f.unlink()
    t0 = time.perf_counter()
    preds = predict_real(weights, spec["real"], spec["targets"], run_dir, spec["device"], names)
    res = {"spec": spec, "epochs": tr.epochs, "train_seconds": round(tr.seconds, 1),
           "training_images": n_train, "validation_images": n_train if val_is_train else n_val,
           "val_is_train": val_is_train,
           "images_per_s": round(tr.epochs * n_train / tr.seconds, 2) if tr.seconds > 0 else None,
           "peak_gpu_mib": peak, "predict_seconds": round(time.perf_counter() - t0, 1),
           "synthetic_val_map50": None if tr.val_map50 is None else round(tr.val_map50, 6),
           "synthetic_val_map50_95": None if tr.val_map50_95 is None else round(tr.val_map50_95, 6),
           "weights": "weights.pt", "predictions": preds}
    if seen is not None:
        res["stream_seen"] = seen
    atomic_write_json(run_dir / "result.json", res)
    return res


def seen_digest(seen) -> dict:
    """A stream run's training images in brief: how many, and the sha256 of its sorted
    ``epoch name pixel-digest`` lines (``StreamTrainResult.seen``)."""
    import hashlib

    lines = sorted(f"{e} {n} {d}" for e, n, d in seen)
    return {"images": len(lines), "epochs": sorted({int(e) for e, _, _ in seen}),
            "sha256": hashlib.sha256("\n".join(lines).encode()).hexdigest()}


def _train_stream(spec: dict, run_dir: Path):
    """A stream arm's run: Ultralytics trains from the stream of the arm's export at the
    run's stream seed (``spec["stream"]["seed"]``), new images each epoch (or pool mode).
    Returns (train result, class names, images per epoch, validation images)."""
    import dataclasses

    from ..dataset.config import ExportConfig
    from ..stream.train import train_from_stream
    from . import ultra

    st = spec["stream"]
    cfg = dataclasses.replace(ExportConfig.from_dict(st["config"]), seed=int(st["seed"]))
    ultra._offline_ultralytics()
    tr = train_from_stream(cfg, run_dir / "train", epochs=spec["epochs"], minutes=spec["minutes"],
                           imgsz=spec["imgsz"], model=spec["weights"] or spec["model"], device=spec["device"],
                           batch=spec["batch"], workers=spec["workers"], seed=spec["seed"], pool=st["pool"],
                           refresh=st["refresh"], trainer_base=ultra._trainer_class(),
                           amp_check=ultra._patched_amp_check(), amp=spec["device"] != "cpu")
    from ..vehicles import CLASSES

    n = st["pool"] if st["pool"] is not None else cfg.images
    return tr, list(CLASSES), n, tr.val_images


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    spec = load_json_file(argv[0], error=Sim2RealError)  # spec.json, written by run_all
    run_one(spec)
    return 0


# -- in the parent ------------------------------------------------------------------------------------

def finished(run_dir: Path, spec: dict) -> dict | None:
    """result.json of a run that finished with this very spec (a rerun reuses it)."""
    try:
        res = load_json_file(run_dir / "result.json", error=Sim2RealError)
    except Sim2RealError:  # missing or cut short by a killed run: run it again
        return None
    return res if isinstance(res, dict) and res.get("spec") == spec else None


class _GpuSampler(threading.Thread):
    """``nvidia-smi`` utilisation and memory of one GPU every ``every`` s while runs train."""

    def __init__(self, index: str, every: float = 2.0):
        super().__init__(daemon=True)
        self.index, self.every, self.samples = index, every, []
        self._stop_event = threading.Event()

    def run(self):
        t0 = time.monotonic()
        while not self._stop_event.is_set():
            try:
                r = subprocess.run(["nvidia-smi", "--query-gpu=utilization.gpu,memory.used",
                                    "--format=csv,noheader,nounits", "-i", self.index],
                                   capture_output=True, text=True, timeout=10)
                util, mem = (float(v) for v in r.stdout.strip().splitlines()[0].split(","))
                self.samples.append((round(time.monotonic() - t0, 1), util, mem))
            except (OSError, ValueError, IndexError, subprocess.SubprocessError):
                return
            self._stop_event.wait(self.every)

    def stop(self) -> dict:
        self._stop_event.set()
        self.join(timeout=15)
        s = np.array([x[1] for x in self.samples]) if self.samples else np.zeros(0)
        return {"tool": "nvidia-smi", "every_s": self.every, "n": len(self.samples),
                "utilisation_mean_pct": round(float(s.mean()), 1) if len(s) else None,
                "utilisation_median_pct": round(float(np.median(s)), 1) if len(s) else None,
                "memory_used_max_mib": max((x[2] for x in self.samples), default=None),
                "samples": [list(x) for x in self.samples]}


def _log_tail(path: Path) -> str:
    try:
        lines = [ln for ln in path.read_text(encoding="utf-8", errors="replace").splitlines()  # guard: the run's own log
                 if ln.strip()]
    except OSError:
        return ""
    return " ".join(lines[-1].split())[:300] if lines else ""


def run_all(specs: list[dict], parallel: int, device: str, log=None) -> tuple[list[dict], dict | None]:
    """Run every spec (its ``run_dir`` holds spec.json, log.txt, result.json), ``parallel``
    at once; a run that finished before with the same spec is reused. Returns the results in
    spec order and the GPU samples (None on the CPU). A failed run stops the others and
    raises :class:`Sim2RealError` with its log's last line."""
    results: list[dict | None] = [None] * len(specs)
    todo = []
    for i, s in enumerate(specs):
        done = finished(Path(s["run_dir"]), s)
        if done is not None:
            results[i] = done
        else:
            todo.append(i)
    sampler = None
    if todo and str(device).startswith("cuda") and shutil.which("nvidia-smi"):
        sampler = _GpuSampler(str(device).split(":", 1)[1])
        sampler.start()
    running: dict[int, tuple[subprocess.Popen, object]] = {}
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    try:
        while todo or running:
            while todo and len(running) < parallel:
                i = todo.pop(0)
                s = specs[i]
                rd = Path(s["run_dir"])
                if rd.exists():
                    shutil.rmtree(rd)  # an unfinished earlier attempt: start it again
                rd.mkdir(parents=True)
                atomic_write_json(rd / "spec.json", s)
                fh = open(rd / "log.txt", "w", encoding="utf-8")  # noqa: SIM115  # guard: the run's own log, streamed
                env_i = dict(env, OMP_NUM_THREADS=str(s["threads"]))
                p = subprocess.Popen([sys.executable, "-m", "aerial_synth.sim2real.runs", str(rd / "spec.json")],
                                     stdout=fh, stderr=subprocess.STDOUT, env=env_i)
                running[i] = (p, fh)
                if log:
                    log(f"run {s['arm']} seed {s['seed']}: started ({len(running)} at once)")
            time.sleep(0.2)
            for i, (p, fh) in list(running.items()):
                if p.poll() is None:
                    continue
                fh.close()
                del running[i]
                s = specs[i]
                rd = Path(s["run_dir"])
                res = finished(rd, s)
                if p.returncode != 0 or res is None:
                    raise Sim2RealError(f"run {s['arm']} seed {s['seed']} failed (exit {p.returncode}; "
                                        f"{rd / 'log.txt'}): {_log_tail(rd / 'log.txt')}")
                results[i] = res
                if log:
                    log(f"run {s['arm']} seed {s['seed']}: {res['epochs']} epochs in {res['train_seconds']} s, "
                        f"{res['images_per_s']} images/s")
    finally:
        for p, _fh in running.values():
            p.terminate()
        for p, fh in running.values():
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
            fh.close()
        gpu = sampler.stop() if sampler is not None else None
    return results, gpu


if __name__ == "__main__":  # pragma: no cover - the run's own process
    sys.exit(main())
