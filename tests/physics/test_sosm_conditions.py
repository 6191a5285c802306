"""The SOSM conditions of Eq. (33)-(38) (components.physics.sosm_conditions) against independent sources."""

from __future__ import annotations

import numpy as np
import pytest

from components.physics.mre_isolator_core import TABLE2, isolator_force
from components.physics.sosm_conditions import phi, psi, sosm_conditions
from components.physics.sosm_controller_core import SosmGains

M_B = 6.0  # kg, an arbitrary base-floor mass: Psi scales with 1/m_b


def test_psi_is_the_current_sensitivity_of_the_isolator_force():
    # Psi = -(1/m_b) dF_total/di with F_total from the isolator's own core, differentiated by a
    # central difference (step 1e-4 A: truncation ~1e-8 relative, far below the 1e-6 asked).
    rng = np.random.default_rng(3)
    x, v, i = rng.uniform(-0.012, 0.012, 50), rng.uniform(-0.3, 0.3, 50), rng.uniform(0, 3, 50)
    di = 1e-4
    numeric = np.array([-(isolator_force(xk, vk, ik + di, TABLE2) - isolator_force(xk, vk, ik - di, TABLE2))
                        / (2 * di) / M_B for xk, vk, ik in zip(x, v, i, strict=True)])
    np.testing.assert_allclose(psi(x, v, i, TABLE2, M_B, n_isolators=2), numeric, rtol=1e-6)


def test_phi_of_an_analytic_motion_and_a_current_ramp():
    # x = A sin(w t), i = 1 + 0.2 t: s'' = x''' + lambda x'' exactly, u = 0.2 A/s, so
    # Phi = s'' - Psi u in closed form. Central differences at h = 1e-4 s err by h^2 w^2 / 6
    # relative (~1e-7 here); the two end samples are one-sided and left out.
    A, w, lam, h = 0.005, 2 * np.pi * 1.3, 13.0, 1e-4
    t = np.arange(0, 3 + h / 2, h)
    x, v, a = A * np.sin(w * t), A * w * np.cos(w * t), -A * w**2 * np.sin(w * t)
    i = 1 + 0.2 * t
    p = psi(x, v, i, TABLE2, M_B)
    exact = -A * w**3 * np.cos(w * t) - lam * A * w**2 * np.sin(w * t) - p * 0.2
    got = phi(t, v, a, i, p, lam)
    np.testing.assert_allclose(got[1:-1], exact[1:-1], rtol=0, atol=1e-6 * np.max(np.abs(exact)))


def test_psi_vanishes_at_rest_so_the_reaching_condition_cannot_hold():
    t = np.linspace(0, 2, 2001)
    x, v, a = 0.004 * np.sin(np.pi * t), 0.004 * np.pi * np.cos(np.pi * t), -0.004 * np.pi**2 * np.sin(np.pi * t)
    x[0] = v[0] = 0.0  # a moment at rest
    gains = SosmGains()
    c = sosm_conditions(t, x, v, a, np.full_like(t, 1.5), gains, TABLE2, M_B)
    assert c.v_m == 0.0 and not c.reaching_holds
    assert c.reaching_margin == pytest.approx(-c.tau - gains.theta**2 / 2)
    assert 0.0 < c.share_pointwise < 1.0  # where |Psi| is large the bound holds locally
    assert c.share_local >= c.share_pointwise  # |Phi(t)| <= tau at every sample
    # zeta theta > rho with the shipped gains: 18.32 * 1.697 / 7.08 = 4.39
    assert c.zeta_theta_over_rho == pytest.approx(gains.zeta * gains.theta / gains.rho) and c.zeta_theta_holds
