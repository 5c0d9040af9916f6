"""Procedural bodies of residential and farm vehicles: tractor, farm trailer, boat trailer
(a trailer with a motor boat on it) and utility trailer.

Vehicle frame: metres, origin at the footprint centre on the ground, +x forward (a
trailer's drawbar points forward), +y left, z up. Each builder takes the catalog length,
width and height and returns parts ``(name, material, rgb_or_None, vertices, faces)``
(``None`` = the variant colour), every part a closed convex hull; :mod:`.meshes` scales
them to the catalog size exactly, as for every procedural body.

Labels (docs/vehicles.md): an RV/campervan, a tractor, a farm trailer and a boat on its
trailer are ``large-vehicle`` (DOTA's large-vehicle covers what is longer and wider than a
car: trucks, buses, RVs, trailers); a car-sized utility trailer is ``small-vehicle``
(DOTA's classes are size classes, and a 3.5 m x 1.9 m trailer is what a detector must tell
from a car by size alone; VEDAI's ``other`` class is not one of ours).
"""

from __future__ import annotations

import numpy as np

from ..scene.model import DEFAULT_COLOR_FOR_MATERIAL
from ._hull import box as _box
from ._hull import convex_hull as _hull

__all__ = ["TOWED_BUILDERS"]

_TYRE = DEFAULT_COLOR_FOR_MATERIAL["tyre"]
_TRIM = DEFAULT_COLOR_FOR_MATERIAL["trim"]
_GLASS = (0.075, 0.095, 0.125)
_GALV = (0.55, 0.56, 0.57)
_FRONT = DEFAULT_COLOR_FOR_MATERIAL["light_front"]
_REAR = DEFAULT_COLOR_FOR_MATERIAL["light_rear"]


def _rear_lights(x0, hw, z):
    """A pair of red rear lights on a trailer's rear edge."""
    out = []
    for s in (1, -1):
        y0, y1 = sorted((s * (hw - 0.05), s * (hw - 0.3)))
        out.append(_part("light_rear", "light_rear", _REAR, _box(x0 - 0.02, x0 + 0.06, y0, y1, z - 0.1, z)))
    return out
_BOAT_WHITE = (0.88, 0.88, 0.86)


def _part(name, material, rgb, vf):
    return (name, material, rgb, vf[0], vf[1])


def _wheel(x, y, r, width, sections=14):
    ang = np.linspace(0.0, 2 * np.pi, sections, endpoint=False)
    ring = np.column_stack([x + r * np.cos(ang), r + r * np.sin(ang)])
    return _hull([(px, y + s * width / 2, pz) for px, pz in ring for s in (-1, 1)])


def _pair(x, hw, r, width):
    return [_part("wheels", "tyre", _TYRE, _wheel(x, s * (hw - width / 2), r, width)) for s in (1, -1)]


def _drawbar(x_front, x_back, z, hw=0.06):
    """A triangular A-frame drawbar from the trailer front to the hitch at x_front."""
    return _part("drawbar", "metal", _GALV, _hull([
        (x_front, -hw, z - 0.05), (x_front, hw, z - 0.05), (x_front, -hw, z + 0.05), (x_front, hw, z + 0.05),
        (x_back, -0.55, z - 0.05), (x_back, 0.55, z - 0.05), (x_back, -0.55, z + 0.05), (x_back, 0.55, z + 0.05),
    ]))


def _tractor(L, W, H):
    """Farm tractor: big rear wheels, small front wheels, bonnet, cab with glass and roof."""
    x0, x1 = -L / 2, L / 2
    hw = W / 2
    rr, rf = 0.78, 0.52  # rear and front wheel radius
    wr, wf = 0.55, 0.38
    xr, xf = x0 + 0.95, x1 - 0.9
    parts = _pair(xr, hw, rr, wr) + _pair(xf, hw - 0.15, rf, wf)
    bonnet = _hull([(x, s * 0.45, z) for x in (xr + 0.5, x1 - 0.1) for s in (1, -1) for z in (0.55, 1.45)])
    parts.append(_part("body", "paint", None, bonnet))
    cab_x0, cab_x1 = xr - 0.75, xr + 0.85
    cw = hw - wr - 0.05
    parts.append(_part("cab_floor", "paint", None, _box(cab_x0, cab_x1, -cw, cw, 0.9, 1.45)))
    parts.append(_part("greenhouse", "glass", _GLASS, _box(cab_x0 + 0.05, cab_x1 - 0.05, -cw + 0.05, cw - 0.05,
                                                          1.45, H - 0.12)))
    parts.append(_part("roof", "paint", None, _box(cab_x0 - 0.1, cab_x1 + 0.1, -cw - 0.1, cw + 0.1, H - 0.12, H)))
    parts.append(_part("windscreen", "glass", _GLASS, _box(cab_x1 - 0.05, cab_x1 + 0.01, -cw + 0.1, cw - 0.1,
                                                          1.55, H - 0.2)))
    parts.append(_part("rear_window", "glass", _GLASS, _box(cab_x0 - 0.01, cab_x0 + 0.05, -cw + 0.1, cw - 0.1,
                                                           1.55, H - 0.2)))
    for s in (1, -1):
        y0, y1 = sorted((s * 0.15, s * 0.4))
        parts.append(_part("light_front", "light_front", _FRONT, _box(x1 - 0.1, x1, y0, y1, 1.2, 1.4)))
        y0, y1 = sorted((s * (cw - 0.05), s * (cw - 0.25)))
        parts.append(_part("light_rear", "light_rear", _REAR, _box(cab_x0 - 0.08, cab_x0, y0, y1, 1.0, 1.2)))
    # mudguards over the rear wheels
    for s in (1, -1):
        y0, y1 = sorted((s * (hw - wr - 0.02), s * hw))
        parts.append(_part("mudguard", "paint", None, _box(xr - rr, xr + rr, y0, y1, 2 * rr, 2 * rr + 0.06)))
    parts.append(_part("exhaust", "metal", (0.20, 0.20, 0.21), _box(cab_x1 + 0.1, cab_x1 + 0.2, 0.3, 0.4, 1.4, H - 0.3)))
    parts.append(_part("hitch", "trim", _TRIM, _box(x0, xr - 0.3, -0.25, 0.25, 0.45, 0.75)))
    return parts


def _farm_trailer(L, W, H):
    """Two-axle tipping trailer: an open box (walls, darker floor) on a chassis, drawbar."""
    x0, x1 = -L / 2, L / 2
    hw = W / 2
    box_front = x1 - 1.6
    floor = 1.0
    parts = [_drawbar(x1, box_front, 0.7)]
    parts.append(_part("chassis", "trim", _TRIM, _box(x0 + 0.5, box_front, -0.6, 0.6, 0.55, floor)))
    parts.append(_part("floor", "cargo", (0.30, 0.26, 0.20), _box(x0, box_front, -hw, hw, floor, floor + 0.08)))
    t = 0.08
    for bx in (_box(x0 + 0.06, box_front, hw - t, hw, floor, H), _box(x0 + 0.06, box_front, -hw, -hw + t, floor, H),
               _box(box_front - t, box_front, -hw + t, hw - t, floor, H), _box(x0 + 0.06, x0 + 0.06 + t, -hw + t, hw - t, floor, H)):
        parts.append(_part("body", "paint", None, bx))  # the box's four walls
    xc = (x0 + box_front) / 2
    for xa in (xc - 0.7, xc + 0.7):
        parts += _pair(xa, hw - 0.05, 0.5, 0.42)
    parts += _rear_lights(x0 + 0.02, hw, floor)
    return parts


def _boat_trailer(L, W, H):
    """A galvanised trailer with a motor boat on it: pointed bow forward, a windscreen and a
    dark cockpit; the boat's hull takes the variant colour's place only on its stripe (the
    hull is white)."""
    x0, x1 = -L / 2, L / 2
    hw = W / 2
    bow = x1 - 1.2  # boat bow; the drawbar runs on to the hitch
    stern = x0
    parts = [_drawbar(x1, bow - 0.5, 0.45)]
    parts.append(_part("frame", "metal", _GALV, _box(stern + 0.3, bow - 0.4, -0.55, 0.55, 0.35, 0.5)))
    parts += _pair(stern + 0.4 * (bow - stern), hw - 0.1, 0.33, 0.2)
    z0, z1 = 0.55, H - 0.45
    bl = bow - stern
    hull = _hull([(stern, s * (hw - 0.05), z) for s in (1, -1) for z in (z0 + 0.15, z1)]
                 + [(stern + 0.7 * bl, s * (hw - 0.05), z) for s in (1, -1) for z in (z0, z1)]
                 + [(bow, 0.0, z1), (bow - 0.3, 0.0, z0 + 0.2)])
    parts.append(_part("body", "paint", _BOAT_WHITE, hull))  # the boat's hull
    parts.append(_part("stripe", "paint", None, _box(stern + 0.2, stern + 0.6 * bl, hw - 0.06, hw - 0.03, z1 - 0.25, z1 - 0.1)))
    parts.append(_part("stripe", "paint", None, _box(stern + 0.2, stern + 0.6 * bl, -hw + 0.03, -hw + 0.06, z1 - 0.25, z1 - 0.1)))
    parts.append(_part("cockpit", "trim", (0.12, 0.12, 0.13),
                       _box(stern + 0.3, stern + 0.45 * bl, -hw + 0.3, hw - 0.3, z1 - 0.05, z1 + 0.01)))
    ws = _hull([(stern + 0.47 * bl, s * (hw - 0.3), z1) for s in (1, -1)]
               + [(stern + 0.52 * bl, s * (hw - 0.35), H) for s in (1, -1)]
               + [(stern + 0.55 * bl, s * (hw - 0.3), z1) for s in (1, -1)])
    parts.append(_part("windscreen", "glass", _GLASS, ws))
    parts.append(_part("motor", "trim", (0.10, 0.10, 0.11), _box(stern + 0.1, stern + 0.5, -0.25, 0.25, z0, z1 + 0.3)))
    parts += _rear_lights(stern + 0.1, hw - 0.1, 0.5)
    return parts


def _utility_trailer(L, W, H):
    """Single-axle open box trailer (car-sized): low walls, wheel boxes, drawbar."""
    x0, x1 = -L / 2, L / 2
    hw = W / 2
    box_front = x1 - 1.1
    floor = 0.55
    parts = [_drawbar(x1, box_front, 0.45)]
    parts.append(_part("floor", "cargo", (0.35, 0.30, 0.24), _box(x0, box_front, -hw + 0.1, hw - 0.1, floor - 0.05, floor)))
    t = 0.04
    for bx in (_box(x0 + 0.06, box_front, hw - 0.1 - t, hw - 0.1, floor, H),
               _box(x0 + 0.06, box_front, -hw + 0.1, -hw + 0.1 + t, floor, H),
               _box(box_front - t, box_front, -hw + 0.1 + t, hw - 0.1 - t, floor, H),
               _box(x0 + 0.06, x0 + 0.06 + t, -hw + 0.1 + t, hw - 0.1 - t, floor, H)):
        parts.append(_part("body", "paint", None, bx))  # the box's four walls
    xc = (x0 + box_front) / 2
    parts += _pair(xc, hw, 0.28, 0.18)
    for s in (1, -1):
        y0, y1 = sorted((s * hw, s * (hw - 0.2)))
        parts.append(_part("mudguard", "metal", _GALV, _box(xc - 0.35, xc + 0.35, y0, y1, 0.55, 0.62)))
    parts += _rear_lights(x0 + 0.02, hw - 0.1, floor - 0.05)
    return parts


#: body name -> builder(L, W, H) -> parts (name, material, rgb or None, vertices, faces)
TOWED_BUILDERS = {
    "tractor": _tractor,
    "farm_trailer": _farm_trailer,
    "boat_trailer": _boat_trailer,
    "utility_trailer": _utility_trailer,
}
