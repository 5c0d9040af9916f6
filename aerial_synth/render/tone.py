"""The camera's tone: the tone curve (clip, soft shoulder, power), its display LUT, and the
auto exposure that picks gain and power for a drawn mean gray and gray spread
(:func:`solve_tone`; its bisections are compiled in :mod:`._tone`)."""

from __future__ import annotations

import math

import numpy as np

from ._tone import histogram_uniform, solve_on_histogram

__all__ = ["solve_tone", "tone_lut"]

_LUT_SIZE = 4 * 4096  # exposed linear values 0 .. 4 (K.LUT_SCALE entries per unit)


def _curve(v: np.ndarray, shoulder: float, power: float) -> np.ndarray:
    """Tone curve on exposed linear values: clip at 1, soft shoulder, power (gamma)."""
    v = np.clip(v, 0.0, 1.0)
    return (v * (1.0 + shoulder) / (1.0 + shoulder * v)) ** power


def tone_lut(shoulder: float, power: float) -> np.ndarray:
    """(16384,) uint8 display value for exposed linear value k / 4096."""
    x = np.arange(_LUT_SIZE, dtype=np.float64) / 4096.0
    return np.clip(_curve(x, shoulder, power) * 255.0 + 0.5, 0, 255).astype(np.uint8)


def solve_tone(luma: np.ndarray, key_gray: float, target_sd: float, shoulder: float,
               power_range: tuple[float, float] = (0.3, 1.6)) -> tuple[float, float]:
    """Auto exposure and contrast: (gain, power) such that the display gray
    255 * curve(gain * luma, shoulder, power) has mean ``key_gray`` and standard deviation
    as close to ``target_sd`` as ``power_range`` allows. ``luma``: linear luminances of a
    subsample of the frame (after white balance). Bisection on a 256-bin log histogram."""
    y = luma[np.isfinite(luma) & (luma > 1e-6)]
    if len(y) == 0:
        return 1.0, 1.0 / 2.2
    ly = np.log(y)
    lo, hi = float(ly.min()), float(ly.max()) + 1e-6
    edges = np.linspace(lo, hi, 257)  # np.histogram(ly, bins=256, range=(lo, hi))
    cnt = histogram_uniform(np.ascontiguousarray(ly, np.float64), edges)
    yc = np.exp(0.5 * (edges[1:] + edges[:-1]))
    wts = cnt / cnt.sum()

    plo, phi = power_range
    lg, p = solve_on_histogram(lo, np.ascontiguousarray(yc, np.float64),
                               np.ascontiguousarray(wts, np.float64), float(key_gray),
                               float(target_sd), float(shoulder), float(plo), float(phi))
    return math.exp(lg), float(p)
