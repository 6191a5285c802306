"""Fixed-step coupling algorithms over the :class:`~orchestration.master.unit.Unit` interface.

All exchanged values live in one array (``values``); every connected or watched output
has a slot. Per unit, the connected inputs and the slotted outputs are prepared once as
reference handles, so a step is a fixed sequence of batched ``set_real``/``step``/
``get_real`` calls with no per-step allocation.

**Order.** Jacobi: every unit takes its inputs before any unit steps. Gauss-Seidel: units
step one after the other in :func:`~orchestration.master.graph.gauss_seidel_order`, so a unit
can use values its sources already computed at t + h ("fresh" sources).

**Inputs held over a step** (``inputs``):

* ``hold``: the latest value (the source's value at t, or at t + h if it is fresh). This
  is classic explicit coupling; its error is first order in the step.
* ``step-mean`` (default): an estimate of the source's *mean over the step*: the trapezoid
  (y(t) + y(t + h)) / 2 if the source is fresh, otherwise the mid-step value of the
  quadratic through y(t - 2h), y(t - h), y(t), i.e. (15 y(t) - 10 y(t - h) + 3 y(t - 2h)) / 8
  (linear, then constant, while the history is shorter). A unit that holds its inputs
  over the step (zero-order hold) then sees the right impulse, which removes the half-step
  lag of explicit coupling; no rollback or iteration is needed.

A ``delayed`` connection always passes the source's value at t: a sample-and-hold, as a
digital controller sampling at the communication points sees its measurements.

Every step ends with *feedthrough propagation*: outputs that depend directly on connected
inputs are re-evaluated level by level with the end-of-step values, so all values at
t + h are consistent with each other (e.g. a force computed from the displacement at
t + h, not at t).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from orchestration.master.graph import Link, Port, feedthrough_inputs, gauss_seidel_order, propagation_order
from orchestration.master.unit import Unit

Scheme = Literal["gauss-seidel", "jacobi"]
InputEstimate = Literal["hold", "step-mean"]

# Mid-step value of the polynomial through the last 1, 2 or 3 values (newest first).
_EXTRAPOLATION = (
    (1.0, 0.0, 0.0),
    (1.5, -0.5, 0.0),
    (15.0 / 8.0, -10.0 / 8.0, 3.0 / 8.0),
)


# How a ``set`` op forms an input from the value arrays (the order is the native kernel's).
RULES = ("start", "fresh", "mean", "extrapolated")


@dataclass
class ProgramOp:
    """One operation of a communication step: ``set`` inputs, ``step`` a unit, or ``get`` outputs."""

    kind: Literal["set", "step", "get"]
    unit: Unit
    handle: Any = None
    slots: np.ndarray | None = None  # per value: its slot in the value arrays
    rules: np.ndarray | None = None  # set only: per value, an index into RULES
    plan: Any = None  # set of a unit's connected inputs: its _InputPlan (the rules grouped)


@dataclass
class _Transfer:
    """Read some outputs of a unit into slots, or set some inputs from slots."""

    unit: Unit
    handle: Any
    slots: np.ndarray


@dataclass
class _InputPlan:
    """How one unit's connected inputs are formed before it steps, grouped by rule."""

    unit: Unit
    handle: Any
    buffer: np.ndarray
    start: tuple[np.ndarray, np.ndarray]  # (positions in buffer, slots): value at t
    fresh: tuple[np.ndarray, np.ndarray]  # value at t + h
    mean: tuple[np.ndarray, np.ndarray]  # trapezoid of t and t + h
    extrapolated: tuple[np.ndarray, np.ndarray]  # mid-step extrapolation from t, t - h, t - 2h


def _pair(items: list[tuple[int, int]]) -> tuple[np.ndarray, np.ndarray]:
    return (np.asarray([p for p, _ in items], dtype=np.intp), np.asarray([s for _, s in items], dtype=np.intp))


class CouplingAlgorithm:
    """Steps a set of units coupled by links (Jacobi or Gauss-Seidel; hold or step-mean inputs)."""

    def __init__(
        self,
        units: Sequence[Unit],
        links: Sequence[Link],
        watched: Sequence[Port] = (),
        scheme: Scheme = "gauss-seidel",
        order: Sequence[str] | None = None,
        inputs: InputEstimate = "step-mean",
    ) -> None:
        self.units = {u.name: u for u in units}
        self.links = list(links)
        self.scheme = scheme
        self.inputs = inputs
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
        n = len(self.slot)
        self.values = np.zeros(n)  # latest values (end of step once a step is done)
        self._history = [np.zeros(n), np.zeros(n), np.zeros(n)]  # values at t, t - h, t - 2h
        self._known = 0  # how many history entries are real
        self._desc = desc
        self._source = {link.target: link.source for link in self.links}
        self._outputs: dict[str, _Transfer] = {}
        for name, unit in self.units.items():
            outs = [(p, k) for p, k in self.slot.items() if p[0] == name]
            if outs:
                self._outputs[name] = self._transfer(unit, [p for p, _ in outs], [k for _, k in outs])
        self._input_plans = self._plan_inputs()
        self._propagation = self._plan_propagation()
        self._program = self._build_program()

    def _transfer(self, unit: Unit, ports: list[Port], slots: list[int]) -> _Transfer:
        refs = [self._desc[unit.name].variables[p[1]].vr for p in ports]
        return _Transfer(unit, unit.prepare(refs), np.asarray(slots, dtype=np.intp))

    def _plan_inputs(self) -> dict[str, _InputPlan]:
        stepped_before: set[str] = set()
        plans = {}
        sequence = self.order if self.scheme == "gauss-seidel" else list(self.units.values())
        for unit in sequence:
            links = [link for link in self.links if link.target[0] == unit.name]
            groups: dict[str, list[tuple[int, int]]] = {"start": [], "fresh": [], "mean": [], "extrapolated": []}
            for k, link in enumerate(links):
                slot = self.slot[link.source]
                fresh = self.scheme == "gauss-seidel" and link.source[0] in stepped_before
                if link.delayed:
                    rule = "start"
                elif self.inputs == "hold":
                    rule = "fresh" if fresh else "start"
                else:
                    rule = "mean" if fresh else "extrapolated"
                groups[rule].append((k, slot))
            if links:
                refs = [self._desc[unit.name].variables[link.target[1]].vr for link in links]
                plans[unit.name] = _InputPlan(
                    unit, unit.prepare(refs), np.zeros(len(links)),
                    **{rule: _pair(items) for rule, items in groups.items()},
                )
            stepped_before.add(unit.name)
        return plans

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
    def _set_inputs(self, plan: _InputPlan) -> None:
        buf = plan.buffer
        now, before, earlier = self._history
        pos, slots = plan.start
        if len(pos):
            buf[pos] = now[slots]
        pos, slots = plan.fresh
        if len(pos):
            buf[pos] = self.values[slots]
        pos, slots = plan.mean
        if len(pos):
            buf[pos] = 0.5 * (now[slots] + self.values[slots])
        pos, slots = plan.extrapolated
        if len(pos):
            c0, c1, c2 = _EXTRAPOLATION[min(self._known, 3) - 1]
            buf[pos] = c0 * now[slots] + c1 * before[slots] + c2 * earlier[slots]
        plan.unit.set_real(plan.handle, buf)

    def _set_all_current(self, name: str) -> None:
        """Set a unit's connected inputs to the present values (initialization)."""
        plan = self._input_plans.get(name)
        if plan is None:
            return
        positions = np.concatenate([plan.start[0], plan.fresh[0], plan.mean[0], plan.extrapolated[0]])
        slots = np.concatenate([plan.start[1], plan.fresh[1], plan.mean[1], plan.extrapolated[1]])
        plan.buffer[positions] = self.values[slots]
        plan.unit.set_real(plan.handle, plan.buffer)

    def _get_outputs(self, name: str) -> None:
        tr = self._outputs.get(name)
        if tr is not None:
            self.values[tr.slots] = tr.unit.get_real(tr.handle)

    def propagate(self) -> None:
        """Re-evaluate feedthrough outputs with the present (end-of-step) inputs, level by level."""
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
            self._set_all_current(name)
        for unit in self.units.values():
            unit.exit_initialization()
        self._consistent_outputs()
        for h in self._history:
            h[:] = self.values
        self._known = 1

    def _consistent_outputs(self) -> None:
        for name in self.units:
            self._get_outputs(name)
        self.propagate()

    def step(self, t: float, h: float) -> None:
        """One communication step from t to t + h [s]: the ops of :meth:`program`, then the history shift."""
        values = self.values
        for op in self._program:
            if op.kind == "step":
                op.unit.step(t, h)
            elif op.kind == "get":
                values[op.slots] = op.unit.get_real(op.handle)
            elif op.plan is not None:
                self._set_inputs(op.plan)
            else:
                op.unit.set_real(op.handle, values[op.slots])
        # history shifts by one step (the arrays stay in place: the native executor holds them)
        now, before, earlier = self._history
        earlier[:] = before
        before[:] = now
        now[:] = values
        self._known += 1

    def program(self) -> list[ProgramOp]:
        """One communication step as a flat list of operations, the one :meth:`step` carries out.

        Jacobi: every unit's inputs, then every step, then every output read; Gauss-Seidel:
        per unit in order, its inputs, its step, its outputs. Then feedthrough propagation
        (inputs from the end-of-step values, outputs re-read). A ``set`` op forms each input
        by its rule (``RULES``) from the value arrays; a ``get`` op writes outputs into slots.
        An output the propagation re-reads before anything uses it is not read after its unit's
        step as well (Kobe: 14 FMI calls per step, not 15). The native executor runs the same list.
        """
        return self._program

    def _build_program(self) -> list[ProgramOp]:
        def set_op(plan: _InputPlan) -> ProgramOp:
            rules = np.zeros(len(plan.buffer), dtype=np.intp)
            slots = np.zeros(len(plan.buffer), dtype=np.intp)
            for rule in RULES:
                pos, group_slots = getattr(plan, rule)
                rules[pos] = RULES.index(rule)
                slots[pos] = group_slots
            return ProgramOp("set", plan.unit, plan.handle, slots, rules, plan)

        def get_op(name: str) -> list[ProgramOp]:
            tr = self._outputs.get(name)
            return [] if tr is None else [ProgramOp("get", tr.unit, tr.handle, tr.slots)]

        plans = self._input_plans
        ops: list[ProgramOp] = []
        if self.scheme == "jacobi":
            ops += [set_op(plans[u.name]) for u in self.order if u.name in plans]
            ops += [ProgramOp("step", u) for u in self.order]
            for unit in self.order:
                ops += get_op(unit.name)
        else:
            for unit in self.order:
                if unit.name in plans:
                    ops.append(set_op(plans[unit.name]))
                ops.append(ProgramOp("step", unit))
                ops += get_op(unit.name)
        for setter, getter in self._propagation:
            fresh = np.full(len(setter.slots), RULES.index("fresh"), dtype=np.intp)
            ops.append(ProgramOp("set", setter.unit, setter.handle, setter.slots, fresh))
            ops.append(ProgramOp("get", getter.unit, getter.handle, getter.slots))
        return self._without_dead_reads(ops)

    def _without_dead_reads(self, ops: list[ProgramOp]) -> list[ProgramOp]:
        """Drop from each ``get`` the outputs a later ``get`` of the step overwrites before anything reads them.

        Typically a feedthrough output read right after its unit steps and read again, with the
        end-of-step inputs, by the propagation (the isolator's force): the first read is never
        used. A ``get`` left with nothing to read is removed, one with fewer outputs gets its
        own handle. The values at the end of the step are the same, with fewer FMI calls.
        """
        reads_values = (RULES.index("fresh"), RULES.index("mean"))  # start/extrapolated read the history
        port_of = {k: p for p, k in self.slot.items()}
        overwritten: set[int] = set()  # slots written later in the step before any op reads them
        kept: list[ProgramOp] = []
        for op in reversed(ops):
            if op.kind == "get":
                live = [k for k, s in enumerate(op.slots.tolist()) if s not in overwritten]
                overwritten.update(op.slots.tolist())
                if not live:
                    continue
                if len(live) < len(op.slots):
                    slots = op.slots[live].tolist()
                    narrowed = self._transfer(op.unit, [port_of[k] for k in slots], slots)
                    op = ProgramOp("get", op.unit, narrowed.handle, narrowed.slots)
            elif op.kind == "set":
                overwritten.difference_update(s for s, rule in zip(op.slots.tolist(), op.rules.tolist(), strict=True)
                                              if rule in reads_values)
            kept.append(op)
        return kept[::-1]

    @property
    def extrapolation(self) -> tuple[tuple[float, float, float], ...]:
        """Mid-step extrapolation weights for 1, 2 and 3 known values (newest first)."""
        return _EXTRAPOLATION

    @property
    def history(self) -> list[np.ndarray]:
        """Values at t, t - h, t - 2h (the arrays :meth:`step` shifts)."""
        return self._history

    @property
    def known(self) -> int:
        """How many history entries hold real values."""
        return self._known

    @known.setter
    def known(self, value: int) -> None:
        self._known = value

    def value(self, port: Port) -> float:
        """Present value of a slotted output."""
        return float(self.values[self.slot[port]])
