"""Parking-lot bay layouts: the pattern of bays in a lot rectangle, and their painted lines.

A lot is a rectangle (any rotation). Its rows run along the rectangle's long side (the
*row direction* u); across it (v) bay rows and aisles alternate: edge row, aisle, two rows
back to back, aisle, ... A circulation lane as wide as an aisle runs along both short ends,
so an entrance on a short end reaches every aisle. Bays are ``bay_width_m`` x
``bay_length_m`` rectangles at ``angle_deg`` to the row direction: 90 (perpendicular),
60 or 45 (angled, all pointing the aisle's one-way direction +u) or 0 (parallel, along the
row). The same function lays out the painted lines (scene generation,
:mod:`aerial_synth.scene.procedural.parking`) and the bays that placement fills (from a lot
found by line traces, :mod:`aerial_synth.placement.parking`), so the two agree. Neutral
ground: a scene module that neither generators nor placement own.

Frames: world metres, x east, y north; angles in radians unless named ``_deg``; a bay's
``axis_rad`` points from its aisle into the bay (the heading of a car parked nose-in).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from .. import validators as V
from ..errors import ConfigError, SceneError

__all__ = [
    "LotLayout",
    "Bays",
    "LotFrame",
    "parse_layout",
    "lot_frame",
    "layout_bays",
    "bay_markings",
    "LAYOUT_KEYS",
    "BAY_ANGLES_DEG",
]

#: The bay angles a layout may use (degrees between the bay axis and the row direction).
BAY_ANGLES_DEG = (90.0, 60.0, 45.0, 0.0)
LAYOUT_KEYS = ("bay_width_m", "bay_length_m", "angle_deg", "aisle_m", "rows", "line_width_m")


@dataclass(frozen=True)
class LotLayout:
    """How a lot is divided into bays.

    bay_width_m  : across the bay (metres, 1.5..10); 2.5 for cars
    bay_length_m : along the bay axis (metres, 2..30); 5.0 for cars
    angle_deg    : angle between the bay axis and the row direction: 90, 60, 45 or 0
    aisle_m      : driving aisle between rows, and the circulation lane at both ends
                   (metres, 2.5..40); 6.0 for cars
    rows         : at most this many bay rows (None = as many as fit)
    line_width_m : painted line width (metres, 0.05..0.5)
    """

    bay_width_m: float = 2.5
    bay_length_m: float = 5.0
    angle_deg: float = 90.0
    aisle_m: float = 6.0
    rows: int | None = None
    line_width_m: float = 0.12

    def __post_init__(self) -> None:
        s = object.__setattr__
        s(self, "bay_width_m", V.in_range("bay_width_m", self.bay_width_m, 1.5, 10.0))
        s(self, "bay_length_m", V.in_range("bay_length_m", self.bay_length_m, 2.0, 30.0))
        a = V.finite("angle_deg", self.angle_deg)
        if not any(abs(a - b) < 1e-9 for b in BAY_ANGLES_DEG):
            raise ConfigError(f"angle_deg: expected one of 90, 60, 45, 0, got {V.show(self.angle_deg)}")
        s(self, "angle_deg", float(a))
        s(self, "aisle_m", V.in_range("aisle_m", self.aisle_m, 2.5, 40.0))
        if self.rows is not None:
            s(self, "rows", V.integer("rows", self.rows, 1, 1000))
        s(self, "line_width_m", V.in_range("line_width_m", self.line_width_m, 0.05, 0.5))

    # geometry of one row
    @property
    def row_depth_m(self) -> float:
        """Depth of a bay row across the row direction."""
        a = np.radians(self.angle_deg)
        if self.angle_deg == 0.0:
            return self.bay_width_m
        return float(self.bay_length_m * np.sin(a) + self.bay_width_m * np.cos(a))

    @property
    def pitch_m(self) -> float:
        """Distance between neighbouring bays along the row."""
        if self.angle_deg == 0.0:
            return self.bay_length_m
        return float(self.bay_width_m / np.sin(np.radians(self.angle_deg)))

    @property
    def row_span_m(self) -> float:
        """Extent of one bay along the row direction."""
        a = np.radians(self.angle_deg)
        if self.angle_deg == 0.0:
            return self.bay_length_m
        return float(self.bay_length_m * np.cos(a) + self.bay_width_m * np.sin(a))

    def min_lot_m(self) -> tuple[float, float]:
        """Smallest (long, short) lot sides that hold one bay with its aisle and end lanes."""
        return self.row_span_m + 2 * self.aisle_m, self.row_depth_m + self.aisle_m

    def to_dict(self) -> dict:
        return asdict(self)


def parse_layout(data: Any, where: str) -> LotLayout:
    """A layout mapping (``layout:`` of a lot in a scene spec, or a scenario's
    ``parking.layout``); errors are one line starting with ``where``."""
    if data is None:
        return LotLayout()
    try:
        V.mapping(where, data)
        V.known_keys(where, data, LAYOUT_KEYS)
        return LotLayout(**dict(data))
    except ConfigError as exc:
        msg = str(exc)
        if msg.startswith(where):
            raise SceneError(msg) from None
        raise SceneError(f"{where}.{msg}") from None


@dataclass(frozen=True)
class LotFrame:
    """A lot's rectangle: centre (world metres), row direction u (radians), long side along
    u, short side along v = u + 90 degrees."""

    cx: float
    cy: float
    u_rad: float
    long_m: float
    short_m: float

    def to_world(self, uv: np.ndarray) -> np.ndarray:
        uv = np.asarray(uv, float)
        c, s = np.cos(self.u_rad), np.sin(self.u_rad)
        x = self.cx + c * uv[..., 0] - s * uv[..., 1]
        y = self.cy + s * uv[..., 0] + c * uv[..., 1]
        return np.stack([x, y], axis=-1)

    def polygon(self):
        import shapely

        h = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * [self.long_m / 2, self.short_m / 2]
        return shapely.Polygon(self.to_world(h))


def lot_frame(poly) -> LotFrame:
    """The minimum rotated rectangle of a polygon, long side = row direction (u in
    [0, pi))."""
    import shapely

    rect = shapely.minimum_rotated_rectangle(poly)
    c = np.asarray(rect.exterior.coords)[:4]
    e1, e2 = c[1] - c[0], c[2] - c[1]
    l1, l2 = math.hypot(*e1), math.hypot(*e2)
    e = e1 if l1 >= l2 else e2
    u = float(np.mod(np.arctan2(e[1], e[0]), np.pi))
    cen = c.mean(axis=0)
    return LotFrame(float(cen[0]), float(cen[1]), u, float(max(l1, l2)), float(min(l1, l2)))


@dataclass(frozen=True)
class Bays:
    """The bays of one lot (n of them), world frame.

    centre_xy : (n, 2) metres; axis_rad : (n,) from the aisle into the bay (nose-in heading;
    for parallel bays the row direction); row : (n,) row index; row_rad : the lot's row
    direction; width_m / length_m : the bay size (across / along the axis)
    """

    centre_xy: np.ndarray
    axis_rad: np.ndarray
    row: np.ndarray
    row_rad: float
    width_m: float
    length_m: float
    angle_deg: float

    def __len__(self) -> int:
        return len(self.centre_xy)

    def corners(self) -> np.ndarray:
        """(n, 4, 2) bay rectangles (front-left, front-right, rear-right, rear-left)."""
        c, s = np.cos(self.axis_rad)[:, None], np.sin(self.axis_rad)[:, None]
        lx = np.array([0.5, 0.5, -0.5, -0.5])[None, :] * self.length_m
        ly = np.array([0.5, -0.5, -0.5, 0.5])[None, :] * self.width_m
        x = self.centre_xy[:, :1] + c * lx - s * ly
        y = self.centre_xy[:, 1:] + s * lx + c * ly
        return np.stack([x, y], axis=-1)

    def take(self, keep: np.ndarray) -> "Bays":
        return Bays(self.centre_xy[keep], self.axis_rad[keep], self.row[keep], self.row_rad,
                    self.width_m, self.length_m, self.angle_deg)


def _rows(frame: LotFrame, lay: LotLayout) -> list[tuple[float, int]]:
    """(v of the row band's low edge, side of its aisle: +1 above, -1 below) per row,
    centred across the lot."""
    dr, a = lay.row_depth_m, lay.aisle_m
    D = frame.short_m
    rows: list[tuple[float, int]] = []
    v = 0.0
    limit = lay.rows if lay.rows is not None else 10**6
    # double modules: row (aisle above), aisle, row (aisle below)
    while v + 2 * dr + a <= D + 1e-9 and len(rows) + 2 <= limit:
        rows += [(v, +1), (v + dr + a, -1)]
        v += 2 * dr + a
    if v + dr + a <= D + 1e-9 and len(rows) < limit:  # one single-loaded row left
        rows.append((v, +1))
        v += dr + a
    used = v
    off = -D / 2 + (D - used) / 2
    return [(r + off, side) for r, side in rows]


def layout_bays(frame: LotFrame, lay: LotLayout) -> Bays:
    """Every bay of a lot rectangle (see the module doc for the pattern)."""
    ang = np.radians(lay.angle_deg)
    usable = frame.long_m - 2 * lay.aisle_m
    span, pitch = lay.row_span_m, lay.pitch_m
    n = int(np.floor((usable - span) / pitch + 1e-9)) + 1 if usable >= span else 0
    rows = _rows(frame, lay)
    if n <= 0 or not rows:
        e = np.zeros((0, 2))
        return Bays(e, np.zeros(0), np.zeros(0, int), frame.u_rad, lay.bay_width_m,
                    lay.bay_length_m, lay.angle_deg)
    u0 = -frame.long_m / 2 + lay.aisle_m + (usable - (span + (n - 1) * pitch)) / 2 + span / 2
    us = u0 + pitch * np.arange(n)
    cs, axes, row_ids = [], [], []
    for k, (v0, side) in enumerate(rows):
        vc = v0 + lay.row_depth_m / 2
        if lay.angle_deg == 0.0:
            local_axis = 0.0
        else:
            # from the aisle into the bay: away from the aisle side, tilted to +u
            local_axis = -side * ang
        cs.append(np.column_stack([us, np.full(n, vc)]))
        axes.append(np.full(n, local_axis))
        row_ids.append(np.full(n, k))
    uv = np.concatenate(cs)
    centre = frame.to_world(uv)
    axis = np.mod(np.concatenate(axes) + frame.u_rad, 2 * np.pi)
    return Bays(centre, axis, np.concatenate(row_ids), frame.u_rad, lay.bay_width_m,
                lay.bay_length_m, lay.angle_deg)


def bay_markings(bays: Bays, lay: LotLayout):
    """Painted lines (shapely polygon): both long sides of every bay (perpendicular and
    angled bays) or both short sides plus the outer line (parallel bays)."""
    import shapely

    if not len(bays):
        return shapely.Polygon()
    c = bays.corners()  # FL, FR, RR, RL
    if lay.angle_deg == 0.0:
        segs = [c[:, [0, 1]], c[:, [2, 3]]]
    else:
        segs = [c[:, [0, 3]], c[:, [1, 2]]]
    lines = shapely.linestrings(np.concatenate(segs))
    polys = shapely.buffer(lines, lay.line_width_m / 2, cap_style="flat")
    return shapely.union_all(polys)
