"""An experiment as one file: ``aerial-synth sim2real --plan PLAN.yaml`` (no torch here).

A plan names the real set, the baseline arm, the seeds, the training and the arms::

    real: path/to/real            # relative paths are read from the plan's folder
    baseline: A
    seeds: [0, 1, 2]
    train: {model: yolo11n-obb.yaml, minutes: 4, imgsz: 640, batch: 16}
    arms:
      A: {export: {scene: city_park, scenario: jam, images: 2000, size: 640}}
      C: {synthetic: path/to/an/existing/export, train: {minutes: 2}}

Every check runs in :func:`load_plan`, before anything is written; a refusal is one
:class:`~.config.Sim2RealError` line naming the plan and the key.

**Arm kinds** (:data:`ARM_KINDS`): an arm holds exactly one kind key. A kind is two small
functions: ``check(arm, value, ctx: PlanContext) -> spec`` (validate, write nothing) and
``build(spec, folder, workers) -> Built`` (make or find the YOLO-OBB folders where the run
happens). ``synthetic`` (existing folders) and ``export`` (generated where sim2real runs,
reused by manifest) and ``stream`` (an export's options, trained from the stream: new images
every epoch, nothing written) are registered here; a new kind is one :func:`arm_kind`
registration.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

from ..errors import AerialSynthError
from .config import Arm, Sim2RealConfig, Sim2RealError, inspect_synthetic

__all__ = ["TrainSpec", "PlanArm", "Plan", "PlanContext", "ArmKind", "Built", "ARM_KINDS", "arm_kind", "load_plan",
           "PLAN_KEYS", "TRAIN_KEYS", "REAL_KEYS", "EXPORT_SET_BY_SIM2REAL", "STREAM_KEYS", "StreamArm", "stream_seed"]

#: the real-set options of a plan (as today's flags, ``-`` written ``_``)
REAL_KEYS = ("real_gsd", "real_classes", "real_scale", "iou_type", "ignore_border", "ignore_classes",
             "group", "tile", "overlap", "conf", "merge_iou", "contact_images")
PLAN_KEYS = ("real", "baseline", "seeds", "train", "arms") + REAL_KEYS
#: ``train:`` keys (plan-wide, or per arm to override). ``workers`` and ``threads`` are per run
#: (data-loader processes, torch CPU threads); left out, they are shared out among the runs.
TRAIN_KEYS = ("model", "weights", "minutes", "epochs", "imgsz", "batch", "workers", "threads")
@dataclass(frozen=True)
class TrainSpec:
    model: str = "yolo11n-obb.yaml"
    weights: Path | None = None
    minutes: float | None = None
    epochs: int | None = None
    imgsz: int = 640
    batch: int = 8
    workers: int | None = None
    threads: int | None = None


@dataclass(frozen=True)
class Built:
    """What an arm kind's ``build`` hands the runs: YOLO-OBB folders and how they came."""

    dirs: tuple[Path, ...]
    seconds: float = 0.0
    reused: bool = False
    images: int | None = None
    #: a stream arm: what each run renders (export parameters, pool, refresh), and its sets' stand-in
    #: (class names, GSD) since it has no folder
    stream: dict | None = None
    sets: tuple | None = None


@dataclass(frozen=True)
class PlanContext:
    """What an arm kind's ``check`` may use: the plan's folder (relative paths) and the
    ``export`` command's options -> ExportConfig (given by the command layer, which owns
    that parser: :func:`aerial_synth.sim2real.cli.export_config`)."""

    plan_dir: Path
    export_config: Callable[[str, dict], object] | None = None


@dataclass(frozen=True)
class ArmKind:
    name: str
    check: Callable[[str, object, PlanContext], object]
    build: Callable[[object, Path, int], Built]
    #: True when ``build`` writes into the report folder (its folder is ``exports/<arm>``)
    writes: bool = False
    #: the folders an arm of this kind reads (kept apart from --out), from its checked spec
    inputs: Callable[[object], tuple] = lambda spec: ()
    #: the GSD (m/px) its images have, known before building; None: unknown until built
    gsd: Callable[[object], object] | None = None


ARM_KINDS: dict[str, ArmKind] = {}


def arm_kind(name: str, *, writes: bool = False, inputs=None, gsd=None):
    """Register ``(check, build)`` as the arm kind ``name``: decorate a function returning
    the pair. ``inputs``, ``gsd``: see :class:`ArmKind`."""

    def deco(fn):
        check, build = fn()
        ARM_KINDS[name] = ArmKind(name, check, build, writes, inputs or (lambda spec: ()), gsd)
        return fn

    return deco


@dataclass(frozen=True)
class PlanArm:
    name: str
    kind: str
    spec: object          # what the kind's check returned
    value: object         # the plan's text for the kind (for the report)
    train: TrainSpec
    gsd: float | None = None


@dataclass(frozen=True)
class Plan:
    path: Path
    real: Path
    baseline: str
    seeds: tuple[int, ...]
    arms: tuple[PlanArm, ...]
    #: one validated Sim2RealConfig per arm (real-set options and training, no out)
    configs: dict = field(default_factory=dict)
    raw: dict = field(default_factory=dict)

    @property
    def ignore_classes(self) -> dict[str, tuple[str, ...]]:
        """{group: prediction classes dropped on its images} (a set labelled with cars only)."""
        return {g: tuple(c) for g, c in (self.raw.get("ignore_classes") or {}).items()}

    def arm(self, name: str) -> PlanArm:
        return next(a for a in self.arms if a.name == name)


def _read_yaml(path: Path) -> dict:
    """The plan's mapping, read through :func:`~aerial_synth.safe_input.load_yaml_file`
    (regular file, size cap, nesting and alias budgets, duplicate keys refused): one line
    naming ``--plan PATH`` otherwise."""
    from ..safe_input import load_yaml_file

    where = f"--plan {path}"
    if not os.path.lexists(path):  # a folder, a device, a FIFO: load_yaml_file names what it is
        raise Sim2RealError(f"{where}: no such file")
    data = load_yaml_file(path, where, Sim2RealError)
    if not isinstance(data, dict):
        raise Sim2RealError(f"{where}: expected a mapping (real, baseline, seeds, train, arms), "
                            f"got {type(data).__name__}")
    return data


def _as_json(obj):
    """``obj`` as JSON gives it back (tuples as lists): how a manifest or a run's spec holds it."""
    import json

    return json.loads(json.dumps(obj))  # guard: a round trip of our own config, no input read


def _unknown(where: str, d: dict, allowed) -> None:
    for k in d:
        if k not in allowed:
            raise Sim2RealError(f"{where}: unknown key {k!r} (expected one of {', '.join(allowed)})")


def _path(plan_dir: Path, value, where: str) -> Path:
    if not isinstance(value, str) or not value.strip():
        raise Sim2RealError(f"{where}: expected a path, got {value!r}")
    p = Path(value).expanduser()
    return p if p.is_absolute() else plan_dir / p


def _train(d, where: str, base: TrainSpec, plan_dir: Path) -> TrainSpec:
    if d is None:
        return base
    if not isinstance(d, dict):
        raise Sim2RealError(f"{where}: expected a mapping of {', '.join(TRAIN_KEYS)}, got {d!r}")
    _unknown(where, d, TRAIN_KEYS)
    kw = dict(d)
    if "minutes" in kw and "epochs" not in kw:
        kw["epochs"] = None  # an arm's minutes replace the plan's epochs, and the reverse
    if "epochs" in kw and "minutes" not in kw:
        kw["minutes"] = None
    if kw.get("weights") is not None:
        kw["weights"] = _path(plan_dir, kw["weights"], f"{where}.weights")
    for k in ("epochs", "imgsz", "batch", "workers", "threads"):
        v = kw.get(k)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int)):
            raise Sim2RealError(f"{where}.{k}: expected an integer, got {v!r}")
    for k in ("workers", "threads"):
        v = kw.get(k)
        if v is not None and v < (0 if k == "workers" else 1):
            raise Sim2RealError(f"{where}.{k}: expected an integer >= {0 if k == 'workers' else 1}, got {v!r}")
    m = kw.get("minutes")
    if m is not None and (isinstance(m, bool) or not isinstance(m, (int, float))):
        raise Sim2RealError(f"{where}.minutes: expected a number > 0, got {m!r}")
    if "model" in kw and not isinstance(kw["model"], str):
        raise Sim2RealError(f"{where}.model: expected a model yaml name, got {kw['model']!r}")
    return replace(base, **kw)


def _real_options(data: dict, where: str) -> dict:
    from ..evaluate.scoring import parse_ignore_border
    from .config import parse_real_scale

    out = {}
    for k in REAL_KEYS:
        if k not in data:
            continue
        v = data[k]
        w = f"{where}: {k}"
        if k == "ignore_border":
            if isinstance(v, dict):
                vals = [f"{g}={px}" for g, px in v.items()]
            elif isinstance(v, (int, float)) and not isinstance(v, bool):
                vals = [str(v)]
            else:
                raise Sim2RealError(f"{w}: expected PX or a mapping GROUP: PX, got {v!r}")
            try:
                out[k] = parse_ignore_border(vals)
            except AerialSynthError as exc:
                raise Sim2RealError(f"{w}: {exc}") from None
        elif k == "ignore_classes":
            if not isinstance(v, dict) or not all(
                    isinstance(g, str) and isinstance(c, list) and c and all(isinstance(x, str) and x for x in c)
                    for g, c in v.items()):
                raise Sim2RealError(f"{w}: expected a mapping GROUP: [CLASS, ...] (predictions of those "
                                    f"classes dropped on that group's images), got {v!r}")
            continue  # not a Sim2RealConfig field: read by Plan.ignore_classes
        elif k == "real_classes":
            if v == "all":
                out[k] = None
            elif isinstance(v, list) and v and all(isinstance(c, str) and c for c in v):
                out[k] = tuple(v)
            elif isinstance(v, str) and v.strip():
                out[k] = tuple(c.strip() for c in v.split(",") if c.strip())
            else:
                raise Sim2RealError(f"{w}: expected a list of class names or 'all', got {v!r}")
        elif k == "real_scale":
            text = ",".join(map(str, v)) if isinstance(v, list) else str(v)
            try:
                out[k] = parse_real_scale(text)
            except Sim2RealError as exc:
                raise Sim2RealError(f"{w}: {exc}") from None
        elif k in ("group", "iou_type"):
            if not isinstance(v, str):
                raise Sim2RealError(f"{w}: expected text, got {v!r}")
            if k == "iou_type" and v not in ("obb", "hbb", "auto"):
                raise Sim2RealError(f"{w}: expected one of obb, hbb, auto, got {v!r}")
            out[k] = v
        elif k in ("tile", "overlap", "contact_images"):
            if isinstance(v, bool) or not isinstance(v, int):
                raise Sim2RealError(f"{w}: expected an integer, got {v!r}")
            out[k] = v
        else:  # real_gsd, conf, merge_iou
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise Sim2RealError(f"{w}: expected a number, got {v!r}")
            out[k] = float(v)
    return out


def load_plan(path, *, device: str = "auto", out: Path | None = None, export_config=None) -> Plan:
    """Read and check a plan (see the module's docstring). Writes nothing. ``export_config``:
    ``(arm, options) -> ExportConfig`` for export arms (:func:`aerial_synth.sim2real.cli.export_config`)."""
    path = Path(path)
    data = _read_yaml(path)
    where = f"--plan {path}"
    _unknown(where, data, PLAN_KEYS)
    plan_dir = Path(os.path.realpath(path)).parent
    if "real" not in data:
        raise Sim2RealError(f"{where}: missing key 'real' (the real images: a DOTA folder or a folder of groups)")
    real = _path(plan_dir, data["real"], f"{where}: real")
    if not real.exists():
        raise Sim2RealError(f"{where}: real {real}: no such folder")
    if not real.is_dir():
        raise Sim2RealError(f"{where}: real {real}: expected a folder, found a file")
    seeds = data.get("seeds", [0])
    if not isinstance(seeds, list) or not seeds:
        raise Sim2RealError(f"{where}: seeds: expected a non-empty list of integers >= 0, got {seeds!r}")
    if any(isinstance(s, bool) or not isinstance(s, int) or s < 0 for s in seeds) or len(set(seeds)) != len(seeds):
        raise Sim2RealError(f"{where}: seeds: expected distinct integers >= 0, got {seeds!r}")
    arms_raw = data.get("arms")
    if not isinstance(arms_raw, dict) or not arms_raw:
        raise Sim2RealError(f"{where}: arms: expected a mapping NAME: {{KIND: ...}} with at least one "
                            f"arm (kinds: {', '.join(ARM_KINDS)}), got {arms_raw!r}")
    base_train = _train(data.get("train"), f"{where}: train", TrainSpec(), plan_dir)
    real_opts = _real_options(data, where)
    baseline = data.get("baseline", next(iter(arms_raw)))
    if baseline not in arms_raw:
        raise Sim2RealError(f"{where}: baseline {baseline!r} is not an arm (arms: "
                            f"{', '.join(map(str, arms_raw))})")
    from .config import ARM_NAME

    arms, configs = [], {}
    for name, spec in arms_raw.items():
        aw = f"{where}: arm {name}"
        if not isinstance(name, str) or not ARM_NAME.match(name):
            raise Sim2RealError(f"{where}: arm name {name!r}: expected letters, digits, _ . - "
                                f"(not starting with _ . -)")
        if not isinstance(spec, dict):
            raise Sim2RealError(f"{aw}: expected a mapping with one of {', '.join(ARM_KINDS)}, got {spec!r}")
        _unknown(aw, spec, tuple(ARM_KINDS) + ("train", "gsd"))
        kinds = [k for k in spec if k in ARM_KINDS]
        if len(kinds) != 1:
            raise Sim2RealError(f"{aw}: expected exactly one of {', '.join(ARM_KINDS)}, got "
                                f"{', '.join(kinds) or 'none'}")
        train = _train(spec.get("train"), f"{aw}: train", base_train, plan_dir)
        gsd = spec.get("gsd")
        if gsd is not None and (isinstance(gsd, bool) or not isinstance(gsd, (int, float)) or not gsd > 0):
            raise Sim2RealError(f"{aw}: gsd: expected a number > 0 (m/px), got {gsd!r}")
        try:
            configs[name] = Sim2RealConfig(
                arms=(Arm(name, ()),), real=real, out=out or plan_dir, model=train.model,
                weights=train.weights, minutes=train.minutes, epochs=train.epochs, imgsz=train.imgsz,
                device=device, batch=train.batch, workers=train.workers or 0, gsd=gsd, **real_opts)
        except Sim2RealError as exc:
            raise Sim2RealError(f"{aw}: {exc}") from None
        kind = kinds[0]
        try:
            checked = ARM_KINDS[kind].check(name, spec[kind], PlanContext(plan_dir, export_config))
        except Sim2RealError as exc:
            raise Sim2RealError(f"{where}: {exc}") from None
        arms.append(PlanArm(name, kind, checked, spec[kind], train, gsd))
    return Plan(path, real, baseline, tuple(seeds), tuple(arms), configs, data)


#: ``export:`` options that sim2real sets itself
EXPORT_SET_BY_SIM2REAL = ("out", "resume", "force", "workers", "dask", "no_progress")


# -- the arm kinds ----------------------------------------------------------------------------------

def _synthetic_gsds(dirs) -> set:
    return {inspect_synthetic(d, "").gsd_m for d in dirs}


@arm_kind("synthetic", inputs=tuple, gsd=_synthetic_gsds)
def _synthetic_kind():
    """``synthetic: DIR`` or ``[DIR, ...]``: existing exports / YOLO-OBB folders."""

    def check(arm, value, ctx):
        vals = value if isinstance(value, list) else [value]
        if not vals:
            raise Sim2RealError(f"arm {arm}: synthetic: expected a folder or a list of folders, got []")
        dirs = tuple(_path(ctx.plan_dir, v, f"arm {arm}: synthetic") for v in vals)
        for d in dirs:
            inspect_synthetic(d, f"arm {arm}: synthetic ")
        return dirs

    def build(dirs, folder, workers):
        return Built(tuple(dirs))

    return check, build


def _export_check(arm, value, ctx, kind: str = "export"):
    """An ``export:`` mapping -> ExportConfig with the export command's checks; its messages
    start ``arm NAME: KIND:``."""
    if ctx.export_config is None:
        raise Sim2RealError(f"arm {arm}: {kind}: no export parser given to load_plan "
                            f"(aerial_synth.sim2real.cli.export_config)")
    try:
        return ctx.export_config(arm, value)
    except AerialSynthError as exc:
        msg = " ".join(str(exc).split())
        if msg.startswith(f"arm {arm}: export: "):
            msg = f"arm {arm}: {kind}: " + msg[len(f"arm {arm}: export: "):]
        raise Sim2RealError(msg if msg.startswith(f"arm {arm}: ") else f"arm {arm}: {kind}: {msg}") from None


@arm_kind("export", writes=True)
def _export_kind():
    """``export: {OPTION: VALUE, ...}``: generated where sim2real runs, into
    ``OUT/exports/<arm>``, with --export-workers processes; a complete export there whose
    manifest holds the same parameters is reused."""

    check = _export_check

    def build(cfg, folder, workers):
        from ..dataset.export import export_dataset
        from ..dataset.manifest import read_manifest

        m = read_manifest(folder)
        same = m is not None and m.get("parameters") == _as_json(cfg.to_dict())
        if same and m.get("status") == "complete":
            return Built((folder,), 0.0, True, cfg.images)
        t0 = time.perf_counter()
        export_dataset(cfg, folder, workers=workers, resume=True, force=True, progress=False)
        return Built((folder,), time.perf_counter() - t0, False, cfg.images)

    return check, build


#: ``stream:`` keys besides the export options
STREAM_KEYS = ("pool", "refresh")
#: the seed stream of a stream arm's runs: run seed s renders from
#: ``SeedSequence([export seed, RUN_STREAM, s])``'s first 63-bit word (:func:`stream_seed`)
RUN_STREAM = 0x52554E  # "RUN"


@dataclass(frozen=True)
class StreamArm:
    """A checked ``stream:`` arm: the export it streams, and its pool mode (None: new images
    every epoch)."""

    config: object  # ExportConfig
    pool: int | None = None
    refresh: float = 0.25

    @property
    def gsd_m(self) -> float | None:
        """Its images' nadir GSD when fixed (None under a GSD or altitude range)."""
        c = self.config
        if c.gsd_range is not None or c.altitude_range is not None:
            return None
        return float(c.camera.nadir_gsd_m)


def stream_seed(export_seed: int, run_seed: int) -> int:
    """The stream's seed in run ``run_seed`` of an arm whose export seed is ``export_seed``:
    every run seed draws its own images (epoch e: :func:`aerial_synth.stream.epoch_config`
    of that seed)."""
    import numpy as np

    word = np.random.SeedSequence([int(export_seed), RUN_STREAM, int(run_seed)]).generate_state(1, np.uint64)[0]
    return int(word >> np.uint64(1))


def _stream_gsds(spec: StreamArm) -> set:
    return {spec.gsd_m}


@arm_kind("stream", gsd=_stream_gsds)
def _stream_kind():
    """``stream: {OPTION: VALUE, ..., pool: P, refresh: F}``: the export options of an
    ``export:`` arm (same checks and messages), trained from the stream: each epoch renders
    new images from (seed, epoch, index) in the data loader, none written. ``pool``: P images
    held, ``refresh`` (0.25) of them re-rendered each epoch. Nothing is built before the runs."""

    def check(arm, value, ctx):
        if not isinstance(value, dict):
            raise Sim2RealError(f"arm {arm}: stream: expected a mapping of export options (and pool, "
                                f"refresh), got {value!r}")
        opts = {k: v for k, v in value.items() if k not in STREAM_KEYS}
        cfg = _export_check(arm, opts, ctx, "stream")
        pool, refresh = value.get("pool"), value.get("refresh", 0.25)
        if pool is not None and (isinstance(pool, bool) or not isinstance(pool, int) or not 1 <= pool <= cfg.images):
            raise Sim2RealError(f"arm {arm}: stream: pool: expected an integer in 1..{cfg.images} (images held, "
                                f"at most images), got {pool!r}")
        if "refresh" in value and pool is None:
            raise Sim2RealError(f"arm {arm}: stream: refresh: only with pool (the share of the pool "
                                f"re-rendered each epoch)")
        if isinstance(refresh, bool) or not isinstance(refresh, (int, float)) or not 0.0 <= refresh <= 1.0:
            raise Sim2RealError(f"arm {arm}: stream: refresh: expected a number in 0..1, got {refresh!r}")
        return StreamArm(cfg, pool, float(refresh))

    def build(spec, folder, workers):
        from ..vehicles import CLASSES
        from .config import SyntheticSet

        run = {"config": _as_json(spec.config.to_dict()), "pool": spec.pool,
               "refresh": spec.refresh}
        n = spec.pool if spec.pool is not None else spec.config.images
        return Built((), 0.0, False, n, run, (SyntheticSet(None, None, None, tuple(CLASSES), spec.gsd_m, n, 0),))

    return check, build


def check_export_arms(plan: Plan) -> None:
    """The loading checks of export arms (scene, scenario, catalog: as ``export`` does
    before it writes); raises with the arm's name."""
    from ..dataset.export import validate_inputs

    for a in plan.arms:
        if a.kind not in ("export", "stream"):
            continue
        try:
            validate_inputs(a.spec if a.kind == "export" else a.spec.config)
        except AerialSynthError as exc:
            raise Sim2RealError(f"--plan {plan.path}: arm {a.name}: {a.kind}: {' '.join(str(exc).split())}") from None
