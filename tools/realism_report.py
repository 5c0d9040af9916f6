"""Realism figures: synthetic frames against real aerial samples (issue 15).

    .venv/bin/python tools/realism_report.py REAL_DIR SYNTH_DIR [--json OUT.json]

Per image: gray mean and gray standard deviation (OpenCV's BGR -> gray, i.e. ITU-R 601
luma), and for every vehicle box its *contrast*: mean gray of the pixels whose centre lies
inside the oriented box minus mean gray of a 4 px ring around it (the box dilated by a 9 x 9
ellipse, minus the box, minus every other box of the image), in units of the image's gray
sd: the same definition and code as ``aerial-synth stats`` (``vehicle_pixels``).
Reports the two-sample KS statistic (scipy.stats.ks_2samp) between the real and the synthetic
per-image means and sds, and the median |contrast| of each side.

Layouts it reads (found recursively):

- DOTA text labels: ``.../images/X.png|jpg`` with ``.../labelTxt/X.txt`` (x1 y1 .. x4 y4 cls
  difficult; our ``aerial-synth export --format dota``). Vehicle classes: small-vehicle,
  large-vehicle.
- YOLO-OBB: ``.../images/X.jpg`` with ``.../labels/X.txt`` (cls x1 y1 .. x4 y4, normalised),
  DOTA class ids 9 (large vehicle) and 10 (small vehicle), as in Ultralytics' dota8.
- VEDAI: ``images/N_co.png`` with ``annotations512/N.txt`` (xc yc angle cls contained occluded
  x1..x4 y1..y4); every class but boats (23) and planes (31) is a vehicle. ``*_ir.png`` skipped.
- ``aerial-synth render`` output: ``NNNNNN/rgb.png`` with ``instance.png``; boxes are the
  minimum-area rectangles of each instance's visible pixels (>= 30 px).

The project never reads the real samples at run time; this tool takes them as an argument.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from aerial_synth.evaluate.stats import RING_PX, vehicle_pixels  # noqa: E402

DOTA_VEHICLES = {"small-vehicle", "large-vehicle"}
YOLO_VEHICLES = {9, 10}
VEDAI_NOT_VEHICLES = {23, 31}


def _dota_boxes(txt: Path) -> list[tuple[np.ndarray, bool]]:
    out = []
    for line in txt.read_text().splitlines():
        parts = line.split()
        if len(parts) >= 9 and parts[8] in DOTA_VEHICLES:
            hard = len(parts) >= 10 and parts[9] == "1"
            out.append((np.array(parts[:8], float).reshape(4, 2), hard))
    return out


def _yolo_boxes(txt: Path, w: int, h: int) -> list[np.ndarray]:
    out = []
    for line in txt.read_text().splitlines():
        parts = line.split()
        if len(parts) >= 9 and int(parts[0]) in YOLO_VEHICLES:
            out.append((np.array(parts[1:9], float).reshape(4, 2) * [w, h], False))
    return out


def _vedai_boxes(txt: Path) -> list[np.ndarray]:
    out = []
    for line in txt.read_text().splitlines():
        parts = line.split()
        if len(parts) >= 14 and int(parts[3]) not in VEDAI_NOT_VEHICLES:
            xs = np.array(parts[6:10], float)
            ys = np.array(parts[10:14], float)
            out.append((np.stack([xs, ys], 1), parts[5] == "1"))  # occluded flag
    return out


def _instance_boxes(inst_png: Path) -> list[np.ndarray]:
    inst = cv2.imread(str(inst_png), cv2.IMREAD_UNCHANGED)
    out = []
    for vid in np.unique(inst):
        if vid == 0:
            continue
        ys, xs = np.nonzero(inst == vid)
        if len(xs) < 30:
            continue
        pts = np.stack([xs, ys], 1).astype(np.float32) + 0.5
        out.append((cv2.boxPoints(cv2.minAreaRect(pts)).astype(float), False))
    return out


def collect(root: Path) -> list[tuple[Path, list[np.ndarray] | None]]:
    """[(image path, [(box (4, 2) pixel corners, difficult)] or None when unlabelled)]."""
    items = []
    for img in sorted(root.rglob("*")):
        if img.suffix.lower() not in (".png", ".jpg", ".jpeg") or not img.is_file():
            continue
        name = img.name
        if name.endswith("_ir.png"):
            continue
        if img.parent.name == "images" or "images" in img.parts:
            rel = img.parent
            stem = img.stem
            if name.endswith("_co.png"):
                ann = img.parent.parent / "annotations512" / (stem[:-3] + ".txt")
                items.append((img, _vedai_boxes(ann) if ann.is_file() else None))
                continue
            txt = Path(str(rel).replace("/images", "/labelTxt")) / (stem + ".txt")
            if txt.is_file():
                items.append((img, _dota_boxes(txt)))
                continue
            txt = Path(str(rel).replace("/images", "/labels")) / (stem + ".txt")
            if txt.is_file():
                im = cv2.imread(str(img))
                items.append((img, _yolo_boxes(txt, im.shape[1], im.shape[0])))
                continue
            items.append((img, None))
        elif name == "rgb.png":
            inst = img.parent / "instance.png"
            items.append((img, _instance_boxes(inst) if inst.is_file() else None))
    return items


def measure(items) -> dict:
    means, sds, contrast, colour, colourful, hard_flags = [], [], [], [], [], []
    for img, boxes in items:
        bgr = cv2.imread(str(img), cv2.IMREAD_COLOR)
        gray = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY).astype(np.float64)
        m, s = gray.mean(), gray.std()
        means.append(m)
        sds.append(s)
        colour.append(bgr.reshape(-1, 3).mean(0)[::-1].tolist())
        f = bgr.astype(np.float64)
        rg = f[..., 2] - f[..., 1]
        yb = 0.5 * (f[..., 2] + f[..., 1]) - f[..., 0]
        colourful.append(float(np.hypot(rg.std(), yb.std())
                               + 0.3 * np.hypot(rg.mean(), yb.mean())))
        if boxes and s > 0:
            # the one definition of `aerial-synth stats` (aerial_synth.evaluate.stats):
            # pixels whose centre lies in the box; a 4 px ring (elliptic dilation) minus the
            # box and minus every other box of the image
            m_in, m_ring, _, _ = vehicle_pixels(gray, [b for b, _ in boxes], RING_PX)
            for mi, mr, (_, hard) in zip(m_in, m_ring, boxes):
                if np.isfinite(mi) and np.isfinite(mr):
                    contrast.append((mi - mr) / s)
                    hard_flags.append(hard)
    c = np.asarray(contrast)
    clear = c[~np.asarray(hard_flags, bool)] if len(c) else c
    return {
        "images": len(means),
        "vehicles": int(len(c)),
        "gray_mean": means,
        "gray_sd": sds,
        "mean_rgb": colour,
        "colourfulness": colourful,
        "contrast_median_abs": float(np.median(np.abs(c))) if len(c) else None,
        "contrast_median_signed": float(np.median(c)) if len(c) else None,
        "contrast_brighter_fraction": float((c > 0).mean()) if len(c) else None,
        "vehicles_not_difficult": int(len(clear)),
        "contrast_median_abs_not_difficult": float(np.median(np.abs(clear))) if len(clear)
        else None,
        "contrast_abs": np.abs(c).tolist(),
    }


def _q(v) -> str:
    a = np.asarray(v)
    return f"{a.min():6.1f} {np.percentile(a, 25):6.1f} {np.median(a):6.1f} " \
           f"{np.percentile(a, 75):6.1f} {a.max():6.1f}"


def main(argv=None) -> int:
    from scipy.stats import ks_2samp

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("real", type=Path)
    ap.add_argument("synth", type=Path)
    ap.add_argument("--json", type=Path, default=None, help="write the figures here")
    a = ap.parse_args(argv)
    real, synth = measure(collect(a.real)), measure(collect(a.synth))
    if not real["images"] or not synth["images"]:
        print("no images found", file=sys.stderr)
        return 2
    ks_m = ks_2samp(real["gray_mean"], synth["gray_mean"]).statistic
    ks_s = ks_2samp(real["gray_sd"], synth["gray_sd"]).statistic
    cr, cs = real["contrast_median_abs"], synth["contrast_median_abs"]
    print(f"{'':10s} {'images':>6s} {'vehicles':>8s}   gray mean min/q1/med/q3/max"
          f"          gray sd min/q1/med/q3/max          |contrast| med  signed med  brighter")
    for name, r in (("real", real), ("synthetic", synth)):
        print(f"{name:10s} {r['images']:6d} {r['vehicles']:8d}   {_q(r['gray_mean'])}   "
              f"{_q(r['gray_sd'])}   {r['contrast_median_abs'] or float('nan'):8.2f}  "
              f"{r['contrast_median_signed'] or float('nan'):10.2f}  "
              f"{r['contrast_brighter_fraction'] or float('nan'):8.2f}")
    for name, r in (("real", real), ("synthetic", synth)):
        rgb = np.asarray(r["mean_rgb"]) + 1.0
        print(f"{name:10s} colourfulness (Hasler-Suesstrunk) {_q(r['colourfulness'])}   "
              f"median log(R/B) {np.median(np.log(rgb[:, 0] / rgb[:, 2])):+.3f}  "
              f"log(G/(R+B)/2) {np.median(np.log(2 * rgb[:, 1] / (rgb[:, 0] + rgb[:, 2]))):+.3f}")
    ks_c = ks_2samp(real["colourfulness"], synth["colourfulness"]).statistic
    print(f"KS colourfulness {ks_c:.3f}")
    gap = (cs / cr - 1.0) if (cr and cs) else float("nan")
    for name, r in (("real", real), ("synthetic", synth)):
        print(f"{name:10s} not difficult / not occluded: {r['vehicles_not_difficult']} vehicles, "
              f"median |contrast| {r['contrast_median_abs_not_difficult'] or float('nan'):.2f}")
    print(f"KS gray mean {ks_m:.3f} (target <= 0.3)   KS gray sd {ks_s:.3f} (target <= 0.3)   "
          f"contrast ours/real - 1 = {gap:+.0%} (target within 30 %)")
    if real["vehicles"] >= 2 and cs:
        # how well the real median is known: bootstrap over the real vehicles (seed 0)
        rc = np.asarray(real["contrast_abs"])
        boot = np.median(np.random.default_rng(0).choice(rc, (10000, len(rc))), axis=1)
        lo, hi = np.quantile(boot, [0.025, 0.975])
        print(f"real median |contrast| bootstrap 95 % interval {lo:.2f}-{hi:.2f} "
              f"({len(rc)} vehicles); ours within 30 % of the resampled median in "
              f"{np.mean(np.abs(cs / boot - 1.0) <= 0.3):.0%} of 10,000 resamples")
    if a.json:
        a.json.write_text(json.dumps({"real": real, "synthetic": synth, "ks_gray_mean": ks_m,
                                      "ks_gray_sd": ks_s, "ks_colourfulness": ks_c,
                                      "contrast_gap": gap}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
