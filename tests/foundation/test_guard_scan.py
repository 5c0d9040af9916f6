"""Forgetting a guard is a test failure (issue 37): an AST scan of ``aerial_synth/`` and
``tools/`` (tests/foundation/guard_scan.py) finds every read of a user's file, YAML/JSON
parse, user regex and raw write that does not go through ``safe_input`` / ``io_utils``; the
CLI takes the ``--out`` lock around every command; each writing command's output option is
``--out`` (so that lock applies). Each check is shown to catch a planted bypass."""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import pytest

from tests.foundation.guard_scan import DEV_TOOLS, cli_locks_every_command, scan, scan_source
from tests.helpers import REPO


def test_no_module_goes_around_the_guards():
    found = scan(REPO)
    assert not found, "bypasses of safe_input / io_utils:\n" + "\n".join(map(str, found))


def test_every_tool_is_scanned_or_listed_with_a_reason():
    for p in sorted((REPO / "tools").glob("*.py")):
        rel = f"tools/{p.name}"
        assert rel not in DEV_TOOLS or DEV_TOOLS[rel].strip(), rel
    assert "tools/make_dev_set.py" not in DEV_TOOLS  # it reads a user's folder: scanned


@pytest.fixture
def tree(tmp_path):
    """A copy of aerial_synth/ and tools/ to plant bypasses in."""
    for d in ("aerial_synth", "tools"):
        shutil.copytree(REPO / d, tmp_path / d, ignore=shutil.ignore_patterns("__pycache__"))
    return tmp_path


def _plant(path: Path, anchor: str, code: str) -> int:
    """Insert ``code`` (indented like ``anchor``'s line) after the first line holding
    ``anchor``; returns the line number of the inserted code."""
    lines = path.read_text().split("\n")
    k = next(i for i, ln in enumerate(lines) if anchor in ln)
    indent = lines[k][: len(lines[k]) - len(lines[k].lstrip())]
    lines[k + 1:k + 1] = [indent + c for c in code.split("\n")]
    path.write_text("\n".join(lines))
    return k + 2


def test_scan_catches_a_planted_yaml_safe_load(tree):
    mod = tree / "aerial_synth" / "dataset" / "scene_mix.py"
    assert scan(tree) == []
    line = _plant(mod, "data = load_yaml_file(path", "data = yaml.safe_load(open(path).read())")
    found = {(f.path, f.line, f.what.split(":")[0]) for f in scan(tree)}
    assert ("aerial_synth/dataset/scene_mix.py", line, "yaml.safe_load") in found
    assert ("aerial_synth/dataset/scene_mix.py", line, "open()") in found


@pytest.mark.parametrize("code,what", [
    ("x = json.loads(path.read_text())", "json.loads"),
    ("x = path.read_bytes()", ".read_bytes()"),
    ("x = re.compile(path.name)", "re.compile of a pattern"),
    ("x = re.search(user, 'abc')", "re.search of a pattern"),
    ("import re2; x = re2.compile('a')", "re2.compile"),
    ("x = path.resolve()", ".resolve()"),
    ("x = np.fromfile(path)", "np.fromfile"),
    ("x = cv2.imread(str(path))", "cv2.imread"),
    ("path.write_text('x')", ".write_text()"),
    ("fh = open(path, 'w')", "open(): write"),
    ("cv2.imwrite(str(path), img)", "cv2.imwrite"),
    ("x = yaml.load(t, Loader=yaml.Loader)", "yaml.load"),
])
def test_scan_catches_each_kind_of_bypass(code, what):
    src = f"def f(path, user, t, img):\n    {code}\n"
    found = scan_source(src, "aerial_synth/planted.py")
    assert any(f.what.startswith(what) for f in found), found
    # the same line with a reason is allowed; a literal pattern is never flagged
    assert scan_source(src.replace(code, code + "  # guard: a test"), "aerial_synth/planted.py") == []
    assert scan_source("import re\nP = re.compile(r'^a+$')\n", "aerial_synth/planted.py") == []


def test_scan_catches_a_tool_writing_without_the_lock():
    src = ("from aerial_synth.io_utils import replace_dir\n"
           "def main(tmp, out):\n    replace_dir(tmp, out)\n")
    assert [f.what for f in scan_source(src, "tools/planted.py")] == [
        "writes an output without out_guard.out_lock"]
    locked = src.replace("    replace_dir(tmp, out)", "    with out_lock(out, 'x'):\n        replace_dir(tmp, out)")
    assert scan_source(locked, "tools/planted.py") == []


def test_cli_locks_out_around_every_command():
    text = (REPO / "aerial_synth" / "cli.py").read_text()
    assert cli_locks_every_command(text)
    planted = text.replace("with _out_locked(args), input_roots(", "with input_roots(")
    assert planted != text and not cli_locks_every_command(planted)


def _actions(parser, path=()):
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            for name, sub in a.choices.items():
                yield from _actions(sub, path + (name,))
        else:
            yield path, a


def test_every_output_option_is_out():
    """The CLI's lock applies to ``args.out``: an output option under any other name would
    escape it (and refuse_out_is_input)."""
    from aerial_synth.cli import build_parser

    outs = set()
    for path, a in _actions(build_parser()):
        names = [o for o in a.option_strings if any(w in o for w in ("out", "write", "save", "dest"))]
        if names:
            assert a.dest == "out" and names == ["--out"], (path, a.option_strings)
            outs.add(path)
    assert {("export",), ("render",), ("mix",), ("stats",), ("eval",), ("place",), ("place-tiled",),
            ("scene", "show"), ("scene", "export"), ("scene", "from-osm"), ("assets", "preview"),
            ("show",), ("sim2real",)} <= outs
