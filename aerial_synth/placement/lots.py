"""Parking lots found by line traces: their rectangles, edges and bay layouts.

Lots. Vertical traces on a grid over the scene find the ``parking`` surface (painted bay
lines, ``parking_marking``, count as lot). An opening removes driveways and entrances
narrower than ``min_lot_m``; each remaining piece is a lot candidate. Its minimum rotated
rectangle gives the row direction (the long side); marching traces outward in 0.05 m steps
(the thesis's step) from seven points along each side then turn the rectangle (Theil-Sen
slope of the edge distances) and place each edge (median). The bay layout is the scene's
lot hint when the scene carries one for that lot (``Scene.hints.lots``: a
procedural lot's painted layout), else it is read from the painted lines
(:func:`_layout_from_markings`), else the scenario's default (2.5 x 5.0 m bays, 6 m aisles, rows parallel to the
rectangle), laid out by :func:`aerial_synth.scene.parking_layout.layout_bays`, the
function that painted the lines. A bay is kept only when traces over a 3 x 3 grid inside it
all land on the lot.

Also the records shared by the parking modules (:class:`Lot`, :class:`Kerb`) and the
vertical traces they use. Part of :mod:`aerial_synth.placement.parking` (docs/parking.md).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, SceneError
from ..scene.model import LABEL_IDS
from ..scene.parking_layout import (
    BAY_ANGLES_DEG,
    Bays,
    LotFrame,
    LotLayout,
    bay_markings,
    layout_bays,
    lot_frame,
)
from .parking_config import ParkingConfig

__all__ = ["Lot", "Kerb", "find_lots", "bays_on_lot", "trace_labels", "lot_label_ids",
           "LOT_LABELS", "STICK_OUT_M"]

#: How far a parked footprint may leave its bay (metres).
STICK_OUT_M = 0.2
#: The labels of a lot's surface.
LOT_LABELS = ("parking", "parking_marking")


@dataclass(frozen=True)
class Lot:
    """A lot found by traces: id, rectangle (LotFrame), layout, bays (kept after the trace
    check), ``layout_source`` ("scene" hint or "default") and how many bays failed."""

    id: int
    frame: object
    layout: object
    bays: object
    layout_source: str
    dropped_bays: int


@dataclass(frozen=True)
class Kerb:
    """A kerb line: id, bays (parallel, axis along the traffic direction of that side)."""

    id: int
    bays: object
    dropped_bays: int


# ------------------------------------------------------------------------- traces
def trace_labels(rs, xy: np.ndarray, chunk: int = 1 << 20) -> np.ndarray:
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    out = np.empty(len(xy), np.int64)
    for i in range(0, len(xy), chunk):
        out[i:i + chunk] = rs.trace_labels(xy[i:i + chunk])
    return out


def lot_label_ids() -> np.ndarray:
    return np.array([LABEL_IDS[n] for n in LOT_LABELS])


def _march_edges(rs, origins, dirs, start_m, reach_m, step_m=0.05):
    """Distance along each direction to the first non-lot trace, starting ``start_m`` from
    the origin and marching ``reach_m`` in ``step_m`` steps. nan where no edge was met or
    the start was not on the lot."""
    ks = start_m[:, None] + np.arange(int(np.ceil(reach_m / step_m)) + 1)[None, :] * step_m
    pts = origins[:, None, :] + dirs[:, None, :] * ks[..., None]
    on = np.isin(trace_labels(rs, pts.reshape(-1, 2)), lot_label_ids()).reshape(ks.shape)
    first_off = np.argmax(~on, axis=1)
    ok = on[:, 0] & (~on).any(axis=1)
    d = ks[np.arange(len(ks)), np.maximum(first_off - 1, 0)]
    # refine between the last lot step and the first off step (5 mm, like the prober)
    sub = (np.arange(1, 10) / 10.0) * step_m
    pts = origins[:, None, :] + dirs[:, None, :] * (d[:, None] + sub[None, :])[..., None]
    on2 = np.isin(trace_labels(rs, pts.reshape(-1, 2)), lot_label_ids()).reshape(len(d), -1)
    last = np.where(on2.all(axis=1), len(sub), np.argmax(~on2, axis=1))  # sub-steps still on
    d = d + np.where(last > 0, sub[np.maximum(last - 1, 0)], 0.0) + 0.0025
    return np.where(ok, d, np.nan)


def find_lots(rayscene, cfg: ParkingConfig | None = None) -> list[Lot]:
    """Lots of a scene, found by vertical traces (see the module doc)."""
    import cv2
    import shapely


    cfg = cfg or ParkingConfig()
    rs = rayscene
    b = rs.scene.bounds()
    lo, hi = b[0, :2], b[1, :2]
    g = cfg.grid_m
    xs = np.arange(lo[0] + g / 2, hi[0], g)
    ys = np.arange(hi[1] - g / 2, lo[1], -g)  # row 0 = north
    if not len(xs) or not len(ys):
        return []
    X, Y = np.meshgrid(xs, ys)
    lab = trace_labels(rs, np.stack([X.ravel(), Y.ravel()], 1)).reshape(X.shape)
    mask = np.isin(lab, lot_label_ids()).astype(np.uint8)
    r = max(1, int(round(cfg.min_lot_m / 2 / g)))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    opened = cv2.morphologyEx(mask, cv2.MORPH_OPEN, kernel)
    n, comp, stats, _ = cv2.connectedComponentsWithStats(opened, connectivity=8)
    default = cfg.lot_layout()
    hints = rs.scene.hints.lots
    lots: list[Lot] = []
    for k in range(1, n):
        x0, y0, w, h, area = stats[k]
        if area * g * g < 60.0:
            continue
        sub = (comp[y0:y0 + h, x0:x0 + w] == k).astype(np.uint8)
        cs, _ = cv2.findContours(sub, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        c = max(cs, key=cv2.contourArea).reshape(-1, 2).astype(float)
        wx = xs[0] + (c[:, 0] + x0) * g
        wy = ys[0] - (c[:, 1] + y0) * g
        if len(c) < 3:
            continue
        fr = lot_frame(shapely.Polygon(np.column_stack([wx, wy])).buffer(g / 2, join_style="mitre"))
        fr = _refine(rs, fr)
        if fr is None:
            continue
        lay, src = default, "default"
        for hnt in hints:
            hc = np.asarray(hnt.center_xy, float)
            if np.hypot(hc[0] - fr.cx, hc[1] - fr.cy) < 1.5 and abs(hnt.long_m - fr.long_m) < 1.5:
                lay, src = LotLayout(**hnt.layout_dict()), "scene"
                fr = LotFrame(float(hc[0]), float(hc[1]), float(np.radians(hnt.row_deg)),
                              hnt.long_m, hnt.short_m)
                break
        space_bays = _bays_from_spaces(rs.scene.hints.spaces, fr) if src == "default" else None
        if space_bays is not None:
            bays, src = space_bays, "osm-spaces"
        else:
            if src == "default" and _has_markings(rs, fr):
                read = _layout_from_markings(rs, fr)
                if read is not None:
                    lay, src = read, "markings"
            bays = layout_bays(fr, lay)
        keep = bays_on_lot(rs, bays)
        lots.append(Lot(len(lots), fr, lay, bays.take(keep), src, int((~keep).sum())))
    return lots


def _refine(rs, fr):
    """Edges and direction of the lot rectangle by 0.05 m marches outward from seven points
    along each side: the slope of the edge distances along the long sides turns the
    rectangle (Theil-Sen, robust to an entrance), then the median distance per side places
    each edge."""
    for _ in range(2):
        res = _side_marches(rs, fr)
        if res is None:
            return None
        dist, offs = res
        from scipy.stats import theilslopes

        slopes = []
        for i, sgn in ((2, 1.0), (3, -1.0)):  # the +v and -v sides
            di, oi = dist[7 * i:7 * i + 7], offs[7 * i:7 * i + 7]
            ok = np.isfinite(di)
            if ok.sum() >= 4:
                slopes.append(sgn * theilslopes(di[ok], oi[ok])[0])
        if not slopes:
            break
        delta = float(np.arctan(np.median(slopes)))
        if abs(delta) < 1e-5:
            break
        fr = dataclasses.replace(fr, u_rad=float(np.mod(fr.u_rad + delta, np.pi)))
    res = _side_marches(rs, fr)
    if res is None:
        return None
    dist, _ = res
    med = []
    for i in range(4):
        di = dist[7 * i:7 * i + 7]
        di = di[np.isfinite(di)]
        if len(di) < 3:
            return None
        med.append(float(np.median(di)))
    u = np.array([np.cos(fr.u_rad), np.sin(fr.u_rad)])
    v = np.array([-u[1], u[0]])
    c = np.array([fr.cx, fr.cy])
    cc = c + u * (med[0] - med[1]) / 2 + v * (med[2] - med[3]) / 2
    L, S = med[0] + med[1], med[2] + med[3]
    if S > L:  # rows follow the long side
        return dataclasses.replace(fr, cx=float(cc[0]), cy=float(cc[1]),
                                   u_rad=float(np.mod(fr.u_rad + np.pi / 2, np.pi)), long_m=S, short_m=L)
    return dataclasses.replace(fr, cx=float(cc[0]), cy=float(cc[1]), long_m=L, short_m=S)


def _bays_from_spaces(spaces, fr):
    """Bays from mapped parking spaces (OSM ``amenity=parking_space`` polygons, local frame)
    whose centre lies in the lot rectangle: each space's minimum rotated rectangle gives the
    bay centre and axis (its long side); all bays of the lot take the median size. None when
    no space lies in the lot."""
    import shapely


    if not spaces:
        return None
    lot = fr.polygon()
    cs, axes, sizes = [], [], []
    for ring in spaces:
        try:
            poly = shapely.Polygon(np.asarray(ring, float))
        except (ValueError, TypeError):
            continue
        if poly.is_empty or poly.area < 1.0 or not lot.contains(poly.centroid):
            continue
        rect = np.asarray(shapely.minimum_rotated_rectangle(poly).exterior.coords)[:4]
        e1, e2 = rect[1] - rect[0], rect[2] - rect[1]
        long_e, short_e = (e1, e2) if math.hypot(*e1) >= math.hypot(*e2) else (e2, e1)
        cs.append(rect.mean(axis=0))
        axes.append(np.arctan2(long_e[1], long_e[0]))
        sizes.append((math.hypot(*short_e), math.hypot(*long_e)))
    if not cs:
        return None
    axes = np.mod(np.array(axes), 2 * np.pi)
    rel = np.degrees(np.abs(np.angle(np.exp(1j * (np.median(axes) - fr.u_rad)))))
    rel = min(rel, 180.0 - rel)
    angle = min((90.0, 60.0, 45.0, 0.0), key=lambda a: abs(a - rel))
    w, ln = np.median(np.array(sizes), axis=0)
    return Bays(np.array(cs), axes, np.zeros(len(cs), int), fr.u_rad, float(w), float(ln), angle)


def _has_markings(rs, fr, step_m: float = 0.03) -> bool:
    """Traces along the rectangle's two diagonals (they cross any painted line that is not
    parallel to them) meet ``parking_marking`` at least twice."""
    t = np.arange(-0.5, 0.5, step_m / np.hypot(fr.long_m, fr.short_m))
    uv = np.concatenate([np.stack([t * fr.long_m, t * fr.short_m], 1),
                         np.stack([t * fr.long_m, -t * fr.short_m], 1)])
    lab = trace_labels(rs, fr.to_world(uv))
    return int((lab == LABEL_IDS["parking_marking"]).sum()) >= 2


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) index pairs of the True runs of a 1-D mask."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _layout_from_markings(rs, fr, res: float = 0.1):
    """Read a lot's bay layout from its painted lines (``parking_marking``), for lots that
    carry no hint: traces on a ``res`` grid in the lot frame; the marking density across the
    rows gives the bay rows and aisles, the line crossings along a row the pitch, their
    drift across the row the bay angle. Returns a LotLayout, or None when the lot has no
    (readable) markings. The layout is accepted only when its predicted lines cover the
    traced ones (both ways, 60 %)."""
    nu, nv = int(fr.long_m / res), int(fr.short_m / res)
    if nu < 10 or nv < 10 or nu * nv > 4_000_000:
        return None
    us = (np.arange(nu) + 0.5) * res - fr.long_m / 2
    vs = (np.arange(nv) + 0.5) * res - fr.short_m / 2
    U, Vv = np.meshgrid(us, vs)  # (nv, nu): rows across v
    xy = fr.to_world(np.stack([U, Vv], -1))
    mark = (trace_labels(rs, xy.reshape(-1, 2)) == LABEL_IDS["parking_marking"]).reshape(nv, nu)
    if mark.sum() < 200:
        return None
    # bay rows: v-bands whose u-profile shows markings (allow 2 px gaps)
    dens = mark.mean(axis=1) > 0.01
    bands = [(a, b) for a, b in _runs(dens) if (b - a) * res >= 1.5]
    if not bands:
        return None
    depths = np.array([(b - a) * res for a, b in bands])
    dr = float(depths.min())
    n_rows = int(sum(round(d / dr) for d in depths))
    gaps = [(bands[i + 1][0] - bands[i][1]) * res for i in range(len(bands) - 1)]
    # the thinnest band gives one row: crossings along u near its two edges
    a, b = bands[int(np.argmin(depths))]
    mid = mark[(a + b) // 2]
    cross_mid = np.array([(s0 + s1) / 2 for s0, s1 in _runs(mid)]) * res
    if len(cross_mid) < 2:
        return None
    pitch = float(np.median(np.diff(cross_mid)))
    # drift of the crossings over 1 m across the row (less than half a pitch for 45-90 deg)
    step_px = max(1, int(round(1.0 / res)))
    r0 = max(a, (a + b) // 2 - step_px // 2)
    r1 = min(b - 1, r0 + step_px)
    c_lo = np.array([(s0 + s1) / 2 for s0, s1 in _runs(mark[r0])]) * res
    c_hi = np.array([(s0 + s1) / 2 for s0, s1 in _runs(mark[r1])]) * res
    dv = (r1 - r0) * res
    if len(c_lo) and len(c_hi) and dv > 0:
        near = c_hi[np.abs(c_hi[None, :] - c_lo[:, None]).argmin(axis=1)]
        du = float(np.median(near - c_lo))
    else:
        du = 0.0
    alpha = float(np.degrees(np.arctan2(dv, abs(du))))
    # the exact length of the painted lines: 0.01 m marches along them (thesis-style traces)
    d_uv = np.array([du, dv]) / max(np.hypot(du, dv), 1e-9)
    v_mid = ((a + b) / 2 + 0.5) * res - fr.short_m / 2
    starts = np.column_stack([cross_mid[:5] - fr.long_m / 2, np.full(min(5, len(cross_mid)), v_mid)])
    steps = np.arange(0, int(40.0 / 0.01)) * 0.01
    ext = []
    for sgn in (1.0, -1.0):
        pts = starts[:, None, :] + sgn * d_uv[None, None, :] * steps[None, :, None]
        lab = trace_labels(rs, fr.to_world(pts).reshape(-1, 2)).reshape(len(starts), -1)
        on = lab == LABEL_IDS["parking_marking"]
        ext.append((np.argmax(~on, axis=1) - 0.5) * 0.01)
    line_len = float(np.median(ext[0] + ext[1]))
    aisle = float(np.round(np.median(gaps) * 10) / 10) if gaps else 6.0
    # candidate layouts: the bay angle snapped to 90/60/45 (or parallel), the width snapped to
    # 5 cm; the length from the painted line (perpendicular, parallel) or from the row depth
    # (angled; searched +-0.2 m); the one whose lines agree best with the traced ones wins
    cands = []
    if alpha > 75.0 and pitch > dr:  # short lines across the row, far apart: parallel bays
        cands.append(dict(bay_width_m=round(line_len, 2), bay_length_m=round(pitch, 2), angle_deg=0.0))
    else:
        ang = min((x for x in BAY_ANGLES_DEG if x > 0), key=lambda x: abs(x - alpha))
        sa, ca = np.sin(np.radians(ang)), np.cos(np.radians(ang))
        w = float(np.round(pitch * sa * 20) / 20)
        if ang == 90.0:
            cands.append(dict(bay_width_m=w, bay_length_m=round(line_len, 2), angle_deg=ang))
        else:
            l0 = float(np.round((dr - w * ca) / sa * 10) / 10)
            cands += [dict(bay_width_m=w, bay_length_m=round(l0 + k * 0.1, 2), angle_deg=ang)
                      for k in (-2, -1, 0, 1, 2)]
    import shapely

    best, best_score = None, 0.0
    for c in cands:
        try:
            lay = LotLayout(aisle_m=aisle, rows=n_rows, **c)
        except (SceneError, ConfigError):
            continue
        pred = bay_markings(layout_bays(fr, lay), lay).buffer(res)
        if pred.is_empty:
            continue
        hit = shapely.contains_xy(pred, xy[..., 0], xy[..., 1])
        covered = (hit & mark).sum() / max(mark.sum(), 1)
        explained = (hit & mark).sum() / max(hit.sum(), 1)
        if covered >= 0.6 and explained >= 0.3 and covered * explained > best_score:
            best, best_score = lay, covered * explained
    return best


def _side_marches(rs, fr):
    """Distances from the rectangle's centre line to each side's edge, 7 marches per side
    (+u, -u, +v, -v), and the marches' offsets along the side (metres)."""
    u = np.array([np.cos(fr.u_rad), np.sin(fr.u_rad)])
    v = np.array([-u[1], u[0]])
    c = np.array([fr.cx, fr.cy])
    halves = [fr.long_m / 2, fr.long_m / 2, fr.short_m / 2, fr.short_m / 2]
    dirs = [u, -u, v, -v]
    across = [v, v, u, u]
    spans = [fr.short_m, fr.short_m, fr.long_m, fr.long_m]
    t = np.linspace(-0.35, 0.35, 7)
    origins, ds, starts, offs = [], [], [], []
    for h, d, a, sp in zip(halves, dirs, across, spans):
        for ti in t:
            origins.append(c + a * ti * sp)
            ds.append(d)
            starts.append(max(h - 3.0, 0.0))
            offs.append(ti * sp)
    dist = _march_edges(rs, np.array(origins), np.array(ds), np.array(starts), 6.0)
    return dist, np.array(offs)


def bays_on_lot(rs, bays, inset_m: float = 0.15) -> np.ndarray:
    """(n,) bool: a 3 x 3 grid of traces inside each bay all land on the lot."""
    if not len(bays):
        return np.zeros(0, bool)
    f = np.array([-1.0, 0.0, 1.0])
    gu, gv = np.meshgrid(f * (bays.length_m / 2 - inset_m), f * (bays.width_m / 2 - inset_m))
    lx, ly = gu.ravel(), gv.ravel()
    c, s = np.cos(bays.axis_rad)[:, None], np.sin(bays.axis_rad)[:, None]
    px = bays.centre_xy[:, :1] + c * lx - s * ly
    py = bays.centre_xy[:, 1:] + s * lx + c * ly
    lab = trace_labels(rs, np.stack([px.ravel(), py.ravel()], 1)).reshape(len(bays), -1)
    return np.isin(lab, lot_label_ids()).all(axis=1)
