"""Fragility fitting (orchestration/ida_study/fragility.py): maximum likelihood against known lognormals."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from orchestration.ida_study.fragility import Stripe, fit_fragility

LEVELS = np.geomspace(0.1, 1.5, 10)


def synthetic(theta: float, beta: float, n: int, seed: int) -> list[Stripe]:
    rng = np.random.default_rng(seed)
    p = stats.norm.cdf(np.log(LEVELS / theta) / beta)
    return [Stripe(float(x), n, int(k)) for x, k in zip(LEVELS, rng.binomial(n, p), strict=True)]


def standard_errors(theta: float, beta: float, n: int) -> tuple[float, float]:
    """Asymptotic standard errors of (ln theta, beta): expected information of binomial probit stripes, by hand."""
    info = np.zeros((2, 2))
    for x in LEVELS:
        z = math.log(x / theta) / beta
        p = stats.norm.cdf(z)
        w = n * stats.norm.pdf(z) ** 2 / (p * (1 - p))
        g = np.array([-1.0 / beta, -z / beta])  # dz/dmu, dz/dbeta
        info += w * np.outer(g, g)
    cov = np.linalg.inv(info)
    return math.sqrt(cov[0, 0]), math.sqrt(cov[1, 1])


@pytest.mark.parametrize("seed", range(5))
def test_mle_recovers_known_parameters_within_the_sampling_error(seed):
    theta, beta, n = 0.4, 0.35, 400
    fit = fit_fragility(synthetic(theta, beta, n, seed))
    se_mu, se_beta = standard_errors(theta, beta, n)
    assert fit.ok
    assert abs(math.log(fit.theta) - math.log(theta)) < 4 * se_mu
    assert abs(fit.beta - beta) < 4 * se_beta
    # the fit's own interval uses the same information, evaluated at the estimate
    lo, hi = fit.theta_interval()
    assert lo < fit.theta < hi
    assert math.log(hi / fit.theta) == pytest.approx(1.959964 * se_mu, rel=0.2)


def test_the_fit_is_the_likelihood_maximum_on_a_grid():
    stripes = synthetic(0.6, 0.5, 30, 11)
    fit = fit_fragility(stripes)
    x = np.array([s.level for s in stripes])
    n = np.array([s.n for s in stripes])
    k = np.array([s.k for s in stripes])

    def loglik(mu: np.ndarray, b: np.ndarray) -> np.ndarray:
        p = stats.norm.cdf((np.log(x) - mu[..., None]) / b[..., None])
        return np.sum(stats.binom.logpmf(k, n, p), axis=-1)

    mu, b = np.meshgrid(np.linspace(-1.5, 0.5, 201), np.linspace(0.1, 1.5, 141))
    best = float(np.max(loglik(mu, b)))
    assert float(loglik(np.array(math.log(fit.theta)), np.array(fit.beta))) >= best - 1e-9


def test_interval_of_the_median_covers_the_truth_about_as_often_as_it_says():
    theta, beta, n, hits, trials = 0.4, 0.35, 40, 0, 100
    for seed in range(trials):
        fit = fit_fragility(synthetic(theta, beta, n, 1000 + seed), confidence=0.95)
        lo, hi = fit.theta_interval()
        hits += lo <= theta <= hi
    assert hits >= 86  # 95 % nominal; 3 standard deviations of a binomial(100, 0.95) below


def test_band_contains_the_curve_and_narrows_with_more_data():
    x = np.geomspace(0.1, 1.5, 50)
    small = fit_fragility(synthetic(0.4, 0.35, 20, 3))
    large = fit_fragility(synthetic(0.4, 0.35, 500, 3))
    for fit in (small, large):
        lo, hi = fit.band(x)
        p = fit.probability(x)
        assert np.all(lo <= p + 1e-12) and np.all(p <= hi + 1e-12)
    assert np.mean(large.band(x)[1] - large.band(x)[0]) < 0.5 * np.mean(small.band(x)[1] - small.band(x)[0])


def test_data_without_a_finite_fit_say_why():
    levels = [0.1, 0.2, 0.4]
    assert fit_fragility([Stripe(v, 10, 0) for v in levels]).kind == "none-exceed"
    assert fit_fragility([Stripe(v, 10, 10) for v in levels]).kind == "all-exceed"
    sep = fit_fragility([Stripe(0.1, 10, 0), Stripe(0.2, 10, 0), Stripe(0.4, 10, 10)])
    assert sep.kind == "separated" and sep.bounds == (0.2, 0.4)
    assert fit_fragility([]).kind == "none-exceed"
    quasi = fit_fragility([Stripe(0.1, 10, 0), Stripe(0.2, 10, 4), Stripe(0.4, 10, 10)])
    assert quasi.kind == "separated" and quasi.bounds == (0.1, 0.4)
