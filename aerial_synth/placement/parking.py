"""Parked vehicles: lots (``parking``), kerbs (``street-parking``) and both plus traffic
(``mixed``), in the spirit of the thesis's line traces (docs/parking.md).

Lots are found in :mod:`.lots`, kerb lines in :mod:`.kerbs`; this module fills their bays.

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

from ..errors import ConfigError, PlacementError
from ..scene.model import LABEL_IDS
from ..vehicles.catalog import stream_key
from .footprints import footprints_on
from .kerbs import find_kerbs
from .lots import LOT_LABELS, STICK_OUT_M, Kerb, Lot, find_lots, lot_label_ids, trace_labels
from .model import PlacedVehicle, Placement, footprint_corners_xy, with_lonlat
from .parking_config import PARKING_KINDS, ParkingConfig

__all__ = ["Lot", "Kerb", "find_lots", "find_kerbs", "fill_bays", "place_parking",
           "parking_report", "STICK_OUT_M"]


# ------------------------------------------------------------------------- filling
def mix_table(catalog, mix: dict, field_name: str, in_traffic_only: bool = False) -> tuple[list, np.ndarray]:
    """(models, weights) of a class mix; an unknown class or model raises ConfigError.

    in_traffic_only : a class stands for its models of traffic weight > 0 only (driveways:
                      the towed bodies, weight 0, come only when named)"""
    names = {m.name: m for m in catalog.models}
    classes = sorted({m.cls for m in catalog.models})
    models, weights = [], []
    for key, w in mix.items():
        if key in names:
            group = [names[key]]
        elif key in classes:
            group = [m for m in catalog.models if m.cls == key and (m.weight > 0 or not in_traffic_only)]
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
    mix_table(catalog, cfg.mix, "parking.mix")
    mix_table(catalog, cfg.depot_mix, "parking.depot_mix")


@dataclass
class _Site:
    kind: str  # "lot" or "kerb"
    id: int
    bays: object


def fill_bays(sites: list, cfg: ParkingConfig, catalog, rng: np.random.Generator,
              obstacles=None, first_id: int = 1, z_of=None, surface_ok=None,
              to_original=None) -> tuple[list, dict]:
    """Fill the bays of every site (lots and kerb lines). Returns (vehicles, stats).

    ``surface_ok(x, y, heading, length, width, is_kerb) -> (n,) bool`` checks that the
    footprints lie on the site's surface (a lot edge or the kerb); a jittered vehicle that
    fails loses its jitter, and one that still fails leaves its bay empty."""
    targets, chosen = _choose_bays(sites, cfg, rng)
    # one row per chosen bay
    rows = [(si, int(b)) for si, ch in enumerate(chosen) for b in ch]
    N = len(rows)
    if N == 0:
        return [], {"targets": targets, "filled": [0] * len(sites), "bays": [len(s.bays) for s in sites],
                    "no_fit": 0, "reset": 0, "dropped": 0, "off_surface": 0}
    si = np.array([r[0] for r in rows])
    bi = np.array([r[1] for r in rows])
    cx, cy, axis, bw, bl, angle, out_m = _bay_rows(sites, si, bi)
    model_idx = _draw_models(catalog, cfg, bw, bl, rng)
    all_models = list(catalog.models)
    ci = rng.choice(len(catalog.colors), size=N, p=catalog.color_probabilities)
    # trim options (roof racks, sunroofs, ...) as in traffic, from a stream of their own:
    # ``rng`` advances exactly as without them

    dressed = catalog.draw_options(model_idx, stream_key(rng))
    L = np.array([all_models[j].length_m if j >= 0 else 0.0 for j in model_idx])
    W = np.array([all_models[j].width_m if j >= 0 else 0.0 for j in model_idx])
    is_semi = np.array([all_models[j].body == "semi_trailer" if j >= 0 else False for j in model_idx])
    back, dth, lat, lon = _draw_jitter(cfg, rng, angle, is_semi, L, W, bl, bw, out_m)
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
            bad = live[~surface_ok(x[live], y[live], h[live], L[live], W[live], kerb_row[live])]
            if not len(bad):
                break
            if rnd == 0:
                jit[bad] = 0.0
                x, y, h = poses(jit)
            else:
                valid[bad] = False
                off_surface = len(bad)
    x, y, h, n_reset = _settle_clashes(obstacles, poses, jit, valid, x, y, h, L, W)
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


def _choose_bays(sites: list, cfg: ParkingConfig, rng: np.random.Generator) -> tuple[list, list]:
    """(occupancy target per site, sorted chosen bay indices per site): the occupancy is
    drawn from Beta(mean c, (1 - mean) c), that share of the bays chosen uniformly."""
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
    return targets, chosen


def _bay_rows(sites: list, si: np.ndarray, bi: np.ndarray):
    """Per chosen bay (site si, bay bi; n of them): centre x, y (metres), axis (radians),
    bay width, length (metres), angle (degrees) and how far a footprint may leave it."""
    N = len(si)
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
    return cx, cy, axis, bw, bl, angle, out_m


def _draw_models(catalog, cfg: ParkingConfig, bw: np.ndarray, bl: np.ndarray,
                 rng: np.random.Generator) -> np.ndarray:
    """(n,) catalog model index per bay (-1: nothing fits): the class mix among the
    vehicles that fit the bay (``depot_mix`` for bays of at least ``depot_bay_min_m``)."""
    tables = {False: mix_table(catalog, cfg.mix, "parking.mix"),
              True: mix_table(catalog, cfg.depot_mix, "parking.depot_mix")}
    model_idx = np.full(len(bw), -1)
    pos = {m.name: i for i, m in enumerate(catalog.models)}
    for key in sorted({(float(a), float(b)) for a, b in zip(bw, bl)}):
        sel = np.flatnonzero((bw == key[0]) & (bl == key[1]))
        models, w = tables[key[1] >= cfg.depot_bay_min_m]
        fit = np.array([m.width_m <= key[0] and m.length_m <= key[1] + STICK_OUT_M for m in models])
        if not fit.any() or w[fit].sum() <= 0:
            continue
        p = np.where(fit, w, 0.0)
        pick = rng.choice(len(models), size=len(sel), p=p / p.sum())
        model_idx[sel] = [pos[models[j].name] for j in pick]
    return model_idx


def _draw_jitter(cfg: ParkingConfig, rng: np.random.Generator, angle, is_semi, L, W, bl, bw, out_m):
    """(back-in (n,) bool, heading jitter (n,) rad, lateral and along-bay offsets (n,) m),
    shrunk until every corner stays within its bay + ``out_m``; semi-trailers stand straight."""
    from scipy import stats as st

    N = len(angle)
    back = (rng.random(N) < cfg.back_in_share) & ((angle == 90.0) | (angle == 0.0))
    a_max = np.radians(cfg.angle_max_deg)
    sig = np.radians(cfg.angle_sigma_deg)
    if sig > 0:
        dth = st.truncnorm(-a_max / sig, a_max / sig, scale=sig).rvs(size=N, random_state=rng)
    else:
        dth = np.zeros(N)
    lat = np.clip(rng.normal(0.0, 1.0, N), -2.5, 2.5) * cfg.lateral_sigma_m
    lon = np.clip(rng.normal(0.0, 1.0, N), -2.5, 2.5) * cfg.lateral_sigma_m
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
    return back, dth, lat, lon


def _settle_clashes(obstacles, poses, jit, valid, x, y, h, L, W):
    """Footprints that overlap each other or an obstacle: both of a pair lose their jitter
    (``jit`` set to 0, poses redrawn), then a vehicle still clashing is dropped from
    ``valid`` (both updated in place). Returns (x, y, heading, number reset)."""
    import shapely

    N = len(x)
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
    return x, y, h, n_reset


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

    lot_ids = lot_label_ids()
    kerb_ids = np.array([LABEL_IDS["road"], LABEL_IDS["lane_marking"]])

    lut = np.zeros((2, max(LABEL_IDS.values()) + 1), bool)  # row 0: a lot, row 1: a kerb
    lut[0, lot_ids] = True
    lut[1, kerb_ids] = True

    def surface_ok(x, y, h, L, W, is_kerb):
        # the whole footprint, traced as the validator traces it (outline and interior
        # every 0.1 m): 5 x 3 outline traces let a kerb car overhang a curved kerb
        return footprints_on(lambda p: trace_labels(rs, p), x, y, h, L, W, lut[is_kerb.astype(int)])

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
            f"{', '.join(LOT_LABELS)}, at least {pc.min_lot_m:g} m wide)")
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
    the share of parked footprints wholly on lot or road surface (traced as the validator traces a footprint).

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
        surf = [LABEL_IDS[s] for s in ("parking", "parking_marking", "road", "lane_marking")]
        on = footprints_on(lambda p: trace_labels(rayscene, p), x, y, h, L, W, surf)
        out["on_surface_fraction"] = round(float(on.mean()), 6)
    return out
