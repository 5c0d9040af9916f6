"""Procedural bodies of the large vehicles real aerial images are full of: city bus, school
bus, coach, delivery van and semi-trailer truck (tractor + 13.6 m trailer).

Vehicle frame: metres, origin at the footprint centre on the ground, +x forward, +y left,
z up. Each builder takes the catalog length, width and height and returns parts as
``(name, material, rgb_or_None, vertices, faces)`` tuples (``None`` = the variant colour);
:mod:`.meshes` wraps them and scales them to the catalog size exactly, like every other
procedural body. Every part is a closed convex hull with outward faces.

This module imports nothing from :mod:`.meshes` (which registers these builders), so there
is no import cycle.

The semi-trailer is built straight: its footprint is the whole vehicle (tractor and trailer
in line). The hitch (fifth wheel) sits :data:`SEMI_HITCH_FROM_FRONT_M` behind the front of
the tractor; see docs/parking.md for how a moving, bent semi is labelled.
"""

from __future__ import annotations

import numpy as np

from ..scene.model import DEFAULT_COLOR_FOR_MATERIAL
from ._hull import box as _box
from ._hull import convex_hull as _hull

__all__ = ["LARGE_BUILDERS", "SEMI_TRAILER_LENGTH_M", "SEMI_HITCH_FROM_FRONT_M", "SCHOOL_BUS_RGB"]

#: The trailer of the semi-trailer truck (EU standard box/curtain trailer).
SEMI_TRAILER_LENGTH_M = 13.6
#: Distance of the fifth-wheel hitch behind the front of the tractor.
SEMI_HITCH_FROM_FRONT_M = 4.0
#: School buses are school-bus yellow whatever the variant colour (that paints the bumpers).
SCHOOL_BUS_RGB = (0.86, 0.60, 0.04)

_GLASS = DEFAULT_COLOR_FOR_MATERIAL["glass"]
_SKY_GLASS = (0.075, 0.095, 0.125)
_TYRE = DEFAULT_COLOR_FOR_MATERIAL["tyre"]
_TRIM = DEFAULT_COLOR_FOR_MATERIAL["trim"]
_FRONT = DEFAULT_COLOR_FOR_MATERIAL["light_front"]
_REAR = DEFAULT_COLOR_FOR_MATERIAL["light_rear"]
_ROOF_UNIT = (0.80, 0.80, 0.78)


def _sym(points_xhz):
    out = []
    for x, hw, z in points_xhz:
        out += [(x, hw, z), (x, -hw, z)]
    return out


def _part(name, material, rgb, vf):
    return (name, material, rgb, vf[0], vf[1])


def _wheel(x, y, r, width, sections=14):
    ang = -np.pi / 2 + np.linspace(0.0, 2 * np.pi, sections, endpoint=False)
    ring = np.column_stack([x + r * np.cos(ang), r + r * np.sin(ang)])
    return _hull([(px, y + s * width / 2, pz) for px, pz in ring for s in (-1, 1)])


def _wheels(axles, half_w, r, width=0.30, inset=0.05, dual=()):
    out = []
    for k, x in enumerate(axles):
        w = width * (1.8 if k in dual else 1.0)
        y = half_w - inset - w / 2
        for side in (1, -1):
            out.append(_part("wheels", "tyre", _TYRE, _wheel(x, side * y, r, w)))
    return out


def _lights(x_front, x_rear, hw, z_front, z_rear, depth=0.10, width=0.35):
    out = []
    for side in (1, -1):
        y0, y1 = sorted((side * (hw - 0.06), side * (hw - 0.06 - width)))
        out.append(_part("light_front", "light_front", _FRONT,
                         _box(x_front - depth, x_front, y0, y1, z_front - 0.18, z_front)))
        out.append(_part("light_rear", "light_rear", _REAR,
                         _box(x_rear, x_rear + depth, y0, y1, z_rear - 0.25, z_rear)))
    return out


def _rounded_body(x0, x1, hw, z0, z1, corner=0.25, front_slope=0.0):
    """A long box with chamfered plan-view corners; the front top edge set back by
    ``front_slope`` (a sloping windscreen face)."""
    c = corner
    return _hull(_sym([
        (x0, hw - c, z0), (x0, hw - c, z1), (x0 + c, hw, z0), (x0 + c, hw, z1),
        (x1 - c, hw, z0), (x1 - c - front_slope, hw, z1),
        (x1, hw - c, z0), (x1 - front_slope, hw - c, z1),
    ]))


def _bus_common(L, W, H, *, body_rgb, roof_h, window_lo, clear, front_slope, corner,
                ac_len, ac_at, hatches=2):
    """Box bus: lower body, a recessed glass band, roof shell, windscreen, roof fittings."""
    x0, x1 = -L / 2, L / 2
    hw = W / 2
    parts = [
        _part("body", "paint", body_rgb, _rounded_body(x0, x1, hw, clear, window_lo, corner)),
        _part("greenhouse", "glass", _GLASS,
              _rounded_body(x0 + 0.05, x1 - 0.05, hw - 0.03, window_lo - 0.02, roof_h - 0.28,
                            corner, front_slope)),
        _part("roof", "paint", body_rgb,
              _rounded_body(x0, x1 - front_slope, hw, roof_h - 0.30, roof_h, corner, 0.0)),
    ]
    # windscreen: a slab on the front face, from the belt to the roof
    ws = _hull(_sym([
        (x1 + 0.01, hw - corner - 0.02, window_lo + 0.05),
        (x1 + 0.03, hw - corner - 0.02, window_lo + 0.05),
        (x1 - front_slope + 0.01, hw - corner - 0.02, roof_h - 0.32),
        (x1 - front_slope + 0.03, hw - corner - 0.02, roof_h - 0.32),
    ]))
    parts.append(_part("windscreen", "glass", _SKY_GLASS, ws))
    parts.append(_part("rear_window", "glass", _SKY_GLASS,
                       _box(x0 - 0.03, x0 - 0.01, -hw + corner + 0.05, hw - corner - 0.05,
                            window_lo + 0.25, roof_h - 0.40)))
    # roof fittings: air conditioner, escape hatches
    a0 = ac_at - ac_len / 2
    parts.append(_part("air_conditioner", "metal", _ROOF_UNIT,
                       _box(a0, a0 + ac_len, -hw + 0.35, hw - 0.35, roof_h - 0.02, H)))
    for k in range(hatches):
        xc = x0 + (k + 1) * L / (hatches + 1) * 0.8 + 0.6
        if abs(xc - ac_at) < ac_len / 2 + 0.6:
            xc = ac_at - ac_len / 2 - 0.9
        parts.append(_part("roof_hatch", "glass", (0.20, 0.21, 0.22),
                           _box(xc - 0.45, xc + 0.45, -0.40, 0.40, roof_h - 0.02, roof_h + 0.05)))
    # roof vents: small boxes near both ends, clear of the AC unit and the hatches
    for xv in (x1 - front_slope - 1.2, x0 + 1.0):
        for yv in (0.75, -0.75):
            parts.append(_part("roof_vents", "metal", (0.62, 0.63, 0.64),
                               _box(xv - 0.25, xv + 0.25, yv - 0.22, yv + 0.22,
                                    roof_h - 0.02, min(roof_h + 0.12, H))))
    parts.append(_part("bumper_front", "trim", _TRIM,
                       _box(x1 - 0.10, x1 + 0.0, -hw + 0.05, hw - 0.05, clear - 0.05, clear + 0.30)))
    parts.append(_part("bumper_rear", "trim", _TRIM,
                       _box(x0, x0 + 0.10, -hw + 0.05, hw - 0.05, clear - 0.05, clear + 0.30)))
    parts += _lights(x1 + 0.005, x0 - 0.005, hw - corner * 0.5, clear + 0.55, window_lo + 0.6)
    return parts


def _city_bus(L, W, H):
    parts = _bus_common(L, W, H, body_rgb=None, roof_h=H - 0.30, window_lo=1.05, clear=0.30,
                        front_slope=0.10, corner=0.22, ac_len=3.2, ac_at=-L / 2 + 4.2)
    parts += _wheels([L / 2 - 2.7, -L / 2 + 3.4], W / 2, 0.50, dual=(1,))
    return parts


def _coach(L, W, H):
    parts = _bus_common(L, W, H, body_rgb=None, roof_h=H - 0.22, window_lo=1.75, clear=0.35,
                        front_slope=0.55, corner=0.35, ac_len=2.4, ac_at=L / 2 - 3.6, hatches=2)
    parts += _wheels([L / 2 - 2.6, -L / 2 + 3.9, -L / 2 + 2.5], W / 2, 0.52, dual=(1,))
    return parts


def _school_bus(L, W, H):
    """Conventional (bonneted) North-American school bus: yellow; the variant colour paints
    the bumpers."""
    x0, x1 = -L / 2, L / 2
    hw = W / 2
    nose = 1.7
    y = SCHOOL_BUS_RGB
    parts = _bus_common(L - nose, W, H, body_rgb=y, roof_h=H - 0.12, window_lo=1.45, clear=0.40,
                        front_slope=0.12, corner=0.18, ac_len=1.6, ac_at=0.0, hatches=2)
    shifted = []
    for name, mat, rgb, v, f in parts:
        if name in ("bumper_front", "bumper_rear"):
            continue
        v = v.copy()
        v[:, 0] -= nose / 2
        shifted.append((name, mat, rgb, v, f))
    parts = shifted
    cab_front = x1 - nose
    parts.append(_part("bonnet", "paint", y, _hull(_sym([
        (cab_front + 0.05, hw - 0.30, 0.45), (cab_front + 0.05, hw - 0.30, 1.45),
        (x1 - 0.12, hw - 0.40, 0.45), (x1 - 0.12, hw - 0.45, 1.25),
    ]))))
    parts.append(_part("grille", "trim", _TRIM,
                       _box(x1 - 0.14, x1 - 0.02, -hw + 0.55, hw - 0.55, 0.55, 1.20)))
    parts.append(_part("bumper_front", "paint", None,
                       _box(x1 - 0.18, x1, -hw + 0.10, hw - 0.10, 0.35, 0.60)))
    parts.append(_part("bumper_rear", "paint", None,
                       _box(x0, x0 + 0.15, -hw + 0.10, hw - 0.10, 0.35, 0.60)))
    # black rub rails along the sides, the look of a school bus from above at a tilt
    for side in (1, -1):
        y0, y1 = sorted((side * hw, side * (hw - 0.02)))
        parts.append(_part("rub_rails", "trim", _TRIM,
                           _box(x0 + 0.2, cab_front - 0.2, y0, y1, 0.9, 1.0)))
    parts += _wheels([x1 - 1.1, x0 + 3.0], hw, 0.50, dual=(1,))
    for side in (1, -1):
        y0, y1 = sorted((side * (hw - 0.45), side * (hw - 0.75)))
        parts.append(_part("light_front", "light_front", _FRONT,
                           _box(x1 - 0.16, x1 - 0.04, y0, y1, 1.05, 1.25)))
    return parts


def _delivery_van(L, W, H):
    """High-roof panel van (Sprinter / Transit class): short bonnet, tall cargo body."""
    x0, x1 = -L / 2, L / 2
    hw = W / 2
    clear = 0.30
    bonnet = 0.95
    belt = 1.20
    body = _hull(_sym([
        (x0, hw - 0.10, clear), (x0, hw - 0.10, H - 0.05), (x0 + 0.10, hw, clear),
        (x0 + 0.10, hw, H - 0.05),
        (x1 - bonnet - 0.75, hw, H - 0.05), (x1 - bonnet - 0.75, hw - 0.08, H),
        (x0 + 0.15, hw - 0.08, H),
        (x1 - bonnet, hw, belt), (x1 - 0.12, hw - 0.05, clear),
        (x1, hw - 0.20, clear + 0.15), (x1 - 0.05, hw - 0.20, belt - 0.15),
        (x1 - 0.12, hw, belt - 0.12),
    ]))
    parts = [_part("body", "paint", None, body)]
    ws = _hull(_sym([
        (x1 - bonnet + 0.02, hw - 0.10, belt + 0.03), (x1 - bonnet + 0.04, hw - 0.10, belt + 0.03),
        (x1 - bonnet - 0.66, hw - 0.12, H - 0.30), (x1 - bonnet - 0.64, hw - 0.12, H - 0.30),
    ]))
    parts.append(_part("windscreen", "glass", _SKY_GLASS, ws))
    for side in (1, -1):
        y0, y1 = sorted((side * hw, side * (hw + 0.01)))
        parts.append(_part("greenhouse", "glass", _GLASS,
                           _box(x1 - bonnet - 0.9, x1 - bonnet - 0.1, y0, y1, belt + 0.05, H - 0.55)))
    parts.append(_part("rear_window", "glass", _SKY_GLASS,
                       _box(x0 - 0.02, x0, -hw + 0.25, hw - 0.25, belt + 0.15, H - 0.55)))
    parts.append(_part("roof", "paint", None,
                       _box(x0 + 0.4, x1 - bonnet - 1.2, -hw + 0.25, hw - 0.25, H - 0.06, H)))
    parts.append(_part("bumper_front", "trim", _TRIM,
                       _box(x1 - 0.12, x1, -hw + 0.12, hw - 0.12, clear, clear + 0.25)))
    parts.append(_part("bumper_rear", "trim", _TRIM,
                       _box(x0, x0 + 0.08, -hw + 0.12, hw - 0.12, clear, clear + 0.22)))
    parts += _lights(x1 - 0.06, x0, hw - 0.15, belt - 0.15, 1.20)
    parts += _wheels([x1 - 0.95, x0 + 1.45], hw, 0.36, width=0.24, inset=0.08)
    return parts


def _semi_trailer(L, W, H):
    """Tractor unit (cab-over, painted) with a 13.6 m box trailer (white), straight."""
    x0, x1 = -L / 2, L / 2
    hw = W / 2
    cab_len = 2.3
    cab_h = min(3.9, H - 0.05)
    cab_back = x1 - cab_len
    tractor_len = L - SEMI_TRAILER_LENGTH_M + 3.6  # trailer front overhangs the tractor
    tractor_rear = x1 - tractor_len
    trailer_front = x0 + SEMI_TRAILER_LENGTH_M
    cab = _hull(_sym([
        (cab_back, hw - 0.12, 0.55), (cab_back, hw - 0.12, cab_h - 0.05),
        (cab_back + 0.1, hw - 0.20, cab_h),
        (x1 - 0.05, hw - 0.05, 0.55), (x1, hw - 0.08, 1.6), (x1 - 0.12, hw - 0.10, cab_h - 0.35),
        (x1 - 0.35, hw - 0.20, cab_h),
    ]))
    parts = [_part("body", "paint", None, cab)]
    ws = _hull(_sym([
        (x1 + 0.005, hw - 0.25, 1.75), (x1 + 0.025, hw - 0.25, 1.75),
        (x1 - 0.10, hw - 0.27, cab_h - 0.55), (x1 - 0.08, hw - 0.27, cab_h - 0.55),
    ]))
    parts.append(_part("windscreen", "glass", _SKY_GLASS, ws))
    parts.append(_part("roof", "paint", None,
                       _box(cab_back + 0.3, x1 - 0.5, -hw + 0.35, hw - 0.35, cab_h - 0.05, cab_h)))
    for side in (1, -1):
        y0, y1 = sorted((side * (hw - 0.11), side * (hw - 0.13)))
        parts.append(_part("greenhouse", "glass", _GLASS,
                           _box(x1 - 1.1, x1 - 0.3, y0, y1, 1.9, cab_h - 0.6)))
    parts.append(_part("rear_window", "glass", _SKY_GLASS,
                       _box(cab_back - 0.02, cab_back, -0.5, 0.5, 2.2, 2.8)))
    parts.append(_part("chassis", "trim", _TRIM,
                       _box(tractor_rear, cab_back + 0.1, -0.55, 0.55, 0.55, 1.05)))
    parts.append(_part("fifth_wheel", "metal", (0.35, 0.35, 0.37),
                       _box(tractor_rear + 0.4, tractor_rear + 1.8, -0.9, 0.9, 1.05, 1.15)))
    parts.append(_part("trailer", "cargo", DEFAULT_COLOR_FOR_MATERIAL["cargo"],
                       _box(x0, trailer_front, -hw, hw, 1.20, H)))
    n = int(SEMI_TRAILER_LENGTH_M / 1.2)
    for xs in np.linspace(x0 + 0.6, trailer_front - 0.6, n):
        parts.append(_part("trailer_ribs", "metal", (0.72, 0.73, 0.74),
                           _box(xs - 0.03, xs + 0.03, -hw + 0.04, hw - 0.04, H - 0.02, H)))
    parts.append(_part("trailer_chassis", "trim", _TRIM,
                       _box(x0 + 0.3, x0 + 4.5, -hw + 0.15, hw - 0.15, 0.55, 1.20)))
    parts += _lights(x1 + 0.005, x0 - 0.005, hw - 0.05, 0.95, 1.05)
    parts += _wheels([x1 - 1.3, tractor_rear + 1.1], hw - 0.02, 0.50, dual=(1,))
    parts += _wheels([x0 + 1.3, x0 + 2.6, x0 + 3.9], hw - 0.02, 0.48, width=0.38)
    return parts


#: body name -> builder(L, W, H) -> parts (name, material, rgb or None, vertices, faces)
LARGE_BUILDERS = {
    "city_bus": _city_bus,
    "school_bus": _school_bus,
    "coach": _coach,
    "delivery_van": _delivery_van,
    "semi_trailer": _semi_trailer,
}
