"""Scene files: load glTF/GLB, OBJ and PLY with label rules; bundled specs; GLB export.

Loading never changes the data: trimesh is called with ``process=False`` and
``maintain_order=True`` (no vertex merging, no reordering). The glTF scene graph is walked
with each node's world transform; then units are scaled to metres and a y-up file is turned
z-up: (x, y, z)_file -> (x, -z, y)_world.

Label rules (:mod:`.label_rules`, docs/scenes.md) map node/mesh names to labels; names no
rule matches get the label ``unknown``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import AerialSynthError, SceneError
from ..io_utils import atomic_write_bytes
from ..safe_input import quote, shown
from .georef import (
    FAR_M,
    SceneWarning,
    check_crs,
    choose_origin,
    float32_step_m,
    origin_fits,
    parse_origin,
)
from .hints import META_KEY, extras_for, meta_from_extras
from .label_rules import load_rules, read_yaml
from .model import (
    DEFAULT_COLOR_FOR_MATERIAL,
    DEFAULT_MATERIAL_FOR_LABEL,
    LABEL_IDS,
    MATERIAL_IDS,
    LabelConfig,
    Scene,
    SceneObject,
)
from .osm import load_osm_scene
from .osm.read import is_osm_path
from .procedural import generate
from .scene_hints import SceneHints

__all__ = [
    "SCENES_DIR",
    "MESH_EXTENSIONS",
    "load_rules",
    "load_scene",
    "load_mesh_scene",
    "list_scenes",
    "export_glb",
    "read_yaml",
]

#: Folder of the bundled scene specs (the package is installed editable).
# bundled data: aerial_synth/data/scenes (a link to the top-level scenes/ in a checkout,
# real files in a wheel)
SCENES_DIR = Path(__file__).resolve().parents[1] / "data" / "scenes"

MESH_EXTENSIONS = (".glb", ".gltf", ".obj", ".ply")
SPEC_EXTENSIONS = (".yaml", ".yml")

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


#: Key of the scene-level glTF extras that :func:`export_glb` writes and the loader reads.
GLTF_EXTRAS_KEY = "aerial_synth"


def _gltf_georef_extras(tscene) -> tuple[Any, Any]:
    """(origin, crs) found in a glTF file's scene extras, each None when absent.

    ``crs`` may sit at the top of the scene extras (``{"crs": "EPSG:32632"}``, as other
    tools write it) or under our key; ``origin`` only under our key (written by export).
    """
    meta = getattr(tscene, "metadata", None) or {}
    ours = meta.get(GLTF_EXTRAS_KEY) if isinstance(meta, Mapping) else None
    ours = ours if isinstance(ours, Mapping) else {}
    crs = ours.get("crs", meta.get("crs") if isinstance(meta, Mapping) else None)
    return ours.get("origin"), crs


def _georeference(path: Path, tscene, rules, items, raw_max_m: float, ext: str):
    """The local frame's origin and the CRS of a mesh file (see scene/georef.py).

    items: [(geom, node, v_without_translation (n, 3), translation (3,), ...)], z-up metres.
    The origin is the one stored by :func:`export_glb` (glTF extras) when it keeps the local
    bounds within ``FAR_M`` of 0, else :func:`~.georef.choose_origin` of the float64 bounds.
    The CRS comes from the labels file's ``crs`` key, else the glTF extras ``crs``.
    """
    import warnings


    pts = [v.min(axis=0) + t for _, _, v, t, *_ in items if len(v)]
    pts += [v.max(axis=0) + t for _, _, v, t, *_ in items if len(v)]
    if pts:
        lo, hi = np.min(pts, axis=0), np.max(pts, axis=0)
    else:
        lo = hi = np.zeros(3)
    stored_origin, stored_crs = (None, None)
    if ext in (".glb", ".gltf"):
        stored_origin, stored_crs = _gltf_georef_extras(tscene)
    origin = None
    if stored_origin is not None:
        o = parse_origin(stored_origin, f"scene file {path}: glTF extras {GLTF_EXTRAS_KEY}.origin")
        if origin_fits(lo, hi, o):
            origin = o
    if origin is None:
        origin = choose_origin(lo, hi)
    if ext in (".glb", ".gltf") and raw_max_m > FAR_M:
        warnings.warn(
            f"scene file {path}: vertex coordinates up to {raw_max_m:.0f} m are stored as "
            f"float32 in the file, which resolves only {float32_step_m(raw_max_m):.2g} m there; "
            f"georeferenced glTF should keep vertices local and put the offset in the node "
            f"translation",
            SceneWarning,
            stacklevel=3,
        )
    crs = None
    if rules.crs is not None:
        crs = rules.crs
    elif stored_crs is not None:
        crs = check_crs(stored_crs, f"scene file {path}: glTF extras crs")
    return origin, crs


#: Largest coordinate (metres) a scene file may place geometry at, after its node transforms
#: and units: 100,000 km, far beyond any map projection's coordinates of the Earth (a UTM
#: northing is below 10,000 km), far below where float64 arithmetic overflows.
MAX_COORD_M = 1e8


def _check_plausible(path: Path, name: str, v: np.ndarray, t: np.ndarray) -> None:
    """Refuse a node whose transformed vertices or translation are not finite or lie
    beyond :data:`MAX_COORD_M` (a translation of 1e308 overflowed later, in the georeference)."""
    for what, arr in (("translation", t), ("transformed vertices", v)):
        a = np.abs(np.asarray(arr, np.float64))
        with np.errstate(invalid="ignore", over="ignore"):
            worst = float(a.max()) if a.size else 0.0
        if not np.isfinite(a).all() or worst > MAX_COORD_M:
            raise SceneError(f"scene file {shown(path)}: node {quote(name)}: expected {what} within "
                             f"{MAX_COORD_M:g} m of the origin (finite), got {worst:g}")


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
        if os.path.lexists(sidecar):  # found, not named: it must not lead out of the folder
            rules = load_rules(sidecar, root=path.parent)
        else:
            rules = load_rules(None)
    else:
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

    # pass 1: every node's vertices in the z-up metre frame, *without* its translation
    # (float64), and the translation apart, so the origin can be taken off the translation
    # before the two meet: a georeferenced glTF (float32 vertices near 0, the UTM offset in
    # a float64 node translation) then loads bit-identically to the unshifted file.
    items, raw_max = _mesh_items(path, tscene, up, scale)
    origin, crs = _georeference(path, tscene, rules, items, raw_max * scale, ext)

    # pass 2: labels, names and the local vertices
    objects, unmatched = _labelled_objects(path, items, origin, rules)
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

    extra = meta_from_extras(getattr(tscene, "metadata", None), origin, f"scene file {path}")
    roads = extra.pop(META_KEY, None)
    meta.update(extra)
    return Scene(
        name=path.stem, objects=objects, source=str(path), label_config=lc, meta=meta,
        origin=origin, crs=crs, hints=SceneHints(roads=roads),
    )


def _mesh_items(path: Path, tscene, up: str, scale: float) -> tuple[list, float]:
    """Every node's mesh of ``tscene``: ``(geometry name, node name, vertices (n, 3) float64
    in the z-up metre frame without the node's translation, translation (3,), faces (m, 3),
    material, colour)``, and the largest absolute raw vertex coordinate (file units)."""
    items = []
    raw_max = 0.0
    geom_names = list(tscene.geometry)
    graph = tscene.graph
    by_geom: dict[str, list[str]] = {g: [] for g in geom_names}
    for node in graph.nodes_geometry:
        _, g = graph[node]
        by_geom.setdefault(g, []).append(node)
    for g in geom_names:
        geom = tscene.geometry[g]
        if not hasattr(geom, "faces") or geom.faces is None or len(geom.faces) == 0:
            continue  # point clouds, paths
        nodes = sorted(by_geom.get(g, [])) or [None]
        mat_name, col = _material_and_color(geom)
        raw = np.asarray(geom.vertices, np.float64)
        for node in nodes:
            if node is None:
                T = np.eye(4)
                name = g
            else:
                T, _ = graph[node]
                name = node
            T = np.asarray(T, np.float64)
            faces = np.asarray(geom.faces, np.int64)
            v, faces = _drop_unused(raw, faces)
            bad = ~np.isfinite(v).all(axis=1)
            if bad.any():
                i = int(np.argmax(bad))
                raise SceneError(
                    f"scene file {path}: mesh {name!r}: expected finite vertex coordinates, got "
                    f"{v[i].tolist()} at vertex {i}"
                )
            if len(v):
                raw_max = max(raw_max, float(np.abs(v).max()))
            R, t = T[:3, :3], T[:3, 3].copy()
            if not np.isfinite(T).all():
                raise SceneError(f"scene file {path}: node {name!r}: transform is not finite")
            if not np.array_equal(R, np.eye(3)):
                v = v @ R.T
            if up == "y":
                v = _yup_to_zup(v)
                t = _yup_to_zup(t[None])[0]
            if scale != 1.0:
                v = v * scale
                t = t * scale
            _check_plausible(path, name, v, t)
            if np.linalg.det(R) < 0:
                faces = faces[:, ::-1]  # mirrored node: keep counter-clockwise winding
            items.append((g, name, v, t, faces, mat_name, col))
    return items, raw_max


def _labelled_objects(path: Path, items: list, origin, rules) -> tuple[list, list]:
    """The scene objects of :func:`_mesh_items`' items (local frame: ``origin`` taken off),
    labelled by ``rules``; and the names no rule matched."""
    objects: list[SceneObject] = []
    unmatched: list[str] = []
    used: set[str] = set()
    o = np.asarray(origin, np.float64)
    for g, name, v, t, faces, mat_name, col in items:
        shift = t - o
        if shift.any():
            v = v + shift
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
        try:
            objects.append(SceneObject(oname, label, v, faces, material, color))
        except AerialSynthError as exc:
            raise SceneError(f"scene file {path}: {exc}") from None
    return objects, unmatched


# --------------------------------------------------------------------------- specs
def list_scenes() -> list[str]:
    """Names of the bundled scenes (``scenes/*.yaml``), sorted."""
    if not SCENES_DIR.is_dir():
        return []
    return sorted(p.stem for p in SCENES_DIR.glob("*.yaml") if not p.name.endswith(".labels.yaml"))


def _load_spec(path: Path, seed: int | None) -> Scene:
    data = read_yaml(path, "scene spec")
    if not isinstance(data, Mapping):
        raise SceneError(f"scene spec {path}: expected a mapping, got {type(data).__name__}")
    return generate(data, seed=seed, source=str(path))


def load_scene(
    name_or_path: str | Path,
    labels: str | Path | None = None,
    seed: int | None = None,
    bbox=None,
    crs: str | None = None,
) -> Scene:
    """Load a bundled scene by name, a scene spec (.yaml), a mesh file (.glb/.gltf/.obj/.ply)
    or an OpenStreetMap extract (.osm/.osm.bz2/.osm.pbf; built once, then cached, see
    :func:`aerial_synth.scene.osm.load_osm_scene`).

    labels : label-rules YAML for mesh files (default: sidecar ``NAME.labels.yaml``, else
             the built-in rules); refused (SceneError) for procedural specs
    seed   : overrides a procedural spec's seed (0 is a valid seed); ignored for meshes
    bbox   : OSM only: "MINLON,MINLAT,MAXLON,MAXLAT" (or 4 numbers) to cut the extract
    crs    : OSM only: projected CRS to build in (default: the local UTM zone)
    """
    s = str(name_or_path)
    if not s.strip():  # Path('') would be the current folder: "scene file .: unsupported ..."
        raise SceneError(f"scene: expected a bundled scene name or a scene file, got {quote(s)}")
    p = Path(s)

    if is_osm_path(s):
        if labels is not None:
            raise SceneError(f"--labels {labels}: label rules apply to mesh files; {s!r} is an "
                             f"OSM extract whose features are labelled by their tags; drop --labels")
        return load_osm_scene(p, bbox=bbox, crs=crs, seed=0 if seed is None else seed)
    if bbox is not None or crs is not None:
        raise SceneError(f"--bbox/--crs apply to OSM extracts (.osm, .osm.bz2, .osm.pbf), but "
                         f"{s!r} is not one; drop them")
    if p.suffix.lower() in SPEC_EXTENSIONS:
        if not p.is_file():
            raise SceneError(f"scene spec {p}: file not found")
        _no_labels_for_spec(labels, s)
        return _load_spec(p, seed)
    if p.suffix or "/" in s or "\\" in s or p.exists():
        if seed is not None:  # a mesh's geometry is fixed: a seed would be silently ignored
            raise SceneError(f"--scene-seed {seed}: applies to procedural scene specs and OSM "
                             f"extracts, but {quote(s)} is a mesh file; drop --scene-seed")
        return load_mesh_scene(p, labels)
    spec = SCENES_DIR / f"{s}.yaml"
    if not spec.is_file():
        avail = ", ".join(list_scenes()) or "(none)"
        raise SceneError(
            f"scene {s!r}: not a bundled scene name and not a file; expected one of {avail} "
            f"or a path to a .glb/.gltf/.obj/.ply/.yaml file"
        )
    _no_labels_for_spec(labels, s)
    return _load_spec(spec, seed)


def _no_labels_for_spec(labels, scene: str) -> None:
    """A label-rules file names mesh nodes; a procedural scene has none to label: refuse it
    rather than ignore it silently."""
    if labels is not None:
        raise SceneError(
            f"--labels {labels}: label rules apply to mesh files (.glb/.gltf/.obj/.ply), but "
            f"{scene!r} is a procedural scene spec whose objects are labelled already; drop --labels"
        )


# --------------------------------------------------------------------------- export
def export_glb(scene: Scene, path: str | Path) -> Path:
    """Write ``scene`` as a binary glTF (y-up, metres), atomically.

    Every node and mesh is named ``<label>__<object name>`` and its glTF material is named
    after the object's material with the object's colour as baseColorFactor (the exact
    float colour also goes into the mesh extras). Loading the file again with the built-in
    rules gives the same objects, labels, materials and triangles (vertices as float32).

    Georeference: vertices stay in the scene's local frame; a non-zero ``scene.origin`` is
    written as every node's translation (float64 in the glTF JSON, so other tools see the
    original frame) and, with ``scene.crs``, into the scene extras under ``aerial_synth``
    (``{"origin": [x, y, z], "crs": ...}``, z-up metres). The loader takes that origin off the
    translation again, so the reload has the same local vertices, origin and CRS.
    """
    import trimesh


    path = Path(path)
    ts = trimesh.Scene()
    origin = np.asarray(scene.origin, np.float64).reshape(3)
    node_T = None
    if origin.any():
        node_T = np.eye(4)
        node_T[:3, 3] = _zup_to_yup(origin[None])[0]
    georef = {}
    if origin.any():
        georef["origin"] = [float(c) for c in origin]
    if scene.crs is not None:
        georef["crs"] = scene.crs
    if georef:
        ts.metadata[GLTF_EXTRAS_KEY] = georef

    ts.metadata.update(extras_for(scene))  # OSM direction hints and attribution (hints.py)
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
        ts.add_geometry(m, node_name=nm, geom_name=nm, transform=node_T)
    try:
        data = ts.export(file_type="glb")
    except Exception as exc:
        raise SceneError(f"export {path}: cannot write GLB ({type(exc).__name__}: {exc})") from None
    return atomic_write_bytes(path, data)
