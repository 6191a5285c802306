"""Isolator physics: Eq. (17) with Table 2, Table 1 per-condition parameters, symmetry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from components.physics.mre_isolator_core import (
    TABLE2,
    TABLE2_PAPER_UNITS,
    GeneralizedCoefficients,
    HyperbolicParams,
    hyperbolic_force,
    isolator_force,
    isolator_stiffness,
)

# Table 1 of the paper, 2 Hz / 4 mm column (k0 N/mm, c0 N*s/mm, alpha N, beta 1/mm).
TABLE1_2HZ_4MM = {
    0: (2.6855, 0.2127, 11.8971, 0.2063),
    1: (10.6519, 0.8358, 2.8526, 0.8528),
    2: (14.9709, 1.3552, 17.5807, 0.5698),
    3: (16.5911, 1.5876, 39.0569, 0.4494),
}


def paper_force_mm(x_mm: float, v_mm: float, k0: float, c0: float, alpha: float, beta: float, F0: float = 0.0):
    """Eq. (3)-(4) written as in the paper, in mm, mm/s and N (z = (1 - e^{-2 beta x}) / (2 e^{-beta x}))."""
    z = (1 - math.exp(-2 * beta * x_mm)) / (2 * math.exp(-beta * x_mm))
    return c0 * v_mm + k0 * x_mm + alpha * z + F0


def test_generalized_force_equals_eq17_in_paper_units():
    rng = np.random.default_rng(1)
    p = TABLE2_PAPER_UNITS
    for _ in range(200):
        x_mm, v_mm, i = rng.uniform(-12, 12), rng.uniform(-300, 300), rng.uniform(0, 3)
        expected = paper_force_mm(
            x_mm, v_mm,
            k0=p["k0_0"] * i + p["k0_1"], c0=p["c0_0"] * i + p["c0_1"],
            alpha=p["alpha_0"] * i + p["alpha_1"], beta=p["beta_0"] * i + p["beta_1"],
        )
        got = isolator_force(x_mm * 1e-3, v_mm * 1e-3, i, TABLE2, n_isolators=1)
        assert got == pytest.approx(expected, rel=1e-12, abs=1e-9)
        assert isolator_force(x_mm * 1e-3, v_mm * 1e-3, i, TABLE2, n_isolators=2) == pytest.approx(2 * got, rel=1e-15)


def test_force_is_odd_in_x_and_v_without_offset():
    rng = np.random.default_rng(2)
    for _ in range(100):
        x, v, i = rng.uniform(-0.015, 0.015), rng.uniform(-0.3, 0.3), rng.uniform(0, 3)
        assert isolator_force(-x, -v, i) == pytest.approx(-isolator_force(x, v, i), rel=1e-13, abs=1e-12)


def test_offset_adds_per_device():
    assert isolator_force(0.0, 0.0, 1.0, F0=5.0, n_isolators=2) == pytest.approx(10.0)


@pytest.mark.parametrize("current", sorted(TABLE1_2HZ_4MM))
def test_table1_parameters_reproduce_the_paper_law(current):
    k0, c0, alpha, beta = TABLE1_2HZ_4MM[current]
    params = HyperbolicParams.from_paper_units(c0=c0, k0=k0, alpha=alpha, beta=beta)
    back = params.to_paper_units()
    assert (back["k0"], back["c0"], back["alpha"], back["beta"]) == pytest.approx((k0, c0, alpha, beta), rel=1e-14)
    for x_mm in (-4.0, -1.3, 0.0, 2.2, 4.0):
        for v_mm in (-100.0, 0.0, 57.0):
            expected = paper_force_mm(x_mm, v_mm, k0, c0, alpha, beta)
            assert hyperbolic_force(x_mm * 1e-3, v_mm * 1e-3, params) == pytest.approx(expected, rel=1e-12, abs=1e-9)


def test_generalized_parameters_are_linear_in_current():
    c = GeneralizedCoefficients.from_paper_units(**TABLE2_PAPER_UNITS)
    p = c.at_current(2.0)
    assert p.k0 == pytest.approx((5.8161 * 2 + 3.3431) * 1e3)
    assert p.c0 == pytest.approx((0.5767 * 2 + 0.3396) * 1e3)
    assert p.alpha == pytest.approx(4.9810 * 2 + 8.1100)
    assert p.beta == pytest.approx((0.1322 * 2 + 0.3463) * 1e3)


def test_tangent_stiffness_is_the_derivative_of_the_force():
    for x in (-0.01, 0.0, 0.004, 0.012):
        for i in (0.0, 1.5, 3.0):
            h = 1e-8
            fd = (isolator_force(x + h, 0.0, i) - isolator_force(x - h, 0.0, i)) / (2 * h)
            assert isolator_stiffness(x, i) == pytest.approx(fd, rel=1e-6)
