import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _quad(x0, y0, x1, y1, z, off):
    v = [(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)]
    return v, [(off + 1, off + 2, off + 3), (off + 1, off + 3, off + 4)]


@pytest.fixture(scope="session")
def tiny_scene(tmp_path_factory) -> str:
    """An 80 m x 80 m hand-built scene: grass and a crossing of two 8 m roads (OBJ)."""
    parts = {
        "ground": (-40, -40, 40, 40, 0.0),
        "road_ew": (-40, -4, 40, 4, 0.05),
        "road_ns": (-4, -40, 4, 40, 0.051),
    }
    lines, off = [], 0
    for name, q in parts.items():
        v, f = _quad(*q, off)
        off += 4
        lines.append(f"o {name}")
        lines += [f"v {a} {b} {c}" for a, b, c in v]
        lines += [f"f {a} {b} {c}" for a, b, c in f]
    p = tmp_path_factory.mktemp("scene") / "tiny.obj"
    p.write_text("\n".join(lines) + "\n")
    return str(p)


def run_cli(*args, timeout=120, **kw):
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run([sys.executable, "-m", "aerial_synth.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout, env=env, **kw)


def tree_bytes(root: Path) -> dict:
    root = Path(root)
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}
