"""Spacing samplers for traffic lines (thesis Table 3.1).

Chosen distribution
-------------------
A skew-normal (:data:`scipy.stats.skewnorm`) with shape ``a = skewness`` whose location and
scale are solved so that the distribution's mean and standard deviation are the table's mu
and sigma, truncated to ``[max(d_min, floor), d_max]`` (jam's fixed 8 m distance is a floor:
two vans in a row).

Why this reading matches Table 3.1: the table gives a skewness *parameter* of +30 / 0 / -30
together with mean and sd. Taken as a moment skewness, 30 is impossible for any unimodal
law with that mean and sd; taken as the skew-normal shape parameter it gives a strongly
right-skewed jam law (mode ~9.5 m, inside the stated 8-10 m, never below ~9.2 m), a
symmetric normal law, and a left-skewed sparse law (never above ~38.4 m < d_max). The
thesis states a sparse mode of 36 m; with the table's mean of 36 m and a negative skew the
mode must lie above the mean (here ~37.8 m). We keep the table's mean, sd and skew sign,
which the thesis gives as parameters, over the prose mode. With the table's bounds the
truncation removes < 1e-9 of the mass, so mean and sd are the table's. When a user's bounds
do cut the law, location and scale are re-solved numerically so the *truncated* law keeps
the requested mean and sd (where that is possible; otherwise a ConfigError says so).

The density, the untruncated moments (from which location and scale follow in closed
form) and the tail quantiles are scipy.stats.skewnorm's formulas written on scipy.special
(see below: importing scipy.stats would cost every placing process ~1.7 s); ``skewnorm``
itself stays the reference (:meth:`SpacingSampler.law`, ``ppf``) and the tests compare
against it. Sampling is by inverse CDF on a fine tabulated grid (the CDF integrated from
the pdf), vectorised: ``skewnorm.cdf`` with a large shape costs ~0.5 ms a point, far too
slow to tabulate, and the table agrees with ``skewnorm.ppf`` to < 1 mm
(tests/placement/test_spacing.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import validators as V
from ..errors import ConfigError

__all__ = ["SpacingSampler", "skewnorm_loc_scale"]

_GRID = 8192


# The skew-normal in closed form on scipy.special (imported in ~0.1 s, where scipy.stats
# costs ~1.7 s of every process that places vehicles): the same formulas scipy.stats.skewnorm
# evaluates. Standardised z = (x - loc) / scale, shape a, delta = a / sqrt(1 + a^2):
#   pdf = 2 phi(z) Phi(a z) / scale            (scipy's skewnorm._pdf)
#   cdf = Phi(z) - 2 T(z, a)                    (T: Owen's T function)
#   mean = delta sqrt(2 / pi), var = 1 - mean^2  (scipy's skewnorm._stats)
# tests/placement/test_spacing.py checks all three against scipy.stats.skewnorm.


def _sn_moments(a: float) -> tuple[float, float]:
    """Mean and variance of the standard skew-normal with shape ``a``."""
    d = a / np.sqrt(1.0 + a * a)
    m = d * np.sqrt(2.0 / np.pi)
    return float(m), float(1.0 - m * m)


def _sn_pdf(x, a, loc, scale):
    from scipy.special import ndtr

    z = (np.asarray(x, float) - loc) / scale
    return 2.0 / scale * np.exp(-0.5 * z * z) / np.sqrt(2.0 * np.pi) * ndtr(a * z)


def _sn_cdf(x, a, loc, scale):
    """CDF; accurate in the lower tail for a <= 0 and the upper one via :func:`_sn_sf`."""
    from scipy.special import ndtr, owens_t

    z = (np.asarray(x, float) - loc) / scale
    return np.clip(ndtr(z) - 2.0 * owens_t(z, a), 0.0, 1.0)


def _sn_sf(x, a, loc, scale):
    """Survival function, by reflection (X ~ SN(a) <=> -X ~ SN(-a)): no cancellation near 1."""
    return _sn_cdf(-(np.asarray(x, float) - loc) / scale, -a, 0.0, 1.0)


def _sn_tail_quantile(p: float, a: float, loc: float, scale: float, upper: bool) -> float:
    """x with P(X < x) = p (lower) or P(X > x) = p (upper), by bisection on the cdf/sf."""
    tail = _sn_sf if upper else _sn_cdf
    lo, hi = -60.0, 60.0  # standardised: far beyond any tail probability >= 1e-300
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        below = float(tail(loc + scale * mid, a, loc, scale)) < p
        if below != upper:  # lower tail: the quantile is above mid
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-12:
            break
    return loc + scale * 0.5 * (lo + hi)


def skewnorm_loc_scale(mean: float, sd: float, a: float) -> tuple[float, float]:
    """Location and scale of the skew-normal with shape ``a`` whose mean and sd are given
    (the standardised moments, solved in closed form)."""
    m1, v1 = _sn_moments(float(a))
    scale = sd / np.sqrt(v1)
    return mean - scale * m1, scale


def _support(loc, scale, a, lo, hi) -> tuple[float, float]:
    """[lo, hi] narrowed to where the law has mass (quantiles 1e-13 and 1 - 1e-13), so a
    narrow law inside wide bounds still gets a fine grid."""
    with np.errstate(all="ignore"):
        qa = _sn_tail_quantile(1e-13, float(a), loc, scale, upper=False)
        qb = _sn_tail_quantile(1e-13, float(a), loc, scale, upper=True)
    if not (np.isfinite(qa) and np.isfinite(qb)):
        return lo, hi
    a_, b_ = max(lo, float(qa)), min(hi, float(qb))
    return (a_, b_) if b_ > a_ else (lo, hi)


def _truncated_moments(loc, scale, a, lo, hi):
    """Mean, sd and mass of the skew-normal truncated to [lo, hi] (quadrature of its pdf)."""
    x = np.linspace(*_support(loc, scale, a, lo, hi), _GRID)
    with np.errstate(all="ignore"):
        p = _sn_pdf(x, a, loc, scale)
    trap = np.trapezoid if hasattr(np, "trapezoid") else np.trapz
    w = float(trap(p, x))
    if not np.isfinite(w) or w <= 0:
        return np.nan, np.nan, 0.0
    pn = p / w
    m = trap(pn * x, x)
    v = trap(pn * (x - m) ** 2, x)
    return float(m), float(np.sqrt(max(v, 0.0))), w


@dataclass(frozen=True)
class SpacingSampler:
    """Centre-to-centre spacing law of one traffic scenario (metres).

    skewness : skew-normal shape parameter a (Table 3.1: 30 / 0 / -30), in [-1000, 1000]
    mean_m, sd_m : target mean and standard deviation (> 0)
    min_m, max_m : d_min, d_max (hard bounds, 0 <= d_min <= d_max)
    floor_m : optional fixed minimum (jam: 8 m); the effective lower bound is max(min, floor)
    """

    skewness: float
    mean_m: float
    sd_m: float
    min_m: float
    max_m: float
    floor_m: float | None = None

    def __post_init__(self) -> None:
        s = object.__setattr__
        s(self, "skewness", V.in_range("spacing.skewness", self.skewness, -1000.0, 1000.0))
        s(self, "mean_m", V.positive("spacing.mean_m", self.mean_m))
        s(self, "sd_m", V.positive("spacing.sd_m", self.sd_m))
        s(self, "min_m", V.non_negative("spacing.min_m", self.min_m))
        s(self, "max_m", V.positive("spacing.max_m", self.max_m))
        if self.floor_m is not None:
            s(self, "floor_m", V.non_negative("spacing.floor_m", self.floor_m))
        if self.min_m > self.max_m:
            raise ConfigError(
                f"spacing: d_min ({self.min_m:g} m) must not exceed d_max ({self.max_m:g} m)"
            )
        lo = self.lower_m
        if lo >= self.max_m:
            raise ConfigError(
                f"spacing: floor/min ({lo:g} m) leaves no room below d_max ({self.max_m:g} m)"
            )
        if not (lo < self.mean_m < self.max_m):
            raise ConfigError(
                f"spacing.mean_m: expected inside ({lo:g}, {self.max_m:g}) m, got {self.mean_m:g}"
            )
        s(self, "_table", self._build_table())

    @property
    def lower_m(self) -> float:
        return max(self.min_m, self.floor_m) if self.floor_m is not None else self.min_m

    def _no_fit(self) -> ConfigError:
        return ConfigError(
            f"spacing: no skew-normal law with skewness {self.skewness:g}, mean {self.mean_m:g} m and "
            f"sd {self.sd_m:g} m fits inside [{self.lower_m:g}, {self.max_m:g}] m"
        )

    def _solve_params(self) -> tuple[float, float]:
        a, lo, hi = float(self.skewness), self.lower_m, self.max_m
        loc, scale = skewnorm_loc_scale(self.mean_m, self.sd_m, a)
        with np.errstate(all="ignore"):
            # mass outside [lo, hi]; the cdf is cheap at two points
            out = float(_sn_sf(hi, a, loc, scale)) + float(_sn_cdf(lo, a, loc, scale))
        if np.isfinite(out) and out < 1e-9:
            return loc, scale
        # The bounds cut the law: solve loc/scale so the truncated law keeps mean and sd.
        from scipy.optimize import root

        def resid(p):
            m_, s_, w_ = _truncated_moments(p[0], np.exp(p[1]), a, lo, hi)
            if not np.isfinite(m_) or w_ <= 0:
                return [1e3, 1e3]
            return [(m_ - self.mean_m) / self.sd_m, np.log(max(s_, 1e-12) / self.sd_m)]

        with np.errstate(all="ignore"):
            sol = root(resid, [loc, np.log(scale)], method="hybr")
            r = np.abs(resid(sol.x))
        if not (np.all(np.isfinite(sol.x)) and np.all(np.isfinite(r)) and r[0] < 1e-3 and r[1] < 1e-3):
            raise self._no_fit()
        return float(sol.x[0]), float(np.exp(sol.x[1]))

    def _build_table(self):
        loc, scale = self._solve_params()
        lo, hi = _support(loc, scale, float(self.skewness), self.lower_m, self.max_m)
        x = np.linspace(lo, hi, _GRID * 4)
        with np.errstate(all="ignore"):
            p = _sn_pdf(x, float(self.skewness), loc, scale)
            cdf = np.concatenate([[0.0], np.cumsum(0.5 * (p[1:] + p[:-1]) * np.diff(x))])
            if not (np.all(np.isfinite(cdf)) and cdf[-1] > 0):
                raise self._no_fit()
            cdf /= cdf[-1]
        # keep strictly increasing support for interpolation
        keep = np.concatenate([[True], np.diff(cdf) > 0])
        if keep.sum() < 2:
            raise self._no_fit()
        return x[keep], cdf[keep], loc, scale

    @property
    def loc_m(self) -> float:
        return float(self._table[2])

    @property
    def scale_m(self) -> float:
        return float(self._table[3])

    def law(self):
        """The untruncated scipy skew-normal (frozen) whose truncation this sampler draws from."""
        from scipy.stats import skewnorm

        return skewnorm(float(self.skewness), loc=self.loc_m, scale=self.scale_m)

    def ppf(self, u) -> np.ndarray:
        """Reference quantiles of the truncated law from ``scipy.stats.skewnorm.ppf``."""
        law = self.law()
        lo, hi = law.cdf([self.lower_m, self.max_m])
        return law.ppf(lo + np.asarray(u, float) * (hi - lo))

    def moments(self) -> tuple[float, float, float]:
        """Mean, sd and skewness (moment) of the untruncated law, from ``skewnorm.stats``."""
        m, v, s = self.law().stats(moments="mvs")
        return float(m), float(np.sqrt(v)), float(s)

    def sample(self, rng: np.random.Generator, n: int | None = None):
        """Draw spacings (metres). n=None gives a float, else an (n,) float64 array."""
        x, cdf, _, _ = self._table
        u = rng.random(1 if n is None else n)
        out = np.interp(u, cdf, x)
        out = np.clip(out, self.lower_m, self.max_m)
        return float(out[0]) if n is None else out

    def quantile(self, u) -> np.ndarray:
        """Tabulated inverse CDF (what :meth:`sample` uses) at probabilities ``u``."""
        x, cdf, _, _ = self._table
        return np.interp(np.asarray(u, float), cdf, x)

    def cdf(self, v) -> np.ndarray:
        """CDF of the (truncated) law at v (metres); for KS tests."""
        x, cdf, _, _ = self._table
        return np.interp(np.asarray(v, float), x, cdf, left=0.0, right=1.0)

    def to_dict(self) -> dict:
        return {
            "distribution": "truncated skew-normal",
            "skewness": self.skewness,
            "mean_m": self.mean_m,
            "sd_m": self.sd_m,
            "min_m": self.min_m,
            "max_m": self.max_m,
            "floor_m": self.floor_m,
            "solved_loc_m": round(self.loc_m, 6),
            "solved_scale_m": round(self.scale_m, 6),
        }
