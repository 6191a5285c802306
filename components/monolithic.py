"""The whole isolated-building system in one process, without FMUs.

Two references for the co-simulation:

* :func:`simulate_coupled` steps the same physics cores with the same communication step
  and the same transfer scheme as the master does with the FMUs (Gauss-Seidel order
  ground, building, controller, isolator, then feedthrough propagation; or Jacobi). It
  must agree with the FMU co-simulation to rounding: it proves the wrapping and the data
  transfer, independently of the coupling error.
* :func:`simulate_radau` integrates the coupled nonlinear ODE (building + isolator force
  at a constant current) in one piece with SciPy's Radau: the physics the co-simulation
  approximates, used to measure the coupling error.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from scipy.integrate import solve_ivp

from components.ground_motion_core import GroundMotion
from components.mre_isolator_core import TABLE2, GeneralizedCoefficients, isolator_force
from components.shear_building_core import BuildingParams, ShearBuilding, state_space
from components.sosm_controller_core import SosmController, SosmGains


@dataclass
class SystemSetup:
    """The paper's system: record playback, building, isolators and the current law."""

    motion: GroundMotion
    building: BuildingParams = field(default_factory=BuildingParams.dyke)
    coeffs: GeneralizedCoefficients = TABLE2
    n_isolators: int = 2
    i_max: float = 3.0
    passive_current: float | None = 0.0  # None: SOSM control
    gains: SosmGains = field(default_factory=SosmGains)


@dataclass
class Trajectory:
    """Time histories on the communication grid: x, v, a (absolute), arel per level; F; i."""

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    arel: np.ndarray
    F: np.ndarray
    i: np.ndarray
    ag: np.ndarray

    @property
    def drift(self) -> np.ndarray:
        """Inter-storey drifts, storeys 1..n [m]."""
        return np.diff(self.x, axis=1)

    def peaks(self) -> dict[str, float]:
        """Peak |value| of base displacement, drifts and absolute accelerations (SI)."""
        out = {"x_0": float(np.max(np.abs(self.x[:, 0])))}
        for j in range(self.drift.shape[1]):
            out[f"drift_{j + 1}"] = float(np.max(np.abs(self.drift[:, j])))
        for j in range(self.a.shape[1]):
            out[f"a_{j}"] = float(np.max(np.abs(self.a[:, j])))
        return out


def _force(setup: SystemSetup, x: float, v: float, i: float) -> float:
    i = min(max(i, 0.0), setup.i_max)
    return isolator_force(x, v, i, setup.coeffs, 0.0, setup.n_isolators)


def simulate_coupled(
    setup: SystemSetup, h: float, n_steps: int, scheme: Literal["gauss-seidel", "jacobi"] = "gauss-seidel"
) -> Trajectory:
    """Step the physics cores exactly as the master steps the FMUs (same step, same scheme)."""
    bld = ShearBuilding(setup.building)
    n = bld.n_levels
    sosm = setup.passive_current is None
    ctrl = SosmController(setup.gains, setup.coeffs) if sosm else None

    def current() -> float:
        if ctrl is not None:
            return ctrl.i
        return min(max(setup.passive_current, 0.0), setup.i_max)

    t_grid = np.array([k * h for k in range(n_steps + 1)])
    t_grid[-1] = n_steps * h
    out = {k: np.zeros((n_steps + 1, n)) for k in ("x", "v", "a", "arel")}
    F_hist = np.zeros(n_steps + 1)
    i_hist = np.zeros(n_steps + 1)
    ag_hist = np.zeros(n_steps + 1)

    ag = setup.motion.acceleration(0.0)
    i = current()
    F = _force(setup, bld.x[0], bld.v[0], i)

    def store(k: int) -> None:
        arel = bld.relative_acceleration(ag, F)
        out["x"][k], out["v"][k] = bld.x, bld.v
        out["arel"][k], out["a"][k] = arel, arel + ag
        F_hist[k], i_hist[k], ag_hist[k] = F, i, ag

    store(0)
    for k in range(n_steps):
        t = t_grid[k]
        t_next = t_grid[k + 1]
        step = t_next - t
        if scheme == "jacobi":
            arel_meas = bld.relative_acceleration(ag, F)[0]
            x_meas, v_meas = bld.x[0], bld.v[0]
            bld.step(ag, F, step)
            if ctrl is not None:
                ctrl.update(x_meas, v_meas, arel_meas, step)
            ag = setup.motion.acceleration(t_next)
        else:
            ag = setup.motion.acceleration(t_next)  # ground steps first
            bld.step(ag, F, step)  # building: fresh ag, force from t
            if ctrl is not None:  # controller: fresh states, acceleration with the force from t
                ctrl.update(bld.x[0], bld.v[0], bld.relative_acceleration(ag, F)[0], step)
        i = current()
        F = _force(setup, bld.x[0], bld.v[0], i)  # isolator, then feedthrough propagation
        store(k + 1)
    return Trajectory(t_grid, out["x"], out["v"], out["a"], out["arel"], F_hist, i_hist, ag_hist)


def simulate_radau(
    setup: SystemSetup, t_stop: float, t_eval: np.ndarray, rtol: float = 1e-8, atol: float = 1e-12
) -> Trajectory:
    """Monolithic reference: the coupled ODE at a constant current, integrated with Radau."""
    if setup.passive_current is None:
        raise ValueError("the Radau reference covers constant currents only")
    A, B = state_space(setup.building)
    n = len(setup.building.m)
    i = min(max(setup.passive_current, 0.0), setup.i_max)
    gm = setup.motion

    def rhs(t: float, q: np.ndarray) -> np.ndarray:
        F = isolator_force(q[0], q[n], i, setup.coeffs, 0.0, setup.n_isolators)
        return A @ q + B @ np.array((gm.acceleration(t), F))

    def jac(t: float, q: np.ndarray) -> np.ndarray:
        c = setup.coeffs
        beta = c.beta_0 * i + c.beta_1
        alpha = c.alpha_0 * i + c.alpha_1
        dF_dx = setup.n_isolators * (c.k0_0 * i + c.k0_1 + alpha * beta * np.cosh(beta * q[0]))
        dF_dv = setup.n_isolators * (c.c0_0 * i + c.c0_1)
        J = A.copy()
        J[:, 0] += B[:, 1] * dF_dx
        J[:, n] += B[:, 1] * dF_dv
        return J

    sol = solve_ivp(rhs, (0.0, t_stop), np.zeros(2 * n), method="Radau", t_eval=t_eval, rtol=rtol,
                    atol=atol, jac=jac, max_step=gm.record.time[1] - gm.record.time[0])
    if not sol.success:
        raise RuntimeError(f"Radau reference failed: {sol.message}")
    q = sol.y.T
    x, v = q[:, :n], q[:, n:]
    ag = np.array([gm.acceleration(t) for t in sol.t])
    F = np.array([isolator_force(xx, vv, i, setup.coeffs, 0.0, setup.n_isolators) for xx, vv in zip(x[:, 0], v[:, 0],
                                                                                                     strict=True)])
    arel = (A[n:] @ q.T + B[n:] @ np.vstack((ag, F))).T
    return Trajectory(sol.t, x, v, arel + ag[:, None], arel, F, np.full(len(sol.t), i), ag)
