import pytest

from ..helpers import run_cli as _run_cli
from ..helpers import tree_bytes, write_crossing_obj

__all__ = ["run_cli", "tree_bytes"]

#: a small city world: 3 x 3 blocks or so, generated in about a second
SMALL_CITY = {"generator": "city", "name": "small_city", "seed": 5, "size_km": 0.5}


@pytest.fixture(scope="session")
def small_city_spec():
    return dict(SMALL_CITY)


@pytest.fixture(scope="session")
def small_city_scene(small_city_spec):
    from aerial_synth.scene.procedural import generate

    return generate(small_city_spec)


@pytest.fixture(scope="session")
def cross_scene(tmp_path_factory) -> str:
    """A 60 m x 60 m OBJ scene: grass and a crossing of two 8 m roads (fast to load)."""
    return write_crossing_obj(tmp_path_factory.mktemp("scene") / "cross.obj", 30)


def run_cli(*args, timeout=300):
    return _run_cli(*args, timeout=timeout)
