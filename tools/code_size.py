"""Modules and functions over the size limits of the package (issue 26).

Usage::

    python tools/code_size.py [PATH ...] [--module-lines 600] [--function-lines 100]

PATHs (files or folders, default: the whole ``aerial_synth`` package) limit the listing.
A module counts its physical lines; a function (or method) the lines from its ``def`` (or
first decorator) to its last line. A module or function may exceed the limit when a comment
in its first lines says why it cannot be split: ``# size: <reason>`` within the first 5
lines of a module, or on the ``def`` line or the line after it. Exit status 1 when any
exceeds its limit without such a reason.
"""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
PKG = REPO / "aerial_synth"


def _reason(lines: list[str], first: int, n: int) -> str:
    for line in lines[first:first + n]:
        if "# size:" in line:
            return line.split("# size:", 1)[1].strip()
    return ""


def oversize(path: Path, module_lines: int, function_lines: int):
    """(what, lines, reason) for the module and each function of ``path`` over the limits."""
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines()
    out = []
    if len(lines) > module_lines:
        out.append(("module", len(lines), _reason(lines, 0, 5)))
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            start = min([node.lineno] + [d.lineno for d in node.decorator_list])
            n = node.end_lineno - start + 1
            if n > function_lines:
                out.append((f"{node.name}() line {node.lineno}", n,
                            _reason(lines, node.lineno - 1, 2)))
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("paths", nargs="*", type=Path)
    p.add_argument("--module-lines", type=int, default=600)
    p.add_argument("--function-lines", type=int, default=100)
    args = p.parse_args(argv)
    files: list[Path] = []
    for root in args.paths or [PKG]:
        root = root.resolve()
        files += [root] if root.is_file() else sorted(root.rglob("*.py"))
    n_over = n_bad = 0
    for f in files:
        rel = f.relative_to(REPO) if f.is_relative_to(REPO) else f
        for what, n, reason in oversize(f, args.module_lines, args.function_lines):
            n_over += 1
            n_bad += not reason
            print(f"{rel}: {what}: {n} lines" + (f"  # size: {reason}" if reason else ""))
    print(f"{n_over} over the limits ({args.module_lines}-line modules, "
          f"{args.function_lines}-line functions), {n_bad} without a '# size:' reason")
    return 1 if n_bad else 0


if __name__ == "__main__":
    sys.exit(main())
