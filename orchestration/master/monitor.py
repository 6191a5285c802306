"""Run-time checks on exchanged values: non-finite values and physical limits stop a run."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from orchestration.master.algorithm import CouplingAlgorithm
from orchestration.master.errors import SimulationError
from orchestration.master.graph import Port


class Monitor:
    """Observer that raises SimulationError on NaN/inf in any exchanged value or a limit exceeded."""

    def __init__(self, algorithm: CouplingAlgorithm, limits: Mapping[Port, float]) -> None:
        self._values = algorithm.values
        self._ports = list(algorithm.slot)
        self._limit_slots = np.asarray([algorithm.slot[p] for p in limits], dtype=np.intp)
        self._limit_ports = list(limits)
        self._limits = np.asarray(list(limits.values()), dtype=float)

    @property
    def limits(self) -> dict[Port, float]:
        """Watched output -> largest admissible absolute value."""
        return dict(zip(self._limit_ports, self._limits.tolist(), strict=True))

    def record(self, k: int, t: float) -> None:
        values = self._values
        if not np.isfinite(values).all():
            j = int(np.flatnonzero(~np.isfinite(values))[0])
            unit, var = self._ports[j]
            raise SimulationError(f"output is {values[j]}", unit=unit, variable=var, time=t)
        if len(self._limits):
            over = np.abs(values[self._limit_slots]) > self._limits
            if over.any():
                j = int(np.flatnonzero(over)[0])
                unit, var = self._limit_ports[j]
                raise SimulationError(
                    f"|{var}| = {abs(values[self._limit_slots[j]]):.6g} exceeds the limit {self._limits[j]:.6g} "
                    "(scenario key limits.max_abs): the run diverged or left the physical range",
                    unit=unit, variable=var, time=t,
                )
