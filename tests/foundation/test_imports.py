"""Import structure: no import cycles between modules, no reaching into another package's
private modules, and a light top-level import (``aerial-synth --help`` stays instant)."""

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


def _imports(name: str, path: Path, known: set[str]) -> set[str]:
    """Every aerial_synth module that ``name`` imports, at module level or inside functions."""
    is_pkg = path.name == "__init__.py"
    base = name.split(".") if is_pkg else name.split(".")[:-1]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                anchor = base[: len(base) - (node.level - 1)]
                mod = ".".join(anchor + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            # "from pkg import sub" imports the submodule pkg.sub when there is one
            targets = [f"{mod}.{a.name}" if f"{mod}.{a.name}" in known else mod for a in node.names]
        else:
            continue
        out.update(t for t in targets if t in known and t != name)
    return out


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
