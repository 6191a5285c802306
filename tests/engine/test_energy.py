"""The building's energy integrals: exact for held inputs, checked against independent integrations and known
dissipation; the balance closes to round-off (linear storeys) or Newton's tolerance (yielding storeys)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from components.physics.shear_building_core import (
    BuildingParams,
    HystereticShearBuilding,
    ShearBuilding,
    StoreyLaws,
    make_building,
    matrices,
    state_space,
    zoh_quadratic_integral,
)

H = 1e-3


def _drive(building, n: int, seed: int = 3, ag_amp: float = 3.0, f_amp: float = 2000.0) -> None:
    """Random-phase inputs held over each step (what a co-simulation gives the building)."""
    rng = np.random.default_rng(seed)
    for k in range(n):
        _drive_step(building, k, rng, ag_amp, f_amp)


def _drive_step(building, k: int, rng: np.random.Generator, ag_amp: float = 3.0, f_amp: float = 2000.0) -> None:
    """Step k of :func:`_drive`."""
    t = k * H
    building.step(ag_amp * np.sin(2 * np.pi * 1.3 * t) + 0.5 * ag_amp * rng.standard_normal(),
                  f_amp * np.sin(2 * np.pi * 0.6 * t + 0.3), H)


def _residual(e: np.ndarray) -> float:
    """E_in - (E_iso + E_damp + E_strain + E_hyst + E_kin)."""
    return float(e[0] - e[1:].sum())


def test_linear_balance_closes_to_round_off():
    """Round-off: each of the n steps adds the step's work to running sums as large as the run's peak energy, a
    few roundings of eps times that peak each (20 of them, a generous count), so |residual| <= 20 n eps peak. The
    final energies are no scale: the input and isolator works here end near 100 J after peaks near 1.4 kJ."""
    b = ShearBuilding(BuildingParams.dyke())
    n, peak, rng = 5000, 0.0, np.random.default_rng(3)
    for k in range(n):
        _drive_step(b, k, rng)  # the inputs of _drive(b, n)
        peak = max(peak, float(np.max(np.abs(b.energies()))))
    e = b.energies()
    assert max(abs(e[0]), abs(e[1])) > 1.0  # the inputs did work
    assert abs(_residual(e)) < 20 * n * np.finfo(float).eps * peak
    assert e[2] > 0 and e[4] == 0.0  # damping takes energy; linear storeys no hysteretic work


def test_each_step_work_matches_a_tight_integration_of_the_held_input_ode():
    # Independent of Van Loan's formula and of Phi/Gamma: DOP853 on q' = A q + B u with the energies as
    # extra states (input power -ag m.v, isolator power F v_0, damping power v'Cv), u held over each step.
    p = BuildingParams.dyke()
    A, B = state_space(p)
    M, C, _ = matrices(p)
    m = np.diag(M)
    n = len(m)
    b = ShearBuilding(p)
    rng = np.random.default_rng(5)
    y = np.zeros(2 * n + 3)
    for _ in range(40):
        ag, F = rng.normal(0, 3.0), rng.normal(0, 1500.0)

        def rhs(t, y, ag=ag, F=F):
            q = y[: 2 * n]
            v = q[n:]
            return np.concatenate([A @ q + B @ [ag, F], [-ag * m @ v, F * v[0], v @ C @ v]])

        y = solve_ivp(rhs, (0.0, H), y, method="DOP853", rtol=1e-12, atol=1e-15).y[:, -1]
        b.step(ag, F, H)
    e = b.energies()
    assert np.allclose(b.q, y[: 2 * n], rtol=1e-8, atol=1e-12)
    for k in range(3):
        assert e[k] == pytest.approx(y[2 * n + k], rel=1e-7, abs=1e-12)


def test_known_dissipation_free_vibration_loses_all_its_energy_to_damping():
    # A building tied to the ground (k_0 > 0, c_0 > 0) released from a deflected, moving state with no input:
    # at rest, the dampers took exactly its initial energy 1/2 x'Kx + 1/2 v'Mv (no other work is done).
    p = BuildingParams(m=(98.3,) * 4, k=(2e5, 516e3, 684e3, 684e3), c=(400.0, 125.0, 50.0, 50.0))
    M, _, K = matrices(p)
    b = ShearBuilding(p)
    x0, v0 = np.array([0.01, 0.012, 0.013, 0.014]), np.array([0.0, 0.05, -0.02, 0.1])
    b.q = np.concatenate([x0, v0])
    initial = 0.5 * x0 @ K @ x0 + 0.5 * v0 @ M @ v0
    for _ in range(60_000):  # 60 s: every mode decays by more than e^-20
        b.step(0.0, 0.0, H)
    e = b.energies()
    assert e[0] == 0.0 and e[1] == 0.0
    assert e[3] + e[5] < 1e-9 * initial
    assert e[2] == pytest.approx(initial, rel=1e-9)


def test_van_loan_integral_of_a_scalar_decay():
    # q' = -a q + u, integral of q^2 over h from q0 with u held: closed form.
    a, h, q0, u = 3.0, 0.2, 1.5, 0.7
    W = zoh_quadratic_integral(np.array([[-a]]), np.array([[1.0]]), np.diag([1.0, 0.0]), h)
    z = np.array([q0, u])
    c = u / a  # q(t) = c + (q0 - c) e^{-a t}
    exact = c * c * h + 2 * c * (q0 - c) * (1 - np.exp(-a * h)) / a + (q0 - c) ** 2 * (1 - np.exp(-2 * a * h)) / (2 * a)
    assert z @ W @ z == pytest.approx(exact, rel=1e-12)


@pytest.mark.parametrize("law", ["bilinear", "bouc-wen"])
def test_yielding_balance_closes_and_storeys_dissipate(law):
    laws = StoreyLaws(law, (1500.0, 1700.0, 1500.0), (0.05,) * 3, (2.0,) * 3)
    b = make_building(BuildingParams.dyke(), laws)
    assert isinstance(b, HystereticShearBuilding)
    _drive(b, 6000, ag_amp=4.0)
    e = b.energies()
    scale = max(abs(e[0]), abs(e[1]))
    assert abs(_residual(e)) < 1e-7 * scale  # Newton's tolerance, not a discretization error
    assert e[4] > 1.0  # [J] the storeys yielded and took energy (all three at yield hold 5.9 J)
    assert e[3] >= 0 and e[5] >= 0


def test_bilinear_storeys_that_stay_elastic_keep_the_linear_books():
    # Far below yield the bilinear building is the linear one (exact elastic path): the same energies.
    p = BuildingParams.dyke()
    lin = ShearBuilding(p)
    bil = make_building(p, StoreyLaws("bilinear", (1e6,) * 3, (0.05,) * 3, (2.0,) * 3))
    _drive(lin, 2000, ag_amp=0.5, f_amp=100.0)
    _drive(bil, 2000, ag_amp=0.5, f_amp=100.0)
    e_lin, e_bil = lin.energies(), bil.energies()
    assert np.allclose(e_bil, e_lin, rtol=1e-8, atol=1e-12 * abs(e_lin[0]))
    assert abs(e_bil[4]) < 1e-9 * abs(e_lin[0])


def test_p_delta_strain_energy_counts_the_geometric_stiffness():
    laws = StoreyLaws("bilinear", (1500.0,) * 3, (0.05,) * 3, (2.0,) * 3, p_delta=True, h=(0.5, 0.5, 0.5))
    b = make_building(BuildingParams.dyke(), laws)
    _drive(b, 4000, ag_amp=4.0)
    e = b.energies()
    assert abs(_residual(e)) < 1e-7 * max(abs(e[0]), abs(e[1]))
