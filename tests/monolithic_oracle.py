"""Test oracle: the isolated building stepped by a hand-written copy of the coupling algorithm.

This is the former ``components.physics.monolithic.simulate_coupled``: the physics cores stepped
with the Gauss-Seidel/Jacobi order, the step-mean/hold input estimate, the delayed controller
measurements and the feedthrough propagation of
:class:`orchestration.master.algorithm.CouplingAlgorithm`, written out by hand for this one
system. The product no longer uses it (tuning and base sensitivity step in-process units with
the engine's own algorithm: :func:`orchestration.inprocess.simulate_coupled`); tests keep it as
an independent expectation of what that algorithm computes for this system.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from components.physics.monolithic import SystemSetup, Trajectory
from components.physics.mre_isolator_core import isolator_force
from components.physics.shear_building_core import ShearBuilding
from components.physics.sosm_controller_core import SosmController


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
