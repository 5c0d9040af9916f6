"""Compiled auto-exposure solver: the bisections of :func:`.tone.solve_tone` on the
256-bin log-luma histogram (about 300 evaluations of the display mean and sd per frame,
which cost 8-14 ms as small numpy calls and well under 1 ms compiled)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..numba_setup import KERNEL_OPTIONS as _OPTS

__all__ = ["solve_on_histogram", "histogram_uniform"]


@njit(**_OPTS)
def _stats(lg, p, yc, wts, shoulder):  # pragma: no cover - compiled
    """Display gray mean and sd of the histogram (bin luminances ``yc``, weights ``wts``)
    under log gain ``lg``, tone power ``p``, shoulder ``shoulder``."""
    e = math.exp(lg)
    m = 0.0
    q = 0.0
    for k in range(yc.shape[0]):
        v = e * yc[k]
        if v < 0.0:
            v = 0.0
        elif v > 1.0:
            v = 1.0
        g = 255.0 * (v * (1.0 + shoulder) / (1.0 + shoulder * v)) ** p
        m += wts[k] * g
        q += wts[k] * g * g
    return m, math.sqrt(max(q - m * m, 0.0))


@njit(**_OPTS)
def _gain_for(p, lo, yc, wts, shoulder, key_gray):  # pragma: no cover - compiled
    a = -lo - 12.0  # log gain: the darkest to the brightest pixel at 1
    b = -lo + 12.0
    for _ in range(22):  # to 24 / 2^22 in log gain
        mid = 0.5 * (a + b)
        if _stats(mid, p, yc, wts, shoulder)[0] < key_gray:
            a = mid
        else:
            b = mid
    return 0.5 * (a + b)


@njit(**_OPTS)
def solve_on_histogram(lo, yc, wts, key_gray, target_sd, shoulder, plo, phi):  # pragma: no cover
    """(log gain, power): the mean hits ``key_gray``; the power in [plo, phi] brings the sd
    as close to ``target_sd`` as it can (bisection in log power, 12 steps)."""
    if _stats(_gain_for(phi, lo, yc, wts, shoulder, key_gray), phi, yc, wts, shoulder)[1] <= target_sd:
        p = phi
    elif _stats(_gain_for(plo, lo, yc, wts, shoulder, key_gray), plo, yc, wts, shoulder)[1] >= target_sd:
        p = plo
    else:
        a = math.log(plo)
        b = math.log(phi)
        for _ in range(12):
            mid = 0.5 * (a + b)
            pm = math.exp(mid)
            if _stats(_gain_for(pm, lo, yc, wts, shoulder, key_gray), pm, yc, wts, shoulder)[1] < target_sd:
                a = mid
            else:
                b = mid
        p = math.exp(0.5 * (a + b))
    return _gain_for(p, lo, yc, wts, shoulder, key_gray), p


@njit(**_OPTS)
def histogram_uniform(a, edges):  # pragma: no cover - compiled
    """Counts (m,) int64 of ``a`` (float64) in the m equal bins ``edges`` (m + 1,) =
    ``np.linspace(lo, hi, m + 1)``: the same counts as ``np.histogram(a, m, (lo, hi))``,
    with numpy's index arithmetic (scaled offset, then the +-1 corrections at the edges;
    the last bin holds ``hi``; values outside [lo, hi] are left out), in one pass."""
    m = edges.shape[0] - 1
    lo = edges[0]
    hi = edges[m]
    denom = hi - lo
    cnt = np.zeros(m, np.int64)
    for x in a:
        if not (x >= lo and x <= hi):
            continue
        k = np.int64(((x - lo) / denom) * m)
        if k == m:
            k -= 1
        if x < edges[k]:
            k -= 1
        if x >= edges[k + 1] and k != m - 1:
            k += 1
        cnt[k] += 1
    return cnt
