"""The small interface the master talks to, and what it knows about a unit's variables.

The stepping algorithm sees only :class:`Unit`: ``setup``, ``exit_initialization``,
``step``, ``get_real``/``set_real`` on prepared reference sets, ``terminate``. The
FMI-backed implementation is :class:`orchestration.master.fmu_unit.FmuUnit`; tests drive the
algorithm with fake units that implement the same methods in plain Python.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np


@dataclass(frozen=True)
class Variable:
    """One FMU variable as declared in its model description."""

    name: str
    vr: int
    type: str  # Real, Integer, Boolean, String, Enumeration
    causality: str
    variability: str
    unit: str | None = None
    start: Any = None
    description: str = ""


@dataclass(frozen=True)
class UnitDescription:
    """A unit's interface: its variables and which inputs each output depends on directly.

    ``dependencies[output]`` is the tuple of input names the output depends on at the
    same time instant (direct feedthrough); ``None`` means not declared, i.e. all inputs.
    """

    name: str
    variables: dict[str, Variable]
    dependencies: dict[str, tuple[str, ...] | None] = field(default_factory=dict)
    model_identifier: str = ""
    fmi_version: str = "2.0"

    def outputs(self) -> list[Variable]:
        """Output variables in declaration order."""
        return [v for v in self.variables.values() if v.causality == "output"]

    def inputs(self) -> list[Variable]:
        """Input variables in declaration order."""
        return [v for v in self.variables.values() if v.causality == "input"]

    def feedthrough(self, output: str) -> tuple[str, ...]:
        """Inputs the output depends on directly (all inputs when undeclared)."""
        deps = self.dependencies.get(output)
        if deps is None:
            return tuple(v.name for v in self.inputs())
        return deps


class Unit(Protocol):
    """What the master needs from a co-simulation unit."""

    name: str
    description: UnitDescription

    def setup(self, start_time: float, stop_time: float) -> None:
        """Instantiate, apply parameters and start values, enter initialization mode."""

    def exit_initialization(self) -> None:
        """Leave initialization mode; the unit is ready to step."""

    def prepare(self, refs: Sequence[int]) -> Any:
        """An opaque handle for a fixed list of Real value references (prepared once)."""

    def get_real(self, handle: Any) -> np.ndarray:
        """Values of the prepared references (the array may be reused by the next call)."""

    def set_real(self, handle: Any, values: np.ndarray) -> None:
        """Set the prepared references to ``values``."""

    def step(self, t: float, h: float) -> None:
        """Advance from t to t + h [s]."""

    def terminate(self) -> None:
        """Terminate and free; safe to call more than once and after a failed setup."""
