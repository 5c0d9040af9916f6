"""Trim options of procedural vehicles: sunroof, roof bars, rack, roof box, ladder rack,
reefer unit, container. Each takes the fitted parts (vehicle frame, bounds [-L/2, L/2] x
[-W/2, W/2] x [0, H]) and returns them with the option added; nothing reaches past L or W,
and nothing above H + OPTION_RISE_M[option].
"""

from __future__ import annotations

import numpy as np

from ._hull import box as _box
from ._hull import convex_hull as _hull
from .catalog import OPTION_RISE_M
from .parts import Part, sym

__all__ = ["OPTIONS"]

SUNROOF_RGB = (0.025, 0.03, 0.04)
RACK_RGB = (0.06, 0.06, 0.065)
ROOF_BOX_RGB = (0.09, 0.09, 0.10)


def _bounds(parts: list[Part], name: str) -> np.ndarray:
    v = np.concatenate([p.v for p in parts if p.name == name])
    return np.stack([v.min(axis=0), v.max(axis=0)])


def _sunroof(parts, L, W, H, body=""):
    """A dark glass panel over the front half of the roof panel; the roof panel's top is
    lowered 4 mm so the glass lies proud of it and the height stays H."""
    (x0, y0, _), (x1, y1, top) = _bounds(parts, "roof")
    out = []
    for p in parts:
        if p.name == "roof":
            v = p.v.copy()
            v[v[:, 2] > top - 1e-6, 2] = top - 0.004
            p = Part(p.name, p.material, p.rgb, v, p.f)
        out.append(p)
    ln, wd = 0.42 * (x1 - x0), 0.56 * (y1 - y0)
    xc = x0 + 0.6 * (x1 - x0)
    out.append(Part("sunroof", "glass", SUNROOF_RGB,
                     *_box(xc - ln / 2, xc + ln / 2, -wd / 2, wd / 2, top - 0.03, top)))
    return out


def _bars(parts, H, rise=0.04, n=2, span=0.92):
    """Transverse roof bars standing on the roof (or an SUV's rails), top at H + rise."""
    (x0, y0, _), (x1, y1, _) = _bounds(parts, "roof")
    hw = span * (y1 - y0) / 2
    out = []
    for k in range(n):
        xc = x0 + (x1 - x0) * (0.22 + 0.56 * k / max(n - 1, 1))
        out.append(Part("roof_rack", "metal", RACK_RGB,
                         *_box(xc - 0.025, xc + 0.025, -hw, hw, H - 0.03, H + rise)))
    return out


def _roof_rack(parts, L, W, H, body=""):
    if body == "delivery_van":
        return _ladder_rack(parts, L, W, H)
    return parts + _bars(parts, H, rise=OPTION_RISE_M["roof_rack"])


def _roof_box(parts, L, W, H, body=""):
    """Roof bars and a rounded roof box on them (a long, low, dark capsule)."""
    (x0, y0, _), (x1, y1, _) = _bounds(parts, "roof")
    bars_top = H + 0.06
    out = parts + _bars(parts, H, rise=0.06)
    ln = min(1.9, 0.8 * (x1 - x0))
    hw = min(0.45, 0.42 * (y1 - y0))
    xc = (x0 + x1) / 2 - 0.05
    top = H + OPTION_RISE_M["roof_box"]
    c = 0.12
    pts = sym([(xc - ln / 2, hw - c, bars_top), (xc - ln / 2, hw - c, top - 0.06),
                (xc - ln / 2 + c, hw, bars_top + 0.03), (xc - ln / 2 + c, hw, top - 0.04),
                (xc - ln / 2 + 2 * c, hw - 0.03, top), (xc + ln / 2 - c, hw - 0.03, top),
                (xc + ln / 2 - c, hw, bars_top + 0.03), (xc + ln / 2, hw - c, bars_top + 0.05),
                (xc + ln / 2, hw - c, top - 0.08)])
    out.append(Part("roof_box", "trim", ROOF_BOX_RGB, *_hull(pts)))
    return out


def _ladder_rack(parts, L, W, H, body=""):
    """Delivery van: a rack of two side rails and cross bars, with a ladder lying on it."""
    (x0, y0, _), (x1, y1, _) = _bounds(parts, "roof")
    rise = OPTION_RISE_M["roof_rack"]
    hw = 0.45 * (y1 - y0)
    out = list(parts)
    for side in (1, -1):
        ya, yb = sorted((side * hw, side * (hw - 0.04)))
        out.append(Part("roof_rack", "metal", RACK_RGB, *_box(x0 + 0.05, x1 - 0.05, ya, yb, H - 0.02, H + 0.04)))
    for xc in np.linspace(x0 + 0.1, x1 - 0.1, 4):
        out.append(Part("roof_rack", "metal", RACK_RGB,
                         *_box(xc - 0.02, xc + 0.02, -hw, hw, H - 0.02, H + 0.04)))
    # the ladder: two rails and rungs, aluminium, on one side
    lx0, lx1 = x0 + 0.15, x1 - 0.15
    for yc in (hw - 0.12, hw - 0.52):
        out.append(Part("ladder", "metal", (0.72, 0.73, 0.75),
                         *_box(lx0, lx1, yc - 0.03, yc + 0.03, H + 0.04, H + rise)))
    for xc in np.arange(lx0 + 0.15, lx1 - 0.1, 0.3):
        out.append(Part("ladder", "metal", (0.72, 0.73, 0.75),
                         *_box(xc - 0.015, xc + 0.015, hw - 0.52, hw - 0.12, H + 0.05, H + rise - 0.005)))
    return out


def _reefer(parts, L, W, H, body=""):
    """Box truck: a refrigeration unit on the front face of the box, above the cab."""
    (bx0, _, _), (bx1, by1, bz1) = _bounds(parts, "cargo_box")
    cab = _bounds(parts, "roof")[1][2]
    z0 = max(cab + 0.05, bz1 - 0.85)
    out = list(parts)
    out.append(Part("reefer", "metal", (0.80, 0.81, 0.82),
                     *_box(bx1 - 0.02, bx1 + 0.04 + 0.0, -0.8, 0.8, z0, bz1 - 0.02)))
    out.append(Part("reefer", "trim", (0.15, 0.16, 0.17),
                     *_box(bx1 - 0.02, bx1 + 0.06, -0.55, 0.55, z0 + 0.1, bz1 - 0.1)))
    return out


def _container(parts, L, W, H, body=""):
    """Semi-trailer: the box trailer becomes a shipping container in the variant's colour
    with corrugated roof (dense transverse ribs) and corner castings."""
    out = []
    for p in parts:
        if p.name == "trailer_ribs":
            continue
        if p.name == "trailer":
            p = Part("container", "paint", None, p.v, p.f)
        out.append(p)
    (x0, y0, _), (x1, y1, top) = _bounds(out, "container")
    for xs in np.arange(x0 + 0.25, x1 - 0.2, 0.28):
        out.append(Part("container_ribs", "paint", None,
                         *_box(xs - 0.05, xs + 0.05, y0 + 0.06, y1 - 0.06, top - 0.02, top)))
    for xc in (x0 + 0.1, x1 - 0.1):
        for yc in (y0 + 0.1, y1 - 0.1):
            out.append(Part("container_corners", "metal", (0.30, 0.30, 0.32),
                             *_box(xc - 0.1, xc + 0.1, yc - 0.1, yc + 0.1, top - 0.15, top)))
    return out


OPTIONS = {"sunroof": _sunroof, "roof_rack": _roof_rack, "roof_box": _roof_box,
            "reefer": _reefer, "container": _container}
