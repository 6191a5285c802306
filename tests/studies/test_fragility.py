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


# --- the stroke capacity: the intensity up to which the device stays within its stroke ---------------------------

STROKE_LEVELS = [0.02, 0.04, 0.08, 0.12, 0.16, 0.24]
RECORD_CAPACITY = [0.05, 0.07, 0.10, 0.13, 0.20]  # [g] each record's intensity at which its isolator passes 15 mm


def _stroke_stripes() -> list[Stripe]:
    """Five records at six levels: a record exceeds at every level above its own capacity (IDA stripes)."""
    return [Stripe(x, len(RECORD_CAPACITY), sum(c < x for c in RECORD_CAPACITY)) for x in STROKE_LEVELS]


def test_stroke_capacity_is_the_likelihood_median_with_the_wald_interval_computed_independently():
    from scipy import optimize

    from orchestration.ida_study.fragility import stroke_capacity

    stripes = _stroke_stripes()
    cap = stroke_capacity(fit_fragility(stripes, confidence=0.95))
    x = np.array(STROKE_LEVELS)
    n = np.array([s.n for s in stripes])
    k = np.array([s.k for s in stripes])

    def nll(q: np.ndarray) -> float:  # binomial log-pmf, another route than the fit's log-CDFs
        p = np.clip(stats.norm.cdf((np.log(x) - q[0]) / q[1]), 1e-300, 1 - 1e-16)
        return -float(np.sum(stats.binom.logpmf(k, n, p)))

    mu, b = np.meshgrid(np.linspace(-4.0, -0.5, 141), np.linspace(0.05, 2.0, 79), indexing="ij")
    grid = np.vectorize(lambda m, s: nll(np.array([m, s])))(mu, b)
    j = np.unravel_index(np.argmin(grid), grid.shape)
    best = optimize.minimize(nll, [mu[j], b[j]], method="Nelder-Mead", options={"xatol": 1e-10, "fatol": 1e-12})
    m_hat, b_hat = best.x
    # expected information sum n dp dp' / (p (1 - p)), the derivatives of p by central differences
    h = 1e-6
    info = np.zeros((2, 2))
    for xj, nj in zip(x, n, strict=True):
        def p_of(q: np.ndarray, xj: float = xj) -> float:
            return float(stats.norm.cdf((math.log(xj) - q[0]) / q[1]))
        p = p_of(best.x)
        g = np.array([(p_of(best.x + d) - p_of(best.x - d)) / (2 * h) for d in (np.array([h, 0]), np.array([0, h]))])
        info += nj * np.outer(g, g) / (p * (1 - p))
    half = 1.959964 * math.sqrt(np.linalg.inv(info)[0, 0])
    assert cap.kind == "fit"
    assert cap.median == pytest.approx(math.exp(m_hat), rel=1e-5)
    assert cap.low == pytest.approx(math.exp(m_hat - half), rel=1e-4)
    assert cap.high == pytest.approx(math.exp(m_hat + half), rel=1e-4)
    assert b_hat > 0 and cap.low < 0.10 < cap.high  # the records' median capacity lies inside


def test_stroke_capacity_without_a_finite_fit_says_where_the_median_is():
    from orchestration.ida_study.fragility import stroke_capacity

    never = stroke_capacity(fit_fragility([Stripe(x, 4, 0) for x in STROKE_LEVELS]))
    assert (never.kind, never.low, never.high) == ("none-exceed", 0.24, math.inf)
    assert "up to 0.24 g" in never.text()
    always = stroke_capacity(fit_fragility([Stripe(x, 4, 4) for x in STROKE_LEVELS]))
    assert (always.kind, always.low, always.high) == ("all-exceed", 0.0, 0.02)
    split = stroke_capacity(fit_fragility([Stripe(x, 4, 4 * (x > 0.1)) for x in STROKE_LEVELS]))
    assert (split.kind, split.low, split.high) == ("separated", 0.08, 0.12)
    assert split.text() == "between 0.08 and 0.12 g"


def test_the_stroke_limit_state_is_the_largest_isolator_displacement_threshold():
    from orchestration.ida_study.fragility import stroke_limit_state

    states = {"identified": ("isolator_displacement", 0.008), "limit": ("isolator_displacement", 0.015),
              "drift": ("storey_drift", 0.05)}
    assert stroke_limit_state(states) == "limit"
    assert stroke_limit_state({"drift": ("storey_drift", 0.05)}) is None


def test_the_ida_report_has_a_stroke_section_per_strategy():
    from types import SimpleNamespace

    from orchestration.ida_study.ida_rendering import _stroke

    spec = SimpleNamespace(confidence=0.95, limit_states={
        "isolator_limit": SimpleNamespace(quantity="isolator_displacement", threshold=0.015),
        "storey_drift": SimpleNamespace(quantity="storey_drift", threshold=0.005)})
    fit = fit_fragility(_stroke_stripes())
    lines = _stroke(spec, {"isolator_limit": {"sosm": fit, "passive-on": fit_fragility(
        [Stripe(x, 5, 0) for x in STROKE_LEVELS])}, "storey_drift": {"sosm": fit}})
    text = "\n".join(lines)
    lo, hi = fit.theta_interval()
    assert "## Stroke" in text and "isolator beyond 15 mm" in text
    assert f"| sosm | {fit.theta:.3g} g (95 % interval {lo:.3g}-{hi:.3g} g) |" in text
    assert "| passive-on | within its stroke up to 0.24 g (the whole ladder) |" in text
