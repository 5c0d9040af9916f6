"""Kerb lines for street parking, found by line traces along road edges.

Kerbs. Random road traces seed kerb lines; from each seed the 36-direction probe finds the
nearest edge (the thesis's fewest-road-hits rule) and the line then steps ``kerb_bay_m`` at
a time along the edge, re-locating it with the two-direction probe and stopping where the
edge jumps or turns (a junction, a road end). A kerb bay is dropped when, beside it or
within ``kerb_clear_m`` before or after it, the trace just beyond the kerb hits road (a
junction's crossing street) or parking (a driveway or lot entrance), or when the bay is
not all road (or lines painted on it).

Part of :mod:`aerial_synth.placement.parking` (docs/parking.md).
"""

from __future__ import annotations

import numpy as np

from ..scene.model import LABEL_IDS
from ..scene.parking_layout import Bays
from .config import ProbeConfig
from .linetrace import Prober, unit
from .lots import Kerb, trace_labels
from .parking_config import ParkingConfig

__all__ = ["find_kerbs"]


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
    rules = _kerb_rules(rs.scene.hints.kerbs)
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
    """Kerb parking tags of mapped roads (``Scene.hints.kerbs``, from OSM
    ``parking:left|right|both`` and ``parking:lane:*``): [(centre line, width, left, right)]."""
    import shapely

    return [(shapely.LineString(r.coords), r.width_m, r.left, r.right) for r in data]


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
    lab = trace_labels(rs, pts.reshape(-1, 2)).reshape(n, len(s), len(outs))
    bad_out = road_lut[lab].any(axis=(1, 2)) | (lab == LABEL_IDS["parking"]).any(axis=(1, 2))
    # the bay itself: road or painted lines on it (edge lines) only
    f = np.array([-0.45, -0.15, 0.15, 0.45])
    gu, gv = np.meshgrid(f * L, np.array([-0.35, 0.0, 0.35]) * bays.width_m)
    c, sn = np.cos(bays.axis_rad)[:, None], np.sin(bays.axis_rad)[:, None]
    px = bays.centre_xy[:, :1] + c * gu.ravel() - sn * gv.ravel()
    py = bays.centre_xy[:, 1:] + sn * gu.ravel() + c * gv.ravel()
    lab_in = trace_labels(rs, np.stack([px.ravel(), py.ravel()], 1)).reshape(n, -1)
    bad_in = ~road_lut[lab_in].all(axis=1)
    # the edge must run straight along the bay (no bend)
    return ~(bad_out | bad_in)
