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

__all__ = ["spread", "weighted_ap", "differences", "paired_difference", "Difference", "BOOTSTRAP",
           "INTERVAL"]

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


def _parts(c: ClassResult, images: np.ndarray | None):
    """(det image, tp, fp, npos by image) of ``c`` restricted to ``images`` (renumbered 0..)."""
    if c.det_image is None:
        raise ValueError("ClassResult without per-detection data (made by an older evaluate)")
    di, tp, fp = (np.asarray(c.det_image, np.int64), np.asarray(c.det_tp, np.float64),
                  np.asarray(c.det_fp, np.float64))
    npos = np.asarray(c.npos_by_image, np.float64)
    # detections after the last true positive never raise the precision envelope at a
    # reachable recall (same true positives, more false ones): left out, exactly
    hit = np.nonzero(tp > 0)[0]
    n = int(hit[-1]) + 1 if len(hit) else 0
    di, tp, fp = di[:n], tp[:n], fp[:n]
    if images is None:
        return di, tp, fp, npos
    remap = np.full(len(npos), -1, np.int64)
    remap[images] = np.arange(len(images))
    m = remap[di] >= 0
    return remap[di[m]], tp[m], fp[m], npos[images]


def _ap(parts, w: np.ndarray) -> np.ndarray:
    """VOC07 AP per row of image weights ``w`` (B, n_images); NaN where the weighted truth is 0."""
    di, tp, fp, npos_img = parts
    npos = w @ npos_img
    ok = npos > 0
    out = np.full(len(w), np.nan)
    if not len(di):
        out[ok] = 0.0
        return out
    dw = w[:, di]
    ctp = np.cumsum(dw * tp, axis=1)
    cfp = np.cumsum(dw * fp, axis=1)
    rec = ctp / np.where(ok, npos, 1.0)[:, None]
    prec = ctp / np.maximum(ctp + cfp, np.finfo(np.float64).eps)
    # max precision at recall >= t: recall never falls along a row, so that is the envelope
    # (running maximum from the right) at the first point reaching t
    env = np.maximum.accumulate(prec[:, ::-1], axis=1)[:, ::-1]
    env = np.concatenate([env, np.zeros((len(w), 1))], axis=1)
    rows = np.arange(len(w))
    ap = np.zeros(len(w))
    for t in _T11:
        ap += env[rows, (rec < t).sum(axis=1)] / 11.0
    out[ok] = ap[ok]
    return out


def weighted_ap(c: ClassResult, w: np.ndarray) -> np.ndarray:
    """VOC07 AP of ``c`` with image weights ``w`` (B, n_images): (B,), NaN where the
    weighted truth is 0. With w = 1 it is ``c.ap`` (evaluate's curve, the same counts)."""
    return _ap(_parts(c, None), np.atleast_2d(np.asarray(w, np.float64)))


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


def differences(runs: dict[str, list[ClassResult]], baseline: str, images=None, *,
                replicates: int = BOOTSTRAP, seed: int = 0) -> dict[str, Difference]:
    """Paired bootstrap of mean AP(arm) - mean AP(baseline) over real images and seeds, for
    every arm of ``runs`` but the baseline. ``runs``: {arm: one class-agnostic result per
    seed, in the same seed order, scored on the same images}; ``images``: indices of the
    images drawn from (default all). Every arm meets the same draws; each run's AP per
    replicate is computed once."""
    k = len(runs[baseline])
    if any(len(v) != k for v in runs.values()) or not k:
        raise ValueError("paired bootstrap: expected the same number of seeds for every arm")
    n_img = len(runs[baseline][0].npos_by_image)
    idx = np.arange(n_img) if images is None else np.asarray(images, np.int64)
    parts = {a: [_parts(c, idx) for c in v] for a, v in runs.items()}
    ones = np.ones((1, len(idx)))
    point = {a: np.array([_ap(p, ones)[0] for p in v]) for a, v in parts.items()}
    others = [a for a in runs if a != baseline]
    if not len(idx) or np.isnan(point[baseline]).any():
        return {a: Difference(None, None, None, 0) for a in others}
    rng = np.random.default_rng(seed)
    boot = {a: [] for a in runs}
    draws_seed = []
    for start in range(0, replicates, _CHUNK):
        nb = min(_CHUNK, replicates - start)
        draws = rng.integers(0, len(idx), size=(nb, len(idx)))
        flat = (np.arange(nb)[:, None] * len(idx) + draws).ravel()
        w = np.bincount(flat, minlength=nb * len(idx)).reshape(nb, len(idx)).astype(np.float64)
        draws_seed.append(rng.integers(0, k, size=(nb, k)))
        for a, v in parts.items():
            boot[a].append(np.stack([_ap(p, w) for p in v]))    # (k, nb)
    seeds = np.concatenate(draws_seed)                           # (B, k)
    cols = np.arange(replicates)[None, :]
    mean = {a: np.concatenate(v, axis=1)[seeds.T, cols].mean(0) for a, v in boot.items()}
    out = {}
    for a in others:
        if np.isnan(point[a]).any():
            out[a] = Difference(None, None, None, 0)
            continue
        diff = float(point[a].mean() - point[baseline].mean())
        d = mean[a] - mean[baseline]
        d = d[np.isfinite(d)]
        if not len(d):
            out[a] = Difference(diff, None, None, 0)
            continue
        lo, hi = np.percentile(d, [100 * (1 - INTERVAL) / 2, 100 * (1 + INTERVAL) / 2])
        out[a] = Difference(diff, float(lo), float(hi), int(len(d)))
    return out


def paired_difference(arm: list[ClassResult], base: list[ClassResult], images=None, *,
                      replicates: int = BOOTSTRAP, seed: int = 0) -> Difference:
    """:func:`differences` of one arm against the baseline."""
    return differences({"arm": arm, "base": base}, "base", images, replicates=replicates, seed=seed)["arm"]
