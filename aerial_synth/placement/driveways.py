"""Vehicles parked on driveways, side pads and farm yards (scenario kind ``driveways``).

A ``residential`` or ``rural`` scene carries a hint per parking site
(``Scene.hints.driveways``, procedural/residential.py and rural.py): its id, kind
(``driveway``, ``pad`` or ``yard``), the usable rectangle (centre, axis from the street
into the site, length along and width across the axis), the bay size, an occupancy and a
class mix. What the hint cannot tell is checked with vertical line traces: a bay is kept
only when a 3 x 3 grid of traces inside it all land on ``parking``, and a parked vehicle
only when the traces over its whole footprint (outline and interior every 0.1 m, as the
validator traces it) all do. Bays are laid along the axis (as many as fit, centred), side by side across it; each bay is filled with probability ``occupancy``
by a vehicle of the mix that fits it (length <= bay length, width <= bay width - 0.3 m),
parked nose-in (70 %) or backed in, with a small sideways and heading jitter that keeps
every corner inside the site. Footprints never overlap (STRtree).

The scenario then runs the kerb parking and the traffic lines of its ``parking`` block and
``spacing`` (as ``mixed`` without lots, placement/parking.py), which keep clear of the
driveway vehicles. Each driveway vehicle records its site in ``driveway`` (the hint id).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from ..errors import PlacementError
from ..scene.model import LABEL_IDS
from .footprints import footprint_points, footprints_on
from .model import PlacedVehicle, Placement, footprint_corners_xy, with_lonlat
from .parking import mix_table, place_parking

__all__ = ["DrivewaySite", "find_sites", "fill_sites", "place_driveways", "driveway_report"]

_SITE_LABELS = ("parking", "parking_marking")
#: Sideways margin kept between a vehicle and its bay side (metres).
SIDE_MARGIN_M = 0.15


@dataclasses.dataclass(frozen=True)
class DrivewaySite:
    """One site: hint id and kind, frame (centre (2,), axis unit (2,)), usable length along
    the axis and width across it (metres), bay centres (k, 2), bay size, occupancy, mix,
    the label ids it stands on."""

    id: int
    kind: str
    center: np.ndarray
    axis: np.ndarray
    long_m: float
    short_m: float
    bays: np.ndarray
    bay_len_m: float
    bay_wid_m: float
    occupancy: float
    mix: dict
    label_ids: np.ndarray  # the labels its bays and footprints must stand on

    def polygon(self, grow_m: float = 0.0):
        import shapely

        v = np.array([-self.axis[1], self.axis[0]])
        a, b = self.long_m / 2 + grow_m, self.short_m / 2 + grow_m
        c = self.center
        return shapely.Polygon([c - self.axis * a - v * b, c + self.axis * a - v * b,
                                c + self.axis * a + v * b, c - self.axis * a + v * b])


def _site_ids(hint) -> np.ndarray:
    """Label ids a site's vehicles may stand on: the hint's ``labels`` (an OSM driveway is
    road surface) or parking and its painted lines."""
    names = hint.labels or _SITE_LABELS
    return np.array([LABEL_IDS[n] for n in names if n in LABEL_IDS])


def _labels(rs, xy):
    return rs.trace_labels(np.asarray(xy, float).reshape(-1, 2))


def find_sites(rayscene) -> list[DrivewaySite]:
    """The scene's driveway hints with the bays that traces confirm (see the module doc)."""
    sites = []
    for h in rayscene.scene.hints.driveways:
        ids = _site_ids(h)
        c = np.asarray(h.center_xy, float)
        a = np.radians(h.axis_deg)
        L, Wd = h.long_m, h.short_m
        bl, bw = h.bay_m
        if not (L > 0 and Wd > 0 and bl > 0 and bw > 0):
            continue
        u = np.array([np.cos(a), np.sin(a)])
        v = np.array([-u[1], u[0]])
        nl, nw = int(np.floor(L / bl + 1e-9)), int(np.floor(Wd / bw + 1e-9))
        if nl < 1 or nw < 1:
            continue
        sl = (np.arange(nl) - (nl - 1) / 2) * (L / nl)
        sw = (np.arange(nw) - (nw - 1) / 2) * (Wd / nw)
        S, T = np.meshgrid(sl, sw, indexing="ij")
        centres = c + np.outer(S.ravel(), u) + np.outer(T.ravel(), v)
        bl_eff, bw_eff = L / nl, Wd / nw
        f = np.array([-0.4, 0.0, 0.4])
        gu, gv = np.meshgrid(f * bl_eff, f * bw_eff, indexing="ij")
        pts = centres[:, None, :] + gu.ravel()[None, :, None] * u + gv.ravel()[None, :, None] * v
        ok = np.isin(_labels(rayscene, pts).reshape(len(centres), -1), ids).all(axis=1)
        sites.append(DrivewaySite(int(h.id), h.kind, c, u, L, Wd, centres[ok], bl_eff, bw_eff,
                                  h.occupancy, h.mix_dict(), ids))
    return sites


def fill_sites(sites, catalog, rng: np.random.Generator, rayscene, first_id: int = 1,
               obstacles=None) -> tuple[list[PlacedVehicle], dict]:
    """Park vehicles in the sites' bays. Returns (vehicles, stats)."""
    import shapely

    placed_polys = list(obstacles or [])
    vehicles: list[PlacedVehicle] = []
    stats = {"sites": len(sites), "bays": 0, "filled": 0, "no_fit": 0, "off_surface": 0, "overlap": 0,
             "by_kind": {}}
    nid = first_id
    for site in sites:
        models, w = mix_table(catalog, site.mix, f"driveways[{site.id}].mix", in_traffic_only=True)
        stats["bays"] += len(site.bays)
        kk = stats["by_kind"].setdefault(site.kind, {"sites": 0, "vehicles": 0})
        kk["sites"] += 1
        fit = np.array([m.length_m <= site.bay_len_m and m.width_m <= site.bay_wid_m - 2 * SIDE_MARGIN_M
                        for m in models])
        for bc in site.bays:
            if rng.random() >= site.occupancy:
                continue
            if not fit.any() or w[fit].sum() <= 0:
                stats["no_fit"] += 1
                continue
            p = np.where(fit, w, 0.0)
            m = models[int(rng.choice(len(models), p=p / p.sum()))]
            col = catalog.colors[int(rng.choice(len(catalog.colors), p=catalog.color_probabilities))]
            back = rng.random() < 0.3
            head0 = float(np.arctan2(site.axis[1], site.axis[0])) + (np.pi if back else 0.0)
            # heading jitter, then a position jitter within the room the bay leaves
            dth = float(np.clip(rng.normal(0.0, np.radians(2.0)), -np.radians(4.0), np.radians(4.0)))
            ext_l = m.length_m / 2 * abs(np.cos(dth)) + m.width_m / 2 * abs(np.sin(dth))
            ext_w = m.length_m / 2 * abs(np.sin(dth)) + m.width_m / 2 * abs(np.cos(dth))
            if ext_l > site.bay_len_m / 2 or ext_w > site.bay_wid_m / 2 - SIDE_MARGIN_M / 2:
                dth, ext_l, ext_w = 0.0, m.length_m / 2, m.width_m / 2
            sl = rng.uniform(-1.0, 1.0) * max(site.bay_len_m / 2 - ext_l, 0.0)
            if site.kind == "driveway":  # cars stand towards the garage door
                sl = abs(sl) * 0.5 + max(site.bay_len_m / 2 - ext_l, 0.0) * 0.5
            st = rng.uniform(-1.0, 1.0) * max(site.bay_wid_m / 2 - SIDE_MARGIN_M - ext_w, 0.0)
            v = np.array([-site.axis[1], site.axis[0]])
            xy = bc + site.axis * sl + v * st
            h = float(np.mod(head0 + dth, 2 * np.pi))
            corners = footprint_corners_xy(xy[0], xy[1], h, m.length_m, m.width_m)
            # the whole footprint on the site's surface, traced as the validator does
            if not footprints_on(lambda p: _labels(rayscene, p), xy[0], xy[1], h, m.length_m,
                                 m.width_m, site.label_ids)[0]:
                stats["off_surface"] += 1
                continue
            poly = shapely.Polygon(corners)
            grown = poly.buffer(0.1)
            if placed_polys and shapely.intersects(np.array(placed_polys, dtype=object), grown).any():
                stats["overlap"] += 1
                continue
            placed_polys.append(poly)
            z = rayscene.trace_down(xy[None, :]).z
            zz = float(z[0]) if np.isfinite(z[0]) else 0.0
            orig = rayscene.scene.to_original(np.array([[xy[0], xy[1], zz]]))[0]
            model = catalog.draw_options([catalog.models.index(m)], int(rng.integers(2**62)))[0]
            vehicles.append(PlacedVehicle(
                id=nid, model=model.name, color=col.name, cls=model.cls, length_m=float(model.length_m),
                width_m=float(model.width_m), height_m=float(model.height_m), x_m=float(xy[0]),
                y_m=float(xy[1]), z_m=zz, heading_rad=h, direction="back-in" if back else "nose-in",
                state="parked", driveway=site.id, x_orig_m=float(orig[0]), y_orig_m=float(orig[1]),
                z_orig_m=float(orig[2])))
            nid += 1
            stats["filled"] += 1
            kk["vehicles"] += 1
    return vehicles, stats


def driveway_report(placement: Placement, sites) -> dict:
    """Share of driveway vehicles whose footprint lies inside its site's rectangle (grown by
    1 cm), and overlaps between all footprints."""
    import shapely

    by = {s.id: s for s in sites}
    dv = [v for v in placement.vehicles if getattr(v, "driveway", -1) >= 0]
    inside = 0
    for v in dv:
        s = by.get(v.driveway)
        if s is not None and s.polygon(0.01).contains(shapely.Polygon(v.corners_xy())):
            inside += 1
    polys = shapely.polygons(footprint_corners_xy(
        np.array([v.x_m for v in placement.vehicles]), np.array([v.y_m for v in placement.vehicles]),
        np.array([v.heading_rad for v in placement.vehicles]),
        np.array([v.length_m for v in placement.vehicles]),
        np.array([v.width_m for v in placement.vehicles]))) if placement.vehicles else np.zeros(0, object)
    overlaps = 0
    if len(polys):
        a, b = shapely.STRtree(polys).query(polys, predicate="intersects")
        k = a < b
        overlaps = int((shapely.area(shapely.intersection(polys[a[k]], polys[b[k]])) > 1e-6).sum())
    return {"driveway_vehicles": len(dv), "in_site_fraction": round(inside / len(dv), 6) if dv else None,
            "overlaps": overlaps}


def place_driveways(rayscene, cfg, rng: np.random.Generator, catalog, seed=None, scene_name=None,
                    n_vehicles=None, n_lines=None, place_traffic=None) -> Placement:
    """Run a ``driveways`` scenario: driveway, pad and yard vehicles, then kerb parking and
    traffic lines (placement/parking.py, as ``mixed`` without lots)."""
    t0 = time.perf_counter()
    sites = find_sites(rayscene)
    if not sites and not rayscene.scene.hints.driveways:
        import warnings

        warnings.warn(f"scene {rayscene.scene.name!r} carries no driveway hints (a residential or "
                      f"rural scene does); only kerbs and traffic are placed", stacklevel=2)
    parked, dstats = fill_sites(sites, catalog, rng, rayscene)
    rest = place_parking(rayscene, cfg, rng, catalog, seed=seed, scene_name=scene_name,
                         n_vehicles=n_vehicles, n_lines=n_lines, place_traffic=place_traffic)
    # kerb and traffic vehicles keep clear of the driveway vehicles, and every footprint
    # sample of theirs lands on drivable surface (a kerb bay on a tight bend may not)
    import shapely

    drv = np.array(sorted(LABEL_IDS[n] for n in rayscene.label_config.drivable))
    ok = np.ones(len(rest.vehicles), bool)
    if rest.vehicles:
        vs = rest.vehicles
        pts, owner, _, _ = footprint_points(np.array([v.x_m for v in vs]), np.array([v.y_m for v in vs]),
                                            np.array([v.heading_rad for v in vs]),
                                            np.array([v.length_m for v in vs]), np.array([v.width_m for v in vs]))
        off = ~np.isin(_labels(rayscene, pts), drv)
        ok[np.unique(owner[off])] = False
    tree = shapely.STRtree([shapely.Polygon(v.corners_xy(0.2)) for v in parked]) if parked else None
    kept = [v for v, good in zip(rest.vehicles, ok) if good and (
        tree is None or not len(tree.query(shapely.Polygon(v.corners_xy()), predicate="intersects")))]
    first = len(parked) + 1
    others = [dataclasses.replace(v, id=first + k) for k, v in enumerate(kept)]
    vehicles = with_lonlat(parked, rayscene.scene.crs) + others
    stats = dict(rest.stats)
    stats["vehicles"] = len(vehicles)
    stats["driveways"] = dstats
    stats["dropped_off_drivable"] = int((~ok).sum())
    stats["dropped_near_driveways"] = len(rest.vehicles) - len(kept) - int((~ok).sum())
    neg = rayscene.scene.hints.negatives
    if neg is not None:
        stats["hard_negatives"] = dict(neg.counts)
    pl = Placement(scene=scene_name or rayscene.scene.name, scenario=cfg.name, seed=seed,
                   parameters=cfg.to_dict(), vehicles=vehicles, stats=stats,
                   georeference=rayscene.scene.georeference())
    stats["driveway_validation"] = driveway_report(pl, sites)
    if not vehicles:
        raise PlacementError(f"scene {rayscene.scene.name!r}: the driveways scenario placed no vehicle")
    elapsed = time.perf_counter() - t0
    pl.timing = {"seconds": elapsed, "vehicles_per_s": len(vehicles) / elapsed if elapsed else 0.0,
                 "rays_per_s": 0.0}
    return pl
