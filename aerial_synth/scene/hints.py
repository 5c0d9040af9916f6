"""Direction hints: what geometry cannot tell placement about a road.

A line trace finds a road's edges and its axis, but not which way a one-way carriageway is
driven. Scenes built from OpenStreetMap know it (``oneway=*``, ``junction=roundabout``,
``highway=motorway``), so they carry a :class:`RoadHints`: every drivable road's centre line
(local scene frame, metres, x east, y north), its width, whether it is one-way (then the line
runs in the driving direction) and its lane counts. Placement asks
:meth:`RoadHints.direction_at` only to pick a direction where geometry is ambiguous.

The hints live in ``Scene.hints.roads`` (scene_hints.py; see :func:`road_hints`) and travel through
GLB export in the glTF scene extras (:meth:`RoadHints.to_dict` / :meth:`RoadHints.from_dict`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from ..errors import SceneError

__all__ = ["HintRoad", "RoadHints", "road_hints", "extras_for", "meta_from_extras", "META_KEY",
           "EXTRAS_KEY"]

#: Key of the hints in ``Scene.meta``.
META_KEY = "road_hints"
#: Key of the hints in the glTF scene extras.
EXTRAS_KEY = "aerial_synth_road_hints"
_FORMAT = 1


@dataclass(frozen=True, eq=False)
class HintRoad:
    """One drivable road.

    coords_xy      : (k, 2) float64, metres, local scene frame; for a one-way road in the
                     driving direction
    width_m        : carriageway width
    oneway         : traffic only follows the line's direction
    lanes_forward  : lanes along the line (-1 = unknown)
    lanes_backward : lanes against the line (0 on one-way roads, -1 = unknown)
    osm_id         : source way id (0 if none)
    name           : road name or class, for people
    """

    coords_xy: np.ndarray
    width_m: float
    oneway: bool
    lanes_forward: int = -1
    lanes_backward: int = -1
    osm_id: int = 0
    name: str = ""

    def __post_init__(self) -> None:
        c = np.ascontiguousarray(self.coords_xy, dtype=np.float64)
        if c.ndim != 2 or c.shape[1] != 2 or len(c) < 2 or not np.isfinite(c).all():
            raise SceneError(
                f"road hint {self.name or self.osm_id}: expected (k >= 2, 2) finite coordinates, "
                f"got shape {c.shape}"
            )
        if not (np.isfinite(self.width_m) and self.width_m > 0):
            raise SceneError(f"road hint {self.name or self.osm_id}: width_m must be > 0, got "
                             f"{self.width_m!r}")
        c.setflags(write=False)
        object.__setattr__(self, "coords_xy", c)


class RoadHints:
    """Per-road driving direction and lanes, with vectorised point queries.

    Queries find, for each point, the nearest road centre line among the roads whose
    carriageway (half the width + ``tol_m``) contains the point.
    """

    def __init__(self, roads: Sequence[HintRoad]):
        self.roads: tuple[HintRoad, ...] = tuple(roads)
        a, b, idx = [], [], []
        for k, r in enumerate(self.roads):
            c = r.coords_xy
            a.append(c[:-1])
            b.append(c[1:])
            idx.append(np.full(len(c) - 1, k))
        if self.roads:
            self._a = np.concatenate(a)
            self._b = np.concatenate(b)
            self._road = np.concatenate(idx).astype(np.int64)
        else:
            self._a = self._b = np.zeros((0, 2))
            self._road = np.zeros(0, np.int64)
        d = self._b - self._a
        n = np.linalg.norm(d, axis=1)
        keep = n > 1e-9
        self._a, self._b, self._road = self._a[keep], self._b[keep], self._road[keep]
        self._dir = d[keep] / n[keep, None]
        self._half = np.array([r.width_m / 2 for r in self.roads])[self._road] if self.roads \
            else np.zeros(0)
        self._oneway = np.array([r.oneway for r in self.roads], bool)
        self._tree = None

    def __len__(self) -> int:
        return len(self.roads)

    def __getstate__(self):  # the segment tree is rebuilt on demand
        d = dict(self.__dict__)
        d["_tree"] = None
        return d

    def __repr__(self) -> str:
        n1 = int(self._oneway.sum()) if len(self.roads) else 0
        return f"RoadHints({len(self.roads)} roads, {n1} one-way)"

    # ------------------------------------------------------------------ queries
    def _segments(self):
        if self._tree is None:
            import shapely

            segs = shapely.linestrings(np.stack([self._a, self._b], axis=1))
            self._tree = shapely.STRtree(segs)
        return self._tree

    def nearest(self, xy, tol_m: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
        """Road index and segment index of the nearest centre line for each point, -1 where
        the point is on no hinted carriageway. xy: (n, 2) metres. Returns ((n,), (n,))."""
        import shapely

        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        road = np.full(len(xy), -1, np.int64)
        seg = np.full(len(xy), -1, np.int64)
        if not len(self._a) or not len(xy):
            return road, seg
        reach = float(self._half.max()) + float(tol_m)
        pi, si = self._segments().query_nearest(
            shapely.points(xy), max_distance=reach, all_matches=False, return_distance=False
        )
        # distance to the chosen segment must be within that road's half width
        a, d = self._a[si], self._dir[si]
        p = xy[pi] - a
        length = np.linalg.norm(self._b[si] - a, axis=1)
        t = np.clip((p * d).sum(axis=1), 0.0, length)
        dist = np.linalg.norm(p - t[:, None] * d, axis=1)
        ok = dist <= self._half[si] + tol_m
        road[pi[ok]] = self._road[si[ok]]
        seg[pi[ok]] = si[ok]
        return road, seg

    def direction_at(self, xy, tol_m: float = 0.5) -> np.ndarray:
        """(n, 2) unit vectors of the legal driving direction at each point (metres, local
        frame); NaN where the road is two-way or the point is on no hinted road."""
        road, seg = self.nearest(xy, tol_m)
        out = np.full((len(road), 2), np.nan)
        hit = seg >= 0
        one = np.zeros(len(road), bool)
        one[hit] = self._oneway[road[hit]]
        out[one] = self._dir[seg[one]]
        return out

    def frame_at(self, xy, tol_m: float = 0.5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The nearest road's local frame at each point: unit direction of its line (n, 2),
        signed distance of the point left of the line (n,) metres, and whether the road is
        one-way (n,) bool. NaN / False where the point is on no hinted road."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        road, seg = self.nearest(xy, tol_m)
        d = np.full((len(road), 2), np.nan)
        left = np.full(len(road), np.nan)
        one = np.zeros(len(road), bool)
        hit = seg >= 0
        if hit.any():
            s = seg[hit]
            d[hit] = self._dir[s]
            r = xy[hit] - self._a[s]
            left[hit] = self._dir[s, 0] * r[:, 1] - self._dir[s, 1] * r[:, 0]
            one[hit] = self._oneway[road[hit]]
        return d, left, one

    def lanes_at(self, xy, tol_m: float = 0.5) -> np.ndarray:
        """(n, 2) int lanes (forward = along the road's line, backward = against it) of the
        road at each point; -1 where unknown or off every hinted road."""
        road, _ = self.nearest(xy, tol_m)
        out = np.full((len(road), 2), -1, np.int64)
        hit = road >= 0
        if hit.any():
            fw = np.array([r.lanes_forward for r in self.roads])
            bw = np.array([r.lanes_backward for r in self.roads])
            out[hit, 0] = fw[road[hit]]
            out[hit, 1] = bw[road[hit]]
        return out

    def lanes_along(self, xy, heading_rad, tol_m: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
        """Lanes in the direction of travel ``heading_rad`` (n,) at each point, and the road's
        lane width (width / all its lanes). -1 / NaN where unknown."""
        road, seg = self.nearest(xy, tol_m)
        h = np.asarray(heading_rad, float).reshape(-1)
        n_dir = np.full(len(road), -1, np.int64)
        lane_w = np.full(len(road), np.nan)
        hit = seg >= 0
        if not hit.any():
            return n_dir, lane_w
        fw = np.array([r.lanes_forward for r in self.roads])[road[hit]]
        bw = np.array([r.lanes_backward for r in self.roads])[road[hit]]
        wid = np.array([r.width_m for r in self.roads])[road[hit]]
        d = self._dir[seg[hit]]
        along = d[:, 0] * np.cos(h[hit]) + d[:, 1] * np.sin(h[hit]) >= 0
        n_dir[hit] = np.where(along, fw, bw)
        total = np.where((fw >= 0) & (bw >= 0), fw + bw, -1)
        lane_w[hit] = np.where(total > 0, wid / np.maximum(total, 1), np.nan)
        return n_dir, lane_w

    def lane_room(self, xy, heading_rad, tol_m: float = 0.5) -> np.ndarray:
        """(n,) metres of carriageway for traffic heading ``heading_rad`` at each point,
        measured from its traffic-side edge: the lanes in that direction x the lane width
        when the lanes are tagged, the whole width on a one-way road, else NaN (unknown:
        geometry decides)."""
        road, seg = self.nearest(xy, tol_m)
        n_dir, lane_w = self.lanes_along(xy, heading_rad, tol_m)
        room = np.where((n_dir >= 0) & np.isfinite(lane_w), n_dir * lane_w, np.nan)
        hit = seg >= 0
        one = np.zeros(len(road), bool)
        one[hit] = self._oneway[road[hit]]
        wid = np.array([r.width_m for r in self.roads])[road[one]] if one.any() else 0.0
        room[one] = np.where(np.isfinite(room[one]), room[one], wid)
        return room

    # ------------------------------------------------------------------ frames, files
    def shifted(self, dxy) -> "RoadHints":
        """The same hints in a frame whose coordinates are ``old + dxy`` (metres)."""
        dxy = np.asarray(dxy, float)[:2]
        return RoadHints([
            HintRoad(r.coords_xy + dxy, r.width_m, r.oneway, r.lanes_forward, r.lanes_backward,
                     r.osm_id, r.name) for r in self.roads
        ])

    def to_dict(self) -> dict:
        """JSON-ready form (coordinates rounded to 0.1 mm)."""
        return {
            "format": _FORMAT,
            "roads": [
                {
                    "coords_xy": np.round(r.coords_xy, 4).tolist(),
                    "width_m": round(float(r.width_m), 4),
                    "oneway": bool(r.oneway),
                    "lanes_forward": int(r.lanes_forward),
                    "lanes_backward": int(r.lanes_backward),
                    "osm_id": int(r.osm_id),
                    "name": str(r.name),
                }
                for r in self.roads
            ],
        }

    @classmethod
    def from_dict(cls, data: Any, where: str = "road hints") -> "RoadHints":
        """Inverse of :meth:`to_dict`; raises :class:`SceneError` naming ``where``."""
        if not isinstance(data, Mapping) or not isinstance(data.get("roads"), list):
            raise SceneError(f"{where}: expected a mapping with a 'roads' list, got "
                             f"{type(data).__name__}")
        if data.get("format") != _FORMAT:
            raise SceneError(f"{where}: expected format {_FORMAT}, got {data.get('format')!r}")
        roads = []
        for i, r in enumerate(data["roads"]):
            try:
                roads.append(HintRoad(
                    coords_xy=np.asarray(r["coords_xy"], float), width_m=float(r["width_m"]),
                    oneway=bool(r["oneway"]), lanes_forward=int(r.get("lanes_forward", -1)),
                    lanes_backward=int(r.get("lanes_backward", -1)),
                    osm_id=int(r.get("osm_id", 0)), name=str(r.get("name", "")),
                ))
            except (KeyError, TypeError, ValueError) as exc:
                raise SceneError(f"{where}: road {i}: expected coords_xy, width_m, oneway "
                                 f"({type(exc).__name__}: {exc})") from None
        return cls(roads)


def road_hints(scene) -> RoadHints | None:
    """The scene's :class:`RoadHints`, or None when it has none (procedural / mesh scenes)."""
    h = getattr(getattr(scene, "hints", None), "roads", None)
    return h if isinstance(h, RoadHints) and len(h) else None


def extras_for(scene) -> dict:
    """glTF scene extras that carry the hints (with the frame they are in) and the data
    attribution through GLB export; {} for a scene without either."""
    out: dict = {}
    h = road_hints(scene)
    if h is not None:
        d = h.to_dict()
        d["origin"] = [float(c) for c in getattr(scene, "origin", (0.0, 0.0, 0.0))]
        out[EXTRAS_KEY] = d
    attribution = (getattr(scene, "meta", None) or {}).get("attribution")
    if attribution:
        out["attribution"] = str(attribution)
    return out


def meta_from_extras(extras, origin, where: str) -> dict:
    """Scene meta entries ({"road_hints": ..., "attribution": ...}) from glTF scene extras.

    origin : the reloaded scene's origin; hints written in a frame with another origin are
             shifted into the reloaded frame (original = local + origin in both).
    """
    out: dict = {}
    if not isinstance(extras, Mapping):
        return out
    d = extras.get(EXTRAS_KEY)
    if d is not None:
        h = RoadHints.from_dict(d, f"{where}: glTF extras {EXTRAS_KEY}")
        o_old = np.asarray(d.get("origin") or (0.0, 0.0, 0.0), float).reshape(-1)[:2]
        o_new = np.asarray(origin, float).reshape(-1)[:2]
        if not np.array_equal(o_old, o_new):
            h = h.shifted(o_old - o_new)
        out[META_KEY] = h
    if isinstance(extras.get("attribution"), str):
        out["attribution"] = extras["attribution"]
    return out
