"""The whole isolated-building system in one process, without FMUs: its description and a monolithic reference.

* :class:`SystemSetup` describes the paper's system (record, building, isolators, current law),
  :class:`Trajectory` holds its time histories on a grid.
* :func:`simulate_radau` integrates the coupled nonlinear ODE (building + isolator force
  at a constant current, or a sampled-data SOSM current) in one piece with SciPy's Radau:
  the physics the co-simulation approximates, used to measure the coupling error.

The co-simulation of the same system without FMUs (the same cores stepped in-process by the
engine's coupling algorithm) is :func:`orchestration.inprocess.simulate_coupled`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp

from components.physics.ground_motion_core import GroundMotion
from components.physics.mre_isolator_core import (
    TABLE2,
    GeneralizedCoefficients,
    isolator_damping,
    isolator_force,
    isolator_stiffness,
)
from components.physics.shear_building_core import BuildingParams, state_space
from components.physics.sosm_controller_core import SosmController, SosmGains


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


def _radau_functions(setup: SystemSetup, current):
    A, B = state_space(setup.building)
    n = len(setup.building.m)
    gm = setup.motion
    c = setup.coeffs

    def rhs(t: float, q: np.ndarray) -> np.ndarray:
        F = isolator_force(q[0], q[n], current(t), c, 0.0, setup.n_isolators)
        return A @ q + B @ np.array((gm.acceleration(t), F))

    def jac(t: float, q: np.ndarray) -> np.ndarray:
        i = current(t)
        dF_dx = isolator_stiffness(float(q[0]), i, c, setup.n_isolators)
        dF_dv = isolator_damping(i, c, setup.n_isolators)
        J = A.copy()
        J[:, 0] += B[:, 1] * dF_dx
        J[:, n] += B[:, 1] * dF_dv
        return J

    return A, B, n, rhs, jac


def simulate_radau(
    setup: SystemSetup, t_stop: float, t_eval: np.ndarray, rtol: float = 1e-8, atol: float = 1e-12
) -> Trajectory:
    """Monolithic reference of the same physics, integrated with Radau.

    Constant current: one Radau solve of the coupled nonlinear ODE. SOSM: the controller is
    a sampled-data controller at the points of ``t_eval`` (uniform): at t_k it measures
    x_0, v_0 and the relative base acceleration, computes the rate u_k of Eq. (39), and the
    current ramps as clip(i_k + (t - t_k) u_k, 0, i_max) until t_{k+1}; the plant is
    integrated with Radau between samples.
    """
    gm = setup.motion
    max_step = gm.record.time[1] - gm.record.time[0]
    if setup.passive_current is not None:
        i0 = min(max(setup.passive_current, 0.0), setup.i_max)
        A, B, n, rhs, jac = _radau_functions(setup, lambda t: i0)
        sol = solve_ivp(rhs, (0.0, t_stop), np.zeros(2 * n), method="Radau", t_eval=t_eval, rtol=rtol,
                        atol=atol, jac=jac, max_step=max_step)
        if not sol.success:
            raise RuntimeError(f"Radau reference failed: {sol.message}")
        q = sol.y.T
        i_t = np.full(len(sol.t), i0)
    else:
        ctrl = SosmController(setup.gains, setup.coeffs)
        seg = {"t0": 0.0, "i0": 0.0, "u": 0.0}

        def current(t: float) -> float:
            return min(max(seg["i0"] + (t - seg["t0"]) * seg["u"], 0.0), setup.i_max)

        A, B, n, rhs, jac = _radau_functions(setup, current)
        q = np.zeros((len(t_eval), 2 * n))
        i_t = np.zeros(len(t_eval))
        for k in range(len(t_eval) - 1):
            t0, t1 = t_eval[k], t_eval[k + 1]
            seg["t0"], seg["i0"], seg["u"] = t0, ctrl.i, 0.0
            i_t[k] = ctrl.i
            F = isolator_force(q[k, 0], q[k, n], ctrl.i, setup.coeffs, 0.0, setup.n_isolators)
            arel0 = (A[n] @ q[k] + B[n] @ np.array((gm.acceleration(t0), F)))
            seg["u"] = ctrl.rate(q[k, 0], q[k, n], arel0)
            ctrl.i = current(t1)
            sol = solve_ivp(rhs, (t0, t1), q[k], method="Radau", rtol=rtol, atol=atol, jac=jac,
                            first_step=(t1 - t0) / 4)
            if not sol.success:
                raise RuntimeError(f"Radau reference failed at t = {t0}: {sol.message}")
            q[k + 1] = sol.y[:, -1]
        i_t[-1] = ctrl.i
    t = np.asarray(t_eval)
    x, v = q[:, :n], q[:, n:]
    ag = np.array([gm.acceleration(tt) for tt in t])
    F = np.array([isolator_force(xx, vv, ii, setup.coeffs, 0.0, setup.n_isolators)
                  for xx, vv, ii in zip(x[:, 0], v[:, 0], i_t, strict=True)])
    arel = (A[n:] @ q.T + B[n:] @ np.vstack((ag, F))).T
    return Trajectory(t, x, v, arel + ag[:, None], arel, F, i_t, ag)
