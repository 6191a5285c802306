"""The paper's isolated building in one process, stepped by the engine's own coupling algorithm.

:func:`simulate_coupled` builds the in-process units of :mod:`orchestration.inprocess.units` for a
:class:`~components.physics.monolithic.SystemSetup`, couples them with the connections of
``scenarios/isolated_building.yaml`` (:data:`CONNECTIONS`) in a
:class:`~orchestration.master.algorithm.CouplingAlgorithm`, which initializes them and plans each
step (order, input estimate, delayed controller measurements, feedthrough propagation), and runs
that plan with the scalar executor (or with the engine's own ``step()`` through
:func:`~orchestration.master.execution.execute`): the scheme of a scenario run with the FMUs,
because it is the same code. Tuning and base sensitivity optimise on it, so they always optimise
the scheme the co-simulation runs.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from components.physics.monolithic import SystemSetup, Trajectory
from orchestration.inprocess.scalar_executor import ScalarExecutor
from orchestration.inprocess.units import GroundMotionUnit, MreIsolatorUnit, ShearBuildingUnit, SosmControllerUnit
from orchestration.master.algorithm import CouplingAlgorithm, InputEstimate, Scheme
from orchestration.master.execution import execute, time_grid
from orchestration.master.graph import Link, Port
from orchestration.master.unit import Unit

CONNECTIONS: tuple[Link, ...] = (
    Link(("ground", "ag"), ("building", "ag")),
    Link(("building", "x_0"), ("isolator", "x")),
    Link(("building", "v_0"), ("isolator", "v")),
    Link(("controller", "i"), ("isolator", "i")),
    Link(("isolator", "F"), ("building", "F")),
    # the controller samples its measurements at the communication points (the value at t)
    Link(("building", "x_0"), ("controller", "x"), delayed=True),
    Link(("building", "v_0"), ("controller", "v"), delayed=True),
    Link(("building", "arel_0"), ("controller", "a"), delayed=True),
)
"""The connections of ``scenarios/isolated_building.yaml`` (a test keeps the two equal)."""


def build_units(setup: SystemSetup) -> list[Unit]:
    """The four units of the system, in the scenario's order: ground, building, isolator, controller."""
    return [
        GroundMotionUnit(setup.motion),
        ShearBuildingUnit(setup.building),
        MreIsolatorUnit(setup.coeffs, setup.n_isolators, setup.i_max),
        SosmControllerUnit(setup.gains, setup.coeffs, setup.passive_current, i_max=setup.i_max),
    ]


class _TrajectoryRecorder:
    """Observer of :func:`execute`: copies the watched slots into one preallocated row per communication point."""

    def __init__(self, algorithm: CouplingAlgorithm, ports: list[Port], n_steps: int) -> None:
        self._values = algorithm.values
        self._slots = np.asarray([algorithm.slot[p] for p in ports], dtype=np.intp)
        self.rows = np.zeros((n_steps + 1, len(ports)))
        self.t = np.zeros(n_steps + 1)

    def record(self, k: int, t: float) -> None:
        np.take(self._values, self._slots, out=self.rows[k])
        self.t[k] = t


def simulate_coupled(
    setup: SystemSetup,
    h: float,
    n_steps: int,
    scheme: Scheme = "gauss-seidel",
    inputs: InputEstimate = "step-mean",
    executor: Literal["scalar", "python"] = "scalar",
    controller_every: int = 1,
) -> Trajectory:
    """Step the system of ``setup`` for ``n_steps`` communication steps of h [s] from t = 0, as a scenario
    run steps its FMUs (``simulation.algorithm`` = ``scheme``, ``simulation.inputs`` = ``inputs``).

    ``executor``: ``scalar`` runs the algorithm's program as Python floats
    (:class:`~orchestration.inprocess.scalar_executor.ScalarExecutor`, the fast one); ``python``
    steps with :meth:`CouplingAlgorithm.step` through the engine's
    :func:`~orchestration.master.execution.execute`. Both give the same numbers, bit for bit.

    The trajectory's absolute accelerations are arel + ag of the recorded columns (as for
    :func:`~components.physics.monolithic.simulate_radau`); the building unit's own ``a_j`` outputs
    sum the same terms in another order and may differ from them in the last bit.

    ``controller_every``: the controller's own step in base steps (``units.controller.step`` =
    ``controller_every`` · h); ``n_steps`` must be a multiple of it.
    """
    units = build_units(setup)
    n = units[1].model.n_levels
    ports = ([("building", f"x_{j}") for j in range(n)] + [("building", f"v_{j}") for j in range(n)]
             + [("building", f"arel_{j}") for j in range(n)]
             + [("isolator", "F"), ("controller", "i"), ("ground", "ag")])
    algorithm = CouplingAlgorithm(units, CONNECTIONS, ports, scheme=scheme, inputs=inputs,
                                  periods={"controller": controller_every})
    stop = n_steps * h
    if executor == "python":
        recorder = _TrajectoryRecorder(algorithm, ports, n_steps)
        result = execute(algorithm, 0.0, stop, h, [recorder], executor="python")
        if not result.complete:
            raise result.error
        t, rows = recorder.t, recorder.rows
    else:
        n_grid, t_of = time_grid(0.0, stop, h)
        try:
            algorithm.initialize(0.0, stop, h)
            scalar = ScalarExecutor(algorithm, ports)
            scalar.run(0, n_grid, t_of)
        finally:
            for unit in units:
                unit.terminate()
        t, rows = np.array([t_of(k) for k in range(n_grid + 1)]), scalar.rows()
    x, v, arel = rows[:, :n], rows[:, n:2 * n], rows[:, 2 * n:3 * n]
    F, i, ag = rows[:, 3 * n], rows[:, 3 * n + 1], rows[:, 3 * n + 2]
    return Trajectory(t, x, v, arel + ag[:, None], arel, F, i, ag)
