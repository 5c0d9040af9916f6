"""Adding a vehicle body is one module (BODIES = Body(...)) plus one registry line."""

import numpy as np
import pytest

from aerial_synth.errors import AssetError
from aerial_synth.vehicles.body_types import REGISTRY, Body
from aerial_synth.vehicles.catalog import catalog_from_mapping
from aerial_synth.vehicles.meshes import build_mesh
from aerial_synth.vehicles.model import BODY_TYPES
from aerial_synth.vehicles.parts import Part

# a closed box: 8 corners, 12 outward triangles
_FACES = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                   [2, 3, 7], [2, 7, 6], [1, 2, 6], [1, 6, 5], [0, 4, 7], [0, 7, 3]])


def _crate(L, W, H):
    x, y = L / 2, W / 2
    v = np.array([[-x, -y, 0], [x, -y, 0], [x, y, 0], [-x, y, 0],
                  [-x, -y, H], [x, -y, H], [x, y, H], [-x, y, H]], float)
    return [Part("body", "paint", None, v, _FACES.copy())]


def _catalog(body):
    return catalog_from_mapping({
        "version": 1,
        "colors": [{"name": "white", "rgb": [0.9, 0.9, 0.9], "weight": 1}],
        "models": [{"name": "crate", "pack": 1, "body": body, "class": "small-vehicle",
                    "length_m": 4.0, "width_m": 1.6, "height_m": 1.2}],
    })


@pytest.fixture
def toy():
    yield REGISTRY.register(Body("toy_crate", _crate))
    REGISTRY.unregister("toy_crate")


def test_builtin_bodies_are_the_registry():
    assert REGISTRY.names() == BODY_TYPES
    assert all(REGISTRY.get(n).name == n for n in ("sedan", "city_bus", "tractor", "minibus"))


def test_toy_body_in_a_catalog_builds_its_mesh(toy):
    cat = _catalog("toy_crate")
    m = build_mesh(cat.models[0], cat.colors[0])
    lo, hi = m.vertices.min(axis=0), m.vertices.max(axis=0)
    np.testing.assert_allclose(hi - lo, [4.0, 1.6, 1.2], atol=1e-9)
    assert len(m.faces) == 12 and set(m.parts) == {"body"}


def test_unregistered_body_is_refused_naming_the_field(toy):
    REGISTRY.unregister("toy_crate")
    with pytest.raises(AssetError, match="field body: expected one of sport, .*got 'toy_crate'"):
        _catalog("toy_crate")
