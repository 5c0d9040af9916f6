"""An AST scan for code that goes around the project's guards (issue 37).

Reading: a module under ``aerial_synth/`` or ``tools/`` must read a user's file, parse YAML or
JSON, and compile a regular expression it was given through :mod:`aerial_synth.safe_input`
(regular files only, size caps, links out of input folders refused, nesting and alias budgets,
duplicate keys refused, RE2 without backtracking). Flagged anywhere else:

- ``yaml.load`` / ``yaml.safe_load`` / ``yaml.full_load`` / ``yaml.*load_all``, ``json.load(s)``,
  ``pickle.load(s)``;
- ``open()``, ``Path.open()``, ``.read_text()``, ``.read_bytes()``, ``np.fromfile``, ``np.load``,
  ``cv2.imread``;
- ``re.compile`` / ``re.match`` / ``re.search`` / ... whose pattern is not a literal (a pattern
  built from input), and any use of ``re2`` (``safe_input.user_regex`` is its one home);
- ``.resolve()`` on anything but ``Path(__file__)`` (a loop of links raises RuntimeError;
  ``os.path.realpath`` does not).

Writing: under ``--out`` only through :mod:`aerial_synth.io_utils` (atomic) inside the
command's lock, which the CLI takes for every command with ``--out``. Flagged: ``.write_text()``,
``.write_bytes()``, ``open(..., "w"/"a"/"x")``, ``cv2.imwrite``, ``np.save`` to a path,
``.tofile()``; a tool under ``tools/`` that writes a folder (``replace_dir``, ``staged_dir``,
``atomic_write_*``) without ``out_lock``.

A use that is safe says why on its line, ``# guard: <reason>`` (own files, package data,
``/proc``, a glob translated by fnmatch, writes inside a staged build). Developer tools that
only read what they wrote themselves are listed in :data:`DEV_TOOLS` with their reason.
"""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass
from pathlib import Path

#: Modules that are the guards themselves.
GUARD_MODULES = {"aerial_synth/safe_input.py", "aerial_synth/io_utils.py", "aerial_synth/out_guard.py"}

#: tools/ scripts that read and write only their own outputs or the repository's files (no
#: user input): benchmarks, sheets for the docs, the hostile runner's own records.
DEV_TOOLS = {
    "tools/bench_aggregate.py": "benchmark: parses the JSON lines of the runs it started",
    "tools/bench_eval.py": "benchmark: its own generated sets",
    "tools/bench_export.py": "benchmark: its own exports",
    "tools/bench_osm.py": "benchmark: its own runs' JSON lines",
    "tools/bench_parking.py": "benchmark",
    "tools/bench_place.py": "benchmark",
    "tools/bench_place_ab.py": "benchmark",
    "tools/bench_place_world.py": "benchmark: its own runs' JSON lines",
    "tools/bench_png.py": "benchmark",
    "tools/bench_render.py": "benchmark",
    "tools/bench_scenes.py": "benchmark: the bundled scenes",
    "tools/bench_suite.py": "benchmark: the bundled scenes and bench.json it writes",
    "tools/bench_tiled_export.py": "benchmark: its own exports and the bundled scenes",
    "tools/code_size.py": "reads the repository's sources",
    "tools/compare_outputs.py": "compares two outputs of its own runs",
    "tools/count_local_imports.py": "reads the repository's sources",
    "tools/crack_count.py": "reads its own renders",
    "tools/hostile_run.py": "the hostile-input runner: its own case records",
    "tools/hostile_fuzz.py": "the CLI fuzzer: runs cases in subprocesses, writes its own report",
    "tools/make_contact_sheet.py": "a docs sheet from its own renders",
    "tools/make_parking_sheet.py": "a docs sheet from its own renders",
    "tools/material_sheet.py": "a docs sheet",
    "tools/osm_demo_town.py": "writes the demo OSM file",
    "tools/realism_contact_sheet.py": "a docs sheet from its own exports",
    "tools/realism_report.py": "a docs report from its own exports",
    "tools/sheet_io.py": "the docs sheets' writer",
    "tools/tree_occlusion.py": "reads its own exports",
}

_YAML_LOADS = {"load", "safe_load", "full_load", "unsafe_load", "load_all", "safe_load_all",
               "full_load_all", "unsafe_load_all"}
_RE_FUNCS = {"compile", "match", "search", "fullmatch", "finditer", "findall", "sub", "subn", "split"}
_GUARD_COMMENT = re.compile(r"#\s*guard:\s*\S")


@dataclass(frozen=True)
class Finding:
    path: str
    line: int
    what: str

    def __str__(self) -> str:
        return f"{self.path}:{self.line}: {self.what}"


def _name(node: ast.AST) -> str:
    """Dotted name of a call's function (``yaml.safe_load``, ``open``, ``x.read_text``)."""
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        base = _name(node.value)
        return f"{base}.{node.attr}" if base else f"?.{node.attr}"
    if isinstance(node, ast.Call):
        return _name(node.func) + "()"
    return ""


def _is_file_path_call(node: ast.AST) -> bool:
    """``Path(__file__)`` (the module's own file)."""
    return (isinstance(node, ast.Call) and _name(node.func) in ("Path", "pathlib.Path") and node.args
            and isinstance(node.args[0], ast.Name) and node.args[0].id == "__file__")


def _write_mode(call: ast.Call) -> bool:
    mode = call.args[1] if len(call.args) > 1 else next(
        (k.value for k in call.keywords if k.arg == "mode"), None)
    return isinstance(mode, ast.Constant) and isinstance(mode.value, str) and any(
        c in mode.value for c in "wax+")


def _findings_in_call(call: ast.Call) -> list[str]:
    name = _name(call.func)
    head, _, attr = name.rpartition(".")
    if not isinstance(call.func, ast.Attribute):  # read_text(...) of safe_input is a function
        head, attr = "", name
    method = isinstance(call.func, ast.Attribute) and head not in ("safe_input", "si", "io_utils")
    out = []
    if head == "yaml" and attr in _YAML_LOADS:
        out.append(f"{name}: parse YAML with safe_input.load_yaml / load_yaml_file")
    elif head == "json" and attr in ("load", "loads"):
        out.append(f"{name}: parse JSON with safe_input.load_json / load_json_file")
    elif head == "pickle" and attr in ("load", "loads"):
        out.append(f"{name}: unpickling a file")
    elif head == "re" and attr in _RE_FUNCS:
        pat = call.args[0] if call.args else None
        if not (isinstance(pat, ast.Constant) and isinstance(pat.value, (str, bytes))):
            out.append(f"{name} of a pattern that is not a literal: use safe_input.user_regex")
    elif head == "re2" or name.startswith("re2."):
        out.append(f"{name}: RE2 only through safe_input.user_regex")
    elif name in ("open", "io.open", "builtins.open"):
        out.append("open(): " + ("write with io_utils.atomic_write_*" if _write_mode(call)
                                 else "read with safe_input.read_bytes / read_text"))
    elif method and attr in ("read_text", "read_bytes"):
        out.append(f".{attr}(): read with safe_input.read_text / read_bytes")
    elif method and attr == "open" and head not in ("os", "tarfile", "zipfile", "gzip", "bz2", "lzma", "webbrowser",
                                         "eng", "self", "engine") and not head.endswith("()"):
        out.append(".open(): read with safe_input.read_bytes / read_text")
    elif name in ("np.fromfile", "numpy.fromfile", "np.load", "numpy.load"):
        out.append(f"{name}: read with safe_input.read_bytes")
    elif name == "cv2.imread":
        out.append("cv2.imread: read with safe_input.read_image")
    elif method and attr == "resolve" and not call.args and not _is_file_path_call(call.func.value):
        out.append(".resolve(): a loop of links raises RuntimeError; use os.path.realpath")
    elif method and attr in ("write_text", "write_bytes"):
        out.append(f".{attr}(): write with io_utils.atomic_write_* (inside the --out lock)")
    elif name == "cv2.imwrite" or (method and attr == "tofile"):
        out.append(f"{name}: write with io_utils.atomic_write_bytes")
    elif name in ("np.save", "numpy.save") and call.args and not (
            isinstance(call.args[0], ast.Name) and call.args[0].id in ("bio", "buf", "fh")):
        out.append(f"{name} to a path: write with io_utils.atomic_write_bytes")
    return out


def scan_source(text: str, rel: str) -> list[Finding]:
    """Findings of one module's source ``text`` (named ``rel`` in them)."""
    if rel in GUARD_MODULES or rel in DEV_TOOLS:
        return []
    tree = ast.parse(text, filename=rel)
    lines = text.splitlines()
    found = []
    writes_folder = locks = False
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        name = _name(node.func)
        writes_folder |= name.split(".")[-1] in ("replace_dir", "staged_dir") or \
            name.split(".")[-1].startswith("atomic_write")
        locks |= name.split(".")[-1] == "out_lock"
        for what in _findings_in_call(node):
            end = getattr(node, "end_lineno", node.lineno) or node.lineno
            span = lines[node.lineno - 1:end]
            if any(_GUARD_COMMENT.search(ln) for ln in span):
                continue
            found.append(Finding(rel, node.lineno, what))
    if rel.startswith("tools/") and writes_folder and not locks:
        found.append(Finding(rel, 1, "writes an output without out_guard.out_lock"))
    return found


def scan(root: Path, folders=("aerial_synth", "tools")) -> list[Finding]:
    """Findings of every ``.py`` file below ``root/<folder>``."""
    out = []
    for folder in folders:
        for p in sorted((root / folder).rglob("*.py")):
            rel = p.relative_to(root).as_posix()
            out += scan_source(p.read_text(encoding="utf-8"), rel)  # guard: the repository's sources
    return out


def cli_locks_every_command(cli_source: str) -> bool:
    """True when ``aerial_synth/cli.py`` runs ``args.func(args)`` inside a ``with`` whose
    items include ``_out_locked(args)`` (the CLI's --out lock around every command)."""
    tree = ast.parse(cli_source)
    for node in ast.walk(tree):
        if isinstance(node, ast.With) and any(
                isinstance(i.context_expr, ast.Call) and _name(i.context_expr.func) == "_out_locked"
                for i in node.items):
            for inner in ast.walk(node):
                if isinstance(inner, ast.Call) and _name(inner.func) == "args.func":
                    return True
    return False
