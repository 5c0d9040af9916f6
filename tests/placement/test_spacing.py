import numpy as np
import pytest
import scipy.stats as st

from aerial_synth.errors import ConfigError
from aerial_synth.placement import load_scenario

TABLE_3_1 = {  # scenario: (skew sign, mean, sd, d_min, d_max)
    "jam": (+1, 10.4, 0.8, 7.5, 23.5),
    "normal": (0, 24.0, 1.6, 11.5, 37.9),
    "sparse": (-1, 36.0, 1.6, 25.0, 40.0),
}


@pytest.mark.parametrize("name", sorted(TABLE_3_1))
def test_spacing_matches_table_3_1(name):
    sign, mean, sd, lo, hi = TABLE_3_1[name]
    sampler = load_scenario(name).spacing
    x = sampler.sample(np.random.default_rng(123), 100_000)
    assert abs(x.mean() - mean) < 0.1
    assert abs(x.std() - sd) < 0.1 * sd
    skew = st.skew(x)
    if sign > 0:
        assert skew > 0.5
    elif sign < 0:
        assert skew < -0.5
    else:
        assert abs(skew) < 0.05
    assert x.min() >= lo and x.max() <= hi
    if name == "jam":
        assert x.min() >= 8.0  # the fixed 8 m distance: two vans in a row
        # stated mode 8-10 m
        hist, edges = np.histogram(x, bins=np.arange(7.5, 23.6, 0.25))
        mode = edges[np.argmax(hist)] + 0.125
        assert 8.0 <= mode <= 10.0
    if name == "sparse":
        # left skew: the mode lies above the mean (the thesis states 36 m; with mean 36 m and
        # a negative skew the law's mode is ~37.8 m, documented in spacing.py)
        hist, edges = np.histogram(x, bins=np.arange(25, 40.01, 0.25))
        mode = edges[np.argmax(hist)] + 0.125
        assert 36.0 < mode < 38.5


def test_sampler_is_deterministic_and_cdf_consistent():
    s = load_scenario("jam").spacing
    a = s.sample(np.random.default_rng(5), 1000)
    b = s.sample(np.random.default_rng(5), 1000)
    assert np.array_equal(a, b)
    x = s.sample(np.random.default_rng(6), 20000)
    assert st.kstest(x, s.cdf).pvalue > 0.01


def test_truncation_that_cuts_the_law_keeps_mean_and_sd():
    s = load_scenario("normal", {"spacing": {"min_m": 21.5, "max_m": 30.0}}).spacing
    x = s.sample(np.random.default_rng(0), 100_000)
    assert abs(x.mean() - 24.0) < 0.05
    assert abs(x.std() - 1.6) < 0.05 * 1.6
    assert x.min() >= 21.5 and x.max() <= 30.0
    assert s.loc_m != 24.0  # the law was re-solved, not just cut


def test_impossible_truncation_is_refused():
    with pytest.raises(ConfigError, match="no skew-normal law"):
        load_scenario("normal", {"spacing": {"min_m": 21.0, "max_m": 26.0}})


@pytest.mark.parametrize(
    "over, match",
    [
        ({"spacing": {"min_m": 30.0}}, "d_min"),
        ({"spacing": {"sd_m": -1.0}}, "sd_m"),
        ({"spacing": {"mean_m": 50.0}}, "mean_m"),
        ({"traffic": "middle"}, "traffic"),
        ({"double_lane_probability": 2}, "double_lane_probability"),
        ({"bogus": 1}, "unknown key"),
    ],
)
def test_bad_scenario_values(over, match):
    with pytest.raises(ConfigError, match=match):
        load_scenario("jam", over)


@pytest.mark.parametrize("name", ["jam", "normal", "sparse", "multilane"])
def test_tabulated_inverse_cdf_agrees_with_scipy_skewnorm(name):
    s = load_scenario(name).spacing
    u = np.linspace(0.0005, 0.9995, 2001)
    ref = s.ppf(u)  # scipy.stats.skewnorm.ppf of the truncated law
    assert np.max(np.abs(s.quantile(u) - ref)) < 1e-3  # < 1 mm
    # the density behind the table is scipy's: its CDF matches skewnorm's at a few points
    law = s.law()
    v = np.quantile(ref, [0.1, 0.5, 0.9])
    lo, hi = law.cdf([s.lower_m, s.max_m])
    assert np.allclose(s.cdf(v), (law.cdf(v) - lo) / (hi - lo), atol=1e-5)


def test_cut_law_table_agrees_with_scipy_too():
    s = load_scenario("normal", {"spacing": {"min_m": 21.5, "max_m": 30.0}}).spacing
    u = np.linspace(0.001, 0.999, 999)
    assert np.max(np.abs(s.quantile(u) - s.ppf(u))) < 1e-3


@pytest.mark.parametrize("name", sorted(TABLE_3_1))
def test_skewnorm_moments_are_table_3_1(name):
    sign, mean, sd, lo, hi = TABLE_3_1[name]
    s = load_scenario(name).spacing
    m, sdev, skew = s.moments()  # scipy.stats.skewnorm.stats of the solved law
    assert abs(m - mean) < 1e-4 and abs(sdev - sd) < 1e-4
    assert np.sign(round(skew, 9)) == sign
    assert s.skewness == {1: 30, 0: 0, -1: -30}[sign]
    # the truncation to [d_min, d_max] keeps those moments (it removes < 1e-9 of the mass)
    x = s.quantile((np.arange(200_000) + 0.5) / 200_000)
    assert abs(x.mean() - mean) < 2e-3 and abs(x.std() - sd) < 2e-3


def test_narrow_law_inside_wide_bounds_is_tabulated_finely():
    s = load_scenario("jam", {"spacing": {"max_m": 10000, "mean_m": 9999, "sd_m": 0.001}}).spacing
    x = s.sample(np.random.default_rng(0), 50_000)
    assert abs(x.mean() - 9999) < 1e-4 and abs(x.std() - 0.001) < 5e-5


@pytest.mark.parametrize("a", [30.0, 3.0, 0.0, -5.0, -30.0])
def test_closed_form_skew_normal_is_scipys(a):
    """The sampler's skew-normal (scipy.special: pdf, Owen's-T cdf, reflected sf, moments,
    tail quantiles) equals scipy.stats.skewnorm, which placement no longer imports."""
    from aerial_synth.placement import spacing as S

    loc, scale = 1.3, 2.1
    x = np.linspace(-12.0, 16.0, 301)
    law = st.skewnorm(a, loc=loc, scale=scale)
    np.testing.assert_allclose(S._sn_pdf(x, a, loc, scale), law.pdf(x), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(S._sn_cdf(x, a, loc, scale), law.cdf(x), rtol=1e-6, atol=1e-13)
    np.testing.assert_allclose(S._sn_sf(x, a, loc, scale), law.sf(x), rtol=1e-6, atol=1e-13)
    m, v = S._sn_moments(a)
    np.testing.assert_allclose([m, v], st.skewnorm.stats(a, moments="mv"), rtol=1e-12, atol=1e-15)
    for p in (1e-13, 1e-6, 0.3):
        q_lo = S._sn_tail_quantile(p, a, loc, scale, upper=False)
        q_hi = S._sn_tail_quantile(p, a, loc, scale, upper=True)
        assert q_lo == pytest.approx(law.ppf(p), abs=1e-4)
        assert q_hi == pytest.approx(law.isf(p), abs=1e-4)
        assert q_lo < q_hi


def test_placing_does_not_import_scipy_stats():
    """scipy.stats costs ~1.7 s of every placing process; the scenario laws need only
    scipy.special (a fresh interpreter shows it)."""
    import subprocess
    import sys

    code = ("import sys; from aerial_synth.placement import load_scenario; "
            "[load_scenario(n) for n in ('jam', 'normal', 'sparse')]; "
            "print('scipy.stats' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
