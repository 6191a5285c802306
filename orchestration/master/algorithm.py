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

**Values of other types** (Integer, Enumeration, Boolean, String, FMI 3.0 Float32 and
integer types) are passed as they are, sample-and-hold, through the units' ``get_values``/
``set_values``: with the same ordering as the Reals (Jacobi and ``delayed``: the value at t;
Gauss-Seidel: the value after the source stepped, if it did), never averaged or
extrapolated. They live in a Python list (``typed``), so 64-bit integers pass exactly. A Real
output of ``discrete`` variability is held the same way (step-mean and extrapolation are for
continuous signals). A system without such values runs exactly the Real-only program.

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

from orchestration.master.errors import SimulationError
from orchestration.master.graph import Link, Port, feedthrough_inputs, gauss_seidel_order, propagation_order
from orchestration.master.unit import Unit, UnitDescription

EXACT_INTEGER_LIMIT = 2**53
"""Largest integer magnitude a float64 column (recording, limits) holds exactly."""

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

    kind: Literal["set", "step", "get", "tset", "tget"]  # tset/tget: values of other types (a _TypedTransfer)
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


@dataclass
class _TypedTransfer:
    """Values of one non-Real type of one unit: read into typed slots (``tget``) or set from them (``tset``)."""

    unit: Unit
    fmi_type: str
    refs: list[int]
    ports: list[Port]  # the unit's variables
    slots: list[int]  # slots in ``typed``
    fresh: list[bool]  # tset: the latest value (True) or the value at t (False)
    mirror: list[int]  # tget: float slot in ``values`` (recorded/limited numbers), or -1


@dataclass
class _PropagationStep:
    """One unit at one propagation level: set its feedthrough inputs, re-read its outputs."""

    real_set: _Transfer | None
    typed_set: list[_TypedTransfer]
    real_get: _Transfer | None
    typed_get: list[_TypedTransfer]


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

        # One slot per output that is connected or watched (recorded, checked); values of other
        # types have a slot in ``typed``, and a float one too when they are watched numbers.
        self.slot: dict[Port, int] = {}
        self.typed_slot: dict[Port, int] = {}
        watched_ports = set(watched)
        for port in [link.source for link in self.links] + list(watched):
            var = desc[port[0]].variables[port[1]]
            if var.causality not in ("output", "local"):  # a local is watched only when a scenario names it
                continue
            if var.fast_real:
                self.slot.setdefault(port, len(self.slot))
                continue
            self.typed_slot.setdefault(port, len(self.typed_slot))
            if port in watched_ports and var.fmi_type != "String":
                self.slot.setdefault(port, len(self.slot))
        self._real_ports = {p for p in self.slot if desc[p[0]].variables[p[1]].fast_real}
        self.typed: list[Any] = [None] * len(self.typed_slot)  # latest values of the other types
        self._typed_now: list[Any] = [None] * len(self.typed_slot)  # their values at t
        self._time = 0.0  # the time the latest values belong to [s] (for error messages)
        n = len(self.slot)
        self.values = np.zeros(n)  # latest values (end of step once a step is done)
        self._history = [np.zeros(n), np.zeros(n), np.zeros(n)]  # values at t, t - h, t - 2h
        self._known = 0  # how many history entries are real
        self._desc = desc
        self._source = {link.target: link.source for link in self.links}
        self._outputs: dict[str, _Transfer] = {}
        self._typed_outputs: dict[str, list[_TypedTransfer]] = {}
        for name, unit in self.units.items():
            outs = [(p, k) for p, k in self.slot.items() if p[0] == name and p in self._real_ports]
            if outs:
                self._outputs[name] = self._transfer(unit, [p for p, _ in outs], [k for _, k in outs])
            typed_outs = [p for p in self.typed_slot if p[0] == name]
            if typed_outs:
                self._typed_outputs[name] = self._typed_transfers(unit, typed_outs, [False] * len(typed_outs))
        self._typed_inputs: dict[str, list[_TypedTransfer]] = {}
        self._input_plans = self._plan_inputs()
        self._propagation = self._plan_propagation()
        self._program = self._build_program()

    def _transfer(self, unit: Unit, ports: list[Port], slots: list[int]) -> _Transfer:
        refs = [self._desc[unit.name].variables[p[1]].vr for p in ports]
        return _Transfer(unit, unit.prepare(refs), np.asarray(slots, dtype=np.intp))

    def _typed_transfers(self, unit: Unit, ports: list[Port], fresh: list[bool],
                         sources: list[Port] | None = None) -> list[_TypedTransfer]:
        """Transfers of a unit's non-Real ``ports``, one per declared type; ``sources`` (for inputs) give the slots."""
        variables = self._desc[unit.name].variables
        groups: dict[str, _TypedTransfer] = {}
        for k, port in enumerate(ports):
            var = variables[port[1]]
            tr = groups.setdefault(var.fmi_type, _TypedTransfer(unit, var.fmi_type, [], [], [], [], []))
            source = port if sources is None else sources[k]
            tr.refs.append(var.vr)
            tr.ports.append(port)
            tr.slots.append(self.typed_slot[source])
            tr.fresh.append(fresh[k])
            tr.mirror.append(self.slot.get(port, -1) if sources is None else -1)
        return list(groups.values())

    def _plan_inputs(self) -> dict[str, _InputPlan]:
        stepped_before: set[str] = set()
        plans = {}
        sequence = self.order if self.scheme == "gauss-seidel" else list(self.units.values())
        for unit in sequence:
            typed_links = [link for link in self.links if link.target[0] == unit.name
                           and link.source in self.typed_slot]
            if typed_links:
                fresh_values = [self.scheme == "gauss-seidel" and not link.delayed
                                and link.source[0] in stepped_before for link in typed_links]
                self._typed_inputs[unit.name] = self._typed_transfers(
                    unit, [link.target for link in typed_links], fresh_values, [link.source for link in typed_links])
            links = [link for link in self.links if link.target[0] == unit.name and link.source in self._real_ports]
            groups: dict[str, list[tuple[int, int]]] = {"start": [], "fresh": [], "mean": [], "extrapolated": []}
            for k, link in enumerate(links):
                slot = self.slot[link.source]
                fresh = self.scheme == "gauss-seidel" and link.source[0] in stepped_before
                held = self._desc[link.source[0]].variables[link.source[1]].variability == "discrete"
                if link.delayed:
                    rule = "start"
                elif self.inputs == "hold" or held:
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

    def _plan_propagation(self) -> list[_PropagationStep]:
        """Per level and unit: the inputs to set, the feedthrough outputs to read."""
        plan = []
        for level in self.levels:
            by_unit: dict[str, list[Port]] = {}
            for port in level:
                if port in self._real_ports or port in self.typed_slot:
                    by_unit.setdefault(port[0], []).append(port)
            for name, outs in by_unit.items():
                ins: list[Port] = []
                for out in outs:
                    for i in feedthrough_inputs(self._desc, self.links, out):
                        if i not in ins:
                            ins.append(i)
                unit = self.units[name]
                real_ins = [i for i in ins if self._source[i] in self._real_ports]
                typed_ins = [i for i in ins if self._source[i] in self.typed_slot]
                real_outs = [o for o in outs if o in self._real_ports]
                typed_outs = [o for o in outs if o in self.typed_slot]
                plan.append(_PropagationStep(
                    self._transfer(unit, real_ins, [self.slot[self._source[i]] for i in real_ins])
                    if real_ins else None,
                    self._typed_transfers(unit, typed_ins, [True] * len(typed_ins),
                                          [self._source[i] for i in typed_ins]),
                    self._transfer(unit, real_outs, [self.slot[o] for o in real_outs]) if real_outs else None,
                    self._typed_transfers(unit, typed_outs, [False] * len(typed_outs)),
                ))
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
        for tr in self._typed_inputs.get(name, ()):
            tr.unit.set_values(tr.fmi_type, tr.refs, [self.typed[s] for s in tr.slots])
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
        for typed in self._typed_outputs.get(name, ()):
            self._get_typed(typed)

    def _get_typed(self, tr: _TypedTransfer) -> None:
        """Read values of another type into their slots (and watched numbers into their float slots)."""
        values = tr.unit.get_values(tr.fmi_type, tr.refs)
        typed = self.typed
        for slot, mirror, port, value in zip(tr.slots, tr.mirror, tr.ports, values, strict=True):
            typed[slot] = value
            if mirror >= 0:
                number = float(value)
                if isinstance(value, int) and abs(value) > EXACT_INTEGER_LIMIT and int(number) != value:
                    raise SimulationError(
                        f"{tr.fmi_type} value {value} cannot be recorded or checked exactly: the float64 columns of "
                        f"timeseries.csv hold integers up to 2^53 = {EXACT_INTEGER_LIMIT} (connections pass it "
                        "exactly; leave it out of outputs/limits to go on)", unit=port[0], variable=port[1],
                        time=self._time)
                self.values[mirror] = number

    def _set_typed(self, tr: _TypedTransfer) -> None:
        """Set inputs of another type: the latest value or the value at t, as planned."""
        latest, now = self.typed, self._typed_now
        tr.unit.set_values(tr.fmi_type, tr.refs,
                           [latest[s] if fresh else now[s] for s, fresh in zip(tr.slots, tr.fresh, strict=True)])

    def propagate(self) -> None:
        """Re-evaluate feedthrough outputs with the present (end-of-step) inputs, level by level."""
        values = self.values
        for p in self._propagation:
            if p.real_set is not None:
                p.real_set.unit.set_real(p.real_set.handle, values[p.real_set.slots])
            for tr in p.typed_set:
                self._set_typed(tr)
            if p.real_get is not None:
                values[p.real_get.slots] = p.real_get.unit.get_real(p.real_get.handle)
            for tr in p.typed_get:
                self._get_typed(tr)

    def initialize(self, start_time: float, stop_time: float) -> None:
        """Set up every unit, make the values at the start time consistent, leave initialization."""
        self._time = start_time
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
        self._typed_now[:] = self.typed
        self._known = 1

    def _consistent_outputs(self) -> None:
        for name in self.units:
            self._get_outputs(name)
        self.propagate()

    def step(self, t: float, h: float) -> None:
        """One communication step from t to t + h [s]: the ops of :meth:`program`, then the history shift."""
        values = self.values
        self._time = t + h
        for op in self._program:
            if op.kind == "step":
                op.unit.step(t, h)
            elif op.kind == "get":
                values[op.slots] = op.unit.get_real(op.handle)
            elif op.plan is not None:
                self._set_inputs(op.plan)
            elif op.kind == "set":
                op.unit.set_real(op.handle, values[op.slots])
            elif op.kind == "tget":
                self._get_typed(op.handle)
            else:
                self._set_typed(op.handle)
        # history shifts by one step (the arrays stay in place: the native executor holds them)
        now, before, earlier = self._history
        earlier[:] = before
        before[:] = now
        now[:] = values
        if self.typed:
            self._typed_now[:] = self.typed
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
            real = [] if tr is None else [ProgramOp("get", tr.unit, tr.handle, tr.slots)]
            return real + [ProgramOp("tget", t.unit, t) for t in self._typed_outputs.get(name, ())]

        def set_ops(name: str) -> list[ProgramOp]:
            real = [set_op(plans[name])] if name in plans else []
            return real + [ProgramOp("tset", t.unit, t) for t in self._typed_inputs.get(name, ())]

        plans = self._input_plans
        ops: list[ProgramOp] = []
        if self.scheme == "jacobi":
            for unit in self.order:
                ops += set_ops(unit.name)
            ops += [ProgramOp("step", u) for u in self.order]
            for unit in self.order:
                ops += get_op(unit.name)
        else:
            for unit in self.order:
                ops += set_ops(unit.name)
                ops.append(ProgramOp("step", unit))
                ops += get_op(unit.name)
        for p in self._propagation:
            if p.real_set is not None:
                fresh = np.full(len(p.real_set.slots), RULES.index("fresh"), dtype=np.intp)
                ops.append(ProgramOp("set", p.real_set.unit, p.real_set.handle, p.real_set.slots, fresh))
            ops += [ProgramOp("tset", t.unit, t) for t in p.typed_set]
            if p.real_get is not None:
                ops.append(ProgramOp("get", p.real_get.unit, p.real_get.handle, p.real_get.slots))
            ops += [ProgramOp("tget", t.unit, t) for t in p.typed_get]
        return self._without_dead_reads(ops)

    def _without_dead_reads(self, ops: list[ProgramOp]) -> list[ProgramOp]:
        """Drop from each ``get`` the outputs a later ``get`` of the step overwrites before anything reads them.

        Typically a feedthrough output read right after its unit steps and read again, with the
        end-of-step inputs, by the propagation (a force fed back to the unit that drives it): the first read is never
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
            elif op.kind == "set":  # tset/tget use the typed slots: no float slot is read or dropped
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

    def typed_value(self, port: Port) -> Any:
        """Present value of an output of another type (int, bool, str or float)."""
        return self.typed[self.typed_slot[port]]

    @property
    def typed_ports(self) -> list[Port]:
        """Outputs of types other than Real that are exchanged or watched."""
        return list(self.typed_slot)

    @property
    def descriptions(self) -> dict[str, UnitDescription]:
        """The units' descriptions by unit name."""
        return self._desc
