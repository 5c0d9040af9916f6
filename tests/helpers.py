"""Small helpers shared by test packages: a hand-built crossing scene, a file tree's bytes,
and running the CLI in a subprocess."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def write_crossing_obj(path: Path, half_m: float) -> str:
    """An OBJ of grass (2 * half_m square) and a crossing of two 8 m roads; returns the path.

    Objects ``ground``, ``road_ew`` and ``road_ns`` (the north-south road 1 mm higher, so the
    crossing has one top surface)."""
    h = half_m
    parts = {"ground": (-h, -h, h, h, 0.0), "road_ew": (-h, -4, h, 4, 0.05),
             "road_ns": (-4, -h, 4, h, 0.051)}
    lines, off = [], 0
    for name, (x0, y0, x1, y1, z) in parts.items():
        lines.append(f"o {name}")
        lines += [f"v {a} {b} {z}" for a, b in ((x0, y0), (x1, y0), (x1, y1), (x0, y1))]
        lines += [f"f {off + 1} {off + 2} {off + 3}", f"f {off + 1} {off + 3} {off + 4}"]
        off += 4
    Path(path).write_text("\n".join(lines) + "\n")
    return str(path)


def tree_bytes(root) -> dict:
    """{relative path: bytes} of every file below ``root``."""
    root = Path(root)
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def run_cli(*args, timeout=120, **kw):
    """``python -m aerial_synth.cli ARGS`` with this checkout first on the path."""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run([sys.executable, "-m", "aerial_synth.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout, env=env, **kw)


def children(pid: int, cmdline: bytes | None = None) -> set[int]:
    """The live processes whose parent is ``pid`` (from /proc; Linux), those whose command
    line contains ``cmdline`` only, if given."""
    out = set()
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            with open(f"/proc/{d}/stat") as fh:
                ppid = int(fh.read().rsplit(")", 1)[1].split()[1])
            if ppid != pid:
                continue
            if cmdline is not None:
                with open(f"/proc/{d}/cmdline", "rb") as fh:
                    if cmdline not in fh.read():
                        continue
        except (OSError, IndexError, ValueError):
            continue
        out.add(int(d))
    return out


def one_line(code, err, status=2):
    """``err`` when a command exited with ``status`` and said so in exactly one line, with no
    traceback (the hostile-input tests' promise)."""
    assert code == status, err
    assert len(err.strip().splitlines()) == 1, err
    assert "Traceback" not in err
    return err
