"""Generator ``residential``: a neighbourhood of detached houses, US or European (``variant``).

Streets: a curved collector street across the scene (west to east), up to two crescents
parallel to it (two parcel depths away, where the scene is tall enough) and ``branches``
curved side streets off the collector, alternately north and south; a share of them end in
a cul-de-sac (a turning circle), the others run on to the scene edge. Parcels line both
sides of every street (and fan round every turning circle); each holds:

- a house (gable, hip or pyramid roof, or flat; coverings and colours per variant,
  procedural/houses.py) set back from the street, with an attached garage on one side
  (or, without one, a parking place beside the house);
- a driveway from the street to the garage door (``parking``, concrete or asphalt; single
  or double width), recorded as a scene hint with an id (``Scene.hints.driveways``) so
  that placement can park cars on it and name the driveway each car stands in;
- sometimes a gravel side pad beside the house for an RV, a boat trailer or a utility
  trailer (also ``parking``, hint kind ``pad``);
- a back yard behind a fence (US: wooden privacy or chain-link fences; EU: hedges or
  fences) with a patio, garden furniture, sometimes a pool or a trampoline, yard trees;
- hard negatives (sheds, garden houses, AC condensers, slabs, boats, dumpsters, bus
  shelters, road patches) at the densities of procedural/negatives.py.

Variants (``variant: us | eu``) set the defaults of every section below: US lots are wide
and deep (24-32 m frontage), streets wide (9 m) with narrow sidewalks, driveways often
double, pools and RV pads common; European lots are narrow (16-22 m), streets 6 m with 2 m
sidewalks, single driveways, hedges, few pools. Every value can be set in the spec::

    variant: us
    streets: {collector_width_m: 11, street_width_m: 9, sidewalk_m: 1.5, branches: 4,
              cul_de_sac_prob: 0.7, curve_m: 25, crescents: 2}
    houses:  {frontage_m: [24, 30], depth_m: [30, 38], setback_m: [7, 12.5],
              width_m: [11, 16], house_depth_m: [9, 13], height_m: [6, 9]}
    yards:   {double_driveway: 0.7, garage: 0.9, pad: 0.3, pool: 0.3, trampoline: 0.2,
              patio: 0.7, furniture: 0.5, hedge: 0.0, trees_per_parcel: 1.5}
    vehicles: {driveway_occupancy: 0.65, pad_occupancy: 0.8,
               driveway_mix: {small-vehicle: 1.0}, pad_mix: {campervan: 0.4, ...}}
    hard_negatives: {scale: 1.0, density_per_ha: {shed: 2.5}}

World frame: metres, x east, y north, z up; the scene is centred on the origin.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ... import validators as V
from ...errors import SceneError
from ..build import polygon_object
from ..scene_hints import DrivewayHint, NegativesHint
from . import spec as S
from .builder import Z_ROAD, Builder
from .generators import Generator
from .houses import HouseSet
from .negatives import NEGATIVE_KINDS, add_negatives
from .roads import Road, chaikin, offset_line, polygonal

__all__ = ["generate_residential", "RESIDENTIAL_DEFAULTS", "check_residential", "NEGATIVES_SECTION",
           "VEHICLES_SECTION"]

RESIDENTIAL_DEFAULTS: dict[str, dict] = {
    "us": {
        "streets": {"collector_width_m": 11.0, "street_width_m": 9.0, "sidewalk_m": 1.5,
                    "branches": 4, "cul_de_sac_prob": 0.7, "curve_m": 25.0, "crescents": 2},
        "houses": {"frontage_m": [24.0, 30.0], "depth_m": [30.0, 38.0], "setback_m": [7.0, 12.5],
                   "width_m": [11.0, 16.0], "house_depth_m": [9.0, 13.0], "height_m": [6.0, 9.0]},
        "yards": {"double_driveway": 0.7, "garage": 0.92, "pad": 0.3, "pool": 0.3,
                  "trampoline": 0.2, "patio": 0.7, "furniture": 0.5, "hedge": 0.05,
                  "trees_per_parcel": 1.5},
        "vehicles": {"driveway_occupancy": 0.6, "pad_occupancy": 0.8,
                     "driveway_mix": {"small-vehicle": 0.95, "delivery_van": 0.05},
                     "pad_mix": {"campervan": 0.4, "boat_trailer": 0.35, "utility_trailer": 0.25}},
    },
    "eu": {
        "streets": {"collector_width_m": 7.5, "street_width_m": 6.0, "sidewalk_m": 2.0,
                    "branches": 4, "cul_de_sac_prob": 0.5, "curve_m": 18.0, "crescents": 2},
        "houses": {"frontage_m": [16.0, 22.0], "depth_m": [26.0, 34.0], "setback_m": [5.8, 8.0],
                   "width_m": [8.5, 12.0], "house_depth_m": [8.0, 11.0], "height_m": [7.0, 10.0]},
        "yards": {"double_driveway": 0.15, "garage": 0.7, "pad": 0.06, "pool": 0.06,
                  "trampoline": 0.15, "patio": 0.8, "furniture": 0.5, "hedge": 0.6,
                  "trees_per_parcel": 1.2},
        "vehicles": {"driveway_occupancy": 0.55, "pad_occupancy": 0.7,
                     "driveway_mix": {"small-vehicle": 0.97, "delivery_van": 0.03},
                     "pad_mix": {"campervan": 0.6, "utility_trailer": 0.3, "boat_trailer": 0.1}},
    },
}

#: Bay sizes of the hints: a car bay in a driveway, metres (length along the driveway).
DRIVEWAY_BAY_M = (5.6, 2.6)


def _mix(f, v):
    V.mapping(f, v, error=SceneError)
    if not v:
        raise SceneError(f"{f}: expected at least one class or model with a weight, got {{}}")
    out = {}
    for k, w in v.items():
        if not isinstance(k, str) or not k:
            raise SceneError(f"{f}: expected class or model names as keys, got {V.show(k)}")
        out[k] = V.in_range(f"{f}.{k}", w, 0.0, 1e6, error=SceneError)
    if sum(out.values()) <= 0:
        raise SceneError(f"{f}: expected a positive total weight, got {V.show(v)}")
    return out


NEGATIVES_SECTION = S.section({
    "scale": S.nonneg(100.0),
    "density_per_ha": S.section({k: S.nonneg(1000.0) for k in NEGATIVE_KINDS}, allow_none=False),
})
VEHICLES_SECTION = S.section({
    "driveway_occupancy": S.prob, "pad_occupancy": S.prob, "yard_occupancy": S.prob,
    "driveway_mix": _mix, "pad_mix": _mix, "yard_mix": _mix,
})
_KEYS = {
    "variant": S.choice("us", "eu"),
    "streets": S.section({"collector_width_m": S.pos(40.0), "street_width_m": S.pos(40.0),
                          "sidewalk_m": S.nonneg(10.0), "branches": S.integer(0, 40),
                          "cul_de_sac_prob": S.prob, "curve_m": S.nonneg(500.0),
                          "crescents": S.integer(0, 2)}),
    "houses": S.section({"frontage_m": S.span(8.0, 200.0), "depth_m": S.span(15.0, 300.0),
                         "setback_m": S.span(5.8, 50.0), "width_m": S.span(5.0, 60.0),
                         "house_depth_m": S.span(6.0, 60.0), "height_m": S.span(3.5, 30.0)}),
    "yards": S.section({k: S.prob for k in ("double_driveway", "garage", "pad", "pool", "trampoline",
                                            "patio", "furniture", "hedge")}
                       | {"trees_per_parcel": S.nonneg(50.0)}),
    "vehicles": VEHICLES_SECTION,
    "hard_negatives": NEGATIVES_SECTION,
}


def check_residential(spec: Mapping) -> dict:
    """Validate the residential keys (the common ones are checked by spec.check_spec) and
    return the spec with the variant's defaults filled in, section by section."""
    V.known_keys("top level", spec, S._COMMON + tuple(_KEYS), error=SceneError)
    out = dict(spec)
    for k, chk in _KEYS.items():
        if k in spec:
            out[k] = chk(k, spec[k])
    var = out.get("variant") or "us"
    out["variant"] = var
    for sec, d in RESIDENTIAL_DEFAULTS[var].items():
        out[sec] = {**d, **(out.get(sec) or {})}
    h = out["houses"]
    if h["setback_m"][0] + h["house_depth_m"][1] + 3.0 > h["depth_m"][0]:
        raise SceneError(
            f"houses.depth_m: expected parcels deeper than setback + house depth + 3 m "
            f"({h['setback_m'][0] + h['house_depth_m'][1] + 3.0:g} m), got {h['depth_m']}")
    return out


# ------------------------------------------------------------------------- streets
def _streets(b: Builder, cfg: Mapping) -> None:
    from shapely.geometry import LineString, Point

    rng = b.rng
    W, H = (float(x) for x in b.spec["size_m"])
    st = cfg["streets"]
    cw, sw, side = st["collector_width_m"], st["street_width_m"], st["sidewalk_m"]
    amp = min(st["curve_m"], H / 6)
    lam = rng.uniform(0.8, 1.4) * W
    ph = rng.uniform(0, 2 * np.pi)
    xs = np.linspace(-W / 2 - 10, W / 2 + 10, 13)
    ys = amp * np.sin(2 * np.pi * xs / lam + ph) + rng.uniform(-0.15, 0.15, len(xs)) * amp
    ys -= ys.mean()
    coll = LineString(chaikin(np.column_stack([xs, ys]), 3))
    b.roads.append(Road("collector", coll, cw, sidewalk_m=side, centre="dashed" if cw >= 8 else "none"))
    # crescents: streets parallel to the collector, two parcel depths away on each side
    hs = cfg["houses"]
    gap = sum(hs["depth_m"]) + sw + 2 * side + 2.0
    for k, sgn in enumerate((1.0, -1.0)[: int(st["crescents"])]):
        if gap + amp > H / 2 - 20.0:
            break
        cres = offset_line(coll, sgn * gap)
        if cres.is_empty or cres.geom_type != "LineString":
            continue
        c = np.asarray(cres.coords)  # run both ends on along their tangents, past the edge
        t0 = (c[0] - c[1]) / max(math.hypot(*(c[0] - c[1])), 1e-9)
        t1 = (c[-1] - c[-2]) / max(math.hypot(*(c[-1] - c[-2])), 1e-9)
        cres = LineString(np.vstack([c[:1] + t0 * W / 4, c, c[-1:] + t1 * W / 4]))
        b.roads.append(Road(f"crescent_{k}", cres, sw, sidewalk_m=side, centre="none"))
    nb = int(st["branches"])
    if nb == 0:
        return
    pitch = W / (nb + 1)
    first = 1.0 if rng.random() < 0.5 else -1.0
    for i in range(nb):
        x = -W / 2 + pitch * (i + 1) + rng.uniform(-0.12, 0.12) * pitch
        sgn = first * (1.0 if i % 2 == 0 else -1.0)
        p0 = coll.interpolate(coll.project(Point(x, 0.0)))
        y0 = p0.y
        reach = H / 2 - sgn * y0  # to the scene edge
        cul = rng.random() < st["cul_de_sac_prob"]
        length = reach * rng.uniform(0.55, 0.8) if cul else reach + 10.0
        bend = rng.uniform(-1.0, 1.0) * st["curve_m"]
        t = np.linspace(0.0, 1.0, 6)
        px = x + bend * np.sin(np.pi * t * (0.6 if cul else 1.0)) * (t > 0)
        py = y0 + sgn * length * t
        pts = chaikin(np.column_stack([px, py]), 3)
        pts[0] = (p0.x, p0.y)
        b.roads.append(Road(f"branch_{i}", LineString(pts), sw, sidewalk_m=side, dead_end=cul,
                            centre="none"))


# ------------------------------------------------------------------------- parcels
def _frames(b: Builder, cfg: Mapping):
    """Candidate parcels: (front point p, unit along-street d, unit normal n away from the
    street, frontage f, street name) along both sides of every street and round every
    turning circle."""
    rng = b.rng
    hs = cfg["houses"]
    out = []
    for r in b.roads:
        edge = r.width_m / 2 + r.sidewalk_m
        if r.dead_end:  # pie parcels round the turning circle
            e = np.asarray(r.line.coords[-1])
            e0 = np.asarray(r.line.interpolate(r.line.length - 1.0).coords[0])
            t = (e - e0) / max(math.hypot(*(e - e0)), 1e-9)
            R = max(r.width_m, 7.0) + r.sidewalk_m
            phi0 = np.arctan2(t[1], t[0])
            for ang in np.radians([-100.0, -50.0, 0.0, 50.0, 100.0]):
                n = np.array([np.cos(phi0 + ang), np.sin(phi0 + ang)])
                d = np.array([n[1], -n[0]])
                f = rng.uniform(*hs["frontage_m"]) * 0.85
                out.append((e + n * R, d, n, f, r.name))
        for sign in (1.0, -1.0):
            front = offset_line(r.line, sign * edge)
            if front.is_empty or front.geom_type != "LineString":
                continue
            L = front.length
            s = 6.0
            while True:
                f = rng.uniform(*hs["frontage_m"])
                sc = s + f / 2
                if sc + f / 2 > L - (0.0 if not r.dead_end else 4.0):
                    break
                p = np.asarray(front.interpolate(sc).coords[0])
                q = np.asarray(front.interpolate(min(sc + 0.5, L)).coords[0])
                p0 = np.asarray(front.interpolate(max(sc - 0.5, 0.0)).coords[0])
                d = q - p0
                nd = math.hypot(*d)
                s += f
                if nd < 1e-6:
                    continue
                d = d / nd
                n = np.array([-d[1], d[0]]) * sign
                out.append((p, d, n, f, r.name))
    return out


def _to_world(p, d, n, uv):
    uv = np.asarray(uv, float)
    return p + d * uv[..., :1] + n * uv[..., 1:2]


def _lrect(p, d, n, u0, u1, v0, v1):
    import shapely

    return shapely.Polygon(_to_world(p, d, n, [[u0, v0], [u1, v0], [u1, v1], [u0, v1]]))


def generate_residential(b: Builder, spec: Mapping) -> None:
    """Fill ``b`` with a residential neighbourhood (see the module doc)."""
    import shapely

    cfg = check_residential(spec)
    b.spec = cfg
    rng = b.rng
    var = cfg["variant"]
    _streets(b, cfg)
    road = b.road_area()
    sidewalk = b.sidewalk_area()
    street_zone = road.union(sidewalk).buffer(0.3)
    shapely.prepare(street_zone)
    inner = b.box.buffer(-1.0)
    shapely.prepare(inner)
    houses = HouseSet(var, rng)
    acc = _Parcels([], [], [], [], [], [], [], [])
    for p, d, n, f, rname in _frames(b, cfg):
        _lay_parcel(b, cfg, rng, houses, inner, street_zone, acc, p, d, n, f, rname)
    drives, pads, hints, yards, sides = acc.drives, acc.pads, acc.hints, acc.yards, acc.sides
    concrete, tree_pts = acc.concrete, acc.tree_pts
    b.parking.extend(drives + pads)
    b.freeze_areas()
    # trees whose trunks stand clear of houses, yard things, driveways and streets
    standing = shapely.union_all(houses.footprints + drives + pads) if houses.footprints else shapely.Polygon()
    if tree_pts:
        pts = np.asarray(tree_pts, float)
        ok = ~shapely.intersects(standing.buffer(1.2), shapely.points(pts))
        b._add_trees(pts[ok], [2.0, 4.0], [5.0, 11.0], 0.4,
                     species={"broadleaf": 0.55, "spreading": 0.15, "columnar": 0.1, "conifer": 0.2})
    # hard negatives
    parking_all = shapely.union_all(drives + pads) if drives else shapely.Polygon()
    clear = shapely.union_all([street_zone, parking_all.buffer(0.8), standing.buffer(0.5)])
    W, H = (float(x) for x in cfg["size_m"])
    kerbside = street_zone.buffer(4.5).difference(street_zone.buffer(0.8)).difference(clear).intersection(inner)
    regions = {
        "yard": shapely.union_all(yards).difference(clear) if yards else None,
        "house_side": shapely.union_all(sides).difference(clear) if sides else None,
        "roadside": kerbside,
        "road": road.buffer(-1.0),
    }
    trunks = [shapely.Point(t[0], t[1]).buffer(0.8) for t in b.trees]
    neg_objs, neg_meta = add_negatives(f"residential_{var}", cfg.get("hard_negatives"), regions, W * H, rng,
                                       taken=houses.footprints + trunks)
    b._res = {"houses": houses, "negatives": neg_objs, "neg_meta": neg_meta, "hints": hints,
              "concrete": concrete, "pads": pads}
    b.scene = functools.partial(_residential_scene, b)


GENERATOR = Generator("residential", generate_residential)


@dataclass
class _Parcels:
    """What :func:`_lay_parcel` lays, parcel after parcel."""

    parcels: list
    drives: list
    pads: list
    hints: list
    yards: list
    sides: list
    concrete: list
    tree_pts: list


def _lay_parcel(b, cfg, rng, houses, inner, street_zone, acc, p, d, n, f, rname) -> None:
    """One parcel of frontage ``f`` at ``p`` (street direction ``d``, inward normal ``n``) on
    street ``rname``: the house, garage or parking place, driveway, side pad, back yard
    and its things, trees. Appends to the lists of ``acc`` (a :class:`_Parcels`); a
    frontage without room for a house adds nothing. Draws from ``rng`` in a fixed order."""
    import shapely

    var = cfg["variant"]
    hs, ys, vs = cfg["houses"], cfg["yards"], cfg["vehicles"]
    parcels, drives, hints, sides = acc.parcels, acc.drives, acc.hints, acc.sides
    concrete, tree_pts = acc.concrete, acc.tree_pts
    depth = rng.uniform(*hs["depth_m"])
    par = _lrect(p, d, n, -f / 2 + 0.3, f / 2 - 0.3, 0.6, depth)
    if not inner.contains(par) or street_zone.intersects(par):
        return
    if parcels and shapely.intersects(np.array(parcels, dtype=object), par).any():
        return
    parcels.append(par)
    street = next(r for r in b.roads if r.name == rname)
    side_w = street.sidewalk_m
    sb = rng.uniform(*hs["setback_m"])
    hw = rng.uniform(*hs["width_m"])
    hd = rng.uniform(*hs["house_depth_m"])
    hh = rng.uniform(*hs["height_m"])
    jog = rng.uniform(-1.5, 1.5)
    double = rng.random() < ys["double_driveway"]
    dw = rng.uniform(5.2, 6.0) if double else rng.uniform(3.0, 3.6)
    has_garage = rng.random() < ys["garage"]
    gw = dw + 0.8
    half = f / 2 - 0.3
    # a side pad (RV, boat, trailer) takes 4.6 m beside the house: the house gives way
    # to it down to 8 m wide, else there is no pad
    want_pad = rng.random() < ys["pad"]
    pad_room = 4.6 if want_pad and 2 * half - 2.4 - gw - 3.4 >= 8.0 else 0.0
    # house and garage slot side by side, 1.2 m or more from the parcel sides
    if hw + gw > 2 * half - 2.4 - pad_room:
        hw = 2 * half - 2.4 - gw - pad_room
    if hw < 6.5:
        double = False
        dw = rng.uniform(3.0, 3.4)
        gw = dw + 0.8
        hw = min(rng.uniform(*hs["width_m"]), 2 * half - 2.4 - gw)
        pad_room = 0.0
        if hw < 6.0:
            return
    gsd = 1.0 if rng.random() < 0.5 else -1.0  # garage on the +u or -u side
    slack = 2 * half - 2.4 - hw - gw - max(pad_room - 1.2, 0.0)
    # the pad goes on the house's side away from the garage: -u when the garage is at +u
    u_lo = -half + 1.2 + (max(pad_room - 1.2, 0.0) if gsd > 0 else 0.0) + rng.uniform(0.0, max(slack, 0.0))
    if gsd > 0:
        hu0, hu1 = u_lo, u_lo + hw
        gu0, gu1 = hu1, hu1 + gw
    else:
        gu0, gu1 = u_lo, u_lo + gw
        hu0, hu1 = gu1, gu1 + hw
    hv0, hv1 = sb + jog, sb + jog + hd
    gdep = min(6.5, hv1 - sb - 1.0)
    if gdep < 5.5:
        has_garage = False
    # house
    hc = _to_world(p, d, n, [(hu0 + hu1) / 2, (hv0 + hv1) / 2])
    u_ax = d if hw >= hd else n
    houses.building(hc, u_ax, max(hw, hd), min(hw, hd), hh)
    # garage or a parking place beside the house
    gc_u = (gu0 + gu1) / 2
    if has_garage:
        gc = _to_world(p, d, n, [gc_u, sb + gdep / 2])
        houses.building(gc, d if gw >= gdep else n, max(gw, gdep), min(gw, gdep),
                        rng.uniform(3.2, 4.2), kind="garages",
                        shape="flat" if rng.random() < 0.2 else None)
        v_end = sb
    else:
        v_end = sb + gdep
    # driveway: from the street's road edge to the garage door
    drive = _lrect(p, d, n, gc_u - dw / 2, gc_u + dw / 2, -(side_w + 1.0), v_end)
    drives.append(drive)
    if rng.random() < (0.75 if var == "us" else 0.35):
        concrete.append(drive)
    hid = len(hints)
    usable = (v_end - 0.3) - 0.4
    hints.append({"id": hid, "kind": "driveway",
                  "center_xy": [round(float(x), 4) for x in _to_world(p, d, n, [gc_u, 0.4 + usable / 2])],
                  "axis_deg": round(float(np.degrees(np.arctan2(n[1], n[0]))), 4),
                  "long_m": round(float(usable), 4), "short_m": round(float(dw - 0.3), 4),
                  "bay_m": list(DRIVEWAY_BAY_M), "occupancy": vs["driveway_occupancy"],
                  "mix": dict(vs["driveway_mix"])})
    has_pad, pad_end = _side_pad(acc, vs, want_pad, p, d, n, gsd, half, hu0, hu1, hv0, hd, side_w)
    back = _yard_fence(houses, rng, ys, var, p, d, n, half, depth, (hu0, hu1, hv0, hv1), (gu0, gu1),
                       hd, sb, gdep, has_garage, gsd, has_pad, pad_end)
    _back_yard(houses, rng, ys, acc, p, d, n, hu0, hu1, hv1, back, half)
    if rng.random() < 0.5:  # a front-lawn tree
        cu = rng.uniform(-half + 1.5, half - 1.5)
        if not (gu0 - 2.0 < cu < gu1 + 2.0):
            tree_pts.append(_to_world(p, d, n, [cu, rng.uniform(1.5, max(2.0, sb - 2.5))]))
    # strips beside the house walls (AC condensers)
    sides.append(_lrect(p, d, n, hu0 - 1.4, hu1 + 1.4, hv0 - 0.2, hv1 + 0.2).difference(
        _lrect(p, d, n, hu0 - 0.3, hu1 + 0.3, hv0 - 0.3, hv1 + 0.3)))


def _side_pad(acc, vs, want_pad, p, d, n, gsd, half, hu0, hu1, hv0, hd, side_w):
    """A side pad for an RV, a boat or a trailer, on the house's side away from the garage,
    when wanted and there is room: appended to ``acc.pads`` with its hint. Returns
    (has_pad, pad_end)."""
    pads, hints = acc.pads, acc.hints
    pad_end = hv0 + 0.5 * hd
    if gsd > 0:
        free = (hu0 - (-half))
        pu0, pu1 = -half + 0.6, hu0 - 0.4
    else:
        free = half - hu1
        pu0, pu1 = hu1 + 0.4, half - 0.6
    has_pad = want_pad and free >= 4.4 and pad_end - 0.4 >= 7.6
    if has_pad:
        pw = min(pu1 - pu0, 3.8)
        pc_u = (pu0 + pu1) / 2
        pad = _lrect(p, d, n, pc_u - pw / 2, pc_u + pw / 2, -(side_w + 1.0), pad_end)
        pads.append(pad)
        usable = pad_end - 0.3 - 0.4
        hints.append({"id": len(hints), "kind": "pad",
                      "center_xy": [round(float(x), 4) for x in _to_world(p, d, n, [pc_u, 0.4 + usable / 2])],
                      "axis_deg": round(float(np.degrees(np.arctan2(n[1], n[0]))), 4),
                      "long_m": round(float(usable), 4), "short_m": round(float(pw - 0.3), 4),
                      "bay_m": [round(float(usable), 4), round(float(pw - 0.3), 4)],
                      "occupancy": vs["pad_occupancy"], "mix": dict(vs["pad_mix"])})
    return has_pad, pad_end


def _yard_fence(houses, rng, ys, var, p, d, n, half, depth, house_uv, garage_u, hd, sb, gdep,
                has_garage, gsd, has_pad, pad_end) -> float:
    """Fences or hedges round a parcel's back yard; returns the yard's back line ``v``."""
    from shapely.geometry import LineString

    hu0, hu1, hv0, hv1 = house_uv
    gu0, gu1 = garage_u
    vf = hv0 + 0.6 * hd
    v_g = (sb + gdep + 0.3) if has_garage else vf
    v_g = min(max(v_g, vf), hv1 - 0.3)
    back = depth - 0.3
    hedge = rng.random() < ys["hedge"]
    if hedge:
        fw, fh, fc = rng.uniform(0.6, 0.9), rng.uniform(1.2, 2.0), (0.06, 0.11, 0.045)
    elif var == "us" and rng.random() < 0.3:  # chain-link
        fw, fh, fc = 0.04, 1.2, (0.55, 0.56, 0.57)
    else:
        fw, fh = 0.06, rng.uniform(1.6, 1.9)
        fc = ((0.45, 0.34, 0.24), (0.60, 0.56, 0.50), (0.80, 0.80, 0.78))[int(rng.integers(3))]
    vl = v_g if gsd < 0 else vf
    vr = v_g if gsd > 0 else vf
    if has_pad:
        if gsd > 0:
            vl = max(vl, pad_end + 0.3)
        else:
            vr = max(vr, pad_end + 0.3)
    ring = [(-half + fw / 2, vl), (-half + fw / 2, back), (half - fw / 2, back), (half - fw / 2, vr)]
    houses.fence(LineString(_to_world(p, d, n, ring)), fw, fh, fc, hedge)
    houses.fence(LineString(_to_world(p, d, n, [(-half + fw, vl), (min(hu0, gu0) + 0.01, vl)])),
                 fw, fh, fc, hedge)
    houses.fence(LineString(_to_world(p, d, n, [(max(hu1, gu1) - 0.01, vr), (half - fw, vr)])),
                 fw, fh, fc, hedge)
    return back


def _back_yard(houses, rng, ys, acc, p, d, n, hu0, hu1, hv1, back, half) -> None:
    """A parcel's back yard: patio and furniture, pool, trampoline, the free yard (for hard
    negatives) and its trees, appended to ``acc``."""
    import shapely

    yards, tree_pts = acc.yards, acc.tree_pts
    yv0, yv1 = hv1 + 0.8, back - 1.2
    yu0, yu1 = -half + 1.2, half - 1.2
    taken = []
    if yv1 - yv0 > 4.0:
        if rng.random() < ys["patio"]:
            pd_ = rng.uniform(3.0, 4.5)
            pu = rng.uniform(hu0, max(hu0, hu1 - 5.0))
            pat = _lrect(p, d, n, pu, min(pu + rng.uniform(4.0, 6.5), hu1), hv1, hv1 + pd_)
            pcol = ((0.62, 0.60, 0.56), (0.58, 0.48, 0.40), (0.50, 0.49, 0.47))[int(rng.integers(3))]
            houses.patio(pat, pcol)
            taken.append(pat)
            if rng.random() < ys["furniture"]:
                c = np.asarray(pat.centroid.coords[0])
                houses.furniture(c, float(np.arctan2(d[1], d[0])))
        if rng.random() < ys["pool"] and yv1 - yv0 > 9.0:
            pl, pw_ = rng.uniform(7.0, 10.0), rng.uniform(3.5, 5.0)
            for _ in range(6):
                cu, cv = rng.uniform(yu0 + pl / 2, yu1 - pl / 2), rng.uniform(yv0 + 1 + pw_ / 2, yv1 - pw_ / 2)
                if yu1 - yu0 < pl:
                    break
                pool = _lrect(p, d, n, cu - pl / 2, cu + pl / 2, cv - pw_ / 2, cv + pw_ / 2)
                if rng.random() < 0.35:
                    pool = pool.buffer(-1.2).buffer(1.2, quad_segs=4)  # rounded
                if not any(pool.buffer(1.0).intersects(t) for t in taken):
                    houses.pool(pool)
                    taken.append(pool.buffer(0.4))
                    break
        if rng.random() < ys["trampoline"]:
            r_t = rng.uniform(1.6, 2.2)
            for _ in range(6):
                cu, cv = rng.uniform(yu0 + r_t, yu1 - r_t), rng.uniform(yv0 + r_t, yv1 - r_t)
                c = _to_world(p, d, n, [cu, cv])
                disc = shapely.Point(c).buffer(r_t + 0.5)
                if not any(disc.intersects(t) for t in taken):
                    houses.trampoline(c, r_t)
                    taken.append(disc)
                    break
        yard = _lrect(p, d, n, yu0, yu1, yv0, yv1)
        for t in taken:
            yard = yard.difference(t.buffer(0.8))
        yards.append(yard)
        nt = int(rng.poisson(ys["trees_per_parcel"]))
        for _ in range(nt):
            cu, cv = rng.uniform(yu0, yu1), rng.uniform(yv0, yv1 + 0.5)
            tree_pts.append(_to_world(p, d, n, [cu, cv]))


def _residential_scene(b: Builder, source: str, meta: dict):
    """Builder.scene, then: driveways in concrete where drawn so, gravel pads, houses and
    yard things, hard negatives; hints and counts in the metadata."""
    import shapely

    r = b._res
    scene = Builder.scene(b, source, {**meta, "variant": b.spec["variant"]})
    objs = scene.objects
    park = next((o for o in objs if o.name == "parking"), None)
    if park is not None:  # split the parking surface by covering
        area = b.parking_area()
        conc = shapely.union_all(r["concrete"]).intersection(area) if r["concrete"] else shapely.Polygon()
        grav = shapely.union_all(r["pads"]).intersection(area).difference(conc) if r["pads"] else shapely.Polygon()
        rest = area.difference(conc).difference(grav)
        new = []
        for name, g, mat, col in (("parking", rest, "asphalt", None),
                                  ("parking_concrete", conc, "concrete", (0.66, 0.65, 0.62)),
                                  ("parking_gravel", grav, "paving", (0.55, 0.52, 0.47))):
            g = polygonal(g)
            if not g.is_empty:
                kw = {"material": mat} if col is None else {"material": mat, "color": col}
                new.append(polygon_object(name, "parking", g, Z_ROAD, **kw))
        i = objs.index(park)
        objs[i:i + 1] = new
    objs.extend(r["houses"].objects("house"))
    objs.extend(r["negatives"])
    scene.objects = [o for o in objs if o.n_triangles]
    scene.hints = scene.hints.replace(
        driveways=tuple(DrivewayHint.from_dict(h, f"scene {scene.name}: driveway hint") for h in r["hints"]),
        negatives=NegativesHint.from_dict(r["neg_meta"], f"scene {scene.name}: hard negatives"))
    scene.meta = {**scene.meta,
                  "yard_counts": {k: (round(v, 2) if isinstance(v, float) else v)
                                  for k, v in r["houses"].counts.items()}}
    return scene
