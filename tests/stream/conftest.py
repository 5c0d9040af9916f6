import pytest

from ..helpers import write_crossing_obj


@pytest.fixture(scope="session")
def tiny_scene(tmp_path_factory) -> str:
    """An 80 m x 80 m hand-built scene: grass and a crossing of two 8 m roads (OBJ)."""
    return write_crossing_obj(tmp_path_factory.mktemp("scene") / "tiny.obj", 40)
