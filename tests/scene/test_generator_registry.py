"""Adding a procedural generator is one module (a GENERATOR) plus one registry line."""

import pytest
from shapely.geometry import LineString

from aerial_synth.errors import SceneError
from aerial_synth.scene.procedural import GENERATORS, generate
from aerial_synth.scene.procedural.generators import Generator
from aerial_synth.scene.procedural.roads import Road


def _one_road(b, spec):
    w = float(spec.get("road_width_m", 7.0))
    b.roads.append(Road("toy_road", LineString([(-40.0, 0.0), (40.0, 0.0)]), w))


@pytest.fixture
def toy():
    gen = GENERATORS.register(Generator("toy_one_road", _one_road))
    yield gen
    GENERATORS.unregister("toy_one_road")


def test_builtin_generators_load_from_their_modules():
    names = GENERATORS.names()
    assert names[:3] == ("city_park", "suburb", "highway") and "rural" in names
    for n in names:
        assert GENERATORS.get(n).name == n


def test_toy_generator_builds_a_scene(toy):
    sc = generate({"generator": "toy_one_road", "size_m": [100, 60], "road_width_m": 9.0, "seed": 1})
    roads = [o for o in sc.objects if o.name.startswith("road_")]
    assert len(roads) == 1
    xy = roads[0].vertices[:, :2]
    assert abs(xy[:, 1].max() - xy[:, 1].min() - 9.0) < 0.05  # the toy's width, not a default
    assert sc.truth.roads[0].name == "toy_road"


def test_unknown_generator_lists_the_registered_ones(toy):
    with pytest.raises(SceneError, match="generator: expected one of .*toy_one_road.*, got 'nope'"):
        generate({"generator": "nope", "size_m": [100, 60]})
    GENERATORS.unregister("toy_one_road")
    with pytest.raises(SceneError, match="got 'toy_one_road'"):
        generate({"generator": "toy_one_road", "size_m": [100, 60]})
