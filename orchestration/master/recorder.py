"""Recording chosen outputs at every communication point into preallocated arrays."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from orchestration.master.algorithm import CouplingAlgorithm
from orchestration.master.graph import Port


class Recorder:
    """Observer that copies the watched values after initialization and after every step."""

    def __init__(self, algorithm: CouplingAlgorithm, ports: Sequence[Port], n_steps: int) -> None:
        self.ports = list(ports)
        self.names = [f"{u}.{v}" for u, v in self.ports]
        self._values = algorithm.values
        self._slots = np.asarray([algorithm.slot[p] for p in self.ports], dtype=np.intp)
        self.time = np.full(n_steps + 1, np.nan)
        self.data = np.full((n_steps + 1, len(self.ports)), np.nan)
        self.count = 0  # rows written

    def record(self, k: int, t: float) -> None:
        """Store row k at time t [s]."""
        self.time[k] = t
        self.data[k] = self._values[self._slots]
        self.count = k + 1

    def column(self, name: str) -> np.ndarray:
        """Recorded values of one variable (``unit.var``), rows written so far."""
        return self.data[: self.count, self.names.index(name)]

    @property
    def times(self) -> np.ndarray:
        """Times of the rows written so far [s]."""
        return self.time[: self.count]
