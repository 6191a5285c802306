"""SOSM controller physics: bounds, integration of the rate, sign of Psi, convergence of s."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from components.physics.mre_isolator_core import TABLE2, isolator_force
from components.physics.sosm_controller_core import (
    SosmController,
    SosmGains,
    control_direction,
    quasi_continuous_rate,
    sliding_variable,
)

finite = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(finite, finite, finite), min_size=1, max_size=60),
       st.floats(min_value=1e-4, max_value=0.1))
def test_current_stays_within_bounds(measurements, h):
    ctrl = SosmController(SosmGains(rho=500.0, zeta=1e3))
    for x, v, a in measurements:
        i = ctrl.update(x * 1e-3, v * 1e-2, a, h)
        assert 0.0 <= i <= ctrl.gains.i_max


def test_current_integrates_the_rate():
    gains = SosmGains(lam=5.0, rho=20.0, zeta=1.0, theta=1.0, i_max=3.0)
    ctrl = SosmController(gains, i0=1.0)
    x, v, a = 2e-3, 0.0, 0.0  # s = 0.01 m/s, s' = 0: u = sign(Psi) * clip(-zeta * theta) = -1 * -1 = +1 A/s
    rate = ctrl.rate(x, v, a)
    assert rate == pytest.approx(1.0)
    for _ in range(500):
        ctrl.update(x, v, a, 1e-3)
    assert ctrl.i == pytest.approx(1.5, rel=1e-12)


def test_quasi_continuous_law_matches_eq39():
    g = SosmGains(rho=10.0, zeta=2.0, theta=0.5)
    s, sd = 0.04, -0.3
    assert quasi_continuous_rate(s, sd, g) == pytest.approx(-2.0 * (sd / math.sqrt(0.04) + 0.5))
    assert quasi_continuous_rate(1e-9, 5.0, g) == -10.0  # saturated at -rho
    assert quasi_continuous_rate(0.0, 2.0, g) == -10.0  # u2 = -rho sign(s')
    assert quasi_continuous_rate(0.0, 0.0, g) == 0.0
    assert sliding_variable(0.01, 0.2, 3.0, 5.0) == pytest.approx((0.25, 4.0))


def test_control_direction_is_the_sign_of_psi():
    """Psi (Eq. 34) = -(2/m_b) dF/di per device: compare with a finite difference of the force law."""
    rng = np.random.default_rng(4)
    for _ in range(500):
        x, v, i = rng.uniform(-0.012, 0.012), rng.uniform(-0.3, 0.3), rng.uniform(0, 3)
        h = 1e-6
        dF_di = (isolator_force(x, v, i + h, TABLE2, n_isolators=1) - isolator_force(x, v, i - h, TABLE2,
                                                                                      n_isolators=1)) / (2 * h)
        if abs(dF_di) < 1e-6:
            continue
        assert control_direction(x, v, i) == -math.copysign(1.0, dF_di)
    assert control_direction(0.0, 0.0, 1.0) == 0.0


def test_sliding_variable_is_driven_to_zero_where_the_sign_condition_holds():
    """Plant x'' = g - kappa i (x > 0): s'' = lambda (g - kappa i) - kappa u, Psi = -kappa < 0 as the
    controller's model predicts for x > 0. Starting off the surface, s must reach a small band."""
    g, kappa = 2.0, 1.0
    gains = SosmGains(lam=2.0, rho=30.0, zeta=20.0, theta=2.0, i_max=3.0)
    ctrl = SosmController(gains, i0=0.0)
    x, v = 0.01, 0.05
    h = 1e-4
    s0 = abs(sliding_variable(x, v, g, gains.lam)[0])
    tail = []
    for k in range(int(4.0 / h)):
        a = g - kappa * ctrl.i
        assert control_direction(x, v, ctrl.i) == -1.0  # the sign condition of the test holds
        ctrl.update(x, v, a, h)
        x, v = x + h * v, v + h * a
        if k * h > 3.0:
            tail.append(abs(v + gains.lam * x))
    assert max(tail) < 1e-3 * s0
    assert x > 0


def test_the_controllers_isolator_model_is_table2():
    """The controller keeps its own copy of the Table 2 coefficients it needs (no module shared
    between FMUs); it must equal the isolator's."""
    from components.physics.sosm_controller_core import IsolatorModel

    model = IsolatorModel()
    for name in ("c0_0", "k0_0", "alpha_0", "alpha_1", "beta_0", "beta_1"):
        assert getattr(model, name) == pytest.approx(getattr(TABLE2, name), rel=1e-12), name


def test_default_gains_are_the_tuned_gains():
    """The controller's defaults are the gains the tuning procedure wrote (scenarios/sosm_gains.yaml)."""
    import yaml

    from .conftest import PROJECT

    tuned = yaml.safe_load((PROJECT / "scenarios" / "sosm_gains.yaml").read_text())["gains"]
    g = SosmGains()
    assert (g.lam, g.rho, g.zeta, g.theta, g.i_max) == (
        tuned["lambda"], tuned["rho"], tuned["zeta"], tuned["theta"], tuned["i_max"])
    assert g.zeta * g.theta > g.rho  # Eq. (39)
