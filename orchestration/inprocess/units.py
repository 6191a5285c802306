"""In-process units: the physics cores of ``components/physics`` behind the engine's :class:`Unit` interface.

Each adapter declares the same variables (names, causality, SI units, direct-feedthrough
dependencies) as the FMU shell of the same core in ``components/shells``, so the engine's
:class:`~orchestration.master.algorithm.CouplingAlgorithm` couples them with the same
connections, order, input estimates and feedthrough propagation as the FMUs of a scenario,
without FMI, zip files or a second interpreter. Parameters are given to the constructor
(the cores' own objects), not as FMU parameters; only Real inputs and outputs are declared.

Fast path: the algorithm exchanges the same prepared reference sets every step; a
handle knows whether it is the unit's whole input (or output) vector in declaration
order, so ``set_real``/``get_real`` then move the values with no per-call look-up.
The values and the floating-point operations are those of the FMU shells: equal results
bit for bit (tests/engine/test_inprocess.py checks it against the FMU co-simulation).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from operator import itemgetter
from typing import Any

import numpy as np

from components.physics.ground_motion_core import GroundMotion
from components.physics.mre_isolator_core import TABLE2, GeneralizedCoefficients, force_law
from components.physics.shear_building_core import BuildingParams, ShearBuilding
from components.physics.sosm_controller_core import SosmController, SosmGains
from orchestration.master.unit import UnitDescription, Variable


@dataclass
class _Handle:
    """A prepared reference set: positions in the unit's input (or output) vector, and its fast path."""

    refs: tuple[int, ...]
    index: np.ndarray  # positions in the input or output vector
    whole: bool  # exactly the whole vector, in declaration order
    inputs: bool  # input references (set_real) rather than outputs (get_real)
    fast: Callable[..., Any] | None = None  # inputs: set(list of floats); outputs: get() -> floats


class _CoreUnit:
    """Common part of the adapters: declared Real inputs/outputs, prepared handles, no other types."""

    def __init__(self, name: str, inputs: Sequence[tuple[str, str]], outputs: Sequence[tuple[str, str]],
                 dependencies: dict[str, tuple[str, ...]]) -> None:
        self.name = name
        variables: dict[str, Variable] = {}
        for vr, (var, unit) in enumerate(inputs):
            variables[var] = Variable(var, vr, "Real", "input", "continuous", unit, 0.0)
        for vr, (var, unit) in enumerate(outputs, start=len(inputs)):
            variables[var] = Variable(var, vr, "Real", "output", "continuous", unit)
        self.description = UnitDescription(name, variables, dict(dependencies), model_identifier=type(self).__name__)
        self._n_inputs = len(inputs)
        self._n_outputs = len(outputs)
        self._inputs = [0.0] * len(inputs)  # present input values, declaration order
        self._time = 0.0

    def prepare(self, refs: Sequence[int]) -> _Handle:
        refs = tuple(int(r) for r in refs)
        n_in = self._n_inputs
        if refs and all(r < n_in for r in refs):
            handle = _Handle(refs, np.asarray(refs, dtype=np.intp), refs == tuple(range(n_in)), True)
            handle.fast = self._setter(handle)
            return handle
        if any(r < n_in or r >= n_in + self._n_outputs for r in refs):
            raise KeyError(f"{self.name}: value references {refs} mix inputs and outputs or are not declared")
        handle = _Handle(refs, np.asarray([r - n_in for r in refs], dtype=np.intp),
                         refs == tuple(range(n_in, n_in + self._n_outputs)), False)
        handle.fast = self._getter(handle)
        return handle

    def set_real(self, handle: _Handle, values: np.ndarray) -> None:
        self.setter(handle)(values.tolist())

    def get_real(self, handle: _Handle) -> np.ndarray:
        return np.asarray(self.getter(handle)(), dtype=float)

    def setter(self, handle: _Handle) -> Callable[[list[float]], None]:
        """The fast path of ``set_real``: a function that sets the handle's inputs from a list of floats."""
        if not handle.inputs:
            raise KeyError(f"{self.name}: only inputs can be set, not value references {handle.refs}")
        return handle.fast

    def getter(self, handle: _Handle) -> Callable[[], Sequence[float]]:
        """The fast path of ``get_real``: a function that returns the handle's values (floats, handle order)."""
        if handle.inputs:
            raise KeyError(f"{self.name}: only outputs are read, not the inputs {handle.refs}")
        return handle.fast

    def _setter(self, handle: _Handle) -> Callable[[list[float]], None]:
        if handle.whole:
            def set_all(values: list[float]) -> None:
                self._inputs = values
            return set_all
        positions = handle.index.tolist()

        def set_some(values: list[float]) -> None:
            inputs = self._inputs = list(self._inputs)
            for position, value in zip(positions, values, strict=True):
                inputs[position] = value
        return set_some

    def _getter(self, handle: _Handle) -> Callable[[], Sequence[float]]:
        if handle.whole:
            return self._output_values
        pick, outputs = _picker(handle.index.tolist()), self._output_values
        return lambda: pick(outputs())

    def _output_values(self) -> Sequence[float]:
        """All outputs for the present state and inputs, in declaration order."""
        raise NotImplementedError

    def get_values(self, fmi_type: str, refs: Sequence[int]) -> list[Any]:
        raise KeyError(f"{self.name}: an in-process unit has Real variables only, not {fmi_type} {list(refs)}")

    def set_values(self, fmi_type: str, refs: Sequence[int], values: Sequence[Any]) -> None:
        raise KeyError(f"{self.name}: an in-process unit has Real variables only, not {fmi_type} {list(refs)}")

    def setup(self, start_time: float, stop_time: float) -> None:
        self._time = start_time

    def exit_initialization(self) -> None:
        pass

    def step(self, t: float, h: float) -> None:
        self._time = t + h

    def terminate(self) -> None:
        pass


class GroundMotionUnit(_CoreUnit):
    """Plays a record (``GroundMotionSource``): output ag [m/s^2] at the unit's time."""

    def __init__(self, motion: GroundMotion, name: str = "ground") -> None:
        super().__init__(name, (), (("ag", "m/s2"),), {"ag": ()})
        self.motion = motion

    def _output_values(self) -> tuple[float]:
        return (self.motion.acceleration(self._time),)


class ShearBuildingUnit(_CoreUnit):
    """The shear building (``ShearBuilding``): inputs ag [m/s^2], F [N]; per level x, v, a, arel; per storey
    drift, shear (the outputs of :meth:`ShearBuilding.output_vector`, in its order)."""

    def __init__(self, params: BuildingParams | None = None, name: str = "building") -> None:
        self.model = ShearBuilding(params if params is not None else BuildingParams.dyke())
        levels, storeys = range(self.model.n_levels), range(1, self.model.n_levels)
        outputs = ([(f"x_{j}", "m") for j in levels] + [(f"v_{j}", "m/s") for j in levels]
                   + [(f"a_{j}", "m/s2") for j in levels] + [(f"arel_{j}", "m/s2") for j in levels]
                   + [(f"drift_{j}", "m") for j in storeys] + [(f"shear_{j}", "N") for j in storeys])
        deps = {name: ("ag", "F") if name.startswith(("a_", "arel_")) else () for name, _ in outputs}
        super().__init__(name, (("ag", "m/s2"), ("F", "N")), outputs, deps)
        self._inputs = [0.0, 0.0]
        self._key: tuple | None = None
        self._values: list[float] = []

    def _output_values(self) -> list[float]:
        ag, F = self._inputs
        key = (self.model.steps, ag, F)
        if key != self._key:  # evaluated once per change of state or inputs, as the shell does
            self._values = self.model.output_vector(ag, F).tolist()
            self._key = key
        return self._values

    def step(self, t: float, h: float) -> None:
        ag, F = self._inputs
        self.model.step(ag, F, h)


class MreIsolatorUnit(_CoreUnit):
    """The MRE isolators (``MreIsolator``): inputs x [m], v [m/s], i [A]; output F [N], direct feedthrough.

    The current is clipped to [0, i_max] before it enters the law of Eq. (17), as in the shell.
    """

    def __init__(self, coeffs: GeneralizedCoefficients = TABLE2, n_isolators: int = 2, i_max: float = 3.0,
                 F0: float = 0.0, name: str = "isolator") -> None:
        super().__init__(name, (("x", "m"), ("v", "m/s"), ("i", "A")), (("F", "N"),), {"F": ("x", "v", "i")})
        self.coeffs, self.n_isolators, self.i_max, self.F0 = coeffs, n_isolators, i_max, F0
        self._law = force_law(coeffs, F0, n_isolators)

    def _output_values(self) -> tuple[float]:
        x, v, i = self._inputs
        return (self._law(x, v, min(max(i, 0.0), self.i_max)),)


class SosmControllerUnit(_CoreUnit):
    """The SOSM current controller (``SosmCurrentController``): inputs x [m], v [m/s], a [m/s^2]; output i [A],
    a state (no feedthrough). ``passive_current`` [A] set: passive mode, i = clip(passive_current, 0, i_max)."""

    def __init__(self, gains: SosmGains | None = None, model: Any = None, passive_current: float | None = None,
                 i_max: float | None = None, i_start: float = 0.0, name: str = "controller") -> None:
        super().__init__(name, (("x", "m"), ("v", "m/s"), ("a", "m/s2")), (("i", "A"),), {"i": ()})
        self.gains = gains if gains is not None else SosmGains()
        self.passive_current = passive_current
        self.i_max = self.gains.i_max if i_max is None else i_max  # passive mode's limit
        self.controller = None if passive_current is not None else SosmController(self.gains, model, i0=i_start)

    def _output_values(self) -> tuple[float]:
        if self.controller is None:
            return (min(max(self.passive_current, 0.0), self.i_max),)
        return (self.controller.i,)

    def step(self, t: float, h: float) -> None:
        if self.controller is not None:
            x, v, a = self._inputs
            self.controller.update(x, v, a, h)


def _picker(positions: list[int]) -> Callable[[Sequence[float]], Sequence[float]]:
    """A function that picks ``positions`` of a sequence, always as a tuple."""
    if len(positions) == 1:
        (p,) = positions
        return lambda values: (values[p],)
    return itemgetter(*positions)
