"""Ground albedos against their documented sources (scene/model.py comments, docs/rendering.md
"Where the spreads come from"): a green lawn's visible reflectance stays in the range of
vegetation spectra, a dry one in that of dry grass, for every ground_albedo gain the default
RenderConfig can draw."""

from __future__ import annotations

import numpy as np

from aerial_synth.render.config import RenderConfig
from aerial_synth.render.shading import material_gains
from aerial_synth.scene.model import DEFAULT_COLOR_FOR_MATERIAL, MATERIAL_IDS

LUMA = np.array([0.299, 0.587, 0.114])


def _grass_luma(ground_albedo: float, dryness: float) -> float:
    g = material_gains({"ground_albedo": ground_albedo, "vegetation_dryness": dryness})
    rgb = np.asarray(DEFAULT_COLOR_FOR_MATERIAL["grass"]) * g[MATERIAL_IDS["grass"]]
    return float(LUMA @ rgb)


def test_green_lawns_reflect_like_green_vegetation():
    lo, hi = RenderConfig().ground_albedo
    # green vegetation: ~0.04 blue, ~0.08-0.12 green, ~0.04-0.06 red -> luma ~0.08-0.12;
    # the drawn gain spreads that by lawn density and thatch, still well under dry grass
    assert 0.06 <= _grass_luma(lo, 0.0) <= 0.09
    assert 0.11 <= _grass_luma(hi, 0.0) <= 0.15
    # still green: the green channel leads
    r, g, b = DEFAULT_COLOR_FOR_MATERIAL["grass"]
    assert g > r > b


def test_dry_lawns_reflect_like_dry_grass_and_asphalt_sits_between():
    lo, hi = RenderConfig().ground_albedo
    dmax = RenderConfig().vegetation_dryness[1]
    # dry grass / straw: ~0.15-0.3 of visible light
    assert 0.14 <= _grass_luma(lo, dmax) <= _grass_luma(hi, dmax) <= 0.32
    # drying brightens a lawn, whatever the gain
    for a in (lo, hi):
        assert _grass_luma(a, dmax) > 1.8 * _grass_luma(a, 0.0)
