"""Count the imports of aerial_synth's own modules that sit inside functions.

Usage::

    python tools/count_local_imports.py [PATH ...] [--quiet]

PATHs (files or folders, default: the whole ``aerial_synth`` package) limit the count.
Prints one line per import statement (``file:line: import text  # reason``), then the
total and how many lack a reason. An import inside a function (or a method) hides the
dependency from readers and tools, so each must say why it is lazy in a comment on its
line or on the line above, starting with ``lazy:`` (for example ``# lazy: open3d, only
when rays are cast``). Exit status 1 when one lacks that reason.
"""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
PKG = REPO / "aerial_synth"


def _is_own(node: ast.AST) -> bool:
    if isinstance(node, ast.ImportFrom):
        return node.level > 0 or (node.module or "").split(".")[0] == "aerial_synth"
    if isinstance(node, ast.Import):
        return any(a.name.split(".")[0] == "aerial_synth" for a in node.names)
    return False


def local_imports(path: Path) -> list[tuple[int, str, str]]:
    """(line, import source, reason or '') for each own-module import inside a function."""
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines()
    out = []
    seen: set[int] = set()
    for fn in ast.walk(ast.parse(text)):
        if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            continue
        for node in ast.walk(fn):
            if _is_own(node) and id(node) not in seen:
                seen.add(id(node))
                src = " ".join(ast.get_source_segment(text, node).split())
                reason = ""
                for ln in (node.end_lineno, node.lineno, node.lineno - 1):
                    line = lines[ln - 1]
                    if "# lazy:" in line:
                        reason = line.split("# lazy:", 1)[1].strip()
                        break
                out.append((node.lineno, src, reason))
    return sorted(out)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("paths", nargs="*", type=Path, help="files or folders (default: aerial_synth/)")
    p.add_argument("--quiet", action="store_true", help="only the totals")
    args = p.parse_args(argv)
    files: list[Path] = []
    for root in args.paths or [PKG]:
        root = root.resolve()
        files += [root] if root.is_file() else sorted(root.rglob("*.py"))
    total = missing = 0
    for f in files:
        for line, src, reason in local_imports(f):
            total += 1
            missing += not reason
            if not args.quiet:
                rel = f.relative_to(REPO) if f.is_relative_to(REPO) else f
                print(f"{rel}:{line}: {src}" + (f"  # lazy: {reason}" if reason else "  # NO REASON"))
    print(f"{total} function-local imports of aerial_synth modules, {missing} without a '# lazy:' reason")
    return 1 if missing else 0


if __name__ == "__main__":
    sys.exit(main())
