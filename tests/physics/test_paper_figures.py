"""Fig. 3(b) and Fig. 13 computations (orchestration.identification.paper_figures) against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from components.physics.mre_isolator_core import MM, GeneralizedCoefficients, HyperbolicParams
from orchestration.identification.paper_figures import effective_stiffness, fig3b, fig13, random_motion


def test_effective_stiffness_of_an_undamped_loop_is_the_secant_at_the_amplitude():
    # Without damping the force is odd and increasing in x, so F_max - F_min = 2 F(A):
    # K_eff = k0 + alpha sinh(beta A) / A exactly; the loop is sampled at its peaks.
    p = HyperbolicParams(c0=0.0, k0=3000.0, alpha=8.0, beta=300.0)
    a = 8 * MM
    assert effective_stiffness(p, a, 2.0) == pytest.approx(p.k0 + p.alpha * np.sinh(p.beta * a) / a, rel=1e-12)
    damped = HyperbolicParams(c0=500.0, k0=3000.0, alpha=8.0, beta=300.0)
    assert effective_stiffness(damped, a, 2.0) > effective_stiffness(p, a, 2.0)  # damping widens the loop


def test_a_model_linear_in_current_gives_a_straight_stiffness_line():
    linear = GeneralizedCoefficients(k0_0=2000.0, k0_1=1500.0, c0_0=0.0, c0_1=0.0, alpha_0=0.0, alpha_1=0.0,
                                     beta_0=0.0, beta_1=100.0)
    line = fig3b(linear)["generalized model (Table 2)"]
    assert line.slope == pytest.approx(2000.0, rel=1e-9) and line.intercept == pytest.approx(1500.0, rel=1e-9)
    assert line.r2 == pytest.approx(1.0, abs=1e-12)


def test_the_synthetic_motion_peaks_at_4_mm_and_v_is_its_derivative():
    t, x, v = random_motion(seed=5)
    assert np.max(np.abs(x)) == pytest.approx(4 * MM, rel=1e-12)
    # central differences at 1 ms of sines up to 5 Hz: error ~ (2 pi 5 * 1e-3)^2 / 6 ~ 2e-4 relative
    np.testing.assert_allclose(np.gradient(x, t)[1:-1], v[1:-1], atol=1e-3 * np.max(np.abs(v)))
    again = random_motion(seed=5)[1]
    np.testing.assert_array_equal(x, again)  # seeded: the same figure every time


def test_fig13_compares_every_1_A_4_mm_fit_with_the_generalized_model():
    r = fig13()
    assert sorted(r["relative_rms_difference"]) == [f"Table 1 fit, {f} Hz, 4 mm" for f in (1, 2, 4)]
    assert all(d > 0 for d in r["relative_rms_difference"].values())
