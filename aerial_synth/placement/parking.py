"""Parked vehicles: lots (``parking``), kerbs (``street-parking``) and both plus traffic
(``mixed``), in the spirit of the thesis's line traces (docs/parking.md).

Lots. Vertical traces on a grid over the scene find the ``parking`` surface (painted bay
lines, ``parking_marking``, count as lot). An opening removes driveways and entrances
narrower than ``min_lot_m``; each remaining piece is a lot candidate. Its minimum rotated
rectangle gives the row direction (the long side); marching traces outward in 0.05 m steps
(the thesis's step) from seven points along each side then turn the rectangle (Theil-Sen
slope of the edge distances) and place each edge (median). The bay layout is the scene's
lot hint when the scene carries one for that lot (``Scene.meta["parking_lots"]``: a
procedural lot's painted layout), else it is read from the painted lines
(:func:`_layout_from_markings`), else the scenario's default (2.5 x 5.0 m bays, 6 m aisles, rows parallel to the
rectangle), laid out by :func:`aerial_synth.scene.parking_layout.layout_bays`, the
function that painted the lines. A bay is kept only when traces over a 3 x 3 grid inside it
all land on the lot.

Kerbs. Random road traces seed kerb lines; from each seed the 36-direction probe finds the
nearest edge (the thesis's fewest-road-hits rule) and the line then steps ``kerb_bay_m`` at
a time along the edge, re-locating it with the two-direction probe and stopping where the
edge jumps or turns (a junction, a road end). A kerb bay is dropped when, beside it or
within ``kerb_clear_m`` before or after it, the trace just beyond the kerb hits road (a
junction's crossing street) or parking (a driveway or lot entrance), or when the bay is
not all road (or lines painted on it).

Filling. Per lot and per kerb line the occupancy is drawn from Beta(mean c, (1 - mean) c)
(scipy.stats) and that share of the bays (rounded) is filled, bays chosen uniformly. The
vehicle of a bay comes from the scenario's class mix restricted to vehicles that fit it
(width <= bay width, length <= bay length + 0.2 m); bays at least ``depot_bay_min_m`` long
use ``depot_mix`` (buses and semi-trailers). Perpendicular and parallel bays take a share
of back-in parkers. Each vehicle gets a lateral / along-bay offset (normal, sigma
``lateral_sigma_m``) and a heading jitter (normal, sigma ``angle_sigma_deg``, truncated at
``angle_max_deg``), shrunk where needed so that no corner leaves its bay by more than
0.2 m. Overlapping pairs (STRtree) put the later vehicle back to the bay's centre line
without jitter, or leave the bay empty. Parked semi-trailers stand straight.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, PlacementError, SceneError
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
from ..vehicles.catalog import stream_key
from .config import ProbeConfig
from .linetrace import Prober, unit
from .model import PlacedVehicle, Placement, footprint_corners_xy, with_lonlat
from .parking_config import PARKING_KINDS, ParkingConfig

__all__ = ["Lot", "Kerb", "find_lots", "find_kerbs", "fill_bays", "place_parking",
           "parking_report", "STICK_OUT_M"]

#: How far a parked footprint may leave its bay (metres).
STICK_OUT_M = 0.2
_LOT_LABELS = ("parking", "parking_marking")


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
def _trace_labels(rs, xy: np.ndarray, chunk: int = 1 << 20) -> np.ndarray:
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    out = np.empty(len(xy), np.int64)
    for i in range(0, len(xy), chunk):
        out[i:i + chunk] = rs.trace_labels(xy[i:i + chunk])
    return out


def _lot_ids() -> np.ndarray:
    return np.array([LABEL_IDS[n] for n in _LOT_LABELS])


def _march_edges(rs, origins, dirs, start_m, reach_m, step_m=0.05):
    """Distance along each direction to the first non-lot trace, starting ``start_m`` from
    the origin and marching ``reach_m`` in ``step_m`` steps. nan where no edge was met or
    the start was not on the lot."""
    ks = start_m[:, None] + np.arange(int(np.ceil(reach_m / step_m)) + 1)[None, :] * step_m
    pts = origins[:, None, :] + dirs[:, None, :] * ks[..., None]
    on = np.isin(_trace_labels(rs, pts.reshape(-1, 2)), _lot_ids()).reshape(ks.shape)
    first_off = np.argmax(~on, axis=1)
    ok = on[:, 0] & (~on).any(axis=1)
    d = ks[np.arange(len(ks)), np.maximum(first_off - 1, 0)]
    # refine between the last lot step and the first off step (5 mm, like the prober)
    sub = (np.arange(1, 10) / 10.0) * step_m
    pts = origins[:, None, :] + dirs[:, None, :] * (d[:, None] + sub[None, :])[..., None]
    on2 = np.isin(_trace_labels(rs, pts.reshape(-1, 2)), _lot_ids()).reshape(len(d), -1)
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
    lab = _trace_labels(rs, np.stack([X.ravel(), Y.ravel()], 1)).reshape(X.shape)
    mask = np.isin(lab, _lot_ids()).astype(np.uint8)
    r = max(1, int(round(cfg.min_lot_m / 2 / g)))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    opened = cv2.morphologyEx(mask, cv2.MORPH_OPEN, kernel)
    n, comp, stats, _ = cv2.connectedComponentsWithStats(opened, connectivity=8)
    default = cfg.lot_layout()
    hints = rs.scene.meta.get("parking_lots") or []
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
            hc = np.asarray(hnt.get("center_xy", (np.inf, np.inf)), float)
            if np.hypot(hc[0] - fr.cx, hc[1] - fr.cy) < 1.5 and abs(hnt.get("long_m", 0) - fr.long_m) < 1.5:
                lay, src = LotLayout(**hnt["layout"]), "scene"
                fr = LotFrame(float(hc[0]), float(hc[1]), float(np.radians(hnt["row_deg"])),
                              float(hnt["long_m"]), float(hnt["short_m"]))
                break
        space_bays = _bays_from_spaces(rs.scene.meta.get("parking_spaces"), fr) if src == "default" else None
        if space_bays is not None:
            bays, src = space_bays, "osm-spaces"
        else:
            if src == "default" and _has_markings(rs, fr):
                read = _layout_from_markings(rs, fr)
                if read is not None:
                    lay, src = read, "markings"
            bays = layout_bays(fr, lay)
        keep = _bays_on_lot(rs, bays)
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
        long_e, short_e = (e1, e2) if np.linalg.norm(e1) >= np.linalg.norm(e2) else (e2, e1)
        cs.append(rect.mean(axis=0))
        axes.append(np.arctan2(long_e[1], long_e[0]))
        sizes.append((np.linalg.norm(short_e), np.linalg.norm(long_e)))
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
    lab = _trace_labels(rs, fr.to_world(uv))
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
    mark = (_trace_labels(rs, xy.reshape(-1, 2)) == LABEL_IDS["parking_marking"]).reshape(nv, nu)
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
        lab = _trace_labels(rs, fr.to_world(pts).reshape(-1, 2)).reshape(len(starts), -1)
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


def _bays_on_lot(rs, bays, inset_m: float = 0.15) -> np.ndarray:
    """(n,) bool: a 3 x 3 grid of traces inside each bay all land on the lot."""
    if not len(bays):
        return np.zeros(0, bool)
    f = np.array([-1.0, 0.0, 1.0])
    gu, gv = np.meshgrid(f * (bays.length_m / 2 - inset_m), f * (bays.width_m / 2 - inset_m))
    lx, ly = gu.ravel(), gv.ravel()
    c, s = np.cos(bays.axis_rad)[:, None], np.sin(bays.axis_rad)[:, None]
    px = bays.centre_xy[:, :1] + c * lx - s * ly
    py = bays.centre_xy[:, 1:] + s * lx + c * ly
    lab = _trace_labels(rs, np.stack([px.ravel(), py.ravel()], 1)).reshape(len(bays), -1)
    return np.isin(lab, _lot_ids()).all(axis=1)


# ------------------------------------------------------------------------- kerbs
def find_kerbs(rayscene, cfg: ParkingConfig, rng: np.random.Generator, probe=None,
               traffic: str = "right") -> list[Kerb]:
    """Kerb lines with their parallel bays (see the module doc)."""
    import shapely

    rs = rayscene
    pr = Prober(rs, probe or ProbeConfig())
    b = rs.scene.bounds()
    lo, hi = b[0, :2], b[1, :2]
    road_lut = np.zeros(len(LABEL_IDS) + 1, bool)
    road_lut[[LABEL_IDS["road"], LABEL_IDS["lane_marking"]]] = True
    kerbs: list[Kerb] = []
    claimed = []  # shapely polygons of kerb stretches already used
    rules = _kerb_rules(rs.scene.meta.get("kerb_parking"))
    want = cfg.kerb_lines
    tries = 0
    while len(kerbs) < want and tries < 8:
        tries += 1
        xy = rng.uniform(lo, hi, size=(4096, 2))
        seeds = xy[pr.is_road(xy)][: max(16, 2 * (want - len(kerbs)))]
        if not len(seeds):
            continue
        D = 36
        ang = np.tile(np.arange(D) * (2 * np.pi / D), (len(seeds), 1))
        m = pr.march(seeds, ang, first_only=True, chunk=24)
        best = np.argmin(m.count, axis=1)
        ok = m.found[np.arange(len(seeds)), best]
        phi = ang[np.arange(len(seeds)), best][ok]  # towards the nearest edge
        for edge, n_out, width in _kerb_lines(pr, seeds[ok], phi, cfg, unit):
            if len(kerbs) >= want:
                break
            if not (cfg.kerb_road_width_m[0] <= width <= cfg.kerb_road_width_m[1]):
                continue
            line = shapely.LineString(edge)
            zone = line.buffer(3.0, cap_style="flat")
            if claimed and shapely.intersects(np.array(claimed, dtype=object), zone).any():
                continue
            if rules and _kerb_allowed(rules, edge, n_out) is False:  # the map says no parking
                claimed.append(zone)
                continue
            centres = (edge[:-1] + edge[1:]) / 2 - n_out[:-1] * cfg.kerb_offset_m
            seg = edge[1:] - edge[:-1]
            axis = np.arctan2(seg[:, 1], seg[:, 0])
            # right-hand traffic: the kerb is on the parked car's right (left: on its left)
            cross = np.cos(axis) * n_out[:-1, 1] - np.sin(axis) * n_out[:-1, 0]
            kerb_left = cross > 0
            axis = np.where(kerb_left == (traffic == "right"), axis + np.pi, axis)
            bays = Bays(centres, np.mod(axis, 2 * np.pi), np.zeros(len(centres), int), 0.0,
                        2.0 * cfg.kerb_offset_m, cfg.kerb_bay_m, 0.0)
            seg_len = np.linalg.norm(seg, axis=1)
            keep = _kerb_free(rs, road_lut, bays, n_out[:-1], cfg)
            keep &= np.abs(seg_len - cfg.kerb_bay_m) < 0.05 * cfg.kerb_bay_m  # a straight kerb
            kerbs.append(Kerb(len(kerbs), bays.take(keep), int((~keep).sum())))
            claimed.append(line.buffer(width + 3.0 if cfg.kerb_sides == "one" else 3.0, cap_style="flat"))
    return kerbs


def _kerb_rules(data) -> list:
    """Kerb parking tags of mapped roads (``Scene.meta["kerb_parking"]``, from OSM
    ``parking:left|right|both`` and ``parking:lane:*``): [(centre line, width, left, right)]."""
    import shapely

    out = []
    for r in data or []:
        try:
            line = shapely.LineString(np.asarray(r["coords"], float))
            out.append((line, float(r.get("width_m", 6.0)), r.get("left"), r.get("right")))
        except (KeyError, TypeError, ValueError):
            continue
    return out


def _kerb_allowed(rules, edge, n_out):
    """The tag of the mapped road side this kerb line runs along: True, False or None (the
    nearest mapped road within half its width + 1 m of a point 1 m inside the kerb)."""
    import shapely

    k = len(edge) // 2
    p = edge[k] - n_out[k] * 1.0
    pt = shapely.Point(p)
    best = None
    for line, width, left, right in rules:
        d = line.distance(pt)
        if d <= width / 2 + 1.0 and (best is None or d < best[0]):
            best = (d, line, left, right)
    if best is None:
        return None
    _, line, left, right = best
    s = line.project(pt)
    a = np.asarray(line.interpolate(max(s - 0.5, 0.0)).coords[0])
    b = np.asarray(line.interpolate(min(s + 0.5, line.length)).coords[0])
    c = np.asarray(line.interpolate(s).coords[0])
    t = b - a
    on_left = t[0] * (edge[k][1] - c[1]) - t[1] * (edge[k][0] - c[0]) > 0
    return left if on_left else right


def _kerb_lines(pr, seeds, phi, cfg, unit, max_steps: int = 400):
    """Walk along the kerb nearest each seed (edge direction ``phi``) both ways, one bay
    length per step, all walkers in lock-step (one probe cast per step). Yields
    (edge points (k, 2), outward normals (k, 2), road width) per seed with k >= 3."""
    P = len(seeds)
    if not P:
        return
    step = cfg.kerb_bay_m
    m = pr.march(seeds, np.stack([phi, phi + np.pi], 1))
    width = m.dist_m.sum(axis=1)
    good = m.found.all(axis=1)
    e0 = m.edge_xy[:, 0]
    n0 = unit(phi)
    # walkers: 2 per seed (sgn +1 / -1)
    sgn = np.concatenate([np.ones(P), -np.ones(P)])
    e = np.concatenate([e0, e0])
    no = np.concatenate([n0, n0])
    active = np.concatenate([good, good])
    trail = [[(e[w].copy(), no[w].copy())] for w in range(2 * P)]
    for _ in range(max_steps):
        ai = np.flatnonzero(active)
        if not len(ai):
            break
        tt = np.stack([-no[ai, 1], no[ai, 0]], 1) * sgn[ai, None]
        q = e[ai] + tt * step - no[ai] * 2.0  # 2 m inside the road
        a1 = np.arctan2(no[ai, 1], no[ai, 0])
        mm = pr.march(q, np.stack([a1, a1 - sgn[ai] * np.radians(10.0)], 1), max_distance_m=6.0)
        e1, e2 = mm.edge_xy[:, 0], mm.edge_xy[:, 1]
        d = e2 - e1
        dn = np.linalg.norm(d, axis=1)
        d = d / np.where(dn > 1e-9, dn, 1.0)[:, None]
        new_no = np.stack([-d[:, 1], d[:, 0]], 1) * sgn[ai, None]
        ok = (mm.found.all(axis=1) & (np.abs(mm.dist_m[:, 0] - 2.0) <= 0.5) & (dn > 1e-6)
              & ((new_no * no[ai]).sum(axis=1) >= np.cos(np.radians(20.0))))
        active[ai[~ok]] = False
        go = ai[ok]
        e[go], no[go] = e1[ok], new_no[ok]
        for w in go:
            trail[w].append((e[w].copy(), no[w].copy()))
    for p in range(P):
        if not good[p]:
            continue
        pts = trail[P + p][::-1] + trail[p][1:]  # backward walk reversed, then forward
        if len(pts) < 3:
            continue
        yield (np.array([t[0] for t in pts]), np.array([t[1] for t in pts]), float(width[p]))


def _kerb_free(rs, road_lut, bays, n_out, cfg) -> np.ndarray:
    """(n,) bool: nothing beyond the kerb beside the bay or within kerb_clear_m of it is
    road (junction) or parking (driveway); no lane marking crosses the bay; the bay is road."""
    n = len(bays)
    if not n:
        return np.zeros(0, bool)
    L = bays.length_m
    u = np.stack([np.cos(bays.axis_rad), np.sin(bays.axis_rad)], 1)
    foot = bays.centre_xy + n_out * cfg.kerb_offset_m  # on the edge
    reach = L / 2 + cfg.kerb_clear_m
    s = np.linspace(-reach, reach, int(np.ceil(2 * reach / 0.5)) + 1)  # every 0.5 m at most
    outs = np.array([0.4, 1.5, 3.5])
    pts = (foot[:, None, None, :] + u[:, None, None, :] * s[None, :, None, None]
           + n_out[:, None, None, :] * outs[None, None, :, None])
    lab = _trace_labels(rs, pts.reshape(-1, 2)).reshape(n, len(s), len(outs))
    bad_out = road_lut[lab].any(axis=(1, 2)) | (lab == LABEL_IDS["parking"]).any(axis=(1, 2))
    # the bay itself: road or painted lines on it (edge lines) only
    f = np.array([-0.45, -0.15, 0.15, 0.45])
    gu, gv = np.meshgrid(f * L, np.array([-0.35, 0.0, 0.35]) * bays.width_m)
    c, sn = np.cos(bays.axis_rad)[:, None], np.sin(bays.axis_rad)[:, None]
    px = bays.centre_xy[:, :1] + c * gu.ravel() - sn * gv.ravel()
    py = bays.centre_xy[:, 1:] + sn * gu.ravel() + c * gv.ravel()
    lab_in = _trace_labels(rs, np.stack([px.ravel(), py.ravel()], 1)).reshape(n, -1)
    bad_in = ~road_lut[lab_in].all(axis=1)
    # the edge must run straight along the bay (no bend)
    return ~(bad_out | bad_in)


# ------------------------------------------------------------------------- filling
def _mix_table(catalog, mix: dict, field_name: str) -> tuple[list, np.ndarray]:
    """(models, weights) of a class mix; an unknown class or model raises ConfigError."""
    names = {m.name: m for m in catalog.models}
    classes = sorted({m.cls for m in catalog.models})
    models, weights = [], []
    for key, w in mix.items():
        if key in names:
            group = [names[key]]
        elif key in classes:
            group = [m for m in catalog.models if m.cls == key]
        else:
            raise ConfigError(
                f"{field_name}.{key}: unknown class or model; expected one of {', '.join(classes)} "
                f"or a catalog model ({', '.join(sorted(names))})")
        cw = np.array([m.weight for m in group], float)
        cw = cw / cw.sum() if cw.sum() > 0 else np.full(len(group), 1.0 / len(group))
        for m, x in zip(group, cw):
            models.append(m)
            weights.append(w * x)
    return models, np.array(weights)


def check_mix(catalog, cfg: ParkingConfig) -> None:
    _mix_table(catalog, cfg.mix, "parking.mix")
    _mix_table(catalog, cfg.depot_mix, "parking.depot_mix")


@dataclass
class _Site:
    kind: str  # "lot" or "kerb"
    id: int
    bays: object


def fill_bays(sites: list, cfg: ParkingConfig, catalog, rng: np.random.Generator,
              obstacles=None, first_id: int = 1, z_of=None, surface_ok=None,
              to_original=None) -> tuple[list, dict]:
    """Fill the bays of every site (lots and kerb lines). Returns (vehicles, stats).

    ``surface_ok(points (n, k, 2), is_kerb (n,)) -> (n,) bool`` checks that footprint
    samples lie on the site's surface (a lot edge or the kerb); a jittered vehicle that
    fails loses its jitter, and one that still fails leaves its bay empty."""
    import shapely
    from scipy import stats as st

    m_mean, conc = cfg.occupancy_mean, cfg.occupancy_concentration
    targets, chosen = [], []
    for site in sites:
        n = len(site.bays)
        if m_mean <= 0.0:
            p = 0.0
        elif m_mean >= 1.0:
            p = 1.0
        else:
            p = float(st.beta(m_mean * conc, (1 - m_mean) * conc).rvs(random_state=rng))
        k = int(round(p * n))
        targets.append(p)
        chosen.append(np.sort(rng.choice(n, size=k, replace=False)) if k else np.zeros(0, int))
    # one row per chosen bay
    rows = [(si, int(b)) for si, ch in enumerate(chosen) for b in ch]
    N = len(rows)
    if N == 0:
        return [], {"targets": targets, "filled": [0] * len(sites), "bays": [len(s.bays) for s in sites],
                    "no_fit": 0, "reset": 0, "dropped": 0, "off_surface": 0}
    si = np.array([r[0] for r in rows])
    bi = np.array([r[1] for r in rows])
    cx = np.empty(N)
    cy = np.empty(N)
    axis = np.empty(N)
    bw = np.empty(N)
    bl = np.empty(N)
    angle = np.empty(N)
    out_m = np.empty(N)
    for k, site in enumerate(sites):
        sel = si == k
        if not sel.any():
            continue
        bb = site.bays
        cx[sel] = bb.centre_xy[bi[sel], 0]
        cy[sel] = bb.centre_xy[bi[sel], 1]
        axis[sel] = bb.axis_rad[bi[sel]]
        bw[sel], bl[sel], angle[sel] = bb.width_m, bb.length_m, bb.angle_deg
        out_m[sel] = STICK_OUT_M if site.kind == "lot" else 0.0  # kerb cars stay off the kerb
    # vehicles: class mix among those that fit
    tables = {False: _mix_table(catalog, cfg.mix, "parking.mix"),
              True: _mix_table(catalog, cfg.depot_mix, "parking.depot_mix")}
    model_idx = np.full(N, -1)
    all_models = list(catalog.models)
    pos = {m.name: i for i, m in enumerate(all_models)}
    for key in sorted({(float(a), float(b)) for a, b in zip(bw, bl)}):
        sel = np.flatnonzero((bw == key[0]) & (bl == key[1]))
        models, w = tables[key[1] >= cfg.depot_bay_min_m]
        fit = np.array([m.width_m <= key[0] and m.length_m <= key[1] + STICK_OUT_M for m in models])
        if not fit.any() or w[fit].sum() <= 0:
            continue
        p = np.where(fit, w, 0.0)
        pick = rng.choice(len(models), size=len(sel), p=p / p.sum())
        model_idx[sel] = [pos[models[j].name] for j in pick]
    ci = rng.choice(len(catalog.colors), size=N, p=catalog.color_probabilities)
    # trim options (roof racks, sunroofs, ...) as in traffic, from a stream of their own:
    # ``rng`` advances exactly as without them

    dressed = catalog.draw_options(model_idx, stream_key(rng))
    L = np.array([all_models[j].length_m if j >= 0 else 0.0 for j in model_idx])
    W = np.array([all_models[j].width_m if j >= 0 else 0.0 for j in model_idx])
    # manoeuvre and jitter
    back = (rng.random(N) < cfg.back_in_share) & ((angle == 90.0) | (angle == 0.0))
    a_max = np.radians(cfg.angle_max_deg)
    sig = np.radians(cfg.angle_sigma_deg)
    if sig > 0:
        dth = st.truncnorm(-a_max / sig, a_max / sig, scale=sig).rvs(size=N, random_state=rng)
    else:
        dth = np.zeros(N)
    lat = np.clip(rng.normal(0.0, 1.0, N), -2.5, 2.5) * cfg.lateral_sigma_m
    lon = np.clip(rng.normal(0.0, 1.0, N), -2.5, 2.5) * cfg.lateral_sigma_m
    is_semi = np.array([all_models[j].body == "semi_trailer" if j >= 0 else False for j in model_idx])
    dth[is_semi] = 0.0
    lat[is_semi] = 0.0
    # shrink jitter until every corner stays within the bay + STICK_OUT_M
    for _ in range(8):
        ext_l = L / 2 * np.cos(dth) + W / 2 * np.abs(np.sin(dth)) + np.abs(lon)
        ext_w = L / 2 * np.abs(np.sin(dth)) + W / 2 * np.cos(dth) + np.abs(lat)
        bad = (ext_l > bl / 2 + out_m - 1e-6) | (ext_w > bw / 2 + out_m - 1e-6)
        if not bad.any():
            break
        dth[bad] *= 0.5
        lat[bad] *= 0.5
        lon[bad] *= 0.5
    else:
        dth[bad] = lat[bad] = lon[bad] = 0.0
    head = np.mod(axis + np.where(back, np.pi, 0.0) + dth, 2 * np.pi)
    ca, sa = np.cos(axis), np.sin(axis)

    def poses(jit):
        x = cx + (ca * lon - sa * lat) * jit
        y = cy + (sa * lon + ca * lat) * jit
        h = np.where(jit > 0, head, np.mod(axis + np.where(back, np.pi, 0.0), 2 * np.pi))
        return x, y, h

    valid = model_idx >= 0
    jit = np.ones(N)
    x, y, h = poses(jit)
    off_surface = 0
    if surface_ok is not None:
        kerb_row = np.array([sites[k].kind == "kerb" for k in si])
        for rnd in range(2):
            live = np.flatnonzero(valid)
            if not len(live):
                break
            pts = _outline(x[live], y[live], h[live], L[live], W[live])
            bad = live[~surface_ok(pts, kerb_row[live])]
            if not len(bad):
                break
            if rnd == 0:
                jit[bad] = 0.0
                x, y, h = poses(jit)
            else:
                valid[bad] = False
                off_surface = len(bad)
    obs = [] if obstacles is None else list(obstacles)
    n_reset = 0
    for rnd in range(2):  # 0: clashing vehicles lose their jitter; 1: still clashing, dropped
        polys = shapely.polygons(footprint_corners_xy(x, y, h, L + 0.02, W + 0.02))
        live = np.flatnonzero(valid)
        clash = np.zeros(N, bool)
        if len(live):
            tree = shapely.STRtree(polys[live])
            a, b = tree.query(polys[live], predicate="intersects")
            pair = a != b
            clash[live[np.maximum(a, b)[pair]]] = True
            if rnd == 0:  # both of a pair lose their jitter
                clash[live[np.minimum(a, b)[pair]]] = True
            if obs:
                q_in, _ = shapely.STRtree(obs).query(polys[live], predicate="intersects")
                clash[live[q_in]] = True
        if not clash.any():
            break
        if rnd == 0:
            n_reset = int(clash.sum())
            jit[clash] = 0.0
            x, y, h = poses(jit)
        else:
            valid &= ~clash
    dropped = int(((model_idx >= 0) & ~valid).sum())
    z = np.zeros(N) if z_of is None else z_of(np.stack([x, y], 1))
    orig = np.full((N, 3), np.nan) if to_original is None else to_original(np.stack([x, y, z], 1))
    vehicles = []
    filled = [0] * len(sites)
    nid = first_id
    for i in np.flatnonzero(valid):
        m = dressed[i]  # the model with its option, if it drew one (same length and width)
        site = sites[si[i]]
        filled[si[i]] += 1
        vehicles.append(PlacedVehicle(
            id=nid, model=m.name, color=catalog.colors[ci[i]].name, cls=m.cls,
            length_m=float(m.length_m), width_m=float(m.width_m), height_m=float(m.height_m),
            x_m=float(x[i]), y_m=float(y[i]), z_m=float(z[i]), heading_rad=float(h[i]),
            direction="back-in" if back[i] else "nose-in", state="parked",
            lot=site.id if site.kind == "lot" else -1, kerb=site.id if site.kind == "kerb" else -1,
            bay=int(bi[i]), x_orig_m=float(orig[i, 0]), y_orig_m=float(orig[i, 1]), z_orig_m=float(orig[i, 2]),
        ))
        nid += 1
    stats = {"targets": targets, "filled": filled, "bays": [len(s.bays) for s in sites],
             "no_fit": int((model_idx < 0).sum()), "reset": n_reset, "dropped": dropped,
             "off_surface": off_surface}
    return vehicles, stats


def _outline(x, y, h, L, W, n_l: int = 5, n_w: int = 3) -> np.ndarray:
    """(n, 2 n_l + 2 n_w - 4 + 1, 2) points on each footprint's outline (1 cm inside) and
    its centre."""
    fl = np.linspace(-0.5, 0.5, n_l)
    fw = np.linspace(-0.5, 0.5, n_w)
    rim = [(a, -0.5) for a in fl] + [(a, 0.5) for a in fl] + [(-0.5, b) for b in fw[1:-1]] + [
        (0.5, b) for b in fw[1:-1]] + [(0.0, 0.0)]
    r = np.array(rim)
    lx = r[None, :, 0] * (L[:, None] - 0.02)
    ly = r[None, :, 1] * (W[:, None] - 0.02)
    c, s = np.cos(h)[:, None], np.sin(h)[:, None]
    return np.stack([x[:, None] + c * lx - s * ly, y[:, None] + s * lx + c * ly], axis=-1)


# ------------------------------------------------------------------------- scenario
def place_parking(rayscene, cfg, rng: np.random.Generator, catalog, seed=None, scene_name=None,
                  n_vehicles=None, n_lines=None, place_traffic=None) -> Placement:
    """Run a ``parking``, ``street-parking`` or ``mixed`` scenario (a ScenarioConfig).

    ``place_traffic`` is :func:`aerial_synth.placement.traffic.place` (passed in by it, so
    this module does not import it back); ``mixed`` needs it."""
    import warnings

    pc: ParkingConfig = cfg.parking
    lots_on, kerbs_on, traffic_on = PARKING_KINDS[cfg.kind]
    check_mix(catalog, pc)
    t0 = time.perf_counter()
    rs = rayscene
    lots = find_lots(rs, pc) if lots_on else []
    kerbs = find_kerbs(rs, pc, rng, cfg.probe, cfg.traffic) if kerbs_on else []
    sites = [_Site("lot", lt.id, lt.bays) for lt in lots] + [_Site("kerb", k.id, k.bays) for k in kerbs]

    def z_of(xy):
        tr = rs.trace_down(xy)
        return np.where(np.isfinite(tr.z), tr.z, 0.0)

    lot_ids = _lot_ids()
    kerb_ids = np.array([LABEL_IDS["road"], LABEL_IDS["lane_marking"]])

    def surface_ok(pts, is_kerb):
        lab = _trace_labels(rs, pts.reshape(-1, 2)).reshape(pts.shape[:2])
        return np.where(is_kerb, np.isin(lab, kerb_ids).all(axis=1), np.isin(lab, lot_ids).all(axis=1))

    parked, fstats = fill_bays(sites, pc, catalog, rng, None, first_id=1, z_of=z_of,
                               surface_ok=surface_ok, to_original=rs.scene.to_original)
    moving: list[PlacedVehicle] = []
    tstats: dict = {}
    if traffic_on:
        # traffic lines after the parked cars, which they keep gap_m from; with kerb parking
        # a line may also drive in the lane beside the parked cars (the lane offset plus the
        # kerb lane); the line checks refuse that lane where it is past the road's middle
        if place_traffic is None:
            raise PlacementError("the mixed scenario needs the traffic engine (place_traffic)")
        offs = cfg.lane_offsets_m
        if kerbs and offs is None:
            offs = (cfg.lane_offset_m, cfg.lane_offset_m + 2.0 * pc.kerb_offset_m)
        tcfg = dataclasses.replace(cfg, kind="lines", parking=None, lane_offsets_m=offs)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            tp = place_traffic(rs, tcfg, rng=rng, n_vehicles=n_vehicles, n_lines=n_lines, catalog=catalog,
                               seed=seed, scene_name=scene_name, obstacles=parked)
        first = len(parked) + 1
        moving = [dataclasses.replace(v, id=first + k, state="moving") for k, v in enumerate(tp.vehicles)]
        tstats = tp.stats
    vehicles = parked + moving  # moving ones carry their original coordinates already
    elapsed = time.perf_counter() - t0
    nl = len(lots)
    stats = {
        "vehicles": len(vehicles),
        "parked": len(parked),
        "moving": len(moving),
        "lots": [{"id": lt.id, "center_xy": [round(lt.frame.cx, 3), round(lt.frame.cy, 3)],
                  "row_deg": round(float(np.degrees(lt.frame.u_rad)), 3),
                  "size_m": [round(lt.frame.long_m, 3), round(lt.frame.short_m, 3)],
                  "layout_source": lt.layout_source, "bays": len(lt.bays),
                  "target_occupancy": round(fstats["targets"][i], 4),
                  "filled": fstats["filled"][i]} for i, lt in enumerate(lots)],
        "kerbs": len(kerbs),
        "kerb_bays": int(sum(len(k.bays) for k in kerbs)),
        "kerb_bays_kept_free": int(sum(k.dropped_bays for k in kerbs)),
        "kerb_filled": int(sum(fstats["filled"][nl:])),
        "no_fit": fstats["no_fit"],
        "jitter_reset": fstats["reset"],
        "dropped_overlap": fstats["dropped"],
        "dropped_off_surface": fstats["off_surface"],
    }
    # the traffic figures every placement has (zero without traffic lines)
    for k, default in (("lines", 0), ("opposite_lanes", 0), ("line_end_reasons", {}),
                       ("spacing_m", {"n": 0, "mean": None, "sd": None, "min": None, "max": None})):
        stats[k] = tstats.get(k, default)
    kept = Placement(scene="", scenario="", seed=None, vehicles=vehicles)
    stats["parking_validation"] = parking_report(kept, lots, kerbs, rs)
    if lots_on and not lots and not kerbs_on:
        raise PlacementError(
            f"scene {rs.scene.name!r}: vertical traces found no parking lot (labels "
            f"{', '.join(_LOT_LABELS)}, at least {pc.min_lot_m:g} m wide)")
    return Placement(
        scene=scene_name or rs.scene.name,
        scenario=cfg.name,
        seed=seed,
        parameters=cfg.to_dict(),
        vehicles=with_lonlat(vehicles, rs.scene.crs),
        stats=stats,
        timing={"seconds": elapsed, "vehicles_per_s": len(vehicles) / elapsed if elapsed else 0.0,
                "rays_per_s": 0.0},
        georeference=rs.scene.georeference(),
    )


# ------------------------------------------------------------------------- validator
def parking_report(placement: Placement, lots: list[Lot] | None = None, kerbs: list[Kerb] | None = None,
                   rayscene=None) -> dict:
    """Parked-vehicle figures: in-bay fraction (share of vehicles whose footprint stays
    within its bay grown by STICK_OUT_M), overlaps between parked footprints, alignment
    (degrees between the vehicle axis and its bay axis, modulo 180), and, with a rayscene,
    the share of parked footprints wholly on lot or road surface (3 x 5 traces each).

    Without ``lots``/``kerbs`` the lots are found again from ``rayscene``'s traces (kerb
    vehicles then count as unmatched)."""
    import shapely

    parked = [v for v in placement.vehicles if v.state == "parked"]
    if not parked:
        return {"parked": 0}
    if lots is None and rayscene is not None:
        pc = placement.parameters.get("parking") or {}
        known = {f.name for f in dataclasses.fields(ParkingConfig)}
        cfg = ParkingConfig(**{k: (tuple(v) if k == "kerb_road_width_m" else v) for k, v in pc.items()
                               if k in known})
        lots = find_lots(rayscene, cfg)
    n = len(parked)
    x = np.array([v.x_m for v in parked])
    y = np.array([v.y_m for v in parked])
    h = np.array([v.heading_rad for v in parked])
    L = np.array([v.length_m for v in parked])
    W = np.array([v.width_m for v in parked])
    bx, by, ba = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
    bl, bw = np.full(n, np.nan), np.full(n, np.nan)
    sites = {("lot", lt.id): lt.bays for lt in lots or []}
    sites.update({("kerb", k.id): k.bays for k in kerbs or []})
    for i, v in enumerate(parked):
        bb = sites.get(("lot", v.lot) if v.lot >= 0 else ("kerb", v.kerb))
        if bb is not None and 0 <= v.bay < len(bb):
            bx[i], by[i] = bb.centre_xy[v.bay]
            ba[i], bl[i], bw[i] = bb.axis_rad[v.bay], bb.length_m, bb.width_m
    matched = np.isfinite(ba)
    corners = footprint_corners_xy(x, y, h, L, W)  # (n, 4, 2)
    dx, dy = corners[..., 0] - bx[:, None], corners[..., 1] - by[:, None]
    along = np.abs(np.cos(ba)[:, None] * dx + np.sin(ba)[:, None] * dy)
    across = np.abs(-np.sin(ba)[:, None] * dx + np.cos(ba)[:, None] * dy)
    tol = STICK_OUT_M + 1e-6
    inside = ((along <= bl[:, None] / 2 + tol) & (across <= bw[:, None] / 2 + tol)).all(axis=1)
    d = np.degrees(np.abs(np.angle(np.exp(1j * (h - ba)))))
    align = np.minimum(d, 180.0 - d)
    polys = shapely.polygons(corners)
    a, b = shapely.STRtree(polys).query(polys, predicate="intersects")
    k = a < b
    overlaps = int((shapely.area(shapely.intersection(polys[a[k]], polys[b[k]])) > 1e-6).sum())
    out = {
        "parked": n,
        "in_bay_fraction": round(float(inside[matched].mean()), 6) if matched.any() else None,
        "unmatched": int((~matched).sum()),
        "overlaps": overlaps,
        "alignment_deg": {"mean": round(float(align[matched].mean()), 4),
                          "max": round(float(align[matched].max()), 4)} if matched.any() else None,
    }
    if rayscene is not None:
        pts = _outline(x, y, h, L, W, n_l=5, n_w=3)
        lab = _trace_labels(rayscene, pts.reshape(-1, 2)).reshape(n, -1)
        surf = [LABEL_IDS[s] for s in ("parking", "parking_marking", "road", "lane_marking")]
        out["on_surface_fraction"] = round(float(np.isin(lab, surf).all(axis=1).mean()), 6)
    return out
