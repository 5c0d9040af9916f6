"""Scene files: load glTF/GLB, OBJ and PLY with label rules; bundled specs; GLB export.

Loading never changes the data: trimesh is called with ``process=False`` and
``maintain_order=True`` (no vertex merging, no reordering). The glTF scene graph is walked
with each node's world transform; then units are scaled to metres and a y-up file is turned
z-up: (x, y, z)_file -> (x, -z, y)_world.

Label rules (YAML, see docs/scenes.md) map node/mesh names to labels with case-insensitive
globs or ``re:`` regular expressions; the first matching rule wins. A name that starts with
``<label>__`` (what :func:`export_glb` writes) takes that label before any rule. Names no
rule matches get the label ``unknown``; they are counted in ``scene.meta["unmatched"]`` and,
unless the rules file gives its own ``label_config``, ``unknown`` is added to the obstacle
set so placement keeps away from unlabelled geometry.
"""

from __future__ import annotations

import fnmatch
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import AerialSynthError, SceneError
from .model import (
    DEFAULT_COLOR_FOR_MATERIAL,
    DEFAULT_MATERIAL_FOR_LABEL,
    LABEL_IDS,
    LABELS,
    MATERIAL_IDS,
    LabelConfig,
    Scene,
    SceneObject,
)

__all__ = [
    "SCENES_DIR",
    "MESH_EXTENSIONS",
    "DEFAULT_RULES",
    "LabelRule",
    "LabelRules",
    "load_rules",
    "load_scene",
    "load_mesh_scene",
    "list_scenes",
    "export_glb",
]

#: Folder of the bundled scene specs (the package is installed editable).
# bundled data: aerial_synth/data/scenes (a link to the top-level scenes/ in a checkout,
# real files in a wheel)
SCENES_DIR = Path(__file__).resolve().parents[1] / "data" / "scenes"

MESH_EXTENSIONS = (".glb", ".gltf", ".obj", ".ply")
SPEC_EXTENSIONS = (".yaml", ".yml")

#: Built-in rules, tried in order after any user rules (case-insensitive globs).
DEFAULT_RULES: tuple[tuple[str, str], ...] = (
    ("lane_marking*", "lane_marking"),
    ("marking*", "lane_marking"),
    ("lane*", "lane_marking"),
    ("crosswalk*", "lane_marking"),
    ("road*", "road"),
    ("street*", "road"),
    ("asphalt*", "road"),
    ("highway*", "road"),
    ("sidewalk*", "sidewalk"),
    ("pavement*", "sidewalk"),
    ("footpath*", "sidewalk"),
    ("kerb*", "sidewalk"),
    ("curb*", "sidewalk"),
    ("parking*", "parking"),
    ("driveway*", "parking"),
    ("building*", "building"),
    ("house*", "building"),
    ("roof*", "building"),
    ("wall*", "building"),
    ("trunk*", "trunk"),
    ("tree*", "tree"),
    ("crown*", "tree"),
    ("foliage*", "tree"),
    ("leaves*", "tree"),
    ("bush*", "tree"),
    ("grass*", "ground"),
    ("ground*", "ground"),
    ("terrain*", "ground"),
    ("lawn*", "ground"),
    ("soil*", "ground"),
    ("water*", "water"),
    ("lake*", "water"),
    ("pond*", "water"),
    ("river*", "water"),
    ("pole*", "pole"),
    ("lamp*", "pole"),
    ("post*", "pole"),
    ("sign*", "pole"),
    ("vehicle*", "vehicle"),
    ("car*", "vehicle"),
)

_UNITS = {"m": 1.0, "metre": 1.0, "meter": 1.0, "cm": 0.01, "mm": 0.001, "km": 1000.0,
          "ft": 0.3048, "in": 0.0254}
_RULE_KEYS = {"match", "label", "material", "color"}
_TOP_KEYS = {"units", "up_axis", "rules", "include_defaults", "label_config", "default_label"}


@dataclass(frozen=True)
class LabelRule:
    """One rule: a glob (case-insensitive) or ``re:`` pattern -> label (+ material/colour)."""

    match: str
    label: str
    material: str | None = None
    color: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        if self.label not in LABEL_IDS:
            raise SceneError(
                f"label rule {self.match!r}: unknown label {self.label!r}; expected one of "
                f"{', '.join(LABELS)}"
            )
        if self.material is not None and self.material not in MATERIAL_IDS:
            raise SceneError(
                f"label rule {self.match!r}: unknown material {self.material!r}; expected one "
                f"of {', '.join(sorted(MATERIAL_IDS))}"
            )
        if self.match.startswith("re:"):
            try:
                pat = re.compile(self.match[3:], re.IGNORECASE)
            except re.error as exc:
                raise SceneError(f"label rule {self.match!r}: bad regular expression ({exc})") from None
        else:
            pat = re.compile(fnmatch.translate(self.match), re.IGNORECASE)
        object.__setattr__(self, "_pattern", pat)

    def matches(self, name: str) -> bool:
        pat = self._pattern  # type: ignore[attr-defined]
        if self.match.startswith("re:"):
            return pat.search(name) is not None
        return pat.match(name) is not None


@dataclass(frozen=True)
class LabelRules:
    """A parsed label-rules file.

    rules : user rules first, then (unless include_defaults is false) the built-in ones
    units_m : metres per file unit (None = the file's own convention: 1.0)
    up_axis : "y" or "z" (None = y for glTF/GLB, z for OBJ/PLY)
    label_config : probing sets, or None for the default (+ ``unknown`` as obstacle)
    default_label : label for names no rule matches
    """

    rules: tuple[LabelRule, ...]
    units_m: float | None = None
    up_axis: str | None = None
    label_config: LabelConfig | None = None
    default_label: str = "unknown"
    source: str = "built-in rules"

    def label_for(self, name: str) -> LabelRule | None:
        """The first rule matching ``name`` (a ``<label>__`` prefix wins), or None."""
        head, sep, _ = name.partition("__")
        if sep and head.lower() in LABEL_IDS:
            return LabelRule(match=f"{head}__*", label=head.lower())
        for r in self.rules:
            if r.matches(name):
                return r
        return None


def _default_rule_objects() -> tuple[LabelRule, ...]:
    return tuple(LabelRule(m, lab) for m, lab in DEFAULT_RULES)


def _read_yaml(path: Path, what: str) -> Any:
    import yaml

    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SceneError(f"{what} {path}: file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{what} {path}: cannot read ({exc})") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        problem = getattr(exc, "problem", None) or " ".join(str(exc).split())
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
        raise SceneError(f"{what} {path}: broken YAML ({where}{problem})") from None


def load_rules(path: str | Path | None) -> LabelRules:
    """Parse a label-rules YAML file; None gives the built-in rules."""
    if path is None:
        return LabelRules(rules=_default_rule_objects())
    path = Path(path)
    data = _read_yaml(path, "label rules")
    try:
        return _rules_from_mapping(data, str(path))
    except AerialSynthError as exc:
        msg = str(exc)
        if str(path) not in msg:
            msg = f"label rules {path}: {msg}"
        raise SceneError(msg) from None


def _rules_from_mapping(data: Any, where: str) -> LabelRules:
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise SceneError(f"expected a mapping with key 'rules', got {type(data).__name__}")
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise SceneError(f"unknown key(s) {sorted(unknown)}; expected {sorted(_TOP_KEYS)}")
    raw = data.get("rules") or []
    items: list[Mapping] = []
    if isinstance(raw, Mapping):  # compact form {pattern: label}
        items = [{"match": k, "label": v} for k, v in raw.items()]
    elif isinstance(raw, list):
        items = raw
    else:
        raise SceneError(f"'rules' must be a list or a mapping, got {type(raw).__name__}")
    rules = []
    for i, it in enumerate(items):
        if not isinstance(it, Mapping) or "match" not in it or "label" not in it:
            raise SceneError(f"rule {i}: expected a mapping with 'match' and 'label', got {it!r}")
        bad = set(it) - _RULE_KEYS
        if bad:
            raise SceneError(f"rule {i}: unknown key(s) {sorted(bad)}; expected {sorted(_RULE_KEYS)}")
        col = it.get("color")
        if col is not None:
            if not (isinstance(col, (list, tuple)) and len(col) == 3):
                raise SceneError(f"rule {i}: color must be [r, g, b] in 0..1, got {col!r}")
            col = tuple(float(c) for c in col)
        rules.append(LabelRule(str(it["match"]), str(it["label"]), it.get("material"), col))
    if data.get("include_defaults", True):
        rules.extend(_default_rule_objects())
    units = data.get("units")
    units_m = None
    if units is not None:
        if isinstance(units, str):
            if units.lower() not in _UNITS:
                raise SceneError(f"'units' must be a number or one of {sorted(_UNITS)}, got {units!r}")
            units_m = _UNITS[units.lower()]
        else:
            try:
                units_m = float(units)
            except (TypeError, ValueError):
                raise SceneError(f"'units' must be a number (metres per unit), got {units!r}") from None
            if not units_m > 0:
                raise SceneError(f"'units' must be > 0, got {units!r}")
    up = data.get("up_axis")
    if up is not None and str(up).lower() not in ("y", "z"):
        raise SceneError(f"'up_axis' must be 'y' or 'z', got {up!r}")
    lc = data.get("label_config")
    label_config = LabelConfig.from_mapping(lc) if lc else None
    default_label = str(data.get("default_label", "unknown"))
    if default_label not in LABEL_IDS:
        raise SceneError(f"'default_label' must be one of {', '.join(LABELS)}, got {default_label!r}")
    return LabelRules(
        rules=tuple(rules),
        units_m=units_m,
        up_axis=None if up is None else str(up).lower(),
        label_config=label_config,
        default_label=default_label,
        source=where,
    )


# --------------------------------------------------------------------------- meshes
def _yup_to_zup(v: np.ndarray) -> np.ndarray:
    """(n, 3) y-up (glTF) -> z-up world: (x, y, z) -> (x, -z, y)."""
    return np.column_stack([v[:, 0], -v[:, 2], v[:, 1]])


def _zup_to_yup(v: np.ndarray) -> np.ndarray:
    """(n, 3) z-up world -> y-up (glTF): (x, y, z) -> (x, z, -y)."""
    return np.column_stack([v[:, 0], v[:, 2], -v[:, 1]])


def _material_and_color(geom) -> tuple[str | None, tuple[float, float, float] | None]:
    """Material name (if one of ours) and base colour of a trimesh geometry, if any."""
    vis = getattr(geom, "visual", None)
    mat = getattr(vis, "material", None)
    name = getattr(mat, "name", None)
    name = name if isinstance(name, str) and name in MATERIAL_IDS else None
    col = None
    extras = (getattr(geom, "metadata", None) or {}).get("extras") or {}
    if isinstance(extras, Mapping) and isinstance(extras.get("color"), (list, tuple)):
        try:
            col = tuple(float(c) for c in extras["color"][:3])
        except (TypeError, ValueError):
            col = None
    if col is None and mat is not None:
        bcf = getattr(mat, "baseColorFactor", None)
        if bcf is not None and len(bcf) >= 3:
            c = np.asarray(bcf[:3], float)
            if c.max() > 1.0:
                c = c / 255.0
            col = tuple(float(x) for x in np.clip(c, 0, 1))
    return name, col


def _trimesh_load(path: Path):
    import trimesh

    kw = {}
    if path.suffix.lower() == ".obj":
        # one geometry per `o` object, named after it; no material grouping
        kw = {"split_objects": True, "group_material": False}
    return trimesh.load(str(path), force="scene", process=False, maintain_order=True, **kw)


def _drop_unused(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Remove vertices no face uses, keeping the order of the others (OBJ objects share
    one vertex list). v: (n, 3), f: (m, 3) -> compacted copies."""
    used = np.zeros(len(v), bool)
    used[f.ravel()] = True
    if used.all():
        return v, f
    new_index = np.cumsum(used) - 1
    return v[used], new_index[f]


def load_mesh_scene(path: str | Path, labels: str | Path | None = None) -> Scene:
    """Load a glTF/GLB, OBJ or PLY file as a labelled :class:`Scene`.

    path   : the mesh file
    labels : label-rules YAML; default ``<stem>.labels.yaml`` next to the file, else the
             built-in rules
    Raises :class:`SceneError` for a missing or corrupt file, a bad rules file, or a scene
    without any ``road`` geometry.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in MESH_EXTENSIONS:
        raise SceneError(
            f"scene file {path}: unsupported extension {path.suffix or '(none)'!r}; expected "
            f"one of {', '.join(MESH_EXTENSIONS + SPEC_EXTENSIONS)} or a bundled scene name"
        )
    if not path.is_file():
        raise SceneError(f"scene file {path}: file not found")
    if labels is None:
        sidecar = path.with_name(path.stem + ".labels.yaml")
        labels = sidecar if sidecar.is_file() else None
    rules = load_rules(labels)
    try:
        tscene = _trimesh_load(path)
    except Exception as exc:  # trimesh raises many types for corrupt input
        msg = " ".join(str(exc).split())[:200]
        raise SceneError(
            f"scene file {path}: cannot read as {ext[1:].upper()} ({type(exc).__name__}: {msg})"
        ) from None
    up = rules.up_axis or ("y" if ext in (".glb", ".gltf") else "z")
    scale = rules.units_m or 1.0

    objects: list[SceneObject] = []
    unmatched: list[str] = []
    geom_names = list(tscene.geometry)
    graph = tscene.graph
    by_geom: dict[str, list[str]] = {g: [] for g in geom_names}
    for node in graph.nodes_geometry:
        _, g = graph[node]
        by_geom.setdefault(g, []).append(node)
    used: set[str] = set()
    for g in geom_names:
        geom = tscene.geometry[g]
        if not hasattr(geom, "faces") or geom.faces is None or len(geom.faces) == 0:
            continue  # point clouds, paths
        nodes = sorted(by_geom.get(g, [])) or [None]
        mat_name, col = _material_and_color(geom)
        for node in nodes:
            if node is None:
                T = np.eye(4)
                name = g
            else:
                T, _ = graph[node]
                name = node
            v = np.asarray(geom.vertices, np.float64)
            if not np.allclose(T, np.eye(4)):
                v = v @ np.asarray(T, float)[:3, :3].T + np.asarray(T, float)[:3, 3]
            if up == "y":
                v = _yup_to_zup(v)
            if scale != 1.0:
                v = v * scale
            rule = rules.label_for(name) or (rules.label_for(g) if g != name else None)
            if rule is None:
                label = rules.default_label
                unmatched.append(name)
                material, color = mat_name, col
            else:
                label = rule.label
                material = rule.material or mat_name
                color = rule.color if rule.color is not None else col
            if material is None:
                material = DEFAULT_MATERIAL_FOR_LABEL[label]
            if color is None:
                color = DEFAULT_COLOR_FOR_MATERIAL[material]
            head, sep, rest = name.partition("__")
            oname = rest if (sep and rest and head.lower() in LABEL_IDS) else name
            base_name, k = oname, 1
            while oname in used:
                oname, k = f"{base_name}.{k}", k + 1
            used.add(oname)
            faces = np.asarray(geom.faces, np.int64)
            v, faces = _drop_unused(v, faces)
            if np.linalg.det(np.asarray(T, float)[:3, :3]) < 0:
                faces = faces[:, ::-1]  # mirrored node: keep counter-clockwise winding
            try:
                objects.append(SceneObject(oname, label, v, faces, material, color))
            except AerialSynthError as exc:
                raise SceneError(f"scene file {path}: {exc}") from None
    if not any(o.label == "road" for o in objects):
        names = ", ".join(sorted({o.name for o in objects})[:6]) or "(no meshes)"
        raise SceneError(
            f"scene file {path}: no 'road' geometry after applying {rules.source}; expected at "
            f"least one node/mesh labelled road (names seen: {names})"
        )
    lc = rules.label_config
    if lc is None:
        base = LabelConfig()
        lc = LabelConfig(
            road=base.road,
            drivable=base.drivable,
            obstacles=base.obstacles | {"unknown"},
            ignore=base.ignore,
        )
    meta = {
        "file": str(path),
        "labels_file": str(labels) if labels is not None else None,
        "up_axis": up,
        "units_m": scale,
        "unmatched": unmatched,
        "n_unmatched": len(unmatched),
    }
    return Scene(name=path.stem, objects=objects, source=str(path), label_config=lc, meta=meta)


# --------------------------------------------------------------------------- specs
def list_scenes() -> list[str]:
    """Names of the bundled scenes (``scenes/*.yaml``), sorted."""
    if not SCENES_DIR.is_dir():
        return []
    return sorted(p.stem for p in SCENES_DIR.glob("*.yaml") if not p.name.endswith(".labels.yaml"))


def _load_spec(path: Path, seed: int | None) -> Scene:
    from .procedural import generate

    data = _read_yaml(path, "scene spec")
    if not isinstance(data, Mapping):
        raise SceneError(f"scene spec {path}: expected a mapping, got {type(data).__name__}")
    return generate(data, seed=seed, source=str(path))


def load_scene(
    name_or_path: str | Path,
    labels: str | Path | None = None,
    seed: int | None = None,
) -> Scene:
    """Load a bundled scene by name, a scene spec (.yaml) or a mesh file (.glb/.gltf/.obj/.ply).

    labels : label-rules YAML for mesh files (default: sidecar ``NAME.labels.yaml``, else
             the built-in rules); ignored for procedural specs
    seed   : overrides a procedural spec's seed (0 is a valid seed); ignored for meshes
    """
    s = str(name_or_path)
    p = Path(s)
    if p.suffix.lower() in SPEC_EXTENSIONS:
        if not p.is_file():
            raise SceneError(f"scene spec {p}: file not found")
        return _load_spec(p, seed)
    if p.suffix or "/" in s or "\\" in s or p.exists():
        return load_mesh_scene(p, labels)
    spec = SCENES_DIR / f"{s}.yaml"
    if not spec.is_file():
        avail = ", ".join(list_scenes()) or "(none)"
        raise SceneError(
            f"scene {s!r}: not a bundled scene name and not a file; expected one of {avail} "
            f"or a path to a .glb/.gltf/.obj/.ply/.yaml file"
        )
    return _load_spec(spec, seed)


# --------------------------------------------------------------------------- export
def export_glb(scene: Scene, path: str | Path) -> Path:
    """Write ``scene`` as a binary glTF (y-up, metres), atomically.

    Every node and mesh is named ``<label>__<object name>`` and its glTF material is named
    after the object's material with the object's colour as baseColorFactor (the exact
    float colour also goes into the mesh extras). Loading the file again with the built-in
    rules gives the same objects, labels, materials and triangles (vertices as float32).
    """
    import trimesh

    from ..io_utils import atomic_write_bytes

    path = Path(path)
    ts = trimesh.Scene()
    for o in scene.objects:
        if not o.n_triangles:
            continue
        m = trimesh.Trimesh(vertices=_zup_to_yup(o.vertices), faces=o.faces, process=False)
        rgba = list(o.color) + [1.0]
        m.visual = trimesh.visual.TextureVisuals(
            material=trimesh.visual.material.PBRMaterial(
                name=o.material, baseColorFactor=rgba, metallicFactor=0.0, roughnessFactor=1.0
            )
        )
        m.metadata["extras"] = {"label": o.label, "color": list(o.color)}
        nm = f"{o.label}__{o.name}"
        ts.add_geometry(m, node_name=nm, geom_name=nm)
    try:
        data = ts.export(file_type="glb")
    except Exception as exc:
        raise SceneError(f"export {path}: cannot write GLB ({type(exc).__name__}: {exc})") from None
    return atomic_write_bytes(path, data)
