"""Small charts drawn with OpenCV (no matplotlib): line charts and overlaid histograms.

Each function returns a BGR uint8 image; :func:`png_bytes` encodes it.
"""

from __future__ import annotations

import math

import numpy as np

from ..safe_input import cv_text

__all__ = ["COLORS", "line_chart", "histogram_chart", "grid", "png_bytes"]

#: BGR colours for series 0, 1, 2, ...
COLORS = ((200, 110, 30), (40, 110, 230), (60, 170, 60), (160, 60, 160), (30, 160, 200))

_W, _H = 560, 380
_L, _R, _T, _B = 64, 16, 40, 52
_FONT = 0  # cv2.FONT_HERSHEY_SIMPLEX


def _nice_ticks(lo: float, hi: float, n: int = 5) -> list[float]:
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return [lo]
    raw = (hi - lo) / n
    mag = 10 ** math.floor(math.log10(raw))
    step = min((m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= raw), default=raw)
    start = math.ceil(lo / step) * step
    out = []
    v = start
    while v <= hi + 1e-9 * step:
        out.append(round(v, 10))
        v += step
    return out


def _fmt(v: float) -> str:
    if v == 0:
        return "0"
    a = abs(v)
    if a >= 1e4 or a < 1e-2:
        return f"{v:.0e}"
    if a >= 100:
        return f"{v:.0f}"
    return f"{v:.3g}"


class _Axes:
    def __init__(self, title, xlabel, ylabel, xlim, ylim, size=(_W, _H)):
        import cv2

        self.cv2 = cv2
        self.w, self.h = size
        self.img = np.full((self.h, self.w, 3), 255, np.uint8)
        self.x0, self.x1 = xlim
        self.y0, self.y1 = ylim
        if self.x1 <= self.x0:
            self.x1 = self.x0 + 1.0
        if self.y1 <= self.y0:
            self.y1 = self.y0 + 1.0
        self.px0, self.px1 = _L, self.w - _R
        self.py0, self.py1 = self.h - _B, _T
        cv2.putText(self.img, cv_text(title[:70]), (_L, 24), _FONT, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        for t in _nice_ticks(self.x0, self.x1):
            x = self.X(t)
            cv2.line(self.img, (x, self.py1), (x, self.py0), (232, 232, 232), 1)
            cv2.line(self.img, (x, self.py0), (x, self.py0 + 4), (0, 0, 0), 1)
            s = _fmt(t)
            cv2.putText(self.img, s, (x - 4 * len(s), self.py0 + 18), _FONT, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
        for t in _nice_ticks(self.y0, self.y1):
            y = self.Y(t)
            cv2.line(self.img, (self.px0, y), (self.px1, y), (232, 232, 232), 1)
            cv2.line(self.img, (self.px0 - 4, y), (self.px0, y), (0, 0, 0), 1)
            s = _fmt(t)
            cv2.putText(self.img, s, (self.px0 - 8 - 8 * len(s), y + 4), _FONT, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
        cv2.rectangle(self.img, (self.px0, self.py1), (self.px1, self.py0), (0, 0, 0), 1)
        cv2.putText(self.img, cv_text(xlabel[:60]), ((self.px0 + self.px1) // 2 - 4 * len(xlabel[:60]), self.h - 12),
                    _FONT, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
        # vertical y label: draw on a strip and rotate
        strip = np.full((20, self.h), 255, np.uint8)
        cv2.putText(strip, cv_text(ylabel[:45]), (max(0, self.h // 2 - 4 * len(ylabel[:45])), 14), _FONT, 0.45, 0, 1, cv2.LINE_AA)
        strip = cv2.rotate(strip, cv2.ROTATE_90_COUNTERCLOCKWISE)
        self.img[:, 2:22][strip < 128] = 0

    def X(self, v):
        return int(round(self.px0 + (v - self.x0) / (self.x1 - self.x0) * (self.px1 - self.px0)))

    def Y(self, v):
        return int(round(self.py0 - (v - self.y0) / (self.y1 - self.y0) * (self.py0 - self.py1)))

    def polyline(self, xs, ys, color, thickness=2):
        if len(xs) == 0:
            return
        pts = np.stack([[self.X(x) for x in xs], [self.Y(y) for y in ys]], 1).astype(np.int32)
        self.cv2.polylines(self.img, [pts], False, color, thickness, self.cv2.LINE_AA)

    def legend(self, labels, colors):
        y = _T + 16
        for lab, c in zip(labels, colors):
            x = self.px1 - 8 - 8 * min(len(lab), 40) - 24
            self.cv2.line(self.img, (x, y - 4), (x + 18, y - 4), c, 3)
            self.cv2.putText(self.img, cv_text(lab[:40]), (x + 24, y), _FONT, 0.42, (0, 0, 0), 1, self.cv2.LINE_AA)
            y += 18


def line_chart(title: str, series, xlabel: str, ylabel: str, xlim=None, ylim=None) -> np.ndarray:
    """``series``: list of (label, xs, ys) or (label, xs, ys, bgr colour). Limits default to
    the data's range."""
    xs_all = np.concatenate([np.asarray(s[1], float) for s in series] or [np.zeros(1)])
    ys_all = np.concatenate([np.asarray(s[2], float) for s in series] or [np.zeros(1)])
    xlim = xlim or (float(np.nanmin(xs_all)), float(np.nanmax(xs_all)))
    ylim = ylim or (float(np.nanmin(ys_all)), float(np.nanmax(ys_all)))
    ax = _Axes(title, xlabel, ylabel, xlim, ylim)
    colors = [s[3] if len(s) > 3 else COLORS[i % len(COLORS)] for i, s in enumerate(series)]
    for s, c in zip(series, colors):
        ax.polyline(np.asarray(s[1], float), np.asarray(s[2], float), c)
    ax.legend([s[0] for s in series], colors)
    return ax.img


def histogram_chart(title: str, series, xlabel: str, bins: int = 40, density: bool = True,
                    range_=None) -> np.ndarray:
    """Overlaid step histograms of ``series`` = list of (label, values); shared bins."""
    vals = [np.asarray(v, float)[np.isfinite(np.asarray(v, float))] for _, v in series]
    allv = np.concatenate(vals) if vals else np.zeros(0)
    if range_ is None:
        if allv.size:
            lo, hi = np.percentile(allv, [0.5, 99.5]) if allv.size > 50 else (allv.min(), allv.max())
        else:
            lo, hi = 0.0, 1.0
        if hi <= lo:
            lo, hi = lo - 0.5, hi + 0.5
        range_ = (float(lo), float(hi))
    edges = np.linspace(range_[0], range_[1], bins + 1)
    hists = []
    for v in vals:
        h, _ = np.histogram(np.clip(v, edges[0], edges[-1]), edges)
        h = h.astype(float)
        if density and h.sum() > 0:
            h /= h.sum()
        hists.append(h)
    ymax = max([h.max() for h in hists if h.size] + [1e-9]) * 1.1
    ax = _Axes(title, xlabel, "fraction" if density else "count", range_, (0.0, ymax))
    colors = [COLORS[i % len(COLORS)] for i in range(len(series))]
    for h, c in zip(hists, colors):
        xs = np.repeat(edges, 2)[1:-1]
        ys = np.repeat(h, 2)
        ax.polyline(xs, ys, c, 2)
    ax.legend([f"{lab} (n={len(v)})" for (lab, _), v in zip(series, vals)], colors)
    return ax.img


def grid(images, cols: int = 3) -> np.ndarray:
    """Tile equal-size images into a sheet (blank cells white)."""
    if not images:
        return np.full((_H, _W, 3), 255, np.uint8)
    h, w = images[0].shape[:2]
    rows = math.ceil(len(images) / cols)
    sheet = np.full((rows * h, cols * w, 3), 255, np.uint8)
    for i, im in enumerate(images):
        r, c = divmod(i, cols)
        sheet[r * h:(r + 1) * h, c * w:(c + 1) * w] = im
    return sheet


def png_bytes(img: np.ndarray) -> bytes:
    import cv2

    ok, buf = cv2.imencode(".png", img)
    if not ok:  # pragma: no cover
        raise RuntimeError("PNG encoding failed")
    return buf.tobytes()
