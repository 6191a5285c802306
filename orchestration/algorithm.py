"""Fixed-step coupling algorithms over the :class:`~orchestration.unit.Unit` interface.

All exchanged values live in one array (``values``); every connected or recorded output
has a slot. Per unit, the connected inputs and the slotted outputs are prepared once as
reference handles, so a step is a fixed sequence of batched ``set_real``/``step``/
``get_real`` calls.

One communication step from t to t + h:

* Jacobi: every unit gets its inputs from the values at t, all step, all outputs are read.
* Gauss-Seidel: units step one after the other in :func:`~orchestration.graph.gauss_seidel_order`;
  each reads the freshest values (t + h from units that already stepped, else t).

Both end with *feedthrough propagation*: outputs that depend directly on connected
inputs are re-evaluated level by level with the new inputs, so that all recorded values
at t + h are consistent with each other (e.g. a force computed from the displacement at
t + h, not at t).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from orchestration.graph import Link, Port, feedthrough_inputs, gauss_seidel_order, propagation_order
from orchestration.unit import Unit

Scheme = Literal["gauss-seidel", "jacobi"]


@dataclass
class _Transfer:
    """Set some inputs of a unit from slots, or read some outputs into slots."""

    unit: Unit
    handle: Any
    slots: np.ndarray


class CouplingAlgorithm:
    """Steps a set of units coupled by links, with Jacobi or Gauss-Seidel transfer."""

    def __init__(
        self,
        units: Sequence[Unit],
        links: Sequence[Link],
        watched: Sequence[Port] = (),
        scheme: Scheme = "gauss-seidel",
        order: Sequence[str] | None = None,
    ) -> None:
        self.units = {u.name: u for u in units}
        self.links = list(links)
        self.scheme = scheme
        desc = {u.name: u.description for u in units}
        self.levels = propagation_order(desc, self.links)  # raises AlgebraicLoopError
        if order is None:
            order = gauss_seidel_order(desc, self.links) if scheme == "gauss-seidel" else list(self.units)
        self.order = [self.units[n] for n in order]

        # One slot per output that is connected or watched (recorded, checked).
        self.slot: dict[Port, int] = {}
        for port in [link.source for link in self.links] + list(watched):
            var = desc[port[0]].variables[port[1]]
            if var.causality != "output":
                continue
            self.slot.setdefault(port, len(self.slot))
        self.values = np.zeros(len(self.slot))
        self._desc = desc
        self._source = {link.target: link.source for link in self.links}
        self._inputs: dict[str, _Transfer] = {}
        self._outputs: dict[str, _Transfer] = {}
        for name, unit in self.units.items():
            ins = [(p, s) for p, s in self._source.items() if p[0] == name]
            outs = [(p, k) for p, k in self.slot.items() if p[0] == name]
            if ins:
                self._inputs[name] = self._transfer(unit, [p for p, _ in ins], [self.slot[s] for _, s in ins])
            if outs:
                self._outputs[name] = self._transfer(unit, [p for p, _ in outs], [k for _, k in outs])
        self._propagation = self._plan_propagation()

    def _transfer(self, unit: Unit, ports: list[Port], slots: list[int]) -> _Transfer:
        refs = [self._desc[unit.name].variables[p[1]].vr for p in ports]
        return _Transfer(unit, unit.prepare(refs), np.asarray(slots, dtype=np.intp))

    def _plan_propagation(self) -> list[tuple[_Transfer, _Transfer]]:
        """Per level and unit: (inputs to set, feedthrough outputs to read)."""
        plan = []
        for level in self.levels:
            by_unit: dict[str, list[Port]] = {}
            for port in level:
                if port in self.slot:
                    by_unit.setdefault(port[0], []).append(port)
            for name, outs in by_unit.items():
                ins: list[Port] = []
                for out in outs:
                    for i in feedthrough_inputs(self._desc, self.links, out):
                        if i not in ins:
                            ins.append(i)
                unit = self.units[name]
                setter = self._transfer(unit, ins, [self.slot[self._source[i]] for i in ins])
                getter = self._transfer(unit, outs, [self.slot[o] for o in outs])
                plan.append((setter, getter))
        return plan

    # -- phases ------------------------------------------------------------------------------------
    def _set_inputs(self, name: str) -> None:
        tr = self._inputs.get(name)
        if tr is not None:
            tr.unit.set_real(tr.handle, self.values[tr.slots])

    def _get_outputs(self, name: str) -> None:
        tr = self._outputs.get(name)
        if tr is not None:
            self.values[tr.slots] = tr.unit.get_real(tr.handle)

    def propagate(self) -> None:
        """Re-evaluate feedthrough outputs with the present inputs, level by level."""
        values = self.values
        for setter, getter in self._propagation:
            setter.unit.set_real(setter.handle, values[setter.slots])
            values[getter.slots] = getter.unit.get_real(getter.handle)

    def initialize(self, start_time: float, stop_time: float) -> None:
        """Set up every unit, make the values at the start time consistent, leave initialization."""
        for unit in self.units.values():
            unit.setup(start_time, stop_time)
        self._consistent_outputs()
        for name in self.units:
            self._set_inputs(name)
        for unit in self.units.values():
            unit.exit_initialization()
        self._consistent_outputs()

    def _consistent_outputs(self) -> None:
        for name in self.units:
            self._get_outputs(name)
        self.propagate()

    def step(self, t: float, h: float) -> None:
        """One communication step from t to t + h [s]."""
        if self.scheme == "jacobi":
            for name in self.units:
                self._set_inputs(name)
            for unit in self.units.values():
                unit.step(t, h)
            for name in self.units:
                self._get_outputs(name)
        else:
            for unit in self.order:
                self._set_inputs(unit.name)
                unit.step(t, h)
                self._get_outputs(unit.name)
        self.propagate()

    def value(self, port: Port) -> float:
        """Present value of a slotted output."""
        return float(self.values[self.slot[port]])
