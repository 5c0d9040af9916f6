"""Benchmark ``aerial-synth eval``: N images x K objects (default 1,000 x 100).

Builds a DOTA labelTxt ground truth (two classes, 10 % difficult) and DOTA task-1
predictions (every object found with 2 px jitter, 20 % duplicates, 20 % clutter) in a
temporary folder, then times, best of ``--repeat``:

- ``evaluate()`` on arrays already in memory (the matching and AP alone);
- ``run_eval()`` from the files (parsing + matching + AP), the work of ``aerial-synth eval``;
- the same with ``--metric coco`` (ten IoU thresholds).

Prints the figures; asserts nothing about time.

    .venv/bin/python tools/bench_eval.py [--images 1000] [--objects 100] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np


def rects(rng, n, size=1024.0):
    c = rng.uniform(20, size - 20, (n, 2))
    lw = np.stack([rng.uniform(14, 40, n), rng.uniform(7, 14, n)], 1)
    t = rng.uniform(0, np.pi, n)
    f = np.stack([np.cos(t), -np.sin(t)], 1)
    r = np.stack([np.sin(t), np.cos(t)], 1)
    L, W = lw[:, :1] / 2, lw[:, 1:] / 2
    return np.stack([c + f * L - r * W, c + f * L + r * W, c - f * L + r * W, c - f * L - r * W], 1)


def build(root: Path, n_img: int, k: int, seed: int = 0) -> tuple[Path, Path]:
    rng = np.random.default_rng(seed)
    gt = root / "gt" / "labelTxt"
    gt.mkdir(parents=True)
    pred = root / "pred"
    pred.mkdir()
    task1 = {"small-vehicle": [], "large-vehicle": []}
    for i in range(n_img):
        name = f"P{i:05d}"
        boxes = rects(rng, k)
        cls = np.where(rng.random(k) < 0.8, "small-vehicle", "large-vehicle")
        diff = rng.random(k) < 0.1
        lines = ["imagesource:bench", "gsd:0.12"]
        for b, c, d in zip(boxes, cls, diff):
            lines.append(" ".join(f"{v:.2f}" for v in b.reshape(-1)) + f" {c} {int(d)}")
        (gt / f"{name}.txt").write_text("\n".join(lines) + "\n")
        det = boxes + rng.normal(0, 2.0, boxes.shape)
        dcls = list(cls)
        dup = rng.random(k) < 0.2
        det = np.concatenate([det, boxes[dup] + rng.normal(0, 4.0, boxes[dup].shape)])
        dcls += list(cls[dup])
        n_clutter = int(0.2 * k)
        det = np.concatenate([det, rects(rng, n_clutter)])
        dcls += list(np.where(rng.random(n_clutter) < 0.8, "small-vehicle", "large-vehicle"))
        score = rng.random(len(det))
        for b, c, s in zip(det, dcls, score):
            task1[c].append(f"{name} {s:.4f} " + " ".join(f"{v:.1f}" for v in b.reshape(-1)))
    for c, lines in task1.items():
        (pred / f"Task1_{c}.txt").write_text("\n".join(lines) + "\n")
    return gt, pred


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=int, default=1000)
    ap.add_argument("--objects", type=int, default=100)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()

    from aerial_synth.evaluate.ap import evaluate
    from aerial_synth.evaluate.evaluation import read_task1_folder, run_eval
    from aerial_synth.evaluate.labels import read_dota_folder

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        gt, pred = build(Path(tmp), args.images, args.objects)
        print(f"built {args.images} images x {args.objects} objects in {time.perf_counter() - t0:.1f} s")
        items = read_dota_folder(gt, None)
        dets = read_task1_folder(pred, {g.name: i for i, g in enumerate(items)})
        n_gt = sum(len(g) for g in items)
        print(f"ground truth boxes {n_gt:,}, detections {len(dets):,}")

        def best(fn):
            """(best wall s, best CPU s of this process, result): the machine is shared, so
            CPU time shows the work when other jobs stretch the wall clock."""
            walls, cpus = [], []
            out = None
            for _ in range(args.repeat):
                t, c = time.perf_counter(), time.process_time()
                out = fn()
                walls.append(time.perf_counter() - t)
                cpus.append(time.process_time() - c)
            return min(walls), min(cpus), out

        print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
        for label, fn in (
            ("evaluate() in memory, voc07 IoU>0.5     ", lambda: evaluate(items, dets, metric="voc07")),
            ("run_eval() from files (aerial-synth eval)", lambda: run_eval(gt, pred, metric="voc07")),
            ("run_eval() from files, coco 0.50:0.95    ", lambda: run_eval(gt, pred, metric="coco")),
        ):
            wall, cpu, res = best(fn)
            print(f"{label}  wall {wall:6.2f} s  cpu {cpu:6.2f} s  mAP {res.map:.4f}")


if __name__ == "__main__":
    main()
