"""``aerial-synth sim2real``: train one detector per synthetic set (arm), predict the real
images (rescaled to the synthetic GSD, tiled, merged back into their own pixel frame),
score them and write one report that compares the arms.

Order: every input is checked (and the [train] extra found) before anything is written;
the run is built in a temporary sibling of ``out`` and renamed into place at the end, so a
failed or interrupted run leaves nothing behind.

Layout of ``out``::

    report.json  summary.txt  pr.png  pr_<group>.png  contact_<arm>.png
    arms/<arm>/predictions/Task1_<class>.txt   (real images, original pixels; names as --real)
    arms/<arm>/train/                          (Ultralytics' run: weights/best.pt, results.csv, args.yaml)
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

from .. import __version__
from ..evaluate.ap import Detections
from ..evaluate.evaluation import read_task1_folder
from ..evaluate.plots import png_bytes
from ..evaluate.scoring import ScoringOptions, ignore_border, image_groups, score
from ..io_utils import (
    atomic_write_bytes,
    atomic_write_json,
    atomic_write_text,
    check_output_dir,
    is_inside,
    replace_dir,
)
from ..safe_input import read_image
from . import report as rep
from . import ultra
from .config import Sim2RealConfig, Sim2RealError, SyntheticSet, inspect_synthetic
from .real import RealImage, load_scaled, merge_tiles, plan_image, read_real, tiles_of

__all__ = ["REPORT_FORMAT", "log", "real_summary", "write_figures", "check_inputs", "run_sim2real", "write_task1", "prepare_training_set",
           "predict_plans"]

REPORT_FORMAT = "aerial-synth-sim2real"
AGNOSTIC = "vehicle"


def log(msg: str) -> None:
    print(f"sim2real: {msg}", file=sys.stderr, flush=True)


def check_inputs(cfg: Sim2RealConfig):
    """Everything that can be refused without training: (sets per arm, GSD per arm, real
    labels, plans per GSD, scoring options). Raises Sim2RealError; writes nothing."""
    ultra.require_train_extra()
    out = check_output_dir(cfg.out, "--out")
    if out.exists() and any(out.iterdir()):
        if not (cfg.force and (out / "report.json").is_file()):
            raise Sim2RealError(f"--out {out}: exists and is not empty" + (
                "" if (out / "report.json").is_file() else " (not a sim2real report)") +
                ("; use --force to replace it" if (out / "report.json").is_file() else "; choose a new folder"))
    inputs = [("--real", Path(cfg.real))] + [(f"--synthetic {a.name}", d) for a in cfg.arms for d in a.dirs]
    for opt, p in inputs:
        if is_inside(out, p) or is_inside(p, out):
            raise Sim2RealError(f"--out {out}: overlaps the input folder {opt} {p}; choose another folder")
    sets: dict[str, list[SyntheticSet]] = {}
    gsds: dict[str, float | None] = {}
    for a in cfg.arms:
        ss = [inspect_synthetic(d, f"--synthetic {a.name}=") for d in a.dirs]
        if len({s.names for s in ss}) > 1:
            raise Sim2RealError(f"--synthetic {a.name}: its folders have different class lists "
                                f"({' vs '.join(str(list(s.names)) for s in ss)})")
        g = {s.gsd_m for s in ss}
        if cfg.gsd is not None:
            gsds[a.name] = cfg.gsd
        elif len(g) == 1 and None not in g:
            gsds[a.name] = g.pop()
        else:
            raise Sim2RealError(f"--synthetic {a.name}: " + (
                "no GSD known (no export manifest.json with gsd_m)" if None in g else
                f"its folders have different GSDs {sorted(g)}") + "; give --gsd M to rescale the real "
                "images to M metres per pixel")
        sets[a.name] = ss
    items = read_real(Path(cfg.real), cfg.real_classes)
    opts = ScoringOptions((AGNOSTIC, None), cfg.iou_type, dict(cfg.ignore_border), cfg.group)
    groups = sorted(set(image_groups(items, cfg.group)))
    for k in cfg.ignore_border:
        if k is not None and k not in groups:
            raise Sim2RealError(f"--ignore-border: no group {k!r} in --real (groups: {', '.join(groups)})")
    targets = {t for a in cfg.arms for t in (_target(cfg, gsds, a.name, s) for s in cfg.real_scale)}
    plans = {t: [plan_image(it, t, cfg.real_gsd, cfg.tile, cfg.overlap) for it in items]
             for t in sorted(targets, key=lambda t: (t is not None, t or 0.0))}
    return out, sets, gsds, items, plans, opts


def _target(cfg: Sim2RealConfig, gsds: dict, arm: str, scale: str) -> float | None:
    """The GSD the real images are rescaled to for ``arm`` (None: kept at their own pixels)."""
    return gsds[arm] if scale == "arm" else None


def prepare_training_set(folder: Path, sets: list[SyntheticSet]) -> tuple[Path, int, int, bool]:
    """A private mirror of an arm's YOLO-OBB folders (images hard-linked, else copied; labels
    copied), so Ultralytics' label caches land here, not in the user's exports. Returns
    (data yaml, training images, validation images, validation is the training set)."""
    import yaml

    train_dirs, val_dirs = [], []
    for i, s in enumerate(sets):
        for split, src in (("train", s.train_images), ("val", s.val_images)):
            if src is None:
                continue
            dst_img = folder / f"set{i}" / "images" / split
            dst_lab = folder / f"set{i}" / "labels" / split
            dst_img.mkdir(parents=True, exist_ok=True)
            dst_lab.mkdir(parents=True, exist_ok=True)
            lab_src = s.root / "labels" / src.relative_to(s.root / "images")
            for p in sorted(src.iterdir()):
                if not p.is_file() or p.suffix.lower() not in (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp"):
                    continue
                try:
                    os.link(p, dst_img / p.name)
                except OSError:
                    shutil.copyfile(p, dst_img / p.name)
                shutil.copyfile(lab_src / (p.stem + ".txt"), dst_lab / (p.stem + ".txt"))
            (train_dirs if split == "train" else val_dirs).append(str(dst_img.resolve()))  # guard: the staged build
    val_is_train = not val_dirs
    data = {"path": str(folder.resolve()), "train": train_dirs, "val": val_dirs or train_dirs,  # guard: the staged build
            "names": dict(enumerate(sets[0].names))}
    y = folder / "data.yaml"
    y.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")  # guard: inside the staged build
    return y, sum(s.n_train for s in sets), sum(s.n_val for s in sets), val_is_train


def write_task1(folder: Path, names: list[str], xy: np.ndarray, scores: np.ndarray,
                classes: list[str], all_classes: list[str]) -> list[Path]:
    """DOTA task-1 files, one per class (``image score x1 y1 .. x4 y4``; 3 decimals for
    coordinates, 6 for scores; rows by image, then score descending)."""
    folder.mkdir(parents=True, exist_ok=True)
    rows: dict[str, list[str]] = {c: [] for c in all_classes}
    for n, p, s, c in zip(names, np.asarray(xy).reshape(-1, 8), scores, classes):
        rows.setdefault(c, []).append(f"{n} {s:.6f} " + " ".join(f"{v:.3f}" for v in p))
    out = []
    for c, lines in sorted(rows.items()):
        safe = "".join(ch if ch.isalnum() or ch in "-_." else "-" for ch in c)
        out.append(atomic_write_text(folder / f"Task1_{safe}.txt", "".join(ln + "\n" for ln in lines)))
    return out


def predict_plans(predictor, plans: list[RealImage], batch: int, merge_iou: float):
    """Per real image: merged (xy original px, scores, classes)."""
    out = []
    for r in plans:
        img = load_scaled(r)
        per_tile = predictor(tiles_of(img, r), batch=batch)
        out.append(merge_tiles(r, per_tile, merge_iou))
    return out


def run_sim2real(cfg: Sim2RealConfig) -> dict:
    """Run every arm and write the report into ``cfg.out``; returns report.json's content."""
    out, sets, gsds, items, plans, opts = check_inputs(cfg)
    device, device_name = ultra.resolve_device(cfg.device)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)).resolve()  # guard: the temporary folder it made
    try:
        report = _run(cfg, tmp, sets, gsds, items, plans, opts, device, device_name)
        replace_dir(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return report


def _run(cfg, tmp: Path, sets, gsds, items, plans, opts, device, device_name) -> dict:
    names = [g.name for g in items]
    per_class_opts = ScoringOptions(None, opts.iou_type, opts.ignore_border, opts.group)
    arms, curves, sheets, pr_curves = [], {}, {}, {}
    for a in cfg.arms:
        arm_dir = tmp / "arms" / a.name
        data_yaml, n_train, n_val, val_is_train = prepare_training_set(arm_dir / "data", sets[a.name])
        log(f"arm {a.name}: training on {n_train} images ({device_name}, "
             + (f"{cfg.minutes:g} min" if cfg.minutes is not None else f"{cfg.epochs} epochs") + ")")
        tr = ultra.train(data_yaml, arm_dir / "train", model=cfg.model, weights=cfg.weights,
                         epochs=cfg.epochs, minutes=cfg.minutes, imgsz=cfg.imgsz, device=device,
                         seed=cfg.seed, batch=cfg.batch, workers=cfg.workers)
        log(f"arm {a.name}: {tr.epochs} epochs in {tr.seconds:.0f} s; predicting {len(items)} real images")
        predictor = ultra.Predictor(tr.weights, imgsz=cfg.imgsz, device=device, conf=cfg.conf)
        shutil.rmtree(arm_dir / "data", ignore_errors=True)  # the mirror (links) is not output
        by_scale = {}
        for k, scale in enumerate(cfg.real_scale):  # the first is the headline
            pred_dir = arm_dir / ("predictions" if k == 0 else f"predictions_{scale}")
            merged = predict_plans(predictor, plans[_target(cfg, gsds, a.name, scale)], cfg.batch, cfg.merge_iou)
            img_names = [n for n, (_, sc, _) in zip(names, merged) for _ in range(len(sc))]
            xy = np.concatenate([m[0] for m in merged] or [np.zeros((0, 4, 2))])
            sc = np.concatenate([m[1] for m in merged] or [np.zeros(0)])
            cl = [c for m in merged for c in m[2]]
            write_task1(pred_dir, img_names, xy, sc, cl, list(sets[a.name][0].names))
            # scored from the files just written: what an independent `aerial-synth eval` reads
            dets = read_task1_folder(pred_dir, {n: i for i, n in enumerate(names)})
            agn = score(items, dets, opts)
            by_scale[scale] = (pred_dir, dets, agn, rep.arm_real_figures(agn, score(items, dets, per_class_opts)))
            label = a.name if k == 0 else f"{a.name} ({scale})"
            pr_curves[label] = agn
        pred_dir, dets, agn, figs = by_scale[cfg.real_scale[0]]
        curves[a.name] = agn
        thr = rep.best_f1_threshold(rep.agnostic(agn))
        sheets[a.name] = (dets, thr)
        if tmp not in tr.weights.resolve().parents:  # guard: weights in its own build
            raise RuntimeError(f"Ultralytics wrote the weights outside the run folder: {tr.weights}")
        weights_rel = tr.weights.resolve().relative_to(tmp)  # guard: weights in its own build
        arms.append({
            "name": a.name, "dirs": [str(d) for d in a.dirs], "gsd_m": gsds[a.name],
            "classes": list(sets[a.name][0].names), "training_images": n_train,
            "validation_images": n_train if val_is_train else n_val, "val_is_train": val_is_train,
            "epochs": tr.epochs, "seconds": round(tr.seconds, 1),
            "synthetic_val_map50": None if tr.val_map50 is None else round(tr.val_map50, 6),
            "synthetic_val_map50_95": None if tr.val_map50_95 is None else round(tr.val_map50_95, 6),
            "real_scale": cfg.real_scale[0], "real_ap50": figs["ap50"], "real_recall": figs["recall"],
            "real": figs,
            "real_by_scale": {s: {"gsd_m": _target(cfg, gsds, a.name, s), "ap50": f["ap50"],
                                  "recall": f["recall"], "real": f, "predictions": str(p.relative_to(tmp))}
                              for s, (p, _, _, f) in by_scale.items()},
            "contact_sheet_score_threshold": round(thr, 6),
            "predictions": str(pred_dir.relative_to(tmp)), "weights": str(weights_rel),
        })
        log(f"arm {a.name}: real AP50 {figs['ap50']}, recall {figs['recall']}")
    report = {
        "format": REPORT_FORMAT, "version": 1,
        "parameters": {
            "real": str(cfg.real), "model": None if cfg.weights else cfg.model,
            "weights": None if cfg.weights is None else str(cfg.weights), "minutes": cfg.minutes,
            "epochs": cfg.epochs, "imgsz": cfg.imgsz, "seed": cfg.seed, "batch": cfg.batch,
            "workers": cfg.workers, "tile": cfg.tile, "overlap": cfg.overlap, "gsd": cfg.gsd,
            "real_gsd": cfg.real_gsd, "real_scale": list(cfg.real_scale), "real_classes": None if cfg.real_classes is None else list(cfg.real_classes),
            "conf": cfg.conf, "merge_iou": cfg.merge_iou, "contact_images": cfg.contact_images,
        },
        "versions": dict(aerial_synth=__version__, python=sys.version.split()[0], **ultra.versions()),
        "device": {"requested": cfg.device, "used": device, "name": device_name},
        "real": real_summary(cfg, items, plans, opts),
        "scoring": dict(opts.to_dict(), metric="voc07", iou_threshold=0.5,
                        iou_type_by_group=dict(next(iter(curves.values())).iou_type) if curves else {},
                        ignore_border_px_by_group=dict(next(iter(curves.values())).border_px) if curves else {}),
        "arms": arms,
        "files": {},
    }
    files = write_figures(tmp, report, curves, sheets, items, cfg.contact_images, pr_curves)
    files["summary"] = "summary.txt"
    files["report"] = "report.json"
    report["files"] = files
    atomic_write_text(tmp / "summary.txt", rep.summary_text(report) + "\n")
    atomic_write_json(tmp / "report.json", report)
    return report


def _subset_dets(dets: Detections, chosen: list[int]) -> Detections:
    """The detections of images ``chosen``, re-indexed 0..len(chosen)-1."""
    remap = {i: k for k, i in enumerate(chosen)}
    m = np.array([int(i) in remap for i in np.asarray(dets.image)], bool)
    img = np.array([remap[int(i)] for i in np.asarray(dets.image)[m]], np.int64)
    return Detections(img, [c for c, k in zip(dets.classes, m) if k], np.asarray(dets.scores)[m],
                      np.asarray(dets.polygons_xy_px).reshape(-1, 4, 2)[m])


def real_summary(cfg, items, plans, opts) -> dict:
    groups = image_groups(items, opts.group)
    by_group: dict[str, dict] = {}
    for g, k in zip(items, groups):
        d = by_group.setdefault(k, {"images": 0, "vehicles": 0})
        d["images"] += 1
        d["vehicles"] += int((~np.asarray(g.difficult, bool)).sum())
    return {
        "dir": str(cfg.real), "images": len(items),
        "vehicles": sum(d["vehicles"] for d in by_group.values()),
        "groups": by_group,
        "tiles_by_gsd": {("native" if k is None else f"{k:g}"): sum(len(r.tiles) for r in v)
                         for k, v in plans.items()},
        "image_gsd_m": {g.name: r.gsd_m for g, r in zip(items, next(iter(plans.values())))} if plans else {},
    }


def write_figures(tmp: Path, report, curves, sheets, items, contact_images: int, pr_curves=None) -> dict:
    """PR charts (``pr_curves``: {label: ScoreResult}, every arm at every --real-scale; default
    ``curves``) and one contact sheet per arm (``curves``/``sheets``: the headline scale)."""
    import cv2

    files = {}
    if not curves or contact_images < 0:
        return files
    pr_curves = pr_curves or curves
    any_res = next(iter(curves.values()))
    img = rep.pr_chart("real images, class-agnostic (all groups)",
                       {k: rep.agnostic(v) for k, v in pr_curves.items()})
    atomic_write_bytes(tmp / "pr.png", png_bytes(img))
    files["pr"] = ["pr.png"]
    for grp in any_res.groups:
        safe = "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in grp)
        img = rep.pr_chart(f"real images, class-agnostic: {grp} ({any_res.iou_type[grp]})",
                           {k: rep.agnostic(v, grp) for k, v in pr_curves.items()})
        atomic_write_bytes(tmp / f"pr_{safe}.png", png_bytes(img))
        files["pr"].append(f"pr_{safe}.png")
    # contact sheet: the image with the most vehicles of each group, then the next fullest
    order = sorted(range(len(items)), key=lambda i: (-len(items[i]), items[i].name))
    groups = image_groups(items, any_res.options.group)
    chosen: list[int] = []
    for k in sorted(set(groups)):
        chosen.append(next(i for i in order if groups[i] == k))
    chosen += [i for i in order if i not in chosen]
    chosen = chosen[:contact_images]
    files["contact_sheets"] = []
    for a in report["arms"]:
        dets, thr = sheets[a["name"]]
        res = curves[a["name"]]
        # as scored: border truth ignored (grey), border detections gone
        shown, kept = ignore_border([items[i] for i in chosen], _subset_dets(dets, chosen),
                                    [res.border_px[groups[i]] for i in chosen])
        imgs, dsel, hbb = [], [], []
        for k, i in enumerate(chosen):
            imgs.append(read_image(items[i].image_path, cv2.IMREAD_COLOR, Sim2RealError))
            m = np.asarray(kept.image) == k
            dsel.append((np.asarray(kept.polygons_xy_px)[m], np.asarray(kept.scores)[m]))
            hbb.append(res.iou_type[groups[i]] == "hbb")
        sheet = rep.contact_sheet(shown, imgs, dsel, thr, hbb)
        safe = "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in a["name"])
        atomic_write_bytes(tmp / f"contact_{safe}.png", png_bytes(sheet))
        files["contact_sheets"].append(f"contact_{safe}.png")
    return files
