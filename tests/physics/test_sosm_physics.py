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

    from ..conftest import PROJECT

    tuned = yaml.safe_load((PROJECT / "scenarios" / "sosm_gains.yaml").read_text())["gains"]
    g = SosmGains()
    assert (g.lam, g.rho, g.zeta, g.theta, g.i_max) == (
        tuned["lambda"], tuned["rho"], tuned["zeta"], tuned["theta"], tuned["i_max"])
    assert g.zeta * g.theta > g.rho  # Eq. (39)


# ---------------------------------------------------------------- the release band (a designer's extension, not in
# the paper: while |s| < s_release the current falls at rate rho)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(finite, finite, finite), min_size=1, max_size=40),
       st.floats(min_value=0.0, max_value=3.0), st.floats(min_value=1e-4, max_value=0.05))
@pytest.mark.slow
def test_a_zero_release_band_is_the_papers_law_exactly(measurements, i0, h):
    """s_release = 0 (the default): every step is sign(Psi) * u of Eq. (39), integrated and clipped, to the bit."""
    gains = SosmGains(lam=6.0, rho=0.9, zeta=7.0, theta=1.3, i_max=2.5)
    assert SosmGains().s_release == 0.0 and gains.s_release == 0.0
    ctrl = SosmController(gains, i0=i0)
    i = min(max(i0, 0.0), gains.i_max)
    for x, v, a in measurements:
        x, v = x * 1e-5, v * 1e-4  # around rest too, where the band would act
        s, sdot = v + gains.lam * x, a + gains.lam * v
        paper = control_direction(x, v, i) * quasi_continuous_rate(s, sdot, gains)
        assert ctrl.rate(x, v, a) == paper
        i = min(max(i + h * paper, 0.0), gains.i_max)
        assert ctrl.update(x, v, a, h) == i


def test_the_release_band_releases_the_current_at_rate_rho():
    """At rest (s = 0 < s_release) the current falls linearly at rho to 0 A and stays there:
    i(t) = max(i0 - rho t, 0); the paper's law would hold it (sign(Psi) = 0 at rest)."""
    gains = SosmGains(lam=6.0, rho=0.8, zeta=7.0, theta=1.3, i_max=2.5, s_release=1e-3)
    h, i0 = 0.01, 2.0
    ctrl = SosmController(gains, i0=i0)
    paper = SosmController(SosmGains(lam=6.0, rho=0.8, zeta=7.0, theta=1.3, i_max=2.5), i0=i0)
    for n in range(1, 400):
        i = ctrl.update(0.0, 0.0, 0.0, h)
        # forward Euler of a constant rate is exact up to the rounding of n additions (1e-12 A)
        assert i == pytest.approx(max(i0 - gains.rho * n * h, 0.0), abs=1e-12), n
        assert paper.update(0.0, 0.0, 0.0, h) == i0
    assert ctrl.i == 0.0  # 2 A / 0.8 A/s = 2.5 s < 4 s: released


def test_the_release_band_acts_inside_the_band_only():
    """A small motion with |s| < s_release gives -rho whatever sign(Psi); outside, the paper's rate."""
    gains = SosmGains(lam=6.0, rho=0.8, zeta=7.0, theta=1.3, i_max=2.5, s_release=1e-3)
    paper = SosmGains(lam=6.0, rho=0.8, zeta=7.0, theta=1.3, i_max=2.5)
    for x, v in ((1e-5, 2e-4), (-1e-5, -2e-4), (1e-4, -5e-4), (-1e-4, 5e-4)):
        s = v + gains.lam * x
        assert abs(s) < gains.s_release
        assert control_direction(x, v, 1.0) != 0.0  # the paper's law would act here ...
        assert SosmController(gains, i0=1.0).rate(x, v, 0.0) == -gains.rho  # ... the band releases instead
    for x, v in ((1e-3, 2e-3), (-1e-3, -2e-3)):  # |s| = 8e-3 m/s > s_release: the paper's law, to the bit
        assert SosmController(gains, i0=1.0).rate(x, v, 0.1) == SosmController(paper, i0=1.0).rate(x, v, 0.1)


@pytest.mark.parametrize("bad", [-1e-3, math.nan, math.inf])
def test_the_release_band_must_be_non_negative_and_finite(bad):
    with pytest.raises(ValueError, match="s_release"):
        SosmGains(s_release=bad)
