"""The small interface the master talks to, and what it knows about a unit's variables.

The stepping algorithm sees only :class:`Unit`: ``setup``, ``exit_initialization``,
``step``, ``get_real``/``set_real`` on prepared reference sets (the fast path for Real values),
``get_values``/``set_values`` for every other type (plain Python values), ``terminate``. The
FMI-backed implementation is :class:`orchestration.master.fmi2_cosim_unit.FmuUnit`; tests drive the
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
    type: str  # Real, Integer, Boolean, String, Enumeration (FMI 3.0: Float64 is Real, Int32/Int64 Integer)
    causality: str
    variability: str
    unit: str | None = None
    start: Any = None
    description: str = ""
    declared_type: str = ""  # the type as the FMU declares it (FMI 3.0: Float64, Int64, ...); empty: ``type``
    items: tuple[tuple[str, int], ...] = ()  # Enumeration: (item name, value) of its type definition
    min_value: float | None = None  # declared min (the variable's, else its declared type's), if any
    max_value: float | None = None  # declared max, if any

    @property
    def fmi_type(self) -> str:
        """The type as the FMU declares it: FMI 2.0 Real ... Enumeration, FMI 3.0 Float64, Int8 ... UInt64, ..."""
        if self.type.endswith(" array") or not self.declared_type:
            return self.type
        return self.declared_type

    @property
    def fast_real(self) -> bool:
        """Exchanged through the Real fast path (prepared arrays): FMI 2.0 Real and FMI 3.0 Float64."""
        return self.type == "Real"


INTEGER_RANGES: dict[str, tuple[int, int]] = {
    "Integer": (-(2**31), 2**31 - 1),  # FMI 2.0 fmi2Integer
    "Int8": (-(2**7), 2**7 - 1), "UInt8": (0, 2**8 - 1),
    "Int16": (-(2**15), 2**15 - 1), "UInt16": (0, 2**16 - 1),
    "Int32": (-(2**31), 2**31 - 1), "UInt32": (0, 2**32 - 1),
    "Int64": (-(2**63), 2**63 - 1), "UInt64": (0, 2**64 - 1),
}
"""Value ranges of the integer types (FMI 2.0 Integer and the FMI 3.0 integer types)."""

EXCHANGED_TYPES = frozenset({"Real", "Float64", "Float32", "Boolean", "String", "Enumeration", *INTEGER_RANGES})
"""Types the master connects, sets and records (FMI 3.0 Binary, clocks and arrays are refused)."""

_SAME_VALUES = {"Float64": "Real", "Int32": "Integer"}  # FMI 3.0 types with the FMI 2.0 type's exact value set


def exchange_kind(fmi_type: str) -> str:
    """The value set of a declared type: two ports connect only when theirs are equal (no conversions).

    FMI 2.0 Real and FMI 3.0 Float64 are the same IEEE double, FMI 2.0 Integer and FMI 3.0
    Int32 the same 32-bit integer, an Enumeration is an Enumeration in both versions; every
    other type only matches itself.
    """
    return _SAME_VALUES.get(fmi_type, fmi_type)


def start_value(var: Variable) -> Any:
    """A declared start value (text in the model description) as the Python value a scenario would set for it.

    By the declared type (:attr:`Variable.fmi_type`), as the FMI XML schema reads the text: Real and
    FloatNN as float (``INF``, ``-INF``, ``NaN`` included), the integer types and Enumeration as int,
    Boolean as xs:boolean (``true``/``1``, surrounding white space ignored, case as written or not);
    text that does not parse, and every other type (String, arrays, ...), is kept as it is.
    """
    fmi_type, start = var.fmi_type, var.start
    try:
        if fmi_type.startswith(("Real", "Float")):
            return float(start)
        if fmi_type in INTEGER_RANGES or fmi_type == "Enumeration":
            return int(start)
    except (TypeError, ValueError):
        return start
    if fmi_type == "Boolean":
        return str(start).strip().lower() in ("true", "1")
    return start


def value_range(fmi_type: str, fmi_version: str = "2.0") -> tuple[int, int] | None:
    """The range of an integer or enumeration type (FMI 2.0 enumerations are 32-bit, FMI 3.0 ones 64-bit)."""
    if fmi_type == "Enumeration":
        return INTEGER_RANGES["Int64" if fmi_version.startswith("3.") else "Integer"]
    return INTEGER_RANGES.get(fmi_type)


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

    @property
    def time(self) -> float | None:
        """The unit's time as error messages report it: t before a step, t + h after it [s] (None before setup)."""

    @time.setter
    def time(self, value: float) -> None:
        """Set by an executor that stepped the unit outside Python (the native one)."""

    # ``handle``: what prepare returned, opaque to the master and handed back to the same unit only (each unit
    # type has its own kind; an FMU unit's is a ValueBuffer)
    def prepare(self, refs: Sequence[int]) -> object:
        """An opaque handle for a fixed list of Real value references (prepared once)."""

    def get_real(self, handle: Any) -> np.ndarray:
        """Values of the prepared references (the array may be reused by the next call)."""

    def set_real(self, handle: Any, values: np.ndarray) -> None:
        """Set the prepared references to ``values``."""

    def get_values(self, fmi_type: str, refs: Sequence[int]) -> list[Any]:
        """Values of variables of any other type (``fmi_type`` as :attr:`Variable.fmi_type`): int for
        integer and enumeration types, bool for Boolean, str for String, float for Real/Float*."""

    def set_values(self, fmi_type: str, refs: Sequence[int], values: Sequence[Any]) -> None:
        """Set variables of any other type to plain Python values (as :meth:`get_values` returns them)."""

    def step(self, t: float, h: float) -> None:
        """Advance from t to t + h [s]."""

    def terminate(self) -> None:
        """Terminate and free; safe to call more than once and after a failed setup."""

    def native_functions(self) -> tuple[int, int, int, int] | None:
        """Addresses of (component, SetReal, GetReal, DoStep) for the native executor, or None: it cannot drive
        this unit (not an instantiated FMI 2.0 co-simulation FMU)."""

    def raise_status(self, function: str, status: int) -> None:
        """Translate an FMI status that ``function`` of this unit returned outside Python (raises above warning)."""
