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

    def extrapolated(self, usable: int = 3, peeked: float | None = None) -> float:
        """Mid-step value from the newest ``usable`` values (fewer after a held input changed); ``peeked``: the
        value at the restart with the new held input, standing in for the history value there."""
        if peeked is not None and usable < 3:
            c = _EXTRAPOLATION[usable]
            second = peeked if usable == 1 else self.values[1]
            third = peeked if usable == 2 else self.values[2]
            return c[0] * self.values[0] + c[1] * second + c[2] * third
        c = _EXTRAPOLATION[min(self.known, usable) - 1]
        return c[0] * self.values[0] + c[1] * self.values[1] + c[2] * self.values[2]

    def usable(self) -> int:
        """For a held signal: how many of its last values equal the newest one in a row (1, 2 or 3)."""
        a, b, c = self.values
        return 1 if a != b else 2 if b != c else 3


def simulate_coupled(
    setup: SystemSetup,
    h: float,
    n_steps: int,
    scheme: Literal["gauss-seidel", "jacobi"] = "gauss-seidel",
    inputs: Literal["step-mean", "hold"] = "step-mean",
    controller_every: int = 1,
) -> Trajectory:
    """Step the physics cores exactly as the master steps the FMUs of ``scenarios/isolated_building.yaml``.

    Same step, order (Gauss-Seidel: ground, controller, building, isolator; Jacobi: all from
    the values at t), input estimate (``hold`` or ``step-mean``), delayed controller
    measurements and feedthrough propagation as :class:`orchestration.master.algorithm.CouplingAlgorithm`.

    ``controller_every`` = m > 1: the controller has its own step m·h. It steps from T = k·h to
    (k + m)·h in the base steps k with k % m == 0, from the measurements at T; its current is held
    over the base steps: Gauss-Seidel (controller first) applies the new current from T on,
    Jacobi the one it had at its last grid point, so from T + m·h on. In Gauss-Seidel the
    isolator force's estimate restarts after the (held) current changed: in the step where it
    jumps, the building gets the force at t with the new current, then the history since the jump.
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
    ag_h, F_h, i_h = _History(ag), _History(F), _History(i)
    m = controller_every
    i_grid = i  # the current at the controller's last grid point (what Jacobi's isolator sees when m > 1)
    restarts = m > 1 and scheme == "gauss-seidel"  # a held current the force depends on (read fresh)
    F_peeked = 0.0  # the force at the last jump of the current, with the new current

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
        if ctrl is not None and k % m == 0:  # it steps before the building (Gauss-Seidel), from the samples at t
            ctrl.update(x_now, v_now, arel_now, step if m == 1 else t_grid[k + m] - t)
        if inputs == "hold":
            ag_in = ag_next if fresh_ground else ag
            F_in = F
        else:
            ag_in = 0.5 * (ag + ag_next) if fresh_ground else ag_h.extrapolated()
            if restarts and current() != i_h.now:  # the held current jumped: the force at t with the new one
                F_peeked = F_in = _force(setup, x_now, v_now, current())
            else:
                F_in = F_h.extrapolated(i_h.usable(), F_peeked) if restarts else F_h.extrapolated()
        bld.step(ag_in, F_in, step)
        ag = ag_next
        i = current()
        if (k + 1) % m == 0:
            i_grid = i
        i_seen = i if m == 1 or scheme == "gauss-seidel" else i_grid
        F = _force(setup, bld.x[0], bld.v[0], i_seen)  # isolator output at t + h (feedthrough propagation)
        ag_h.push(ag)
        F_h.push(F)
        i_h.push(i)
        store(k + 1)
    return Trajectory(t_grid, out["x"], out["v"], out["a"], out["arel"], F_hist, i_hist, ag_hist)
