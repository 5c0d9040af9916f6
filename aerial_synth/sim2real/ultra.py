"""The Ultralytics side of ``aerial-synth sim2real``: the only module that imports torch and
ultralytics (the optional ``[train]`` extra), and only when a function here is called.

Offline by construction (Ultralytics 8.4.190, checked with the network cut off, see
docs/sim2real.md), not by luck of the environment:

- a private settings folder (``YOLO_CONFIG_DIR``) with ``sync`` and every logger
  integration off, ``YOLO_OFFLINE`` and ``YOLO_AUTOINSTALL=false`` (no update check, no pip);
- the fonts that the dataset check fetches (``Arial.ttf``, ``Arial.Unicode.ttf``) are put
  in that folder first, copied from matplotlib's own DejaVu Sans, so nothing is fetched;
- ``plots=False`` (plots fetch fonts too);
- the AMP self-test, which loads ``yolo26n.pt`` (a download) on a GPU, is replaced by a
  check of the model being trained: fp32 and autocast outputs on a fixed input must agree;
- ``results.csv`` is read with the standard library instead of polars (54 MB that Ultralytics
  imports for that one read);
- models are a yaml (built from scratch, no weights) or a local ``.pt`` file; a bare ``.pt``
  name that is not a file is refused before Ultralytics could try to download it.
"""

from __future__ import annotations

import contextlib
import copy
import csv
import importlib.util
import os
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .config import Sim2RealError

__all__ = ["INSTALL_HINT", "missing_packages", "require_train_extra", "versions", "resolve_device",
           "TrainResult", "train", "Predictor"]

INSTALL_HINT = ("aerial-synth sim2real needs the optional [train] extra (Ultralytics 8.4.190 with "
                "torch and torchvision): pip install 'aerial-synth[train]', or make test-train for "
                "a separate .venv-train")

_SETTINGS_OFF = {"sync": False, "clearml": False, "comet": False, "dvc": False, "mlflow": False,
                 "raytune": False, "tensorboard": False, "wandb": False, "vscode_msg": False,
                 "openvino_msg": False}


def _present(name: str) -> bool:
    if name in sys.modules:
        return sys.modules[name] is not None
    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError):
        return False


def missing_packages() -> list[str]:
    """The [train] packages that cannot be imported here (no import is done)."""
    return [n for n in ("ultralytics", "torch", "torchvision") if not _present(n)]


def require_train_extra() -> None:
    miss = missing_packages()
    if miss:
        raise Sim2RealError(f"{INSTALL_HINT} (missing: {', '.join(miss)})")


_CONFIG_DIR: Path | None = None


def _offline_ultralytics():
    """Import ultralytics with the offline settings above (once per process)."""
    global _CONFIG_DIR
    if _CONFIG_DIR is None:
        _CONFIG_DIR = Path(tempfile.mkdtemp(prefix="aerial-synth-ultralytics-"))
        import atexit

        atexit.register(shutil.rmtree, _CONFIG_DIR, True)
        os.environ["YOLO_CONFIG_DIR"] = str(_CONFIG_DIR)
        os.environ["YOLO_OFFLINE"] = "true"
        os.environ["YOLO_AUTOINSTALL"] = "false"
        os.environ.setdefault("YOLO_VERBOSE", "false")
    import ultralytics  # noqa: F401  (heavy: torch)
    from ultralytics.utils import SETTINGS, USER_CONFIG_DIR

    _provide_fonts(Path(USER_CONFIG_DIR))  # where check_font looks first

    # its default folders are relative to a git checkout it may sit in: keep them private
    SETTINGS.update(dict(_SETTINGS_OFF, runs_dir=str(_CONFIG_DIR / "runs"),
                         weights_dir=str(_CONFIG_DIR / "weights"),
                         datasets_dir=str(_CONFIG_DIR / "datasets")))
    return ultralytics


def _provide_fonts(folder: Path) -> None:
    """Ultralytics' dataset check asks for Arial.ttf (a download when missing, whether or not
    it plots): give it matplotlib's DejaVu Sans under that name."""
    folder.mkdir(parents=True, exist_ok=True)
    spec = importlib.util.find_spec("matplotlib")
    src = None
    if spec is not None and spec.submodule_search_locations:
        cand = Path(list(spec.submodule_search_locations)[0]) / "mpl-data" / "fonts" / "ttf" / "DejaVuSans.ttf"
        src = cand if cand.is_file() else None
    if src is None:
        raise Sim2RealError("sim2real: matplotlib's DejaVuSans.ttf not found (Ultralytics would "
                            "download a font); reinstall matplotlib")
    for name in ("Arial.ttf", "Arial.Unicode.ttf"):
        if not (folder / name).is_file():
            shutil.copyfile(src, folder / name)


def versions() -> dict:
    """Versions of the frameworks (without importing them)."""
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for n in ("ultralytics", "torch", "torchvision", "numpy", "opencv-python-headless"):
        try:
            out[n] = version(n)
        except PackageNotFoundError:
            out[n] = None
    return out


def resolve_device(device: str) -> tuple[str, str]:
    """``auto|cpu|N|cuda:N`` -> (torch device string, device name). A CUDA device where
    there is none raises :class:`Sim2RealError`."""
    import torch

    d = str(device).strip().lower()
    if d == "auto":
        d = "0" if torch.cuda.is_available() else "cpu"
    if d == "cpu":
        return "cpu", _cpu_name()
    idx = d.split(":", 1)[1] if d.startswith("cuda:") else d
    if d == "cuda":
        idx = "0"
    if not idx.isdigit():
        raise Sim2RealError(f"--device: expected auto, cpu, a CUDA index (0) or cuda:N, got {device!r}")
    n = torch.cuda.device_count() if torch.cuda.is_available() else 0
    if n == 0:
        raise Sim2RealError(f"--device {device}: no CUDA device here (torch {torch.__version__} sees "
                            f"none); use --device cpu or auto")
    if int(idx) >= n:
        raise Sim2RealError(f"--device {device}: expected a CUDA index below {n}, got {idx}")
    return f"cuda:{idx}", torch.cuda.get_device_name(int(idx))


def _cpu_name() -> str:
    try:
        for ln in Path("/proc/cpuinfo").read_text().splitlines():  # guard: /proc
            if ln.lower().startswith("model name"):
                return f"CPU: {ln.split(':', 1)[1].strip()} ({os.cpu_count()} cores)"
    except OSError:
        pass
    import platform

    return f"CPU: {platform.processor() or platform.machine()} ({os.cpu_count()} cores)"


def _amp_check_offline(model) -> bool:
    """Replaces Ultralytics' AMP self-test (which downloads yolo26n.pt): the model being
    trained, fp32 vs autocast on a fixed input; AMP when both are finite and agree."""
    import torch

    dev = next(model.parameters()).device
    if dev.type != "cuda":
        return False
    m = copy.deepcopy(model).eval().float()
    g = torch.Generator().manual_seed(0)
    x = torch.rand(2, 3, 256, 256, generator=g).to(dev)
    with torch.no_grad():
        a = m(x)
        with torch.autocast("cuda"):
            b = m(x)
    a = a[0] if isinstance(a, (tuple, list)) else a
    b = b[0] if isinstance(b, (tuple, list)) else b
    a, b = a.float(), b.float()
    if not (torch.isfinite(a).all() and torch.isfinite(b).all()) or a.shape != b.shape:
        return False
    scale = float(a.abs().max()) or 1.0
    return bool(float((a - b).abs().max()) <= 0.05 * scale)


@contextlib.contextmanager
def _patched_amp_check():
    import ultralytics.engine.trainer as tr

    saved = tr.check_amp
    tr.check_amp = _amp_check_offline
    try:
        yield
    finally:
        tr.check_amp = saved


def _trainer_class():
    from ultralytics.models.yolo.obb import OBBTrainer

    class OfflineOBBTrainer(OBBTrainer):
        """OBBTrainer that reads results.csv with the standard library (no polars)."""

        def read_results_csv(self):
            try:
                with open(self.csv, newline="", encoding="utf-8") as fh:  # guard: the trainer's own results.csv
                    rows = list(csv.DictReader(fh))
            except OSError:
                return {}
            out: dict[str, list] = {}
            for r in rows:
                for k, v in r.items():
                    k = (k or "").strip()
                    try:
                        val = float(v)
                    except (TypeError, ValueError):
                        val = v
                    out.setdefault(k, []).append(val)
            return out

    return OfflineOBBTrainer


@dataclass
class TrainResult:
    weights: Path
    epochs: int
    seconds: float
    val_map50: float | None
    val_map50_95: float | None


def train(data_yaml: Path, run_dir: Path, *, model: str | None, weights: Path | None,
          epochs: int | None, minutes: float | None, imgsz: int, device: str, seed: int,
          batch: int, workers: int) -> TrainResult:
    """Train one OBB detector; ``run_dir`` receives Ultralytics' run folder."""
    _offline_ultralytics()
    from ultralytics import YOLO

    src = str(weights) if weights is not None else str(model)
    net = YOLO(src, task="obb")
    kw = dict(data=str(data_yaml), imgsz=imgsz, device=device, seed=seed, deterministic=True,
              batch=batch, workers=workers, plots=False, amp=device != "cpu", project=str(run_dir.parent.resolve()),  # guard: its own run folder
              name=run_dir.name, exist_ok=True, verbose=False, pretrained=False, cache=False,
              val=True, trainer=_trainer_class(), patience=0)
    if minutes is not None:
        kw.update(epochs=100000, time=minutes / 60.0)
    else:
        kw.update(epochs=int(epochs))
    t0 = time.perf_counter()
    with _patched_amp_check():
        metrics = net.train(**kw)
    seconds = time.perf_counter() - t0
    tr = net.trainer
    best = Path(tr.best) if Path(tr.best).is_file() else Path(tr.last)
    rd = getattr(metrics, "results_dict", None) or {}
    m50 = rd.get("metrics/mAP50(B)")
    m5095 = rd.get("metrics/mAP50-95(B)")
    return TrainResult(best, int(tr.epoch) + 1, seconds,
                       None if m50 is None else float(m50), None if m5095 is None else float(m5095))


class Predictor:
    """A trained model predicting BGR arrays: per array (polygons (n,4,2) px of that array,
    scores (n,), class names)."""

    def __init__(self, weights: Path, *, imgsz: int, device: str, conf: float, iou: float = 0.7,
                 max_det: int = 1000):
        _offline_ultralytics()
        from ultralytics import YOLO

        self.model = YOLO(str(weights), task="obb")
        self.kw = dict(imgsz=imgsz, device=device, conf=conf, iou=iou, max_det=max_det,
                       verbose=False, save=False)

    def __call__(self, arrays: list[np.ndarray], batch: int = 8):
        out = []
        for i in range(0, len(arrays), batch):
            res = self.model.predict(source=list(arrays[i:i + batch]), **self.kw)
            for r in res:
                names = r.names
                if r.obb is None or len(r.obb) == 0:
                    out.append((np.zeros((0, 4, 2)), np.zeros(0), []))
                    continue
                xy = r.obb.xyxyxyxy.cpu().numpy().astype(np.float64).reshape(-1, 4, 2)
                sc = r.obb.conf.cpu().numpy().astype(np.float64)
                cl = [str(names[int(c)]) for c in r.obb.cls.cpu().numpy()]
                out.append((xy, sc, cl))
        return out


def save_weights(src: Path, dst: Path, meta: dict) -> Path:
    """``src`` (an Ultralytics checkpoint) as ``dst``: the EMA model in half precision, no
    optimizer state (about 5.5 MB for yolo11n-obb), with ``meta`` under ``aerial_synth``
    (what ``sim2real score`` needs: image size, GSD, tiling)."""
    _offline_ultralytics()
    from ultralytics.utils.torch_utils import strip_optimizer

    dst.parent.mkdir(parents=True, exist_ok=True)
    tmp = dst.with_name(f".{dst.name}.tmp")
    if not strip_optimizer(src, s=str(tmp), updates={"aerial_synth": dict(meta)}):
        raise Sim2RealError(f"{src}: not an Ultralytics checkpoint")
    os.replace(tmp, dst)
    return dst


def weights_meta(path: Path) -> dict:
    """The ``aerial_synth`` record of a kept weights file ({} for another checkpoint);
    a file torch cannot read is one line."""
    _offline_ultralytics()
    from ultralytics.nn.tasks import torch_safe_load

    try:
        ckpt = torch_safe_load(str(path))[0]
    except Exception as exc:  # noqa: BLE001 - any unreadable file is the user's input
        raise Sim2RealError(f"--weights {path}: expected an Ultralytics .pt file, cannot read it "
                            f"({type(exc).__name__})") from None
    if not isinstance(ckpt, dict) or "model" not in ckpt:
        raise Sim2RealError(f"--weights {path}: expected an Ultralytics checkpoint (a dict with 'model')")
    meta = ckpt.get("aerial_synth")
    return dict(meta) if isinstance(meta, dict) else {}


def gpu_peak_mib(device: str) -> float | None:
    """Peak memory torch reserved on ``device`` in this process (None on the CPU)."""
    if not str(device).startswith("cuda"):
        return None
    import torch

    return round(torch.cuda.max_memory_reserved(torch.device(device)) / 2**20, 1)


def free_gpu_gib(device: str) -> tuple[float, float] | None:
    """(free, total) GiB of a CUDA device, None on the CPU."""
    if not str(device).startswith("cuda"):
        return None
    import torch

    free, total = torch.cuda.mem_get_info(torch.device(device))
    return free / 2**30, total / 2**30
