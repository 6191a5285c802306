"""The MRE isolator beyond its identified range: extrapolate (today's law), tangent (C1), stop."""

from __future__ import annotations

import numpy as np
import pytest

from components.physics.mre_isolator_core import (
    DEVICE_LIMIT_M,
    IDENTIFIED_RANGE_M,
    STOP_DAMPING,
    STOP_STIFFNESS,
    bounded_force_law,
    force_law,
    isolator_force,
    isolator_stiffness,
)

XB, XL = IDENTIFIED_RANGE_M, DEVICE_LIMIT_M


def test_extrapolate_is_todays_law_bit_for_bit():
    law = bounded_force_law(beyond_range="extrapolate")
    rng = np.random.default_rng(2)
    for x, v, i in zip(rng.uniform(-0.03, 0.03, 500), rng.normal(0, 0.2, 500), rng.uniform(0, 3, 500), strict=True):
        assert law(x, v, i) == isolator_force(x, v, i) == force_law()(x, v, i)


@pytest.mark.parametrize("i", [0.0, 1.5, 3.0])
@pytest.mark.parametrize("side", [1.0, -1.0])
def test_tangent_is_continuous_and_c1_at_the_boundary(i, side):
    law, exact = bounded_force_law(beyond_range="tangent"), force_law()
    edge = side * XB
    assert law(edge, 0.0, i) == exact(edge, 0.0, i)  # inside: the identified law itself
    eps = 1e-9
    outside = law(edge + side * eps, 0.0, i)
    assert outside == pytest.approx(exact(edge, 0.0, i), abs=1e-6 * abs(exact(edge, 0.0, i)) + 1e-9)
    # slope beyond = the law's tangent stiffness at the boundary (analytic, Eq. 17 differentiated)
    h = 1e-4
    slope = (law(edge + side * 2 * h, 0.0, i) - law(edge + side * h, 0.0, i)) / (side * h)
    assert slope == pytest.approx(isolator_stiffness(edge, i), rel=1e-9)
    # and linear: equal increments give equal force increments, far out
    f1, f2, f3 = (law(edge + side * k * 5e-3, 0.0, i) for k in (1, 2, 3))
    assert f3 - f2 == pytest.approx(f2 - f1, rel=1e-12)


def test_tangent_keeps_the_viscous_term():
    law, exact = bounded_force_law(beyond_range="tangent"), force_law()
    x, i = 0.012, 1.0
    assert law(x, 0.3, i) - law(x, 0.0, i) == pytest.approx(exact(x, 0.3, i) - exact(x, 0.0, i), rel=1e-12)


def test_stop_adds_the_kelvin_contact_beyond_the_limit():
    tangent, stop = bounded_force_law(beyond_range="tangent"), bounded_force_law(beyond_range="stop")
    for x in (0.0, 0.009, 0.0149, -0.0149):
        assert stop(x, 0.1, 0.0) == tangent(x, 0.1, 0.0)  # no contact inside the limit
    pen, v = 2e-3, 0.05
    assert stop(XL + pen, v, 0.0) - tangent(XL + pen, v, 0.0) == pytest.approx(STOP_STIFFNESS * pen + STOP_DAMPING * v)
    assert stop(-XL - pen, -v, 0.0) - tangent(-XL - pen, -v, 0.0) == pytest.approx(
        -(STOP_STIFFNESS * pen + STOP_DAMPING * v))
    # leaving the wall fast: the dashpot would pull, the contact force is clipped at zero
    assert stop(XL + 1e-5, -1.0, 0.0) == tangent(XL + 1e-5, -1.0, 0.0)
    # the stated damping: restitution 0.65 on 4 x 98.3 kg against 5 MN/m
    zeta = STOP_DAMPING / (2 * np.sqrt(STOP_STIFFNESS * 4 * 98.3))
    assert np.exp(-zeta * np.pi / np.sqrt(1 - zeta**2)) == pytest.approx(0.65, rel=1e-9)


@pytest.mark.parametrize(("kwargs", "text"), [
    ({"beyond_range": "clamp"}, "beyond_range"),
    ({"beyond_range": "stop", "x_limit": 0.005}, "x_limit"),
    ({"beyond_range": "stop", "k_stop": -1.0}, "k_stop"),
])
def test_bad_parameters_are_refused(kwargs, text):
    with pytest.raises(ValueError, match=text):
        bounded_force_law(**kwargs)
