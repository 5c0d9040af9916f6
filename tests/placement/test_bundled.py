"""Placement on the bundled scenes: validator invariants and the spacing shape."""

import warnings

import numpy as np
import pytest
import scipy.stats as st

from aerial_synth.placement import load_scenario, place, validate_placement
from aerial_synth.placement.traffic import PlacementWarning
from aerial_synth.scene import load_scene
from aerial_synth.scene.raycast import RayScene
from aerial_synth.vehicles import load_catalog

SCENES = ("city_park", "suburb", "highway")


@pytest.fixture(scope="module")
def catalog():
    return load_catalog()


@pytest.fixture(scope="module")
def worlds():
    out = {}
    for name in SCENES:
        s = load_scene(name)
        out[name] = (s, RayScene(s))
    return out


def _place(rs, scenario, seed, catalog, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PlacementWarning)
        return place(rs, scenario, seed=seed, catalog=catalog, **kw)


def test_city_park_jam_spacing_keeps_the_sampler_shape(worlds, catalog):
    scene, rs = worlds["city_park"]
    sampler = load_scenario("jam").spacing
    spac = []
    for seed in range(3):
        p = _place(rs, "jam", seed, catalog, n_vehicles=600)
        # lines not cut short by road ends: complete, or stopped by traffic / the count
        keep = {(ln[0], ln[1]) for ln in p.stats["line_table"]
                if ln[2] in ("complete", "blocked", "limit")}
        by_line = {}
        for v in p.vehicles:
            by_line.setdefault((v.line_id, v.lane), []).append(v.spacing_m)
        for key, sp in by_line.items():
            if key in keep:
                spac += [s for s in sp if np.isfinite(s)]
    spac = np.array(spac)
    assert len(spac) >= 150
    assert st.kstest(spac, sampler.cdf).pvalue > 0.01
    assert abs(spac.mean() - 10.4) < 0.25


def test_city_park_jam_one_placement_is_clean(worlds, catalog):
    scene, rs = worlds["city_park"]
    p = _place(rs, "jam", 0, catalog, n_vehicles=1000)
    rep = validate_placement(rs, p, scene.truth)
    assert len(p.vehicles) >= 900
    assert rep.overlaps == 0 and rep.gap_violations == 0
    assert rep.corners_drivable == 1.0
    assert rep.footprint_drivable == 1.0  # the whole footprint, not only its corners
    assert np.nanmedian(rep.heading_error_deg) < 2.0
    assert np.nanpercentile(rep.heading_error_deg, 99) < 8.0


@pytest.mark.slow
@pytest.mark.parametrize("scene_name", SCENES)
@pytest.mark.parametrize("scenario", ["jam", "normal", "sparse", "random"])
def test_2000_vehicles_per_scenario_on_every_bundled_scene(worlds, catalog, scene_name, scenario):
    scene, rs = worlds[scene_name]
    herr, total, seed = [], 0, 0
    while total < 2000:
        p = _place(rs, scenario, seed, catalog, n_vehicles=2000 - total)
        assert len(p.vehicles) > 0
        rep = validate_placement(rs, p, scene.truth)
        assert rep.overlaps == 0 and rep.gap_violations == 0
        assert rep.footprint_drivable == 1.0
        herr.append(rep.heading_error_deg)
        total += len(p.vehicles)
        seed += 1
        assert seed < 40
    if scenario != "random":
        h = np.concatenate(herr)
        h = h[np.isfinite(h)]
        assert np.median(h) < 2.0
        assert np.percentile(h, 99) < 8.0
