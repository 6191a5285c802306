"""Fake units for testing the master without FMUs: plain Python behind the Unit interface."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from orchestration.master.unit import UnitDescription, Variable

_ZERO = {"Boolean": False, "String": ""}


class FakeUnit:
    """A unit with named inputs/outputs. ``outputs_fn(state, inputs)`` gives the outputs,
    ``step_fn(state, inputs, t, h)`` returns the new state. Every call is appended to ``calls``.

    Variables are Real unless ``types`` names another FMI type for them (``Integer``,
    ``Boolean``, ``String``, ``Int64``, ...); those are read and set through ``get_values``/
    ``set_values``, which check the type the master passes. ``discrete`` names Real outputs of
    discrete variability; ``local`` names Real local variables (``outputs_fn`` gives them too, no
    dependencies declared, as FMI 2.0 locals).
    """

    def __init__(
        self,
        name: str,
        inputs: Sequence[str],
        outputs: Sequence[str],
        outputs_fn: Callable[[dict, dict], dict],
        step_fn: Callable[[dict, dict, float, float], dict] | None = None,
        dependencies: dict[str, tuple[str, ...] | None] | None = None,
        state: dict | None = None,
        calls: list | None = None,
        fail_at: float | None = None,
        types: dict[str, str] | None = None,
        discrete: Sequence[str] = (),
        local: Sequence[str] = (),
    ) -> None:
        self.name = name
        types = dict(types or {})
        variables = {}
        for k, n in enumerate(inputs):
            t = types.get(n, "Real")
            variables[n] = Variable(n, k, t, "input", "continuous" if t == "Real" else "discrete", None,
                                    _ZERO.get(t, 0.0 if t == "Real" else 0), declared_type=t)
        for k, n in enumerate(outputs, start=len(inputs)):
            t = types.get(n, "Real")
            continuous = t == "Real" and n not in discrete
            variables[n] = Variable(n, k, t, "output", "continuous" if continuous else "discrete", declared_type=t)
        for k, n in enumerate(local, start=len(inputs) + len(outputs)):
            variables[n] = Variable(n, k, "Real", "local", "continuous", declared_type="Real")
        deps = dependencies if dependencies is not None else {o: () for o in outputs}
        self.description = UnitDescription(name, variables, deps)
        self._by_vr = {v.vr: v.name for v in variables.values()}
        self.inputs = {n: variables[n].start for n in inputs}
        self.state = dict(state or {})
        self._outputs_fn = outputs_fn
        self._step_fn = step_fn
        self.calls = calls if calls is not None else []
        self.fail_at = fail_at
        self.terminated = 0
        self.initialized = False
        self.time: float | None = None  # the Unit protocol's: t before a step, t + h after it

    def native_functions(self) -> None:
        """None: the native executor cannot drive a Python unit."""
        return None

    def raise_status(self, function: str, status: int) -> None:
        from orchestration.master.errors import SimulationError

        if status > 1:
            raise SimulationError(f"{function} returned status {status}", unit=self.name, time=self.time)

    def setup(self, start_time: float, stop_time: float) -> None:
        self.calls.append(("setup", self.name, start_time))
        self.time = start_time

    def exit_initialization(self) -> None:
        self.initialized = True
        self.calls.append(("exit_init", self.name))

    def prepare(self, refs):
        return tuple(refs)

    def get_real(self, handle) -> np.ndarray:
        out = self._outputs_fn(self.state, self.inputs)
        self.calls.append(("get", self.name, tuple(self._by_vr[r] for r in handle)))
        return np.array([out[self._by_vr[r]] for r in handle], dtype=float)

    def set_real(self, handle, values) -> None:
        for r, v in zip(handle, values, strict=True):
            self.inputs[self._by_vr[r]] = float(v)
        self.calls.append(("set", self.name, tuple(self._by_vr[r] for r in handle)))

    def get_values(self, fmi_type: str, refs) -> list:
        names = [self._by_vr[r] for r in refs]
        assert all(self.description.variables[n].fmi_type == fmi_type for n in names), (fmi_type, names)
        out = self._outputs_fn(self.state, self.inputs)
        self.calls.append(("tget", self.name, tuple(names)))
        return [out[n] for n in names]

    def set_values(self, fmi_type: str, refs, values) -> None:
        names = [self._by_vr[r] for r in refs]
        assert all(self.description.variables[n].fmi_type == fmi_type for n in names), (fmi_type, names)
        for n, v in zip(names, values, strict=True):
            self.inputs[n] = v
        self.calls.append(("tset", self.name, tuple(names)))

    def step(self, t: float, h: float) -> None:
        from orchestration.master.errors import SimulationError

        self.calls.append(("step", self.name, t, h))
        if self.fail_at is not None and t >= self.fail_at:
            raise SimulationError("fake failure", unit=self.name, time=t)
        if self._step_fn is not None:
            self.state = self._step_fn(self.state, dict(self.inputs), t, h)
        self.time = t + h

    def terminate(self) -> None:
        self.terminated += 1
        self.calls.append(("terminate", self.name))


def clock(name: str = "clock", calls: list | None = None, fail_at: float | None = None) -> FakeUnit:
    """Output y = its own time (a state: no inputs)."""
    return FakeUnit(name, [], ["y"], lambda s, i: {"y": s["t"]},
                    lambda s, i, t, h: {"t": t + h}, state={"t": 0.0}, calls=calls, fail_at=fail_at)


def sampler(name: str = "sampler", calls: list | None = None) -> FakeUnit:
    """Holds the input it saw at its last step: output z = u at step start (a state)."""
    return FakeUnit(name, ["u"], ["z"], lambda s, i: {"z": s["z"]},
                    lambda s, i, t, h: {"z": i["u"]}, state={"z": -1.0}, calls=calls)


def gain(name: str = "gain", k: float = 2.0, calls: list | None = None) -> FakeUnit:
    """Direct feedthrough: w = k * u."""
    return FakeUnit(name, ["u"], ["w"], lambda s, i: {"w": k * i["u"]},
                    dependencies={"w": ("u",)}, calls=calls)
