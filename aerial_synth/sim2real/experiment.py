"""``aerial-synth sim2real --plan PLAN.yaml``: arms x seeds on one device, in parallel, with
intervals; and ``aerial-synth sim2real score``: kept weights scored on any real set.

Layout of ``--out`` for a plan (a working folder: a second run of the same plan reuses the
export arms whose manifest matches and the runs that finished with the same spec)::

    plan.json  report.json  summary.txt  pr.png  pr_<group>.png  contact_<arm>.png
    exports/<arm>/                       export arms, generated here (--export-workers K)
    runs/<arm>/seed<S>/weights.pt        half precision, no optimizer state (+ aerial_synth meta)
    runs/<arm>/seed<S>/predictions/      DOTA task-1 files, real images' own pixels
    runs/<arm>/seed<S>/result.json, log.txt, train/ (results.csv, args.yaml)
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from .. import __version__
from ..evaluate.ap import Detections
from ..evaluate.evaluation import read_task1_folder
from ..evaluate.scoring import ScoringOptions, image_groups, score
from ..io_utils import (
    atomic_write_json,
    atomic_write_text,
    check_output_dir,
    is_inside,
    replace_dir,
)
from . import report as rep
from . import ultra
from .confidence import BOOTSTRAP, INTERVAL, differences, spread
from .config import Arm, Sim2RealConfig, Sim2RealError, inspect_synthetic
from .pipeline import AGNOSTIC, REPORT_FORMAT, log, real_summary, write_figures
from .plan import ARM_KINDS, Plan, check_export_arms, load_plan, stream_seed
from .real import plan_image, read_real
from .runs import auto_parallel, predict_real, run_all, share_out

__all__ = ["run_plan", "run_score", "drop_classes", "PLAN_MARKER", "CONFIDENCE_METHOD"]

PLAN_MARKER = "plan.json"
CONFIDENCE_METHOD = (f"paired bootstrap over real images and seeds ({BOOTSTRAP} replicates, "
                     f"percentile {INTERVAL:.0%} interval, RNG seed 0)")


def _check_out(out: Path, inputs) -> Path:
    out = check_output_dir(out, "--out")
    if out.exists() and any(out.iterdir()) and not (out / PLAN_MARKER).is_file():
        raise Sim2RealError(f"--out {out}: exists, is not empty and is not a sim2real plan folder "
                            f"(no {PLAN_MARKER}); choose a new folder")
    for opt, p in inputs:
        if is_inside(out, p) or is_inside(p, out):
            raise Sim2RealError(f"--out {out}: overlaps the input folder {opt} {p}; choose another folder")
    return out


def _real_checks(cfg: Sim2RealConfig, items, ignore_classes=None) -> None:
    """Refusals that need only the real set: groups named by ignore_border and
    ignore_classes, GSD headers where an arm scale is asked for."""
    groups = sorted(set(image_groups(items, cfg.group)))
    for opt, keys in (("ignore_border", cfg.ignore_border), ("ignore_classes", ignore_classes or {})):
        for k in keys:
            if k is not None and k not in groups:
                raise Sim2RealError(f"{opt}: no group {k!r} in the real set (groups: {', '.join(groups)})")
    if "arm" in cfg.real_scale:
        for it in items:
            plan_image(it, 1.0, cfg.real_gsd, cfg.tile, cfg.overlap)


def _options(cfg: Sim2RealConfig) -> tuple[ScoringOptions, ScoringOptions]:
    agn = ScoringOptions((AGNOSTIC, None), cfg.iou_type, dict(cfg.ignore_border), cfg.group)
    return agn, ScoringOptions(None, agn.iou_type, agn.ignore_border, agn.group)


def check_plan(plan_path, out, device: str, export_config=None) -> tuple[Plan, Path, list]:
    """Every refusal of a plan, before anything is written: (plan, out, real items). The
    [train] extra is asked for last, so a plan can be checked where torch is not installed."""
    plan = load_plan(plan_path, device=device, out=Path(out), export_config=export_config)
    where = f"--plan {plan.path}"
    inputs = [("real", plan.real)] + [(f"arm {a.name}", d) for a in plan.arms
                                      for d in ARM_KINDS[a.kind].inputs(a.spec)]
    out = _check_out(Path(out), inputs)
    try:
        items = read_real(plan.real, plan.configs[plan.baseline].real_classes)
        for a in plan.arms:
            _real_checks(plan.configs[a.name], items, plan.ignore_classes)
            kind = ARM_KINDS[a.kind]
            if kind.gsd is None or a.gsd is not None or "arm" not in plan.configs[a.name].real_scale:
                continue
            gs = kind.gsd(a.spec)
            if len(gs) != 1 or None in gs:
                raise Sim2RealError(f"arm {a.name}: " + (
                    ("no single GSD (a GSD or altitude range)" if a.kind == "stream"
                     else "no GSD known (no export manifest.json with gsd_m)")
                    if None in gs else f"its folders have different GSDs {sorted(gs)}") + "; give the arm gsd: M")
    except Sim2RealError as exc:
        msg = str(exc)
        raise Sim2RealError(msg if msg.startswith("--plan") else f"{where}: {msg}") from None
    check_export_arms(plan)
    ultra.require_train_extra()
    return plan, out, items


def _arm_gsd(a, sets) -> float:
    if a.gsd is not None:
        return float(a.gsd)
    g = {s.gsd_m for s in sets}
    if len(g) != 1 or None in g:
        raise Sim2RealError(f"arm {a.name}: no single GSD in its sets ({sorted(map(str, g))}); give the arm gsd: M")
    return float(g.pop())


def run_plan(plan_path, out, *, parallel="auto", device: str = "auto", export_workers: int = 1,
             export_config=None) -> dict:
    """Run a plan into ``out`` (see the module's docstring); returns report.json's content.
    ``export_config``: as :func:`~.plan.load_plan` takes it (the CLI gives the export's)."""
    plan, out, items = check_plan(plan_path, out, device, export_config)
    dev, dev_name = ultra.resolve_device(device)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(out / PLAN_MARKER, {"plan": str(plan.path), "content": plan.raw})
    built, arm_info = {}, {}
    for a in plan.arms:  # the arms' data, here (export arms with K processes)
        kind = ARM_KINDS[a.kind]
        if kind.writes:
            log(f"arm {a.name}: {a.kind} into {out / 'exports' / a.name} ({export_workers} processes)")
        b = kind.build(a.spec, out / "exports" / a.name, export_workers)
        sets = list(b.sets) if b.sets is not None else [inspect_synthetic(d, f"arm {a.name}: ") for d in b.dirs]
        built[a.name] = (b, sets)
        arm_info[a.name] = {"gsd_m": _arm_gsd(a, sets) if "arm" in plan.configs[a.name].real_scale or a.gsd
                            else (sets[0].gsd_m if sets[0].gsd_m else None)}
        if kind.writes:
            log(f"arm {a.name}: " + ("reused (same manifest)" if b.reused else f"{b.seconds:.1f} s"))
    n_runs = len(plan.arms) * len(plan.seeds)
    if parallel == "auto":
        n_par, rule = auto_parallel(n_runs, dev, [a.train for a in plan.arms])
    else:
        n_par, rule = max(1, min(int(parallel), n_runs)), f"--parallel {parallel}"
    specs = []
    for a in plan.arms:
        cfg = plan.configs[a.name]
        workers, threads = share_out(n_par, a.train.workers, a.train.threads)
        gsd = arm_info[a.name]["gsd_m"]
        real = {"dir": str(plan.real), "classes": None if cfg.real_classes is None else list(cfg.real_classes),
                "real_gsd": cfg.real_gsd, "tile": cfg.tile, "overlap": cfg.overlap, "imgsz": cfg.imgsz,
                "conf": cfg.conf, "merge_iou": cfg.merge_iou, "batch": cfg.batch}
        for s in plan.seeds:
            specs.append({
                "arm": a.name, "seed": s, "run_dir": os.path.realpath(out / "runs" / a.name / f"seed{s}"),
                "dirs": [os.path.realpath(d) for d in built[a.name][0].dirs], "model": cfg.model,
                "weights": None if cfg.weights is None else os.path.realpath(cfg.weights),
                "epochs": cfg.epochs, "minutes": cfg.minutes, "imgsz": cfg.imgsz, "batch": cfg.batch,
                "device": dev, "workers": workers, "threads": threads, "gsd_m": gsd, "plan": str(plan.path),
                "real": real, "targets": {sc: (gsd if sc == "arm" else None) for sc in cfg.real_scale}})
            if built[a.name][0].stream is not None:  # a stream arm: each seed its own images
                specs[-1]["stream"] = dict(built[a.name][0].stream,
                                           seed=stream_seed(built[a.name][0].stream["config"]["seed"], s))
    log(f"{n_runs} runs, {n_par} at once ({rule}) on {dev_name}")
    t0 = time.perf_counter()
    results, gpu = run_all(specs, n_par, dev, log)
    wall = time.perf_counter() - t0
    report = _plan_report(plan, out, items, built, arm_info, specs, results, gpu,
                          {"requested": str(parallel), "runs_at_once": n_par, "rule": rule,
                           "runs": n_runs, "wall_seconds": round(wall, 1)},
                          {"requested": device, "used": dev, "name": dev_name}, export_workers)
    return report


def drop_classes(items, dets: Detections, ignore_classes: dict, group_regex=None) -> Detections:
    """``dets`` without the predictions of ``ignore_classes[group]`` on that group's images
    (a real set labelled with cars only: its trucks are not false positives)."""
    if not ignore_classes or not len(dets):
        return dets
    groups = image_groups(items, group_regex)
    img = np.asarray(dets.image, np.int64)
    keep = np.array([c not in ignore_classes.get(groups[i], ()) for i, c in zip(img, dets.classes)], bool)
    return Detections(img[keep], [c for c, k in zip(dets.classes, keep) if k], np.asarray(dets.scores)[keep],
                      np.asarray(dets.polygons_xy_px).reshape(-1, 4, 2)[keep])


def _score_run(items, folder: Path, opts, ignore_classes=None) -> tuple:
    names = {g.name: i for i, g in enumerate(items)}
    dets = drop_classes(items, read_task1_folder(folder, names), ignore_classes, opts[0].group)
    agn = score(items, dets, opts[0])
    return dets, agn, rep.arm_real_figures(agn, score(items, dets, opts[1]))


def _arm_stats(per_seed: list[dict]) -> dict:
    """Mean and spread over seeds: class-agnostic, per group, per class."""
    groups = list(per_seed[0]["per_group"])
    classes = sorted({c for f in per_seed for c in f["per_class_ap50"]})
    return {"ap50": spread([f["ap50"] for f in per_seed]),
            "recall": spread([f["recall"] for f in per_seed]),
            "per_group": {g: spread([f["per_group"][g]["ap50"] for f in per_seed]) for g in groups},
            "per_class": {c: spread([f["per_class_ap50"].get(c) for f in per_seed]) for c in classes}}


def _plan_report(plan, out, items, built, arm_info, specs, results, gpu, par, device, export_workers) -> dict:
    base_cfg = plan.configs[plan.baseline]
    opts = _options(base_cfg)
    scored = {}  # arm -> [(dets, agn, figs) per seed]
    for s, r in zip(specs, results):
        scored.setdefault(s["arm"], []).append(
            _score_run(items, Path(s["run_dir"]) / r["predictions"][base_cfg.real_scale[0]], opts,
                       plan.ignore_classes))
    groups = np.array(image_groups(items, base_cfg.group))
    gnames = sorted(set(groups.tolist()))
    agn = {a: [rep.agnostic(x[1]) for x in v] for a, v in scored.items()}
    vs = differences(agn, plan.baseline)
    vs_group = {g: differences(agn, plan.baseline, np.nonzero(groups == g)[0]) for g in gnames} if len(gnames) > 1 else {}
    arms = []
    by_arm = {}
    for a in plan.arms:
        rs = [(s, r) for s, r in zip(specs, results) if s["arm"] == a.name]
        b, sets = built[a.name]
        figs = [x[2] for x in scored[a.name]]
        entry = {
            "name": a.name, "kind": a.kind, "spec": a.value, "dirs": [str(d) for d in b.dirs],
            "gsd_m": arm_info[a.name]["gsd_m"], "classes": list(sets[0].names),
            "training_images": rs[0][1]["training_images"], "validation_images": rs[0][1]["validation_images"],
            "export_seconds": round(b.seconds, 1) if ARM_KINDS[a.kind].writes else None,
            "export_reused": b.reused if ARM_KINDS[a.kind].writes else None,
            "train": {k: getattr(a.train, k) if k != "weights" or a.train.weights is None else str(a.train.weights)
                      for k in ("model", "weights", "minutes", "epochs", "imgsz", "batch")},
            "workers_per_run": rs[0][0]["workers"], "threads_per_run": rs[0][0]["threads"],
            "runs": [{"seed": s["seed"], "epochs": r["epochs"], "train_seconds": r["train_seconds"],
                      "images_per_s": r["images_per_s"], "peak_gpu_mib": r["peak_gpu_mib"],
                      "synthetic_val_map50": r["synthetic_val_map50"], "real_ap50": f["ap50"],
                      "real_recall": f["recall"], "real": f,
                      "weights": str(Path(s["run_dir"], r["weights"]).relative_to(os.path.realpath(out))),
                      "predictions": {k: str(Path(s["run_dir"], v).relative_to(os.path.realpath(out)))
                                      for k, v in r["predictions"].items()}}
                     for (s, r), f in zip(rs, figs)],
            "images_per_s": spread([r["images_per_s"] for _, r in rs]),
            "peak_gpu_mib": max((r["peak_gpu_mib"] for _, r in rs if r["peak_gpu_mib"] is not None), default=None),
        }
        if b.stream is not None:
            entry["stream"] = {"images_per_epoch": b.images, "pool": b.stream["pool"],
                               "refresh": b.stream["refresh"] if b.stream["pool"] is not None else None,
                               "epochs": [r["epochs"] for _, r in rs],
                               "stream_seeds": [s["stream"]["seed"] for s, _ in rs]}
        entry.update(_arm_stats(figs))
        if a.name != plan.baseline:
            entry["vs_baseline"] = vs[a.name].to_dict()
            entry["vs_baseline_per_group"] = {g: v[a.name].to_dict() for g, v in vs_group.items()}
        arms.append(entry)
        by_arm[a.name] = scored[a.name][0]
    report = {
        "format": REPORT_FORMAT, "version": 2, "kind": "plan",
        "plan": {"path": str(plan.path), "baseline": plan.baseline, "seeds": list(plan.seeds),
                 "content": plan.raw},
        "parameters": {"real": str(plan.real), "real_scale": list(base_cfg.real_scale),
                       "tile": base_cfg.tile, "overlap": base_cfg.overlap, "conf": base_cfg.conf,
                       "merge_iou": base_cfg.merge_iou, "real_gsd": base_cfg.real_gsd,
                       "real_classes": None if base_cfg.real_classes is None else list(base_cfg.real_classes),
                       "export_workers": export_workers},
        "versions": dict(aerial_synth=__version__, python=sys.version.split()[0], **ultra.versions()),
        "device": device, "parallel": par, "gpu_utilisation": gpu,
        "confidence": {"method": CONFIDENCE_METHOD, "level": INTERVAL, "replicates": BOOTSTRAP,
                       "spread": "sample standard deviation over seeds (ddof 1)"},
        "real": real_summary(base_cfg, items, {}, opts[0]),
        "scoring": dict(opts[0].to_dict(), metric="voc07", iou_threshold=0.5,
                        ignore_classes_by_group={g: list(c) for g, c in plan.ignore_classes.items()}),
        "arms": arms, "files": {},
    }
    curves = {k: v[1] for k, v in by_arm.items()}
    sheets = {k: (v[0], rep.best_f1_threshold(rep.agnostic(v[1]))) for k, v in by_arm.items()}
    report["files"] = write_figures(out, report, curves, sheets, items, base_cfg.contact_images)
    report["files"].update(summary="summary.txt", report="report.json")
    atomic_write_text(out / "summary.txt", rep.plan_summary_text(report) + "\n")
    atomic_write_json(out / "report.json", report)
    return report


# -- sim2real score ----------------------------------------------------------------------------------

def run_score(weights: list, real, out, *, device: str = "auto", real_gsd=None, real_classes=None,
              real_scale=("arm",), iou_type="auto", ignore_border=None, group=None, conf=0.001,
              merge_iou=0.3, batch=8, contact_images=6, force=False, ignore_classes=None) -> dict:
    """Predict and score ``real`` with kept weights (no training): the same tiling (the
    weights' image size, GSD and tiles, kept in the file), merge, scoring and report layout
    as a run. One "arm" per weights file."""
    ultra.require_train_extra()
    ws = [Path(w) for w in weights]
    for w in ws:
        if not os.path.lexists(w):
            raise Sim2RealError(f"--weights {w}: no such file")
        if not w.is_file():  # a folder, a device, a FIFO: never opened
            raise Sim2RealError(f"--weights {w}: expected a .pt file, found "
                                f"{'a folder' if w.is_dir() else 'no regular file'}")
    out = check_output_dir(Path(out), "--out")
    if out.exists() and any(out.iterdir()) and not (force and (out / "report.json").is_file()):
        raise Sim2RealError(f"--out {out}: exists and is not empty; choose a new folder"
                            + ("" if not (out / "report.json").is_file() else " or use --force"))
    for opt, p in [("--real", Path(real))] + [("--weights", w) for w in ws]:
        if is_inside(out, p) or is_inside(p, out):
            raise Sim2RealError(f"--out {out}: overlaps the input {opt} {p}; choose another folder")
    metas = [ultra.weights_meta(w) for w in ws]
    names, seen = [], set()
    for w, m in zip(ws, metas):
        base = f"{m['arm']}-seed{m['seed']}" if "arm" in m and "seed" in m else w.stem
        n, k = base, 2
        while n in seen:
            n, k = f"{base}-{k}", k + 1
        seen.add(n)
        names.append(n)
    cfgs = []
    for w, m, name in zip(ws, metas, names):
        imgsz = int(m.get("imgsz", 640))
        try:  # the arm is the weights file: nothing to train from, so no folders
            cfgs.append(Sim2RealConfig(arms=(Arm(name, ()),), real=Path(real), out=out, epochs=1, imgsz=imgsz, device=device,
                                       tile=m.get("tile"), overlap=m.get("overlap"), gsd=m.get("gsd_m"),
                                       real_gsd=real_gsd, real_scale=real_scale, real_classes=real_classes,
                                       conf=conf, merge_iou=merge_iou, iou_type=iou_type,
                                       ignore_border=dict(ignore_border or {}), group=group, batch=batch,
                                       contact_images=contact_images))
        except Sim2RealError as exc:
            raise Sim2RealError(f"--weights {w}: {exc}") from None
        if "arm" in cfgs[-1].real_scale and m.get("gsd_m") is None:
            raise Sim2RealError(f"--weights {w}: no GSD recorded in the file (not kept by sim2real); "
                                f"use --real-scale native")
    items = read_real(Path(real), cfgs[0].real_classes)
    for c in cfgs:
        _real_checks(c, items, ignore_classes)
    dev, dev_name = ultra.resolve_device(device)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(os.path.realpath(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)))
    try:
        opts = _options(cfgs[0])
        arms, by_arm = [], {}
        for w, m, n, c in zip(ws, metas, names, cfgs):
            real_d = {"dir": str(real), "classes": None if c.real_classes is None else list(c.real_classes),
                      "real_gsd": c.real_gsd, "tile": c.tile, "overlap": c.overlap, "imgsz": c.imgsz,
                      "conf": c.conf, "merge_iou": c.merge_iou, "batch": c.batch}
            log(f"{n}: predicting {len(items)} real images with {w}")
            preds = predict_real(w, real_d, {sc: (c.gsd if sc == "arm" else None) for sc in c.real_scale},
                                 tmp / "arms" / n, dev, list(m.get("classes") or []) or ["small-vehicle"])
            by_scale = {sc: _score_run(items, tmp / "arms" / n / rel, opts, ignore_classes)
                        for sc, rel in preds.items()}
            dets, agn, figs = by_scale[c.real_scale[0]]
            by_arm[n] = (dets, agn)
            arms.append({"name": n, "weights": str(w), "meta": m, "gsd_m": m.get("gsd_m"),
                         "imgsz": c.imgsz, "tile": c.tile, "overlap": c.overlap,
                         "real_scale": c.real_scale[0], "real_ap50": figs["ap50"], "real_recall": figs["recall"],
                         "real": figs, "real_by_scale": {sc: {"ap50": f[2]["ap50"], "recall": f[2]["recall"],
                                                              "predictions": f"arms/{n}/{preds[sc]}"}
                                                         for sc, f in by_scale.items()},
                         "predictions": f"arms/{n}/{preds[c.real_scale[0]]}"})
        report = {"format": REPORT_FORMAT, "version": 2, "kind": "score",
                  "parameters": {"real": str(real), "real_scale": list(cfgs[0].real_scale), "conf": conf,
                                 "merge_iou": merge_iou, "real_gsd": real_gsd,
                                 "real_classes": None if cfgs[0].real_classes is None else list(cfgs[0].real_classes)},
                  "versions": dict(aerial_synth=__version__, python=sys.version.split()[0], **ultra.versions()),
                  "device": {"requested": device, "used": dev, "name": dev_name},
                  "real": real_summary(cfgs[0], items, {}, opts[0]),
                  "scoring": dict(opts[0].to_dict(), metric="voc07", iou_threshold=0.5,
                                  ignore_classes_by_group={g: list(c) for g, c in (ignore_classes or {}).items()}),
                  "arms": arms, "files": {}}
        curves = {k: v[1] for k, v in by_arm.items()}
        sheets = {k: (v[0], rep.best_f1_threshold(rep.agnostic(v[1]))) for k, v in by_arm.items()}
        report["files"] = write_figures(tmp, report, curves, sheets, items, contact_images)
        report["files"].update(summary="summary.txt", report="report.json")
        atomic_write_text(tmp / "summary.txt", rep.score_summary_text(report) + "\n")
        atomic_write_json(tmp / "report.json", report)
        replace_dir(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return report
