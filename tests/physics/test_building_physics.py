"""Shear-building physics: modes, modal damping, statics, exact discretization."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import eigh

from components.physics.shear_building_core import (
    BuildingParams,
    ShearBuilding,
    matrices,
    natural_frequencies,
    state_space,
)


def grounded_dyke(beta_damping: float = 0.0) -> BuildingParams:
    """The Dyke building with a base spring (so every mode oscillates), damping c = b k."""
    k = (12e3, 516e3, 684e3, 684e3)
    return BuildingParams(m=(98.3,) * 4, k=k, c=tuple(beta_damping * kj for kj in k))


def test_default_is_the_paper_building():
    p = BuildingParams.dyke()
    assert p.m == (98.3, 98.3, 98.3, 98.3)
    assert p.k == (0.0, 516e3, 684e3, 684e3)
    assert p.c == (0.0, 125.0, 50.0, 50.0)
    _, C, K = matrices(p)
    assert K[1, 1] == 516e3 + 684e3 and K[0, 1] == -516e3 and K[3, 3] == 684e3
    assert C[0, 0] == 125.0 and C[1, 2] == -50.0


def test_natural_frequencies_are_eigenvalues_of_m_inv_k():
    p = grounded_dyke()
    M, _, K = matrices(p)
    expected = np.sqrt(eigh(K, M, eigvals_only=True))
    assert natural_frequencies(p) == pytest.approx(expected, rel=1e-10)
    # and the undamped state matrix oscillates at exactly those frequencies
    A, _ = state_space(p)
    omegas = np.sort(np.abs(np.linalg.eigvals(A).imag))[::2]
    assert omegas == pytest.approx(expected, rel=1e-8)


def test_free_base_has_a_rigid_body_mode():
    assert natural_frequencies(BuildingParams.dyke())[0] == pytest.approx(0.0, abs=1e-3)


@pytest.mark.parametrize("mode", [0, 1, 3])
def test_free_decay_follows_the_modal_damping(mode):
    b = 2e-4  # stiffness-proportional damping: zeta_j = b * omega_j / 2
    p = grounded_dyke(b)
    M, _, K = matrices(p)
    w2, phi = eigh(K, M)
    w = np.sqrt(w2[mode])
    zeta = b * w / 2
    wd = w * np.sqrt(1 - zeta**2)
    bld = ShearBuilding(p)
    bld.q[: len(p.m)] = 1e-3 * phi[:, mode] / np.max(np.abs(phi[:, mode]))
    x0 = bld.x.copy()
    h = 1e-3
    for k in range(1, 2001):
        bld.step(0.0, 0.0, h)
        t = k * h
        envelope = np.exp(-zeta * w * t) * (np.cos(wd * t) + zeta / np.sqrt(1 - zeta**2) * np.sin(wd * t))
        assert bld.x == pytest.approx(envelope * x0, abs=1e-12)


def test_static_deflection_under_a_constant_base_force():
    p = grounded_dyke(1e-2)
    _, _, K = matrices(p)
    F = 250.0  # isolator restoring force [N]; the base is pushed by -F
    expected = np.linalg.solve(K, np.r_[-F, 0.0, 0.0, 0.0])
    bld = ShearBuilding(p)
    bld.step(0.0, F, 1e3)  # one exact step over a long time reaches the static state
    assert bld.x == pytest.approx(expected, rel=1e-9)
    assert bld.v == pytest.approx(np.zeros(4), abs=1e-12)


def test_ground_acceleration_loads_every_mass():
    p = grounded_dyke(1e-2)
    _, _, K = matrices(p)
    ag = 0.7
    bld = ShearBuilding(p)
    bld.step(ag, 0.0, 1e3)
    assert bld.x == pytest.approx(np.linalg.solve(K, -np.asarray(p.m) * ag), rel=1e-9)
    # at rest relative to the ground: no relative acceleration, the absolute one is the ground's
    assert bld.relative_acceleration(ag, 0.0) == pytest.approx(np.zeros(4), abs=1e-9)
    assert bld.absolute_acceleration(ag, 0.0) == pytest.approx(np.full(4, ag), abs=1e-9)


def test_exact_discretization_equals_a_tight_ode_solution():
    p = BuildingParams.dyke()
    A, B = state_space(p)
    rng = np.random.default_rng(3)
    bld = ShearBuilding(p)
    q = np.zeros(8)
    for _ in range(40):
        h = rng.choice([1e-3, 2.5e-3, 1e-2])
        u = np.array([rng.normal(0, 3.0), rng.normal(0, 200.0)])
        sol = solve_ivp(lambda t, y, u=u: A @ y + B @ u, (0, h), q, method="DOP853", rtol=1e-12, atol=1e-15)
        q = sol.y[:, -1]
        bld.step(u[0], u[1], h)
        assert bld.q == pytest.approx(q, rel=1e-8, abs=1e-13)


def test_drifts_and_storey_shears():
    p = grounded_dyke(1e-3)
    bld = ShearBuilding(p)
    bld.q[:] = [1e-3, 3e-3, 4e-3, 4.5e-3, 0.01, 0.02, 0.015, 0.0]
    assert bld.drifts() == pytest.approx([2e-3, 1e-3, 0.5e-3])
    k, c = np.array(p.k[1:]), np.array(p.c[1:])
    assert bld.storey_shears() == pytest.approx(k * [2e-3, 1e-3, 0.5e-3] + c * [0.01, -0.005, -0.015])


def test_invalid_parameters_are_rejected():
    with pytest.raises(ValueError, match="positive"):
        BuildingParams(m=(1.0, 0.0), k=(0.0, 1.0), c=(0.0, 1.0))
    with pytest.raises(ValueError, match="one entry per level"):
        BuildingParams(m=(1.0, 1.0), k=(0.0,), c=(0.0, 1.0))
