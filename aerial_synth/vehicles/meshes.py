# size: every procedural body builder (cars, vans, trucks, buses) in one module, which the body registry (body_types.py) reads
"""Vehicle meshes: procedural low-poly bodies and user glTF/GLB/OBJ files.

Vehicle frame: metres, origin at the footprint centre on the ground, +x forward, +y left,
z up. Every procedural part (body, greenhouse, roof, windscreen, wheels, cargo box, ...) is
a separate closed convex volume whose triangles are counter-clockwise seen from outside
(outward normals, positive signed volume). Parts may overlap; a ray always meets the
outermost surface first, so overlaps never show.

Procedural parts are designed in real metres from the catalog's length, width and height,
then scaled by a factor close to 1 so the mesh bounds equal the catalog size exactly.
Elsewhere: parts and shape helpers :mod:`.parts`, trim options :mod:`.options`, buses and
trucks :mod:`.large`, tractors and trailers :mod:`.towed`, the car segments :mod:`.bodies`."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..errors import AssetError
from ..scene.model import DEFAULT_COLOR_FOR_MATERIAL, MATERIAL_IDS
from ..validators import finite
from ._hull import box as _box
from ._hull import convex_hull as _hull
from .bodies import CAR_PROFILES, car_kwargs
from .body_types import REGISTRY as BODY_REGISTRY
from .body_types import Body
from .catalog import OPTION_RISE_M
from .large import LARGE_BUILDERS
from .model import VehicleColor, VehicleModel
from .options import OPTIONS
from .parts import Part, fit_to_size, glass_slab, sym, wheel
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

    def to_world(self, x_m: float, y_m: float, z_m: float, heading_rad: float) -> tuple[np.ndarray, np.ndarray]:
        """Place the vehicle: rotate about z by ``heading_rad`` (0 = +x, counter-clockwise),
        then translate its origin to (x_m, y_m, z_m) in the world frame (finite numbers).
        Returns (vertices_world (n, 3) float64 metres, faces (m, 3) int64, a copy)."""
        for name, val in (("x_m", x_m), ("y_m", y_m), ("z_m", z_m), ("heading_rad", heading_rad)):
            finite(f"vehicle to_world {name}", val, error=AssetError)
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
def _model_parts(model: VehicleModel) -> tuple["Part", ...]:
    """The parts of one model, whatever its colour (paint parts have ``rgb=None``): the
    geometry is built once per model and each colour only fills the albedo column."""
    if model.is_procedural:
        # the base body is built and fitted to the base size; options go on top in metres
        # (rounded: 1.78 + 0.42 - 0.42 is 1.7800000000000002, and the base body must be
        # the base model's to the bit)
        h0 = round(model.height_m - sum(OPTION_RISE_M[o] for o in model.options), 9)
        parts = _procedural_parts(model, h0)
        parts = fit_to_size(parts, model.length_m, model.width_m, h0)
        for opt in model.options:
            parts = OPTIONS[opt](parts, model.length_m, model.width_m, h0, model.body)
    else:
        user = load_user_mesh_parts(
            model.mesh_path, scale=model.scale, forward=model.forward, up=model.up
        )
        parts = []
        for p in user:
            painted = bool(model.paint_material) and p.material_name == model.paint_material
            parts.append(
                Part(
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


def _car_like(s: _CarSpec) -> list[Part]:
    """Body, greenhouse, roof, windscreen, rear window, front and rear lights."""
    hw = s.half_w
    c = s.corner
    # sills tucked in 6 cm over the lowest 14 cm: the dark contact line along a car's sides
    tk, sill = 0.06, s.clear + 0.14
    body_pts = sym(
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
    parts = [Part("body", s.body_material, s.body_rgb, *_hull(body_pts))]
    # panel line: the dark cowl (scuttle) strip where the bonnet meets the windscreen, 7 cm
    # of black plastic and the bonnet's shut line; about half a pixel at 0.12 m GSD
    cw0 = s.ws_base + 0.005
    cw1 = min(s.ws_base + 0.075, s.x_front - 0.05)
    slope = (s.belt - s.nose_top) / max(s.x_front - s.ws_base, 1e-3)
    parts.append(Part("cowl", "trim", COWL_RGB,
                       *_box(cw0, cw1, -(hw - 0.16), hw - 0.16, s.belt - 0.04 - slope * 0.075,
                             s.belt + 0.006)))

    roof_t = 0.05  # roof panel thickness
    g_top = s.roof - roof_t * 0.6
    hb = hw - 0.04
    ht = hw - s.tumble
    gh_pts = sym(
        [
            (s.rw_base, hb, s.belt - 0.06),
            (s.ws_base, hb, s.belt - 0.06),
            (s.rw_base, hb, s.belt),
            (s.ws_base, hb, s.belt),
            (s.rw_top, ht, g_top),
            (s.ws_top, ht, g_top),
        ]
    )
    parts.append(Part("greenhouse", "glass", DEFAULT_COLOR_FOR_MATERIAL["glass"], *_hull(gh_pts)))
    inside = np.array([(s.rw_base + s.ws_base) / 2, 0.0, (s.belt + g_top) / 2])
    ws = [(s.ws_base, -hb, s.belt), (s.ws_base, hb, s.belt),
          (s.ws_top, ht, g_top), (s.ws_top, -ht, g_top)]
    parts.append(Part("windscreen", "glass", WINDSCREEN_RGB, *glass_slab(ws, inside)))
    rw = [(s.rw_base, hb, s.belt), (s.rw_base, -hb, s.belt),
          (s.rw_top, -ht, g_top), (s.rw_top, ht, g_top)]
    # a near-vertical back (truck cab, campervan cab) gets a panel lying closer to it
    off = 0.012 if s.rw_top - s.rw_base > 0.05 else 0.005
    rear = glass_slab(rw, inside, offset=off)
    parts.append(Part("rear_window", "glass", WINDSCREEN_RGB, *rear))
    # roof panel: covers the greenhouse top, slightly rounded edges
    r0, r1 = s.rw_top + 0.01, s.ws_top - 0.01
    roof_pts = sym(
        [
            (r0, ht + 0.01, s.roof - roof_t),
            (r1, ht + 0.01, s.roof - roof_t),
            (r0 + 0.04, ht - 0.03, s.roof),
            (r1 - 0.04, ht - 0.03, s.roof),
        ]
    )
    parts.append(Part("roof", "paint", s.body_rgb, *_hull(roof_pts)))

    # lights: small blocks standing proud of the nose / tail tops
    lx = 0.16
    ly0, ly1 = hw - c - 0.36, hw - c - 0.01
    for side in (1, -1):
        y0, y1 = sorted((side * ly0, side * ly1))
        parts.append(
            Part(
                "light_front",
                "light_front",
                DEFAULT_COLOR_FOR_MATERIAL["light_front"],
                *_box(s.x_front - lx, s.x_front - 0.004, y0, y1,
                      s.nose_top - 0.16, s.nose_top + 0.006),
            )
        )
        if s.rear_lights:
            parts.append(
                Part(
                    "light_rear",
                    "light_rear",
                    DEFAULT_COLOR_FOR_MATERIAL["light_rear"],
                    *_box(s.x_rear + 0.004, s.x_rear + lx, y0, y1,
                          s.tail_top - 0.16, s.tail_top + 0.006),
                )
            )
    return parts


def _wheels(axles, half_w, r, width, inset=0.06, dual_rear=False) -> list[Part]:
    """Tyres at the given axle x positions, their outer face ``inset`` inside half_w."""
    parts = []
    for k, x in enumerate(axles):
        w = width * (1.8 if (dual_rear and k > 0) else 1.0)
        y = half_w - inset - w / 2
        for side in (1, -1):
            tyre = wheel(x, side * y, r, w)
            parts.append(Part("wheels", "tyre", DEFAULT_COLOR_FOR_MATERIAL["tyre"], *tyre))
    return parts


# ----------------------------------------------------------------- body types
def _procedural_parts(model: VehicleModel, height_m: float | None = None) -> list[Part]:
    if model.body not in BODY_REGISTRY.names():  # the catalog validates body types; this guards hand-made models
        raise AssetError(f"model {model.name!r}: body must be one of "
                         f"{', '.join(BODY_REGISTRY.names())}, got {model.body!r}")
    h = model.height_m if height_m is None else height_m
    return BODY_REGISTRY.get(model.body).build(model.length_m, model.width_m, h)


def _car(L, W, H, *, bonnet, ws_run, rw_top_from_rear, rw_base_from_rear, belt, nose_top,
         tail_top, wheel_r, tumble=0.16, clear=0.16, rails=False) -> list[Part]:
    """A passenger car. Lengths in metres; bonnet = nose to windscreen base; ws_run =
    horizontal run of the windscreen; rw_* = rear window edges measured from the tail;
    tumble = side glass lean at the roof (16 cm: side windows show from above as dark strips)."""
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
                Part("roof_rails", "trim", DEFAULT_COLOR_FOR_MATERIAL["trim"],
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
    parts.append(Part("bed", "paint", None, *_box(b0 + 0.02, b1, -hw, hw, clear + 0.05, floor)))
    liner = _box(b0 + wt, b1 - wt, -hw + wt, hw - wt, floor, floor + 0.02)
    parts.append(Part("bed_floor", "trim", BED_LINER_RGB, *liner))
    parts.append(Part("bed", "paint", None, *_box(b0 + 0.02, b1, hw - wt, hw, floor, top)))
    parts.append(Part("bed", "paint", None, *_box(b0 + 0.02, b1, -hw, -hw + wt, floor, top)))
    parts.append(Part("bed", "paint", None, *_box(b1 - wt, b1, -hw, hw, floor, top)))
    parts.append(Part("tailgate", "paint", None, *_box(b0, b0 + wt, -hw, hw, floor - 0.05, top)))
    for side in (1, -1):
        y0, y1 = sorted((side * (hw - 0.02), side * (hw - 0.30)))
        parts.append(Part("light_rear", "light_rear", DEFAULT_COLOR_FOR_MATERIAL["light_rear"],
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
    parts.append(Part("chassis", "trim", DEFAULT_COLOR_FOR_MATERIAL["trim"],
                       *_box(x0 + 0.25, cab_back + 0.3, -0.5, 0.5, 0.55, 0.95)))
    parts.append(Part("cargo_box", "cargo", DEFAULT_COLOR_FOR_MATERIAL["cargo"],
                       *_box(box0 + 0.03, box1, -W / 2, W / 2, 0.98, H)))
    # roof panel seams on the box: thin raised strips every ~1.2 m (read as a box from above)
    n_seams = max(2, int((box1 - box0) / 1.3))
    for xs in np.linspace(box0 + 0.6, box1 - 0.6, n_seams):
        parts.append(Part("cargo_box_ribs", "metal", (0.70, 0.71, 0.72),
                           *_box(xs - 0.03, xs + 0.03, -W / 2 + 0.04, W / 2 - 0.04, H - 0.02, H)))
    parts.append(Part("bumper_rear", "trim", DEFAULT_COLOR_FOR_MATERIAL["trim"],
                       *_box(x0, x0 + 0.12, -W / 2 + 0.05, W / 2 - 0.05, 0.55, 0.75)))
    for side in (1, -1):
        y0, y1 = sorted((side * (W / 2 - 0.08), side * (W / 2 - 0.38)))
        parts.append(Part("light_rear", "light_rear", DEFAULT_COLOR_FOR_MATERIAL["light_rear"],
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
    box_pts = sym(
        [
            (x0 + 0.04, hw, 0.50),
            (x0 + 0.04, hw, box_h),
            (x1 - 1.95, hw, box_h),
            (x1 - 1.52, hw - 0.06, cab_h - 0.04),
            (cab_back - 0.05, hw, 0.50),
        ]
    )
    parts.append(Part("living_box", "cargo", (0.88, 0.88, 0.86), *_hull(box_pts)))
    # roof fittings: two skylights, a solar panel, an air conditioner
    for xc, sx, sy in ((x1 - 2.45, 0.45, 0.45), (x0 + 1.0, 0.45, 0.45)):
        parts.append(Part("skylight", "glass", (0.10, 0.11, 0.12),
                           *_box(xc - sx / 2, xc + sx / 2, -sy / 2, sy / 2,
                                 box_h - 0.01, box_h + 0.06)))
    xs = (x1 - 2.45 + x0 + 1.0) / 2
    parts.append(Part("solar_panel", "glass", SOLAR_RGB,
                       *_box(xs - 0.90, xs + 0.10, -0.05, hw - 0.18, box_h - 0.01, box_h + 0.05)))
    parts.append(Part("air_conditioner", "metal", (0.78, 0.78, 0.76),
                       *_box(xs + 0.35, xs + 1.05, -hw + 0.40, -0.05, box_h - 0.01, H)))
    for side in (1, -1):
        y0, y1 = sorted((side * (hw - 0.05), side * (hw - 0.30)))
        parts.append(Part("light_rear", "light_rear", DEFAULT_COLOR_FOR_MATERIAL["light_rear"],
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
        return [Part(name, mat, rgb, v, f) for name, mat, rgb, v, f in fn(L, W, H)]

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
            parts = [Part(p.name, "paint", None, p.v, p.f) if p.name == "greenhouse" else p
                     for p in parts]
        return parts

    return build


# compact, estate, mpv, van, minibus (vehicles/bodies.py)
_BUILDERS.update({body: _profiled(body) for body in CAR_PROFILES})

#: the built-in bodies, as the body registry (vehicles/body_types.py) loads them
BODIES = {name: Body(name, fn) for name, fn in _BUILDERS.items()}
