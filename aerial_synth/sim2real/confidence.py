"""How sure a sim2real comparison is: mean and spread over seeds, and the paired difference
of two arms with a 95 % bootstrap interval.

The method (docs/sim2real.md): a *paired* bootstrap over real images and seeds. One
replicate draws the real images with replacement (a weight per image: how often it was
drawn) and the seed positions with replacement; every arm is scored on the same draw, so
the difference is paired on both. An arm's AP50 in a replicate is the mean, over the drawn
seeds, of the VOC07 AP recomputed from its detections with those image weights (the
matching of a detection to a truth box stays within its image, so it does not change; only
the curve's counts are weighted). The interval is the 2.5 and 97.5 percentiles of the
replicates' differences. Images are the resampled unit because detections on one image are
not independent; seeds because one training run is one draw of the training's randomness.
A replicate with all weight 1 and every seed once is exactly the report's figure (tested).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..evaluate.ap import ClassResult

__all__ = ["spread", "weighted_ap", "paired_difference", "Difference", "BOOTSTRAP", "INTERVAL"]

#: replicates of the bootstrap, and the RNG seed that makes a report reproducible
BOOTSTRAP = 2000
INTERVAL = 0.95
_CHUNK = 200
_T11 = np.arange(0.0, 1.1, 0.1)


def spread(values) -> dict:
    """Mean and sample standard deviation (ddof 1; 0 for one value) of the values that are
    not None; None when there are none."""
    v = np.array([x for x in values if x is not None], np.float64)
    if not len(v):
        return {"mean": None, "sd": None, "n": 0, "values": list(values)}
    return {"mean": round(float(v.mean()), 6), "sd": round(float(v.std(ddof=1)) if len(v) > 1 else 0.0, 6),
            "n": int(len(v)), "values": [None if x is None else round(float(x), 6) for x in values]}


def weighted_ap(c: ClassResult, w: np.ndarray) -> np.ndarray:
    """VOC07 AP of ``c`` with image weights ``w`` (B, n_images): (B,), NaN where the
    weighted truth is 0. With w = 1 it is ``c.ap`` (evaluate's curve, the same counts)."""
    w = np.atleast_2d(np.asarray(w, np.float64))
    if c.det_image is None:
        raise ValueError("ClassResult without per-detection data (made by an older evaluate)")
    npos = w @ np.asarray(c.npos_by_image, np.float64)
    out = np.full(len(w), np.nan)
    if not len(c.det_image):
        out[npos > 0] = 0.0
        return out
    dw = w[:, np.asarray(c.det_image, np.int64)]
    ctp = np.cumsum(dw * np.asarray(c.det_tp, np.float64), axis=1)
    cfp = np.cumsum(dw * np.asarray(c.det_fp, np.float64), axis=1)
    ok = npos > 0
    rec = ctp / np.where(ok, npos, 1.0)[:, None]
    prec = ctp / np.maximum(ctp + cfp, np.finfo(np.float64).eps)
    ap = np.zeros(len(w))
    for t in _T11:
        ap += np.where(rec >= t, prec, 0.0).max(axis=1) / 11.0
    out[ok] = ap[ok]
    return out


@dataclass(frozen=True)
class Difference:
    """Arm minus baseline: the point difference of the seed means, its interval, and the
    verdict ("no difference" when the interval holds 0)."""

    diff: float | None
    lo: float | None
    hi: float | None
    replicates: int

    @property
    def verdict(self) -> str:
        if self.diff is None or self.lo is None:
            return "-"
        if self.lo <= 0.0 <= self.hi:
            return "no difference"
        return "better" if self.lo > 0 else "worse"

    def to_dict(self) -> dict:
        r = (lambda v: None if v is None else round(float(v), 6))
        return {"diff": r(self.diff), "lo": r(self.lo), "hi": r(self.hi), "level": INTERVAL,
                "replicates": self.replicates, "verdict": self.verdict}


def paired_difference(arm: list[ClassResult], base: list[ClassResult], images=None, *,
                      replicates: int = BOOTSTRAP, seed: int = 0) -> Difference:
    """Paired bootstrap of mean AP(arm) - mean AP(base) over real images and seeds.
    ``arm`` and ``base``: one class-agnostic result per seed, in the same seed order, scored
    on the same images; ``images``: indices of the images drawn from (default all)."""
    if not arm or len(arm) != len(base):
        raise ValueError("paired_difference: expected the same number of seeds for both arms")
    n_img = len(arm[0].npos_by_image)
    idx = np.arange(n_img) if images is None else np.asarray(images, np.int64)
    ones = np.zeros((1, n_img))
    ones[0, idx] = 1.0
    a0 = np.array([weighted_ap(c, ones)[0] for c in arm])
    b0 = np.array([weighted_ap(c, ones)[0] for c in base])
    if np.isnan(a0).any() or np.isnan(b0).any() or not len(idx):
        return Difference(None, None, None, 0)
    rng = np.random.default_rng(seed)
    k = len(arm)
    diffs = []
    for start in range(0, replicates, _CHUNK):
        nb = min(_CHUNK, replicates - start)
        draws = idx[rng.integers(0, len(idx), size=(nb, len(idx)))]
        flat = (np.arange(nb)[:, None] * n_img + draws).ravel()
        w = np.bincount(flat, minlength=nb * n_img).reshape(nb, n_img).astype(np.float64)
        seeds = rng.integers(0, k, size=(nb, k))
        a = np.stack([weighted_ap(c, w) for c in arm])   # (k, nb)
        s = np.stack([weighted_ap(c, w) for c in base])
        cols = np.arange(nb)[None, :]
        d = a[seeds.T, cols].mean(0) - s[seeds.T, cols].mean(0)
        diffs.append(d)
    d = np.concatenate(diffs)
    d = d[np.isfinite(d)]
    if not len(d):
        return Difference(float(a0.mean() - b0.mean()), None, None, 0)
    lo, hi = np.percentile(d, [100 * (1 - INTERVAL) / 2, 100 * (1 + INTERVAL) / 2])
    return Difference(float(a0.mean() - b0.mean()), float(lo), float(hi), int(len(d)))
