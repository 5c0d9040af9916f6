"""Vehicle meshes: procedural low-poly bodies and user glTF/GLB/OBJ files.

Vehicle frame: metres, origin at the footprint centre on the ground, +x forward, +y left,
z up. Every procedural part (body, greenhouse, roof, windscreen, wheels, cargo box, ...) is
a separate closed convex volume whose triangles are counter-clockwise seen from outside
(outward normals, positive signed volume). Parts may overlap; a ray always meets the
outermost surface first, so overlaps never show.

Procedural parts are designed in real metres from the catalog's length, width and height,
then scaled by a factor close to 1 so the mesh bounds equal the catalog size exactly.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..errors import AssetError
from ..scene.model import DEFAULT_COLOR_FOR_MATERIAL, MATERIAL_IDS
from ._hull import box as _box
from ._hull import convex_hull as _hull
from .bodies import CAR_PROFILES, car_kwargs
from .catalog import OPTION_RISE_M
from .large import LARGE_BUILDERS
from .model import VehicleColor, VehicleModel
from .towed import TOWED_BUILDERS
from .user_mesh import load_user_mesh_parts

__all__ = ["VehicleMesh", "build_mesh"]

#: Albedo of glass facing the sky (windscreen, rear window): a touch lighter and bluer than
#: the side glass, as the sky reflects in it seen from above.
WINDSCREEN_RGB = (0.075, 0.095, 0.125)
SOLAR_RGB = (0.06, 0.08, 0.17)
BED_LINER_RGB = (0.07, 0.07, 0.07)
COWL_RGB = (0.035, 0.035, 0.04)


@dataclass(frozen=True, eq=False)
class VehicleMesh:
    """A vehicle mesh in the vehicle frame (read-only arrays; shared through a cache).

    vertices      : (n, 3) float64, metres, vehicle frame (+x forward, +y left, z up),
                    origin at the footprint centre on the ground
    faces         : (m, 3) int64, counter-clockwise seen from outside (outward normals)
    face_material : (m,) uint8, ids from ``scene.model.MATERIAL_IDS``
    face_albedo   : (m, 3) float32, RGB in [0, 1]
    face_part     : (m,) int16, index into ``parts``
    parts         : part names (``body``, ``greenhouse``, ``roof``, ``windscreen``, ...)
    model, color  : names of the model and colour
    """

    vertices: np.ndarray
    faces: np.ndarray
    face_material: np.ndarray
    face_albedo: np.ndarray
    face_part: np.ndarray
    parts: tuple[str, ...]
    model: str = ""
    color: str = ""

    def __post_init__(self) -> None:
        for name, dt in (
            ("vertices", np.float64),
            ("faces", np.int64),
            ("face_material", np.uint8),
            ("face_albedo", np.float32),
            ("face_part", np.int16),
        ):
            a = np.ascontiguousarray(getattr(self, name), dtype=dt)
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    @property
    def n_triangles(self) -> int:
        return int(len(self.faces))

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) float64: [[xmin, ymin, zmin], [xmax, ymax, zmax]], metres, vehicle frame."""
        return np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)])

    def part_faces(self, part: str) -> np.ndarray:
        """(k,) int64 indices of the faces of one part ('' if unknown -> empty)."""
        if part not in self.parts:
            return np.zeros(0, np.int64)
        return np.flatnonzero(self.face_part == self.parts.index(part))

    def part_mesh(self, part: str) -> tuple[np.ndarray, np.ndarray]:
        """(vertices (k, 3), faces (j, 3)) of one part, re-indexed compactly."""
        f = self.faces[self.part_faces(part)]
        used, inv = np.unique(f.ravel(), return_inverse=True)
        return self.vertices[used].copy(), inv.reshape(-1, 3).astype(np.int64)

    def to_world(
        self, x_m: float, y_m: float, z_m: float, heading_rad: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Place the vehicle: rotate about z by ``heading_rad`` (0 = +x, counter-clockwise),
        then translate its origin to (x_m, y_m, z_m) in the world frame.

        Returns (vertices_world (n, 3) float64 metres, faces (m, 3) int64, a copy).
        """
        c, s = np.cos(heading_rad), np.sin(heading_rad)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        v = self.vertices @ rot.T + np.array([x_m, y_m, z_m], dtype=np.float64)
        return v, self.faces.copy()


# --------------------------------------------------------------------------- public
def build_mesh(model: VehicleModel, color: VehicleColor) -> VehicleMesh:
    """The mesh of one model in one colour (cached per (model, colour)).

    Procedural models are built from the catalog size and body type; user models are read
    from their file, turned into the vehicle frame, and the faces of ``paint_material``
    take the colour.
    """
    return _build_mesh_cached(model, color)


@lru_cache(maxsize=512)
def _build_mesh_cached(model: VehicleModel, color: VehicleColor) -> VehicleMesh:
    return _assemble(_model_parts(model), color, model.name)


@lru_cache(maxsize=256)
def _model_parts(model: VehicleModel) -> tuple["_Part", ...]:
    """The parts of one model, whatever its colour (paint parts have ``rgb=None``): the
    geometry is built once per model and each colour only fills the albedo column."""
    if model.is_procedural:
        # the base body is built and fitted to the base size; options go on top in metres
        # (rounded: 1.78 + 0.42 - 0.42 is 1.7800000000000002, and the base body must be
        # the base model's to the bit)
        h0 = round(model.height_m - sum(OPTION_RISE_M[o] for o in model.options), 9)
        parts = _procedural_parts(model, h0)
        parts = _fit_to_size(parts, model.length_m, model.width_m, h0)
        for opt in model.options:
            parts = _OPTIONS[opt](parts, model.length_m, model.width_m, h0, model.body)
    else:
        user = load_user_mesh_parts(
            model.mesh_path, scale=model.scale, forward=model.forward, up=model.up
        )
        parts = []
        for p in user:
            painted = bool(model.paint_material) and p.material_name == model.paint_material
            parts.append(
                _Part(
                    name=p.name,
                    material="paint" if painted else p.material,
                    rgb=None if painted else p.rgb,
                    v=p.vertices,
                    f=p.faces,
                )
            )
    for p in parts:  # shared between colours: read-only
        p.v.setflags(write=False)
        p.f.setflags(write=False)
    return tuple(parts)


# --------------------------------------------------------------------------- parts
@dataclass
class _Part:
    name: str
    material: str
    rgb: tuple[float, float, float] | None  # None = the variant's paint colour
    v: np.ndarray
    f: np.ndarray


def _assemble(parts, color: VehicleColor, model_name: str) -> VehicleMesh:
    names: list[str] = []
    vs, fs, mats, albs, pids = [], [], [], [], []
    off = 0
    for p in parts:
        if p.name not in names:
            names.append(p.name)
        m = len(p.f)
        rgb = color.rgb if p.rgb is None else p.rgb
        vs.append(p.v)
        fs.append(p.f + off)
        mats.append(np.full(m, MATERIAL_IDS[p.material], np.uint8))
        albs.append(np.tile(np.asarray(rgb, np.float32), (m, 1)))
        pids.append(np.full(m, names.index(p.name), np.int16))
        off += len(p.v)
    return VehicleMesh(
        vertices=np.concatenate(vs),
        faces=np.concatenate(fs),
        face_material=np.concatenate(mats),
        face_albedo=np.concatenate(albs),
        face_part=np.concatenate(pids),
        parts=tuple(names),
        model=model_name,
        color=color.name,
    )


def _fit_to_size(parts: list[_Part], length: float, width: float, height: float) -> list[_Part]:
    """Scale (per axis, factors close to 1) and shift so the bounds are exactly
    [-L/2, L/2] x [-W/2, W/2] x [0, H]."""
    allv = np.concatenate([p.v for p in parts])
    lo, hi = allv.min(axis=0), allv.max(axis=0)
    scale = np.array([length, width, height]) / (hi - lo)
    centre = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    shift = np.array([0.0, 0.0, 0.0])
    out = []
    for p in parts:
        v = (p.v - centre) * scale + shift
        out.append(_Part(p.name, p.material, p.rgb, v, p.f))
    return out


def _sym(points_xhz) -> list[tuple[float, float, float]]:
    """Mirror (x, half_width, z) points to both sides: [(x, +hw, z), (x, -hw, z), ...]."""
    out = []
    for x, hw, z in points_xhz:
        out.append((x, hw, z))
        out.append((x, -hw, z))
    return out


def _wheel(x, y, r, width, sections=14) -> tuple[np.ndarray, np.ndarray]:
    """A closed cylinder with its axis along y, standing on the ground (z from 0 to 2r)."""
    # start at the bottom so a vertex touches z = 0
    ang = -np.pi / 2 + np.linspace(0.0, 2 * np.pi, sections, endpoint=False)
    ring = np.column_stack([x + r * np.cos(ang), r + r * np.sin(ang)])
    pts = [(px, y + s * width / 2, pz) for px, pz in ring for s in (-1, 1)]
    return _hull(pts)


def _glass_slab(quad, inside_point, offset=0.012, thickness=0.012, inset=0.05):
    """A thin slab lying on a planar quad (4, 3), pushed ``offset`` outward (away from
    ``inside_point``) and shrunk by ``inset`` toward the quad centre."""
    q = np.asarray(quad, np.float64)
    c = q.mean(axis=0)
    q = c + (q - c) * (1.0 - inset)
    n = np.cross(q[1] - q[0], q[2] - q[0])
    n /= np.linalg.norm(n)
    if np.dot(n, c - np.asarray(inside_point, float)) < 0:
        n = -n
    a = q + n * offset
    b = q + n * (offset + thickness)
    return _hull(np.concatenate([a, b]))


@dataclass
class _CarSpec:
    """Side profile of a car-like body, in metres of the vehicle frame.

    x_rear, x_front : body extent; half_w : half width of the body
    clear           : body underside height; belt : beltline (bonnet/boot top at the cabin)
    nose_top, nose_bot, tail_top, tail_bot : heights of the front and rear ends
    ws_base, ws_top : x of the windscreen's lower and upper edge
    rw_top, rw_base : x of the rear window's upper and lower edge
    roof            : roof top height; tumble : inward lean of the side glass at the top
    """

    x_rear: float
    x_front: float
    half_w: float
    clear: float
    belt: float
    nose_top: float
    nose_bot: float
    tail_top: float
    tail_bot: float
    ws_base: float
    ws_top: float
    rw_top: float
    rw_base: float
    roof: float
    tumble: float = 0.12
    corner: float = 0.14  # plan-view chamfer of the body corners
    rear_lights: bool = True
    body_rgb: tuple[float, float, float] | None = None
    body_material: str = "paint"


def _car_like(s: _CarSpec) -> list[_Part]:
    """Body, greenhouse, roof, windscreen, rear window, front and rear lights."""
    hw = s.half_w
    c = s.corner
    # sills tucked in: the body's sides slope in by 6 cm over their lowest 14 cm (rocker
    # panels), so an oblique view sees the ground in the body's shade under them: the
    # dark contact line real cars show along their sides
    tk, sill = 0.06, s.clear + 0.14
    body_pts = _sym(
        [
            (s.x_rear, hw - c, s.tail_bot),
            (s.x_rear, hw - c, s.tail_top - 0.04),
            (s.x_rear + c, hw - tk, s.clear),
            (s.x_rear + c, hw, sill),
            (s.x_rear + c, hw, s.tail_top),
            (s.rw_base, hw - tk, s.clear),
            (s.rw_base, hw, sill),
            (s.rw_base, hw, s.belt),
            (s.ws_base, hw - tk, s.clear),
            (s.ws_base, hw, sill),
            (s.ws_base, hw, s.belt),
            (s.x_front - c, hw - tk, s.clear),
            (s.x_front - c, hw, sill),
            (s.x_front - c, hw, s.nose_top),
            (s.x_front, hw - c, s.nose_bot),
            (s.x_front, hw - c, s.nose_top - 0.05),
        ]
    )
    parts = [_Part("body", s.body_material, s.body_rgb, *_hull(body_pts))]
    # panel line: the dark cowl (scuttle) strip where the bonnet meets the windscreen, 7 cm
    # of black plastic and the bonnet's shut line; about half a pixel at 0.12 m GSD
    cw0 = s.ws_base + 0.005
    cw1 = min(s.ws_base + 0.075, s.x_front - 0.05)
    slope = (s.belt - s.nose_top) / max(s.x_front - s.ws_base, 1e-3)
    parts.append(_Part("cowl", "trim", COWL_RGB,
                       *_box(cw0, cw1, -(hw - 0.16), hw - 0.16, s.belt - 0.04 - slope * 0.075,
                             s.belt + 0.006)))

    roof_t = 0.05  # roof panel thickness
    g_top = s.roof - roof_t * 0.6
    hb = hw - 0.04
    ht = hw - s.tumble
    gh_pts = _sym(
        [
            (s.rw_base, hb, s.belt - 0.06),
            (s.ws_base, hb, s.belt - 0.06),
            (s.rw_base, hb, s.belt),
            (s.ws_base, hb, s.belt),
            (s.rw_top, ht, g_top),
            (s.ws_top, ht, g_top),
        ]
    )
    parts.append(_Part("greenhouse", "glass", DEFAULT_COLOR_FOR_MATERIAL["glass"], *_hull(gh_pts)))
    inside = np.array([(s.rw_base + s.ws_base) / 2, 0.0, (s.belt + g_top) / 2])
    ws = [(s.ws_base, -hb, s.belt), (s.ws_base, hb, s.belt),
          (s.ws_top, ht, g_top), (s.ws_top, -ht, g_top)]
    parts.append(_Part("windscreen", "glass", WINDSCREEN_RGB, *_glass_slab(ws, inside)))
    rw = [(s.rw_base, hb, s.belt), (s.rw_base, -hb, s.belt),
          (s.rw_top, -ht, g_top), (s.rw_top, ht, g_top)]
    # a near-vertical back (truck cab, campervan cab) gets a panel lying closer to it
    off = 0.012 if s.rw_top - s.rw_base > 0.05 else 0.005
    rear = _glass_slab(rw, inside, offset=off)
    parts.append(_Part("rear_window", "glass", WINDSCREEN_RGB, *rear))
    # roof panel: covers the greenhouse top, slightly rounded edges
    r0, r1 = s.rw_top + 0.01, s.ws_top - 0.01
    roof_pts = _sym(
        [
            (r0, ht + 0.01, s.roof - roof_t),
            (r1, ht + 0.01, s.roof - roof_t),
            (r0 + 0.04, ht - 0.03, s.roof),
            (r1 - 0.04, ht - 0.03, s.roof),
        ]
    )
    parts.append(_Part("roof", "paint", s.body_rgb, *_hull(roof_pts)))

    # lights: small blocks standing proud of the nose / tail tops
    lx = 0.16
    ly0, ly1 = hw - c - 0.36, hw - c - 0.01
    for side in (1, -1):
        y0, y1 = sorted((side * ly0, side * ly1))
        parts.append(
            _Part(
                "light_front",
                "light_front",
                DEFAULT_COLOR_FOR_MATERIAL["light_front"],
                *_box(s.x_front - lx, s.x_front - 0.004, y0, y1,
                      s.nose_top - 0.16, s.nose_top + 0.006),
            )
        )
        if s.rear_lights:
            parts.append(
                _Part(
                    "light_rear",
                    "light_rear",
                    DEFAULT_COLOR_FOR_MATERIAL["light_rear"],
                    *_box(s.x_rear + 0.004, s.x_rear + lx, y0, y1,
                          s.tail_top - 0.16, s.tail_top + 0.006),
                )
            )
    return parts


def _wheels(axles, half_w, r, width, inset=0.06, dual_rear=False) -> list[_Part]:
    """Tyres at the given axle x positions, their outer face ``inset`` inside half_w."""
    parts = []
    for k, x in enumerate(axles):
        w = width * (1.8 if (dual_rear and k > 0) else 1.0)
        y = half_w - inset - w / 2
        for side in (1, -1):
            tyre = _wheel(x, side * y, r, w)
            parts.append(_Part("wheels", "tyre", DEFAULT_COLOR_FOR_MATERIAL["tyre"], *tyre))
    return parts


# ----------------------------------------------------------------- body types
def _procedural_parts(model: VehicleModel, height_m: float | None = None) -> list[_Part]:
    builder = _BUILDERS.get(model.body)
    if builder is None:  # the catalog validates body types; this guards hand-made models
        raise AssetError(
            f"model {model.name!r}: body must be one of {', '.join(_BUILDERS)}, got {model.body!r}"
        )
    return builder(model.length_m, model.width_m, model.height_m if height_m is None else height_m)


def _car(L, W, H, *, bonnet, ws_run, rw_top_from_rear, rw_base_from_rear, belt, nose_top,
         tail_top, wheel_r, tumble=0.16, clear=0.16, rails=False) -> list[_Part]:
    """A passenger car. Lengths in metres; bonnet = nose to windscreen base; ws_run =
    horizontal run of the windscreen; rw_* = rear window edges measured from the tail.
    tumble: the side glass leans in by 16 cm at the roof (a 1.8 m car's roof is ~1.3 m
    wide), so the side windows show from above as dark strips beside the roof (was 10 cm:
    a 1-2 px line at 4 cm/px, nothing at 0.12 m)."""
    x0, x1 = -L / 2, L / 2
    roof_h = H - (0.04 if rails else 0.0)
    spec = _CarSpec(
        x_rear=x0,
        x_front=x1,
        half_w=W / 2,
        clear=clear,
        belt=belt,
        nose_top=nose_top,
        nose_bot=clear + 0.12,
        tail_top=tail_top,
        tail_bot=clear + 0.14,
        ws_base=x1 - bonnet,
        ws_top=x1 - bonnet - ws_run,
        rw_top=x0 + rw_top_from_rear,
        rw_base=x0 + rw_base_from_rear,
        roof=roof_h,
        tumble=tumble,
    )
    parts = _car_like(spec)
    oh_f, oh_r = 0.2 * L, 0.21 * L
    parts += _wheels([x1 - oh_f, x0 + oh_r], W / 2, wheel_r, 0.22)
    if rails:
        ht = W / 2 - tumble
        for side in (1, -1):
            y0, y1 = sorted((side * (ht - 0.10), side * (ht - 0.04)))
            parts.append(
                _Part("roof_rails", "trim", DEFAULT_COLOR_FOR_MATERIAL["trim"],
                      *_box(spec.rw_top + 0.10, spec.ws_top - 0.12, y0, y1, roof_h - 0.02, H))
            )
    return parts


def _sport(L, W, H):
    return _car(L, W, H, bonnet=0.36 * L, ws_run=0.62, rw_top_from_rear=0.34 * L,
                rw_base_from_rear=0.13 * L, belt=0.62 * H, nose_top=0.46 * H, tail_top=0.62 * H,
                wheel_r=0.33, tumble=0.14, clear=0.12)


def _hatchback(L, W, H):
    return _car(L, W, H, bonnet=0.27 * L, ws_run=0.78, rw_top_from_rear=0.12 * L,
                rw_base_from_rear=0.03 * L, belt=0.60 * H, nose_top=0.52 * H, tail_top=0.60 * H,
                wheel_r=0.31)


def _sedan(L, W, H):
    return _car(L, W, H, bonnet=0.29 * L, ws_run=0.80, rw_top_from_rear=0.30 * L,
                rw_base_from_rear=0.17 * L, belt=0.62 * H, nose_top=0.52 * H, tail_top=0.62 * H,
                wheel_r=0.32)


def _suv(L, W, H):
    return _car(L, W, H, bonnet=0.26 * L, ws_run=0.62, rw_top_from_rear=0.07 * L,
                rw_base_from_rear=0.025 * L, belt=0.60 * H, nose_top=0.56 * H, tail_top=0.60 * H,
                wheel_r=0.37, clear=0.22, rails=True)


def _pickup(L, W, H):
    x0, x1 = -L / 2, L / 2
    bed_len = 0.33 * L
    cab_back = x0 + bed_len + 0.06
    belt = 0.58 * H
    clear = 0.26
    spec = _CarSpec(
        x_rear=cab_back,
        x_front=x1,
        half_w=W / 2,
        clear=clear,
        belt=belt,
        nose_top=0.56 * H,
        nose_bot=clear + 0.14,
        tail_top=belt,
        tail_bot=clear + 0.1,
        ws_base=x1 - 0.23 * L,
        ws_top=x1 - 0.23 * L - 0.62,
        rw_top=cab_back + 0.10,
        rw_base=cab_back + 0.02,
        roof=H,
        tumble=0.12,
        corner=0.04,
        rear_lights=False,
    )
    parts = _car_like(spec)
    # open bed: base, dark liner floor, four walls
    b0, b1 = x0, cab_back - 0.04
    floor = belt - 0.42
    top = belt - 0.02
    wt = 0.07
    hw = W / 2 - 0.02
    parts.append(_Part("bed", "paint", None, *_box(b0 + 0.02, b1, -hw, hw, clear + 0.05, floor)))
    liner = _box(b0 + wt, b1 - wt, -hw + wt, hw - wt, floor, floor + 0.02)
    parts.append(_Part("bed_floor", "trim", BED_LINER_RGB, *liner))
    parts.append(_Part("bed", "paint", None, *_box(b0 + 0.02, b1, hw - wt, hw, floor, top)))
    parts.append(_Part("bed", "paint", None, *_box(b0 + 0.02, b1, -hw, -hw + wt, floor, top)))
    parts.append(_Part("bed", "paint", None, *_box(b1 - wt, b1, -hw, hw, floor, top)))
    parts.append(_Part("tailgate", "paint", None, *_box(b0, b0 + wt, -hw, hw, floor - 0.05, top)))
    for side in (1, -1):
        y0, y1 = sorted((side * (hw - 0.02), side * (hw - 0.30)))
        parts.append(_Part("light_rear", "light_rear", DEFAULT_COLOR_FOR_MATERIAL["light_rear"],
                           *_box(b0 - 0.0, b0 + 0.08, y0, y1, top - 0.30, top + 0.004)))
    parts += _wheels([x1 - 0.18 * L, x0 + 0.24 * L], W / 2, 0.39, 0.25)
    return parts


def _box_truck(L, W, H):
    x0, x1 = -L / 2, L / 2
    cab_len = 1.85
    cab_h = min(2.6, 0.80 * H)
    cab_back = x1 - cab_len
    cab_hw = W / 2 - 0.06
    spec = _CarSpec(
        x_rear=cab_back,
        x_front=x1,
        half_w=cab_hw,
        clear=0.50,
        belt=0.58 * cab_h,
        nose_top=0.55 * cab_h,
        nose_bot=0.50,
        tail_top=0.58 * cab_h,
        tail_bot=0.55,
        ws_base=x1 - 0.12,
        ws_top=x1 - 0.62,
        rw_top=cab_back + 0.03,
        rw_base=cab_back + 0.02,
        roof=cab_h,
        tumble=0.10,
        corner=0.12,
        rear_lights=False,
    )
    parts = _car_like(spec)
    box0, box1 = x0, cab_back - 0.10
    parts.append(_Part("chassis", "trim", DEFAULT_COLOR_FOR_MATERIAL["trim"],
                       *_box(x0 + 0.25, cab_back + 0.3, -0.5, 0.5, 0.55, 0.95)))
    parts.append(_Part("cargo_box", "cargo", DEFAULT_COLOR_FOR_MATERIAL["cargo"],
                       *_box(box0 + 0.03, box1, -W / 2, W / 2, 0.98, H)))
    # roof panel seams on the box: thin raised strips every ~1.2 m (read as a box from above)
    n_seams = max(2, int((box1 - box0) / 1.3))
    for xs in np.linspace(box0 + 0.6, box1 - 0.6, n_seams):
        parts.append(_Part("cargo_box_ribs", "metal", (0.70, 0.71, 0.72),
                           *_box(xs - 0.03, xs + 0.03, -W / 2 + 0.04, W / 2 - 0.04, H - 0.02, H)))
    parts.append(_Part("bumper_rear", "trim", DEFAULT_COLOR_FOR_MATERIAL["trim"],
                       *_box(x0, x0 + 0.12, -W / 2 + 0.05, W / 2 - 0.05, 0.55, 0.75)))
    for side in (1, -1):
        y0, y1 = sorted((side * (W / 2 - 0.08), side * (W / 2 - 0.38)))
        parts.append(_Part("light_rear", "light_rear", DEFAULT_COLOR_FOR_MATERIAL["light_rear"],
                           *_box(x0 + 0.0, x0 + 0.10, y0, y1, 0.75, 0.93)))
    parts += _wheels([x1 - 1.15, x0 + 0.30 * L], W / 2, 0.46, 0.28, dual_rear=True)
    return parts


def _campervan(L, W, H):
    x0, x1 = -L / 2, L / 2
    cab_len = 2.25
    cab_back = x1 - cab_len
    cab_h = 2.05
    cab_hw = W / 2 - 0.13
    box_h = H - 0.18  # roof-top fittings (air conditioner) reach H
    spec = _CarSpec(
        x_rear=cab_back,
        x_front=x1,
        half_w=cab_hw,
        clear=0.32,
        belt=1.12,
        nose_top=1.00,
        nose_bot=0.42,
        tail_top=1.12,
        tail_bot=0.45,
        ws_base=x1 - 0.72,
        ws_top=x1 - 1.48,
        rw_top=cab_back + 0.02,
        rw_base=cab_back + 0.01,
        roof=cab_h,
        tumble=0.10,
        corner=0.16,
        rear_lights=False,
    )
    parts = _car_like(spec)
    # living box: full width, sloped "aero" front over the cab roof
    hw = W / 2
    box_pts = _sym(
        [
            (x0 + 0.04, hw, 0.50),
            (x0 + 0.04, hw, box_h),
            (x1 - 1.95, hw, box_h),
            (x1 - 1.52, hw - 0.06, cab_h - 0.04),
            (cab_back - 0.05, hw, 0.50),
        ]
    )
    parts.append(_Part("living_box", "cargo", (0.88, 0.88, 0.86), *_hull(box_pts)))
    # roof fittings: two skylights, a solar panel, an air conditioner
    for xc, sx, sy in ((x1 - 2.45, 0.45, 0.45), (x0 + 1.0, 0.45, 0.45)):
        parts.append(_Part("skylight", "glass", (0.10, 0.11, 0.12),
                           *_box(xc - sx / 2, xc + sx / 2, -sy / 2, sy / 2,
                                 box_h - 0.01, box_h + 0.06)))
    xs = (x1 - 2.45 + x0 + 1.0) / 2
    parts.append(_Part("solar_panel", "glass", SOLAR_RGB,
                       *_box(xs - 0.90, xs + 0.10, -0.05, hw - 0.18, box_h - 0.01, box_h + 0.05)))
    parts.append(_Part("air_conditioner", "metal", (0.78, 0.78, 0.76),
                       *_box(xs + 0.35, xs + 1.05, -hw + 0.40, -0.05, box_h - 0.01, H)))
    for side in (1, -1):
        y0, y1 = sorted((side * (hw - 0.05), side * (hw - 0.30)))
        parts.append(_Part("light_rear", "light_rear", DEFAULT_COLOR_FOR_MATERIAL["light_rear"],
                           *_box(x0, x0 + 0.08, y0, y1, 0.55, 0.95)))
    parts += _wheels([x1 - 0.95, x0 + 0.34 * L], hw, 0.36, 0.24, inset=0.17, dual_rear=False)
    return parts


_BUILDERS = {
    "sport": _sport,
    "hatchback": _hatchback,
    "sedan": _sedan,
    "suv": _suv,
    "pickup": _pickup,
    "box_truck": _box_truck,
    "campervan": _campervan,
}


def _wrap_large(fn):
    def build(L, W, H):
        return [_Part(name, mat, rgb, v, f) for name, mat, rgb, v, f in fn(L, W, H)]

    return build


# buses, coach, delivery van, semi-trailer truck (vehicles/large.py)
_BUILDERS.update({name: _wrap_large(fn) for name, fn in LARGE_BUILDERS.items()})
# tractor, farm, boat and utility trailers (vehicles/towed.py)
_BUILDERS.update({name: _wrap_large(fn) for name, fn in TOWED_BUILDERS.items()})


def _profiled(body: str):
    """The builder of a car body of :data:`.bodies.CAR_PROFILES` (a panel van's upper body
    is painted, not glazed)."""
    prof = CAR_PROFILES[body]

    def build(L, W, H):
        parts = _car(L, W, H, **car_kwargs(prof, L, H))
        if not prof.glass_sides:
            parts = [_Part(p.name, "paint", None, p.v, p.f) if p.name == "greenhouse" else p
                     for p in parts]
        return parts

    return build


# compact, estate, mpv, van, minibus (vehicles/bodies.py)
_BUILDERS.update({body: _profiled(body) for body in CAR_PROFILES})


# ----------------------------------------------------------------- trim options
# Each takes the fitted parts (vehicle frame, bounds [-L/2, L/2] x [-W/2, W/2] x [0, H])
# and returns them with the option added; nothing reaches past L or W, and nothing above
# H + OPTION_RISE_M[option].
SUNROOF_RGB = (0.025, 0.03, 0.04)
RACK_RGB = (0.06, 0.06, 0.065)
ROOF_BOX_RGB = (0.09, 0.09, 0.10)


def _bounds(parts: list[_Part], name: str) -> np.ndarray:
    v = np.concatenate([p.v for p in parts if p.name == name])
    return np.stack([v.min(axis=0), v.max(axis=0)])


def _sunroof(parts, L, W, H, body=""):
    """A dark glass panel over the front half of the roof panel; the roof panel's top is
    lowered 4 mm so the glass lies proud of it and the height stays H."""
    (x0, y0, _), (x1, y1, top) = _bounds(parts, "roof")
    out = []
    for p in parts:
        if p.name == "roof":
            v = p.v.copy()
            v[v[:, 2] > top - 1e-6, 2] = top - 0.004
            p = _Part(p.name, p.material, p.rgb, v, p.f)
        out.append(p)
    ln, wd = 0.42 * (x1 - x0), 0.56 * (y1 - y0)
    xc = x0 + 0.6 * (x1 - x0)
    out.append(_Part("sunroof", "glass", SUNROOF_RGB,
                     *_box(xc - ln / 2, xc + ln / 2, -wd / 2, wd / 2, top - 0.03, top)))
    return out


def _bars(parts, H, rise=0.04, n=2, span=0.92):
    """Transverse roof bars standing on the roof (or an SUV's rails), top at H + rise."""
    (x0, y0, _), (x1, y1, _) = _bounds(parts, "roof")
    hw = span * (y1 - y0) / 2
    out = []
    for k in range(n):
        xc = x0 + (x1 - x0) * (0.22 + 0.56 * k / max(n - 1, 1))
        out.append(_Part("roof_rack", "metal", RACK_RGB,
                         *_box(xc - 0.025, xc + 0.025, -hw, hw, H - 0.03, H + rise)))
    return out


def _roof_rack(parts, L, W, H, body=""):
    if body == "delivery_van":
        return _ladder_rack(parts, L, W, H)
    return parts + _bars(parts, H, rise=OPTION_RISE_M["roof_rack"])


def _roof_box(parts, L, W, H, body=""):
    """Roof bars and a rounded roof box on them (a long, low, dark capsule)."""
    (x0, y0, _), (x1, y1, _) = _bounds(parts, "roof")
    bars_top = H + 0.06
    out = parts + _bars(parts, H, rise=0.06)
    ln = min(1.9, 0.8 * (x1 - x0))
    hw = min(0.45, 0.42 * (y1 - y0))
    xc = (x0 + x1) / 2 - 0.05
    top = H + OPTION_RISE_M["roof_box"]
    c = 0.12
    pts = _sym([(xc - ln / 2, hw - c, bars_top), (xc - ln / 2, hw - c, top - 0.06),
                (xc - ln / 2 + c, hw, bars_top + 0.03), (xc - ln / 2 + c, hw, top - 0.04),
                (xc - ln / 2 + 2 * c, hw - 0.03, top), (xc + ln / 2 - c, hw - 0.03, top),
                (xc + ln / 2 - c, hw, bars_top + 0.03), (xc + ln / 2, hw - c, bars_top + 0.05),
                (xc + ln / 2, hw - c, top - 0.08)])
    out.append(_Part("roof_box", "trim", ROOF_BOX_RGB, *_hull(pts)))
    return out


def _ladder_rack(parts, L, W, H, body=""):
    """Delivery van: a rack of two side rails and cross bars, with a ladder lying on it."""
    (x0, y0, _), (x1, y1, _) = _bounds(parts, "roof")
    rise = OPTION_RISE_M["roof_rack"]
    hw = 0.45 * (y1 - y0)
    out = list(parts)
    for side in (1, -1):
        ya, yb = sorted((side * hw, side * (hw - 0.04)))
        out.append(_Part("roof_rack", "metal", RACK_RGB, *_box(x0 + 0.05, x1 - 0.05, ya, yb, H - 0.02, H + 0.04)))
    for xc in np.linspace(x0 + 0.1, x1 - 0.1, 4):
        out.append(_Part("roof_rack", "metal", RACK_RGB,
                         *_box(xc - 0.02, xc + 0.02, -hw, hw, H - 0.02, H + 0.04)))
    # the ladder: two rails and rungs, aluminium, on one side
    lx0, lx1 = x0 + 0.15, x1 - 0.15
    for yc in (hw - 0.12, hw - 0.52):
        out.append(_Part("ladder", "metal", (0.72, 0.73, 0.75),
                         *_box(lx0, lx1, yc - 0.03, yc + 0.03, H + 0.04, H + rise)))
    for xc in np.arange(lx0 + 0.15, lx1 - 0.1, 0.3):
        out.append(_Part("ladder", "metal", (0.72, 0.73, 0.75),
                         *_box(xc - 0.015, xc + 0.015, hw - 0.52, hw - 0.12, H + 0.05, H + rise - 0.005)))
    return out


def _reefer(parts, L, W, H, body=""):
    """Box truck: a refrigeration unit on the front face of the box, above the cab."""
    (bx0, _, _), (bx1, by1, bz1) = _bounds(parts, "cargo_box")
    cab = _bounds(parts, "roof")[1][2]
    z0 = max(cab + 0.05, bz1 - 0.85)
    out = list(parts)
    out.append(_Part("reefer", "metal", (0.80, 0.81, 0.82),
                     *_box(bx1 - 0.02, bx1 + 0.04 + 0.0, -0.8, 0.8, z0, bz1 - 0.02)))
    out.append(_Part("reefer", "trim", (0.15, 0.16, 0.17),
                     *_box(bx1 - 0.02, bx1 + 0.06, -0.55, 0.55, z0 + 0.1, bz1 - 0.1)))
    return out


def _container(parts, L, W, H, body=""):
    """Semi-trailer: the box trailer becomes a shipping container in the variant's colour
    with corrugated roof (dense transverse ribs) and corner castings."""
    out = []
    for p in parts:
        if p.name == "trailer_ribs":
            continue
        if p.name == "trailer":
            p = _Part("container", "paint", None, p.v, p.f)
        out.append(p)
    (x0, y0, _), (x1, y1, top) = _bounds(out, "container")
    for xs in np.arange(x0 + 0.25, x1 - 0.2, 0.28):
        out.append(_Part("container_ribs", "paint", None,
                         *_box(xs - 0.05, xs + 0.05, y0 + 0.06, y1 - 0.06, top - 0.02, top)))
    for xc in (x0 + 0.1, x1 - 0.1):
        for yc in (y0 + 0.1, y1 - 0.1):
            out.append(_Part("container_corners", "metal", (0.30, 0.30, 0.32),
                             *_box(xc - 0.1, xc + 0.1, yc - 0.1, yc + 0.1, top - 0.15, top)))
    return out


_OPTIONS = {"sunroof": _sunroof, "roof_rack": _roof_rack, "roof_box": _roof_box,
            "reefer": _reefer, "container": _container}
