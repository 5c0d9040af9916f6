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
