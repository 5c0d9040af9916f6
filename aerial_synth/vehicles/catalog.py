"""Vehicle catalog: models (sizes, class, frequency), colour palette, sampling.

The catalog is a YAML file (the bundled one is ``vehicle_assets/catalog.yaml``)::

    colors:
      - {name: white, rgb: [0.86, 0.86, 0.84], weight: 0.27}
    models:
      - {name: hatchback, pack: 1, body: hatchback, class: small-vehicle,
         length_m: 4.05, width_m: 1.76, height_m: 1.48, weight: 2.0}
      - {name: my_van, mesh: meshes/van.glb, scale: 1.0, forward: -z, up: +y,
         class: small-vehicle, paint_material: Body, weight: 1.0}

A model is either *procedural* (``body`` names one of :data:`BODY_TYPES`; the catalog
gives length, width and height) or a *user mesh* (``mesh`` is a glTF/GLB/OBJ path inside
the catalog's folder; its size comes from the mesh bounds after scale and axis change).

Trim options. A procedural model may come with an option built into its mesh: a sunroof,
a roof rack or a roof box on cars, a refrigeration unit on box trucks, a ladder rack on
delivery vans, a shipping container on semi-trailers (:data:`OPTION_BODIES`). How often
each is drawn is :data:`DEFAULT_OPTION_RATES` per body, or the model's ``options:
{name: probability}`` in the catalog. A vehicle with an option is the model ``base+option``
(e.g. ``sedan+sunroof``): same class, length and width, its height raised by the option's
:data:`OPTION_RISE_M`; :meth:`Catalog.model` resolves such names. :meth:`Catalog.sample`
draws the options from a stream of its own, keyed by the generator's state on entry, so
models, colours and every later draw of the caller's generator are exactly what they were
without options.

Vehicle frame (every mesh): metres, origin at the footprint centre on the ground,
+x forward, +y left, z up.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .. import validators as v
from ..errors import AssetError
from ..safe_input import load_yaml_file, shown
from .bodies import CAR_PROFILES
from .body_types import REGISTRY as BODIES
from .model import (
    AXES,
    BODY_TYPES,
    CLASSES,
    MESH_SUFFIXES,
    VehicleColor,
    VehicleModel,
    VehicleVariant,
)
from .user_mesh import load_user_mesh_parts

__all__ = [
    "CLASSES",
    "BODY_TYPES",
    "AXES",
    "VehicleModel",
    "VehicleColor",
    "VehicleVariant",
    "Catalog",
    "load_catalog",
    "bundled_catalog_path",
    "OPTION_BODIES",
    "OPTION_RISE_M",
    "DEFAULT_OPTION_RATES",
    "with_option",
]


def with_option(model: VehicleModel, option: str) -> VehicleModel:
    """The model ``model.name+option``: same size but for the option's height."""
    import dataclasses

    if model.options or not model.is_procedural or model.body not in OPTION_BODIES.get(option, ()):
        fits = ", ".join(b for b in BODY_TYPES if b in OPTION_BODIES.get(option, ())) or "none"
        raise AssetError(f"vehicle model {model.name!r}: option {option!r} does not fit it "
                         f"(option {option!r} fits bodies: {fits})")
    return dataclasses.replace(model, name=f"{model.name}+{option}",
                               height_m=model.height_m + OPTION_RISE_M[option], options=(option,))


def stream_key(rng: np.random.Generator) -> int:
    """An integer that depends only on the generator's state (which it leaves untouched)."""
    import hashlib

    d = hashlib.sha256(repr(rng.bit_generator.state).encode()).digest()
    return int.from_bytes(d[:16], "little")

#: The catalog file format version this code reads (``version:`` in the YAML).
CATALOG_VERSION = 1

_PROCEDURAL_KEYS = {"name", "pack", "body", "class", "length_m", "width_m", "height_m", "weight",
                    "options"}

#: Trim option -> the procedural bodies it fits.
OPTION_BODIES: dict[str, tuple[str, ...]] = {
    "sunroof": ("sport", "hatchback", "sedan", "suv"),
    "roof_rack": ("hatchback", "sedan", "suv", "delivery_van"),
    "roof_box": ("hatchback", "sedan", "suv"),
    "reefer": ("box_truck",),
    "container": ("semi_trailer",),
}
#: Height an option adds on top of the model (metres): bars 8 cm, a roof box 42 cm.
OPTION_RISE_M: dict[str, float] = {"sunroof": 0.0, "roof_rack": 0.08, "roof_box": 0.42,
                                   "reefer": 0.0, "container": 0.0}
#: Default option probabilities per body (the rest: no option). Rough shares of what one
#: sees on European roads and car parks (no published census of roof racks was found): a
#: glass roof or sunroof on a quarter of mid-size cars and a third of SUVs, roof bars or a
#: box on a few percent, refrigerated bodies on a third of small trucks, ladder racks on a
#: third of panel vans, containers on a third of semi-trailers.
DEFAULT_OPTION_RATES: dict[str, dict[str, float]] = {
    "sport": {"sunroof": 0.10},
    "hatchback": {"sunroof": 0.15, "roof_rack": 0.03, "roof_box": 0.02},
    "sedan": {"sunroof": 0.25, "roof_rack": 0.02, "roof_box": 0.02},
    "suv": {"sunroof": 0.30, "roof_rack": 0.06, "roof_box": 0.05},
    "box_truck": {"reefer": 0.30},
    "delivery_van": {"roof_rack": 0.30},
    "semi_trailer": {"container": 0.35},
}
# the car bodies of .bodies: their options and rates come with their profiles
OPTION_BODIES.update({opt: bodies + tuple(b for b, p in CAR_PROFILES.items() if opt in p.option_rates)
                      for opt, bodies in OPTION_BODIES.items()})
DEFAULT_OPTION_RATES.update({b: dict(p.option_rates) for b, p in CAR_PROFILES.items()})
_MESH_KEYS = {"name", "pack", "mesh", "scale", "forward", "up", "class", "paint_material", "weight"}
_COLOR_KEYS = {"name", "rgb", "weight"}


def bundled_catalog_path() -> Path:
    """Path of the bundled catalog: ``aerial_synth/data/vehicle_assets/catalog.yaml`` (in a
    checkout a link to the top-level ``vehicle_assets/``)."""
    return Path(__file__).resolve().parents[1] / "data" / "vehicle_assets" / "catalog.yaml"


@dataclass(frozen=True)
class Catalog:
    """Models and colours of one catalog file (immutable).

    models : tuple of :class:`VehicleModel` (names unique)
    colors : tuple of :class:`VehicleColor` (names unique)
    path   : the catalog file (None when built in memory)
    option_rates : model name -> {option: probability}; models not named use
             :data:`DEFAULT_OPTION_RATES` of their body (user meshes: none)
    """

    models: tuple[VehicleModel, ...]
    colors: tuple[VehicleColor, ...]
    path: Path | None = None
    option_rates: dict = field(default_factory=dict, compare=False)
    _model_index: dict = field(default_factory=dict, repr=False, compare=False)
    _color_index: dict = field(default_factory=dict, repr=False, compare=False)
    _option_tables: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        where = str(self.path) if self.path else "catalog"
        object.__setattr__(self, "models", tuple(self.models))
        object.__setattr__(self, "colors", tuple(self.colors))
        if not self.models:
            raise AssetError(f"{where}: models: expected at least one model, got none")
        if not self.colors:
            raise AssetError(f"{where}: colors: expected at least one colour, got none")
        for kind, items, index in (
            ("models", self.models, self._model_index),
            ("colors", self.colors, self._color_index),
        ):
            for i, it in enumerate(items):
                if it.name in index:
                    raise AssetError(f"{where}: {kind}[{i}] name {it.name!r} is used twice")
                index[it.name] = it
            if sum(it.weight for it in items) <= 0:
                raise AssetError(f"{where}: {kind}: weights sum to 0; expected a positive sum")

    # ------------------------------------------------------------------ look-ups
    def model(self, name: str) -> VehicleModel:
        """A model by name; ``base+option`` names give the base model with that option."""
        try:
            return self._model_index[name]
        except KeyError:
            pass
        base, plus, opt = name.partition("+")
        if plus and base in self._model_index and "+" not in base:
            if opt not in OPTION_BODIES:
                raise AssetError(f"vehicle model {name!r}: unknown option {opt!r}; expected one of "
                                 f"{', '.join(OPTION_BODIES)}")
            m = with_option(self._model_index[base], opt)
            self._model_index[name] = m
            return m
        raise AssetError(
            f"unknown vehicle model {name!r}; expected one of "
            f"{', '.join(k for k in self._model_index if '+' not in k)}"
        ) from None

    def options_of(self, model: VehicleModel) -> dict[str, float]:
        """{option: probability} drawn for a model (empty: never an option)."""
        if not model.is_procedural:
            return {}
        rates = self.option_rates.get(model.name)
        return dict(DEFAULT_OPTION_RATES.get(model.body, {}) if rates is None else rates)

    def color(self, name: str) -> VehicleColor:
        try:
            return self._color_index[name]
        except KeyError:
            raise AssetError(
                f"unknown vehicle colour {name!r}; expected one of {', '.join(self._color_index)}"
            ) from None

    @property
    def model_probabilities(self) -> np.ndarray:
        """(n_models,) float64, model weights normalised to sum 1 (catalog order)."""
        w = np.array([m.weight for m in self.models], dtype=np.float64)
        return w / w.sum()

    @property
    def color_probabilities(self) -> np.ndarray:
        """(n_colors,) float64, colour weights normalised to sum 1 (catalog order)."""
        w = np.array([c.weight for c in self.colors], dtype=np.float64)
        return w / w.sum()

    # ------------------------------------------------------------------ variants
    def variants(self) -> list[VehicleVariant]:
        """Every model x colour combination, models outer, in catalog order."""
        return [VehicleVariant(m, c) for m in self.models for c in self.colors]

    def sample(self, rng: np.random.Generator, n: int) -> list[VehicleVariant]:
        """Draw ``n`` variants: model by model weight, colour (independently) by colour weight,
        then each vehicle's trim option (:meth:`options_of`; a variant with an option has
        the model ``base+option``).

        Deterministic for a seeded ``rng``. Draws the n model indices first, then the n
        colour indices, from ``rng`` (as always); the options come from a generator of
        their own seeded by ``rng``'s state on entry, so ``rng`` advances exactly as it did
        without options.
        """
        if not isinstance(rng, np.random.Generator):
            raise AssetError(f"catalog sample rng: expected a numpy.random.Generator, got "
                             f"{type(rng).__name__}")
        n = v.integer("catalog sample n", n, 0, 100_000_000, error=AssetError)
        key = stream_key(rng) if n else 0
        mi = rng.choice(len(self.models), size=n, p=self.model_probabilities)
        ci = rng.choice(len(self.colors), size=n, p=self.color_probabilities)
        picked = self.draw_options(mi, key)
        colors = self.colors
        return [VehicleVariant(m, colors[j]) for m, j in zip(picked, ci.tolist())]

    def draw_options(self, model_idx, key: int) -> list[VehicleModel]:
        """The models ``self.models[i]`` for ``i`` in ``model_idx``, each with the trim
        option it draws (:meth:`options_of`), or None where ``i < 0``. The draws come from
        ``SeedSequence([key, 17])``, one uniform number per vehicle in order: option k of a
        model is the first whose cumulative rate exceeds it. ``key`` is typically
        ``stream_key(rng)`` at a fixed point, so the caller's generator never advances."""
        mi = np.asarray(model_idx, int).reshape(-1)
        n = len(mi)
        u = np.random.default_rng(np.random.SeedSequence([int(key), 17])).random(n) if n else np.zeros(0)
        models = self.models
        picked = [models[i] if i >= 0 else None for i in mi.tolist()]
        for i in np.unique(mi[mi >= 0]).tolist():
            names, cum = self._options_table(i)
            if not names:
                continue
            sel = np.flatnonzero(mi == i)
            k = np.searchsorted(cum, u[sel], side="right")
            some = k < len(names)
            for s, kk in zip(sel[some].tolist(), k[some].tolist()):
                picked[s] = self.model(f"{models[i].name}+{names[kk]}")
        return picked

    def _options_table(self, i: int) -> tuple[list[str], np.ndarray]:
        """(option names, cumulative rates) of model ``i`` (:meth:`options_of`), cached."""
        tab = self._option_tables.get(i)
        if tab is None:
            rates = self.options_of(self.models[i])
            tab = (list(rates), np.cumsum(list(rates.values())) if rates else np.zeros(0))
            self._option_tables[i] = tab
        return tab

    def with_models(self, models) -> "Catalog":
        """A copy restricted to the given models (names or VehicleModel objects)."""
        picked = [self.model(m) if isinstance(m, str) else m for m in models]
        return Catalog(models=tuple(picked), colors=self.colors, path=self.path,
                       option_rates=self.option_rates)


# --------------------------------------------------------------------------- loading
def load_catalog(path: str | Path | None = None) -> Catalog:
    """Load and validate a catalog YAML file.

    path : the catalog file; None = the bundled ``vehicle_assets/catalog.yaml``.
    Raises :class:`AssetError` (one line: file, entry, field, expected, got) on bad input.
    """

    p = bundled_catalog_path() if path is None else Path(path)
    if not p.is_file():
        raise AssetError(f"{p}: catalog file not found")
    data = load_yaml_file(p, shown(p), AssetError)  # nesting and alias budgets, a regular file
    return catalog_from_mapping(data, path=p)


def catalog_from_mapping(data: Any, path: Path | None = None) -> Catalog:
    """Build a :class:`Catalog` from the parsed YAML mapping. Mesh paths are resolved
    inside ``path``'s folder (or the current folder when path is None)."""
    where = str(path) if path is not None else "catalog"
    if not isinstance(data, Mapping):
        raise AssetError(
            f"{where}: expected a mapping with keys 'models' and 'colors', "
            f"got {type(data).__name__}"
        )
    unknown = set(data) - {"models", "colors", "version"}
    if unknown:
        raise AssetError(
            f"{where}: unknown top-level key(s) {sorted(map(str, unknown))}; expected models, colors, version"
        )
    if "version" in data and (isinstance(data["version"], bool) or data["version"] != CATALOG_VERSION):
        raise AssetError(
            f"{where}: version: expected {CATALOG_VERSION} (the catalog format this aerial-synth "
            f"reads), got {data['version']!r}"
        )
    folder = Path(os.path.realpath(path.parent if path is not None else "."))
    raw_colors = data.get("colors")
    raw_models = data.get("models")
    for key, val in (("colors", raw_colors), ("models", raw_models)):
        if not isinstance(val, list) or not val:
            got = "nothing" if val is None else repr(val)[:60]
            raise AssetError(f"{where}: {key}: expected a non-empty list, got {got}")
    colors = tuple(_parse_color(where, i, e) for i, e in enumerate(raw_colors))
    models = tuple(_parse_model(where, folder, i, e) for i, e in enumerate(raw_models))
    rates = {}
    for i, (m, e) in enumerate(zip(models, raw_models)):
        if "options" in e:
            rates[m.name] = _parse_options(where, _entry_name("models", i, e), m, e["options"])
    return Catalog(models=models, colors=colors, path=path, option_rates=rates)


def _parse_options(where: str, ent: str, model: VehicleModel, value: Any) -> dict[str, float]:
    """A model's ``options: {name: probability}`` (probabilities in [0, 1], sum <= 1)."""
    name = f"{where}: {ent} field options"
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise AssetError(f"{name}: expected a mapping of option: probability, got {value!r}")
    out = {}
    for k, p in value.items():
        fits = [o for o, bodies in OPTION_BODIES.items() if model.body in bodies]
        if k not in fits:
            raise AssetError(f"{name}: option {k!r} does not fit body {model.body!r}; expected one "
                             f"of {', '.join(fits) or 'none'}")
        if isinstance(p, bool) or not isinstance(p, (int, float)) or not (0.0 <= p <= 1.0):
            raise AssetError(f"{name}.{k}: expected a probability in [0, 1], got {p!r}")
        out[str(k)] = float(p)
    if sum(out.values()) > 1.0 + 1e-9:
        raise AssetError(f"{name}: expected probabilities that sum to at most 1, got {sum(out.values()):g}")
    return out


def _entry_name(kind: str, i: int, entry: Any) -> str:
    if isinstance(entry, Mapping) and isinstance(entry.get("name"), str):
        return f"{kind}[{i}] {entry['name']!r}"
    return f"{kind}[{i}]"


def _number(where: str, ent: str, entry: Mapping, key: str, default=None, positive=False,
            non_negative=False) -> float:
    val = entry.get(key, default)
    name = f"{where}: {ent} field {key}"
    if val is None:
        raise AssetError(f"{name}: expected a number, got nothing")
    if positive:
        return v.positive(name, val, error=AssetError)
    if non_negative:
        return v.non_negative(name, val, error=AssetError)
    return v.finite(name, val, error=AssetError)


def _string(where: str, ent: str, entry: Mapping, key: str, default=None) -> str:
    val = entry.get(key, default)
    if not isinstance(val, str) or not val:
        raise AssetError(f"{where}: {ent} field {key}: expected a non-empty string, got {val!r}")
    return val


def _parse_color(where: str, i: int, entry: Any) -> VehicleColor:
    ent = _entry_name("colors", i, entry)
    if not isinstance(entry, Mapping):
        raise AssetError(f"{where}: {ent}: expected a mapping, got {entry!r}")
    unknown = set(entry) - _COLOR_KEYS
    if unknown:
        raise AssetError(
            f"{where}: {ent}: unknown field(s) {sorted(map(str, unknown))}; expected {sorted(_COLOR_KEYS)}"
        )
    name = _string(where, ent, entry, "name")
    rgb = entry.get("rgb")
    if (
        not isinstance(rgb, (list, tuple))
        or len(rgb) != 3
        or not all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in rgb)
        or not all(0.0 <= c <= 1.0 for c in rgb)
    ):
        raise AssetError(f"{where}: {ent} field rgb: expected 3 numbers in [0, 1], got {rgb!r}")
    weight = _number(where, ent, entry, "weight", default=1.0, non_negative=True)
    return VehicleColor(name=name, rgb=tuple(float(c) for c in rgb), weight=weight)


def _parse_model(where: str, folder: Path, i: int, entry: Any) -> VehicleModel:
    ent = _entry_name("models", i, entry)
    if not isinstance(entry, Mapping):
        raise AssetError(f"{where}: {ent}: expected a mapping, got {entry!r}")
    name = _string(where, ent, entry, "name")
    if "+" in name:
        raise AssetError(f"{where}: {ent} field name: expected a name without '+' (it joins a "
                         f"model and a trim option), got {name!r}")
    is_mesh = "mesh" in entry
    allowed = _MESH_KEYS if is_mesh else _PROCEDURAL_KEYS
    unknown = set(entry) - allowed
    if unknown:
        hint = (
            " (a mesh entry takes its size from the mesh bounds; use scale)"
            if is_mesh and unknown & {"length_m", "width_m", "height_m"}
            else ""
        )
        raise AssetError(
            f"{where}: {ent}: unknown field(s) {sorted(map(str, unknown))}; expected {sorted(allowed)}{hint}"
        )
    cls = entry.get("class")
    if cls not in CLASSES:
        raise AssetError(
            f"{where}: {ent} field class: expected one of {', '.join(CLASSES)}, got {cls!r}"
        )
    weight = _number(where, ent, entry, "weight", default=1.0, non_negative=True)
    pack = entry.get("pack", 0)
    if not isinstance(pack, int) or isinstance(pack, bool) or pack < 0:
        raise AssetError(f"{where}: {ent} field pack: expected an integer >= 0, got {pack!r}")

    if not is_mesh:
        body = entry.get("body")
        if body not in BODIES.names():
            raise AssetError(
                f"{where}: {ent} field body: expected one of {', '.join(BODIES.names())}, got {body!r}"
            )
        dims = {
            k: _number(where, ent, entry, k, positive=True)
            for k in ("length_m", "width_m", "height_m")
        }
        return VehicleModel(name=name, pack=pack, cls=cls, weight=weight, body=body, **dims)

    rel = _string(where, ent, entry, "mesh")
    mesh_path = resolve_inside(folder, rel, f"{where}: {ent} field mesh")
    if mesh_path.suffix.lower() not in MESH_SUFFIXES:
        raise AssetError(
            f"{where}: {ent} field mesh: expected a {'/'.join(MESH_SUFFIXES)} file, got {rel!r}"
        )
    if not mesh_path.is_file():
        raise AssetError(f"{where}: {ent} field mesh: file not found: {rel!r} (looked in {folder})")
    scale = _number(where, ent, entry, "scale", default=1.0, positive=True)
    forward = entry.get("forward", "+x")
    up = entry.get("up", "+z")
    for key, val in (("forward", forward), ("up", up)):
        if val not in AXES:
            raise AssetError(
                f"{where}: {ent} field {key}: expected one of {', '.join(AXES)}, got {val!r}"
            )
    if abs(float(np.dot(AXES[forward], AXES[up]))) > 0.5:
        raise AssetError(
            f"{where}: {ent} fields forward/up: expected two different axes, got {forward} and {up}"
        )
    paint = entry.get("paint_material", "")
    if not isinstance(paint, str):
        raise AssetError(f"{where}: {ent} field paint_material: expected a string, got {paint!r}")


    try:
        parts = load_user_mesh_parts(mesh_path, scale=scale, forward=forward, up=up)
    except AssetError as exc:
        raise AssetError(f"{where}: {ent} field mesh: {exc}") from None
    v = np.concatenate([p.vertices for p in parts])
    size = v.max(axis=0) - v.min(axis=0)
    if not np.all(size > 0):
        raise AssetError(
            f"{where}: {ent} field mesh: expected a mesh with positive length, width and height, "
            f"got size {tuple(round(float(s), 4) for s in size)} m"
        )
    if paint and not any(p.material_name == paint for p in parts):
        names = sorted({p.material_name for p in parts if p.material_name})
        raise AssetError(
            f"{where}: {ent} field paint_material: no material {paint!r} in {rel!r}; "
            f"materials there: {', '.join(names) or 'none'}"
        )
    return VehicleModel(
        name=name,
        pack=pack,
        length_m=float(size[0]),
        width_m=float(size[1]),
        height_m=float(size[2]),
        cls=cls,
        weight=weight,
        source=f"mesh:{rel}",
        mesh_path=mesh_path,
        scale=scale,
        forward=forward,
        up=up,
        paint_material=paint,
    )


def resolve_inside(folder: Path, rel: str, what: str) -> Path:
    """Resolve ``rel`` inside ``folder``; refuse absolute paths and paths that escape it
    (``..``, or symlinks that lead outside)."""
    folder = Path(os.path.realpath(folder))  # a link loop resolves as far as it goes
    if Path(rel).is_absolute():
        raise AssetError(f"{what}: expected a path relative to {folder}, got absolute {rel!r}")
    p = Path(os.path.realpath(folder / rel))
    if not p.is_relative_to(folder):
        raise AssetError(f"{what}: expected a path inside {folder}, got {rel!r} which escapes it")
    return p
