"""Import structure: imports go down one package order (:data:`LAYERS`), no import cycles
between modules, no private name or another package's private module imported, and a light
top-level import (``aerial-synth --help`` stays instant).

Every import is seen: module level, inside functions and classes, in ``__init__`` files,
relative and absolute (the whole tree is parsed with :mod:`ast`)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import aerial_synth

PKG_DIR = Path(aerial_synth.__file__).resolve().parent


def _module_name(path: Path) -> str:
    rel = path.relative_to(PKG_DIR.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in PKG_DIR.rglob("*.py") if "data" not in p.parts}


def _import_records(name: str, path: Path, known: set[str]):
    """``(target module, imported name or None, line)`` for every import of an aerial_synth
    module in ``name``: module level, inside functions and classes, relative and absolute.
    ``from pkg import sub`` imports the submodule ``pkg.sub`` (name None) when there is one."""
    is_pkg = path.name == "__init__.py"
    base = name.split(".") if is_pkg else name.split(".")[:-1]
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            targets = [(a.name, None) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                anchor = base[: len(base) - (node.level - 1)]
                mod = ".".join(anchor + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            targets = [(f"{mod}.{a.name}", None) if f"{mod}.{a.name}" in known else (mod, a.name)
                       for a in node.names]
        else:
            continue
        for target, imported in targets:
            if target in known and target != name:
                yield target, imported, node.lineno


def _imports(name: str, path: Path, known: set[str]) -> set[str]:
    """Every aerial_synth module that ``name`` imports, at module level or inside functions."""
    return {t for t, _, _ in _import_records(name, path, known)}


def _graph():
    mods = _modules()
    known = set(mods)
    return {m: _imports(m, p, known) for m, p in mods.items()}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def _package_edges_only(graph):
    """Drop edges from a package's __init__ to its own submodules (re-exports, not cycles)."""
    mods = _modules()
    out = {}
    for m, deps in graph.items():
        is_pkg = mods[m].name == "__init__.py"
        out[m] = {d for d in deps if not (is_pkg and d.startswith(m + "."))}
    return out


def test_the_graph_sees_known_imports():
    g = _graph()
    assert "aerial_synth.errors" in g["aerial_synth.validators"]
    assert "aerial_synth.vehicles.model" in g["aerial_synth.vehicles.catalog"]
    assert "aerial_synth.camera_rays" in g["aerial_synth.camera"]  # import inside a method


def test_no_import_cycles():
    cycles = _cycles(_package_edges_only(_graph()))
    assert cycles == [], f"import cycles: {cycles}"


def test_no_module_imports_another_packages_private_module():
    bad = []
    for m, deps in _graph().items():
        for d in deps:
            parts = d.split(".")
            private = [i for i, p in enumerate(parts) if p.startswith("_") and p != "__init__"]
            if not private:
                continue
            owner = ".".join(parts[: private[0]])  # the package that holds the private module
            if not (m == owner or m.startswith(owner + ".")):
                bad.append(f"{m} -> {d}")
    assert bad == [], bad


def test_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_top_level_import_stays_light():
    code = ("import sys, aerial_synth.cli as c; c.build_parser(); "
            "heavy = [m for m in ('open3d', 'cv2', 'trimesh', 'numba', 'shapely', 'scipy', "
            "'pyrender', 'osmium', 'dask') if m in sys.modules]; print(','.join(heavy))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"heavy modules imported by the CLI parser: {out.stdout}"


# --- the package order ----------------------------------------------------------------------

#: Components of the package, lowest first. A module may import modules of its own component
#: and of components on a lower line; never one on a higher line or another on its own line.
#: A component is ``aerial_synth.X`` for the top-level module or package X, except that
#: ``aerial_synth.cli`` and every package's command module (``*.cli``, ``*_cli``) form "cli".
#: The root package ``aerial_synth`` holds only ``__version__``.
LAYERS = (
    ("aerial_synth", "errors", "numba_setup", "_open3d", "lazy", "registry"),  # leaves: import nothing of ours
    ("validators", "io_utils", "png", "versions", "safe_input", "memory"),  # field checks, atomic
    # writes, PNG, versions, hostile-input guards (budgeted YAML/JSON, links, image headers),
    # the memory a process may still take
    ("out_guard",),  # the --out lock and refusals shared by every writing command
    ("annotate", "camera_rays"),  # mask -> oriented box; pixel rays (numba)
    ("camera",),  # pinhole model, poses
    ("scene",),  # labelled meshes, RayScene, procedural and OSM scenes, tiles
    ("vehicles",),  # catalog and vehicle meshes (stand on a scene's ground)
    ("placement",),  # line traces and parking on a scene -> Placement
    ("render",),  # frame buffers and RGB of scene + placed vehicles
    ("formats",),  # label files (registry of DOTA, EAGLE, YOLO-OBB, COCO, meta)
    ("dataset", "evaluate"),  # export orchestration | measurement (an island, see below)
    ("stream",),  # an export's samples in memory: iter_samples, shards, a torch dataset
    ("sim2real",),  # trains a detector on exports, scores it on real images through evaluate
    ("cli",),  # aerial_synth.cli and every package's command module
)
#: ``evaluate`` stands beside the pipeline: it reads label files, so it may import only
#: these components, and only sim2real and the cli import it.
EVALUATE_MAY_IMPORT = {"formats", "annotate", "camera_rays", "validators", "io_utils", "png",
                       "safe_input", "out_guard", "memory",
                       "aerial_synth", "errors", "numba_setup", "_open3d", "lazy", "registry"}
_RANK = {c: i for i, line in enumerate(LAYERS) for c in line}

#: Edges that break the order inside the packages of PART B of issue 26 (dataset engines,
#: render backends, formats/evaluate, cli). Each entry is one edge, "importer -> imported" or,
#: for a private name, "importer -> module:name". Delete entries as that work is merged; the
#: test fails on an entry that no longer occurs, so the list can only shrink.
KNOWN_PART_B: set[str] = set()  # emptied when arch-b (engines, public fork-server helpers) merged


def _component(module: str) -> str:
    parts = module.split(".")
    if parts[-1] == "cli" or parts[-1].endswith("_cli"):
        return "cli"
    return parts[1] if len(parts) > 1 else parts[0]


def _order_violations(records: dict[str, list[tuple[str, str | None, int]]],
                      is_package: dict[str, bool]) -> list[str]:
    """Every import in ``records`` (``{importer: [(imported module, name, line)]}``) that goes
    up :data:`LAYERS`, sideways, into ``evaluate`` from outside the cli, out of ``evaluate``
    beyond :data:`EVALUATE_MAY_IMPORT`, back into the importer's own package ``__init__``, or
    takes a private name (``_x``) from another module. One ``"a -> b"`` string per edge."""
    bad: list[str] = []
    for src, recs in sorted(records.items()):
        cs = _component(src)
        for dst, name, _line in recs:
            cd = _component(dst)
            edge = f"{src} -> {dst}"
            if name and name.startswith("_") and not name.startswith("__"):
                bad.append(f"{edge}:{name}")
            if cs != cd:
                if _RANK[cd] >= _RANK[cs]:  # up, or sideways on one line
                    bad.append(edge)
                elif cs == "evaluate" and cd not in EVALUATE_MAY_IMPORT:
                    bad.append(edge)
            elif dst != "aerial_synth" and src.startswith(dst + ".") and is_package.get(dst):
                bad.append(edge)  # a submodule imports its own package's __init__: upward
    return sorted(set(bad))


def _records():
    mods = _modules()
    known = set(mods)
    recs = {m: list(_import_records(m, p, known)) for m, p in mods.items()}
    return recs, {m: p.name == "__init__.py" for m, p in mods.items()}


def test_every_component_has_a_place_in_the_order():
    assert {_component(m) for m in _modules()} <= set(_RANK)


def test_imports_go_down_the_package_order():
    found = _order_violations(*_records())
    new = [e for e in found if e not in KNOWN_PART_B]
    assert new == [], "imports against the package order (tests/foundation/test_imports.py " \
        "LAYERS; move the code down or the import up):\n" + "\n".join(new)
    stale = sorted(KNOWN_PART_B - set(found))
    assert stale == [], "fixed, delete from KNOWN_PART_B:\n" + "\n".join(stale)


def test_order_check_sees_upward_sideways_private_and_package_edges():
    recs = {
        "aerial_synth.scene.io": [("aerial_synth.dataset.export", None, 9),  # upward, in a function
                                  ("aerial_synth.errors", None, 3)],  # down: fine
        "aerial_synth.scene.procedural.spec": [("aerial_synth.scene.procedural", "GENERATORS", 5)],
        "aerial_synth.scene.tiles": [("aerial_synth.scene.io", "_read_yaml", 4)],
        "aerial_synth.dataset.export": [("aerial_synth.evaluate.ap", None, 1)],  # sideways
        "aerial_synth.evaluate.ap": [("aerial_synth.scene.model", None, 1),  # beyond its list
                                     ("aerial_synth.formats.dota", None, 2)],  # allowed
        "aerial_synth.evaluate.cli": [("aerial_synth.evaluate.ap", None, 1)],
        "aerial_synth.cli": [("aerial_synth", "__version__", 1)],
    }
    pkgs = {"aerial_synth.scene.procedural": True, "aerial_synth": True}
    assert _order_violations(recs, pkgs) == [
        "aerial_synth.dataset.export -> aerial_synth.evaluate.ap",
        "aerial_synth.evaluate.ap -> aerial_synth.scene.model",
        "aerial_synth.scene.io -> aerial_synth.dataset.export",
        "aerial_synth.scene.procedural.spec -> aerial_synth.scene.procedural",
        "aerial_synth.scene.tiles -> aerial_synth.scene.io:_read_yaml",
    ]


#: Packages whose function-local imports of our own modules are all justified (issue 26:
#: at most 40 in the whole package, each with a reason). PART B's packages join after merging.
LAZY_CHECKED = ("scene", "vehicles", "placement", "annotate", "errors", "validators", "io_utils",
                "png", "numba_setup", "_open3d", "camera_rays")


def _local_own_imports(path: Path):
    """(line, has a '# lazy:' reason) of each import of our own modules inside a function."""
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines()
    seen = set()
    for fn in ast.walk(ast.parse(text)):
        if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        for node in ast.walk(fn):
            own = (isinstance(node, ast.ImportFrom) and (node.level > 0 or (node.module or "")
                                                           .startswith("aerial_synth"))) or \
                  (isinstance(node, ast.Import) and any(a.name.startswith("aerial_synth") for a in node.names))
            if own and node.lineno not in seen:
                seen.add(node.lineno)
                around = lines[max(node.lineno - 2, 0):node.end_lineno]
                yield node.lineno, any("# lazy:" in line for line in around)


def test_function_local_imports_of_our_modules_say_why():
    found, bad = 0, []
    for name, path in sorted(_modules().items()):
        parts = name.split(".")
        if len(parts) < 2 or parts[1] not in LAZY_CHECKED:
            continue
        for line, ok in _local_own_imports(path):
            found += 1
            if not ok:
                bad.append(f"{path.relative_to(PKG_DIR.parent)}:{line}")
    assert bad == [], "imports of our own modules inside functions without a '# lazy: <why>' " \
        "comment (move them to module level, or say what stays unloaded):\n" + "\n".join(bad)
    assert 0 < found <= 15  # scene, vehicles, placement: 9 at the end of issue 26's PART A
