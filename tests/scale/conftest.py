import pytest

#: a small city world: 3 x 3 blocks or so, generated in about a second
SMALL_CITY = {"generator": "city", "name": "small_city", "seed": 5, "size_km": 0.5}


@pytest.fixture(scope="session")
def small_city_spec():
    return dict(SMALL_CITY)


@pytest.fixture(scope="session")
def small_city_scene(small_city_spec):
    from aerial_synth.scene.procedural import generate

    return generate(small_city_spec)


def _quad(x0, y0, x1, y1, z, off):
    v = [(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)]
    return v, [(off + 1, off + 2, off + 3), (off + 1, off + 3, off + 4)]


@pytest.fixture(scope="session")
def cross_scene(tmp_path_factory) -> str:
    """A 60 m x 60 m OBJ scene: grass and a crossing of two 8 m roads (fast to load)."""
    parts = {"ground": (-30, -30, 30, 30, 0.0), "road_ew": (-30, -4, 30, 4, 0.05),
             "road_ns": (-4, -30, 4, 30, 0.051)}
    lines, off = [], 0
    for name, q in parts.items():
        v, f = _quad(*q, off)
        off += 4
        lines.append(f"o {name}")
        lines += [f"v {a} {b} {c}" for a, b, c in v]
        lines += [f"f {a} {b} {c}" for a, b, c in f]
    p = tmp_path_factory.mktemp("scene") / "cross.obj"
    p.write_text("\n".join(lines) + "\n")
    return str(p)


def tree_bytes(root) -> dict:
    from pathlib import Path

    root = Path(root)
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def run_cli(*args, timeout=300):
    import os
    import subprocess
    import sys
    from pathlib import Path

    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    return subprocess.run([sys.executable, "-m", "aerial_synth.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout, env=env)
