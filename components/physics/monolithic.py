"""The whole isolated-building system in one process, without FMUs.

Two references for the co-simulation:

* :func:`simulate_coupled` steps the same physics cores with the same communication step,
  order, input estimate and feedthrough propagation as the master does with the FMUs. It
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

from components.physics.ground_motion_core import GroundMotion
from components.physics.mre_isolator_core import TABLE2, GeneralizedCoefficients, isolator_force
from components.physics.shear_building_core import BuildingParams, ShearBuilding, state_space
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


def _force(setup: SystemSetup, x: float, v: float, i: float) -> float:
    i = min(max(i, 0.0), setup.i_max)
    return isolator_force(x, v, i, setup.coeffs, 0.0, setup.n_isolators)


_EXTRAPOLATION = ((1.0, 0.0, 0.0), (1.5, -0.5, 0.0), (15.0 / 8.0, -10.0 / 8.0, 3.0 / 8.0))


class _History:
    """The last three values of a signal, newest first, and its mid-step extrapolation."""

    def __init__(self, value: float) -> None:
        self.values = [value, value, value]
        self.known = 1

    def push(self, value: float) -> None:
        self.values = [value, *self.values[:2]]
        self.known += 1

    @property
    def now(self) -> float:
        return self.values[0]

    def extrapolated(self) -> float:
        c = _EXTRAPOLATION[min(self.known, 3) - 1]
        return c[0] * self.values[0] + c[1] * self.values[1] + c[2] * self.values[2]


def simulate_coupled(
    setup: SystemSetup,
    h: float,
    n_steps: int,
    scheme: Literal["gauss-seidel", "jacobi"] = "gauss-seidel",
    inputs: Literal["step-mean", "hold"] = "step-mean",
) -> Trajectory:
    """Step the physics cores exactly as the master steps the FMUs of ``scenarios/isolated_building.yaml``.

    Same step, order (Gauss-Seidel: ground, controller, building, isolator; Jacobi: all from
    the values at t), input estimate (``hold`` or ``step-mean``), delayed controller
    measurements and feedthrough propagation as :class:`orchestration.master.algorithm.CouplingAlgorithm`.
    """
    bld = ShearBuilding(setup.building)
    n = bld.n_levels
    ctrl = SosmController(setup.gains, setup.coeffs) if setup.passive_current is None else None

    def current() -> float:
        if ctrl is not None:
            return ctrl.i
        return min(max(setup.passive_current, 0.0), setup.i_max)

    t_grid = np.array([k * h for k in range(n_steps + 1)])
    out = {k: np.zeros((n_steps + 1, n)) for k in ("x", "v", "a", "arel")}
    F_hist = np.zeros(n_steps + 1)
    i_hist = np.zeros(n_steps + 1)
    ag_hist = np.zeros(n_steps + 1)

    ag = setup.motion.acceleration(0.0)
    i = current()
    F = _force(setup, bld.x[0], bld.v[0], i)
    ag_h, F_h = _History(ag), _History(F)

    def store(k: int) -> None:
        arel = bld.relative_acceleration(ag, F)
        out["x"][k], out["v"][k] = bld.x, bld.v
        out["arel"][k], out["a"][k] = arel, arel + ag
        F_hist[k], i_hist[k], ag_hist[k] = F, i, ag

    store(0)
    for k in range(n_steps):
        t = t_grid[k]
        step = t_grid[k + 1] - t
        arel_now = bld.relative_acceleration(ag, F)[0]  # the controller's delayed measurements
        x_now, v_now = bld.x[0], bld.v[0]
        ag_next = setup.motion.acceleration(t_grid[k + 1])
        fresh_ground = scheme == "gauss-seidel"  # Gauss-Seidel steps the ground first
        if inputs == "hold":
            ag_in = ag_next if fresh_ground else ag
            F_in = F
        else:
            ag_in = 0.5 * (ag + ag_next) if fresh_ground else ag_h.extrapolated()
            F_in = F_h.extrapolated()
        if ctrl is not None:
            ctrl.update(x_now, v_now, arel_now, step)
        bld.step(ag_in, F_in, step)
        ag = ag_next
        i = current()
        F = _force(setup, bld.x[0], bld.v[0], i)  # isolator output at t + h (feedthrough propagation)
        ag_h.push(ag)
        F_h.push(F)
        store(k + 1)
    return Trajectory(t_grid, out["x"], out["v"], out["a"], out["arel"], F_hist, i_hist, ag_hist)


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
        beta = c.beta_0 * i + c.beta_1
        alpha = c.alpha_0 * i + c.alpha_1
        dF_dx = setup.n_isolators * (c.k0_0 * i + c.k0_1 + alpha * beta * np.cosh(beta * q[0]))
        dF_dv = setup.n_isolators * (c.c0_0 * i + c.c0_1)
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
