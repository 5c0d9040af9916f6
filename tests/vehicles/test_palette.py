"""The bundled paint palette: shares from the documented colour-popularity figures, diffuse
(specular-excluded) albedos, sampling frequencies. Sources: vehicle_assets/catalog.yaml and
docs/vehicles.md ("Palette")."""

from __future__ import annotations

import numpy as np
import pytest

from aerial_synth.vehicles import load_catalog

#: Axalta, "Global Automotive Color Popularity Report" 2022 (worldwide), in percent.
AXALTA_2022_GLOBAL = {"white": 34, "black": 21, "grey": 19, "silver": 8, "blue": 8, "red": 5,
                      "green": 1}
#: The 4 % the release does not itemise, split as the earlier table did (3 : 1.5 : 1 : 0.5).
REST = {"brown": 2.0, "beige": 1.0, "yellow": 0.7, "orange": 0.3}
LUMA = np.array([0.299, 0.587, 0.114])


@pytest.fixture(scope="module")
def cat():
    return load_catalog()


def test_shares_are_the_documented_worldwide_figures(cat):
    p = dict(zip((c.name for c in cat.colors), cat.color_probabilities))
    assert set(p) == set(AXALTA_2022_GLOBAL) | set(REST)
    for name, pct in {**AXALTA_2022_GLOBAL, **REST}.items():
        assert p[name] == pytest.approx(pct / 100, abs=1e-9), name
    # the raw weights already sum to 1 (so the YAML reads as percentages)
    assert sum(c.weight for c in cat.colors) == pytest.approx(1.0, abs=1e-9)
    # the report's headline: white, black, grey and silver are 82 % of cars
    assert sum(p[k] for k in ("white", "black", "grey", "silver")) == pytest.approx(0.82)
    assert sum(REST.values()) == pytest.approx(100 - sum(AXALTA_2022_GLOBAL.values()))


def test_paint_albedos_are_diffuse_only(cat):
    """rgb excludes the clear coat's ~4-5 % mirror reflection, which the shader adds
    (render/shading.py _F0 of paint): black pigment under the clear coat reflects ~0.01."""
    from aerial_synth.render.shading import _F0
    from aerial_synth.scene.model import MATERIAL_IDS

    f0 = float(_F0[MATERIAL_IDS["paint"]])
    assert 0.04 <= f0 <= 0.06
    luma = {c.name: float(LUMA @ np.asarray(c.rgb)) for c in cat.colors}
    assert 0.005 <= luma["black"] <= 0.015  # gloss black L*(SCE) ~5-10
    assert luma["black"] < f0  # the clear coat outshines the pigment of a black car
    assert luma["white"] > luma["silver"] > luma["grey"] > luma["black"]
    assert 0.7 <= luma["white"] <= 0.9


def test_sampled_colour_frequencies_match_the_shares(cat):
    n = 100_000
    vs = cat.sample(np.random.default_rng(11), n)
    names, counts = np.unique([v.color.name for v in vs], return_counts=True)
    got = dict(zip(names, counts / n))
    for c, p in zip(cat.colors, cat.color_probabilities):
        # binomial sd <= 0.0015 at n = 100,000: 5 sd
        assert got.get(c.name, 0.0) == pytest.approx(p, abs=5 * np.sqrt(p * (1 - p) / n) + 1e-4)
    again = cat.sample(np.random.default_rng(11), n)
    assert [v.name for v in again] == [v.name for v in vs]  # deterministic
