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

**Held sources and restarts.** A Real output that is piecewise constant on the base grid (``discrete``
variability, or an output of a unit with its own step) is held, and an extrapolated output
that depends directly (ModelStructure) on an input fed by such a source uses only the history
computed with the present held value (:func:`usable_history`): after a current jump, the
value at t alone, then linear, then the quadratic (docs/master.md, "Estimates after a jump").

**Units with their own step** (``periods``: unit -> m base steps): such a unit steps from t_k
to t_(k+m) in the base steps k with k % m == 0 and costs nothing in between; it samples its
inputs at its grid point; its outputs are held: read as they are (``fresh``) by the units it
steps before in Gauss-Seidel, else as they were at its last grid point (``grid``, the values a
``latch`` op copies at the end of its steps). Its feedthrough outputs are re-evaluated at the
end of its steps. Ops carry ``every``/``phase`` for this; with every m = 1 the program is the
single-rate one (docs/master.md, "Multi-rate stepping").

Every step ends with *feedthrough propagation*: outputs that depend directly on connected
inputs are re-evaluated level by level with the end-of-step values, so all values at
t + h are consistent with each other (e.g. a force computed from the displacement at
t + h, not at t). Watched ``local`` variables, whose dependencies FMI 2.0 does not declare, are
read last, after their unit's connected inputs are set to their end-of-step values.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, TypedDict

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
RULES = ("start", "fresh", "mean", "extrapolated", "grid")


OpKind = Literal["set", "step", "get", "tset", "tget", "latch", "peek"]  # tset/tget: values of other types


def _no_slots() -> np.ndarray:
    return np.zeros(0, dtype=np.intp)


class _Timing(TypedDict):
    """When an op runs: in the base steps k with k % every == phase."""

    every: int
    phase: int


@dataclass
class ProgramOp:
    """One operation of a communication step: ``set`` inputs, ``step`` a unit, or ``get`` outputs."""

    kind: OpKind
    unit: Unit
    handle: object = None  # set, get, peek: the unit's prepared references (what Unit.prepare returned)
    slots: np.ndarray = field(default_factory=_no_slots)  # per value: its slot in the value arrays
    rules: np.ndarray | None = None  # set only: per value, an index into RULES
    plan: _InputPlan | None = None  # set of a unit's connected inputs: the rules grouped
    every: int = 1  # the op runs in the steps k with k % every == phase (a unit stepping every m base steps)
    phase: int = 0
    drivers: list[np.ndarray] | None = None  # set only: per value, the held slots whose change restarts its estimate
    fresh_drivers: list[np.ndarray] | None = None  # set: per value, the drivers whose jump is peeked; peek: its drivers
    out_handle: object = None  # peek only: the source output to read after setting the fresh drivers
    out_slot: int = -1  # peek only: the slot of that output (its peeked value goes to ``peeked[out_slot]``)
    transfer: _TypedTransfer | None = None  # tset, tget: the values of one other type to set or read

    def __post_init__(self) -> None:
        # a plain ``set`` (propagation): the positions whose value comes from the grid values, or None
        self.grid_positions: np.ndarray | None = None
        if self.kind == "set" and self.plan is None and self.rules is not None:
            found = np.flatnonzero(self.rules == RULES.index("grid"))
            self.grid_positions = found if len(found) else None


@dataclass
class _Transfer:
    """Read some outputs of a unit into slots, or set some inputs from slots."""

    unit: Unit
    handle: object
    slots: np.ndarray


@dataclass
class _InputPlan:
    """How one unit's connected inputs are formed before it steps, grouped by rule."""

    unit: Unit
    handle: object
    buffer: np.ndarray
    start: tuple[np.ndarray, np.ndarray]  # (positions in buffer, slots): value at t
    fresh: tuple[np.ndarray, np.ndarray]  # value at t + h
    mean: tuple[np.ndarray, np.ndarray]  # trapezoid of t and t + h
    extrapolated: tuple[np.ndarray, np.ndarray]  # mid-step extrapolation from t, t - h, t - 2h
    grid: tuple[np.ndarray, np.ndarray]  # value at the source's last grid point (a unit with its own step)
    restarting: list[_Restart]  # extrapolated values with held drivers


@dataclass
class _Restart:
    """An extrapolated input whose source output depends on held inputs (see :func:`usable_history`).

    ``fresh``: the drivers whose new value is known before the consumer steps (they stepped
    before it, and the source unit reads them as they are): when one of them changed in this
    step, the source output is evaluated with it at t (``peek``, the value at t+) and the
    consumer gets that value.
    """

    position: int  # in the consumer's input buffer
    slot: int  # the source output's slot
    drivers: np.ndarray  # slots of the held sources it depends on
    fresh: np.ndarray  # those of them known before the consumer steps
    peek: ProgramOp | None = None  # ProgramOp "peek" that evaluates the source output with the fresh drivers, or None


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
    set_rules: np.ndarray | None = None  # per value of real_set: "fresh", or "grid" for a source with its own step


def usable_history(now: np.ndarray, before: np.ndarray, earlier: np.ndarray, drivers: np.ndarray) -> int:
    """How many of the values at t, t - h, t - 2h of an output were computed with the present held inputs.

    ``drivers``: slots of the held (piecewise-constant) sources the output depends on directly.
    1 when one of them differs between t and t - h (the history restarts at t), 2 when one
    differs between t - h and t - 2h, else 3. The native kernel makes the same comparisons.
    """
    if bool(np.any(now[drivers] != before[drivers])):
        return 1
    if bool(np.any(before[drivers] != earlier[drivers])):
        return 2
    return 3


def _no_grid(k: int) -> float:
    raise ValueError("units with their own step need the base step: initialize(start, stop, step)")


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
        periods: Mapping[str, int] | None = None,
    ) -> None:
        self.units = {u.name: u for u in units}
        self.links = list(links)
        self.scheme = scheme
        self.inputs = inputs
        # each unit's own step as a whole number of base steps (1: the base step)
        self.periods = {name: int((periods or {}).get(name, 1)) for name in self.units}
        if any(m < 1 for m in self.periods.values()):
            raise ValueError(f"unit periods must be whole numbers >= 1, got {dict(periods or {})}")
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
        self._grid = np.zeros(n)  # per slot: its value at its unit's last grid point (read by the "grid" rule)
        self._peeked = np.zeros(n)  # per slot: its value at t with the new held inputs (written by "peek" ops)
        self._known = 0  # how many history entries are real
        self._k = 0  # steps done
        self._t_of: Callable[[int], float] = _no_grid  # the base grid (for the steps of units with periods)
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
        self._link_rule: dict[Port, str] = {}  # target port -> its rule (RULES) in the step
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

    def _is_held(self, port: Port) -> bool:
        """Is this Real output piecewise constant on the base grid: ``discrete``, or of a unit with its own step?"""
        return self._desc[port[0]].variables[port[1]].variability == "discrete" or self.periods[port[0]] > 1

    def _rule(self, link: Link, fresh: bool) -> str:
        """How the target of a Real link forms its input (an entry of RULES); ``fresh``: the source steps first."""
        m_source, m_target = self.periods[link.source[0]], self.periods[link.target[0]]
        if m_source == 1 and m_target == 1:
            if link.delayed:
                return "start"
            if self.inputs == "hold" or self._is_held(link.source):
                return "fresh" if fresh else "start"
            return "mean" if fresh else "extrapolated"
        if m_source == 1:  # a unit with its own step samples its faster sources at its grid point
            return "start"
        # the output of a unit with its own step is held: the latest one, or the one at its last grid point
        if fresh and not link.delayed and m_target in (1, m_source):
            return "fresh"
        return "grid"

    def _drivers(self, port: Port) -> np.ndarray:
        """Slots of the held sources that the output ``port`` depends on directly (ModelStructure).

        When one of them changed, the history of ``port`` mixes values computed with different
        held inputs: its extrapolation restarts (see :meth:`_set_inputs`).
        """
        found = []
        for target in feedthrough_inputs(self._desc, self.links, port):
            source = self._source[target]
            # an input read at its source's grid points ("grid") changes with the grid values, which the history
            # does not keep: such a driver is left out (the output's estimate then never restarts for it)
            if source in self._real_ports and self._is_held(source) and self._link_rule.get(target) != "grid":
                found.append(self.slot[source])
        return np.asarray(sorted(set(found)), dtype=np.intp)

    def _restart(self, position: int, port: Port, drivers: np.ndarray, stepped_before: set[str]) -> _Restart:
        """The restart plan of an extrapolated input from ``port``, and its peek when a driver is known first."""
        source_unit = self.units[port[0]]
        fresh_inputs = [target for target in feedthrough_inputs(self._desc, self.links, port)
                        if self._link_rule.get(target) == "fresh" and self._source[target][0] in stepped_before
                        and self.slot.get(self._source[target]) in set(drivers.tolist())]
        fresh = np.asarray([self.slot[self._source[t]] for t in fresh_inputs], dtype=np.intp)
        peek = None
        if fresh_inputs:
            refs = [self._desc[port[0]].variables[t[1]].vr for t in fresh_inputs]
            out = source_unit.prepare([self._desc[port[0]].variables[port[1]].vr])
            peek = ProgramOp("peek", source_unit, source_unit.prepare(refs), fresh, fresh_drivers=[fresh],
                             out_handle=out, out_slot=self.slot[port])
        return _Restart(position, self.slot[port], drivers, fresh, peek)

    def _plan_inputs(self) -> dict[str, _InputPlan]:
        sequence = self.order if self.scheme == "gauss-seidel" else list(self.units.values())
        stepped_before: set[str] = set()
        for unit in sequence:  # every Real link's rule first: the drivers of an estimate depend on other links' rules
            for link in self.links:
                if link.target[0] == unit.name and link.source in self._real_ports:
                    fresh = self.scheme == "gauss-seidel" and link.source[0] in stepped_before
                    self._link_rule[link.target] = self._rule(link, fresh)
            stepped_before.add(unit.name)
        stepped_before = set()
        plans = {}
        for unit in sequence:
            typed_links = [link for link in self.links if link.target[0] == unit.name
                           and link.source in self.typed_slot]
            if typed_links:
                fresh_values = [self.scheme == "gauss-seidel" and not link.delayed
                                and link.source[0] in stepped_before for link in typed_links]
                self._typed_inputs[unit.name] = self._typed_transfers(
                    unit, [link.target for link in typed_links], fresh_values, [link.source for link in typed_links])
            links = [link for link in self.links if link.target[0] == unit.name and link.source in self._real_ports]
            groups: dict[str, list[tuple[int, int]]] = {rule: [] for rule in RULES}
            restarting: list[_Restart] = []
            for k, link in enumerate(links):
                slot = self.slot[link.source]
                rule = self._link_rule[link.target]
                drivers = self._drivers(link.source) if rule == "extrapolated" else np.zeros(0, dtype=np.intp)
                if len(drivers):
                    restarting.append(self._restart(k, link.source, drivers, stepped_before))
                else:
                    groups[rule].append((k, slot))
            if links:
                refs = [self._desc[unit.name].variables[link.target[1]].vr for link in links]
                plans[unit.name] = _InputPlan(
                    unit, unit.prepare(refs), np.zeros(len(links)),
                    **{rule: _pair(items) for rule, items in groups.items()}, restarting=restarting,
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
                rules = [RULES.index("grid" if self._link_rule.get(i) == "grid" else "fresh") for i in real_ins]
                plan.append(_PropagationStep(
                    self._transfer(unit, real_ins, [self.slot[self._source[i]] for i in real_ins])
                    if real_ins else None,
                    self._typed_transfers(unit, typed_ins, [True] * len(typed_ins),
                                          [self._source[i] for i in typed_ins]),
                    self._transfer(unit, real_outs, [self.slot[o] for o in real_outs]) if real_outs else None,
                    self._typed_transfers(unit, typed_outs, [False] * len(typed_outs)),
                    np.asarray(rules, dtype=np.intp) if real_ins else None,
                ))
        return self._plan_local_reads(plan)

    def _plan_local_reads(self, plan: list[_PropagationStep]) -> list[_PropagationStep]:
        """``plan`` with the watched locals read last, after their unit's connected inputs carry their end-of-step
        values: in the unit's last propagation step when that one sets all of them, else in a step of their own.

        FMI 2.0 declares no dependencies for a local variable, so it may depend on every input, as a feedthrough
        output does. Read right after the step, it would pair the state at t + h with the inputs the step used
        (the step means); read here, it is consistent with the outputs at t + h.
        """
        plan = list(plan)
        for name, unit in self.units.items():
            local = [p for p in self.slot if p[0] == name and p in self._real_ports
                     and self._desc[name].variables[p[1]].causality == "local"]
            typed_local = [p for p in self.typed_slot if p[0] == name
                           and self._desc[name].variables[p[1]].causality == "local"]
            if not local and not typed_local:
                continue
            ins = [link.target for link in self.links if link.target[0] == name and not link.delayed]
            real_ins = [i for i in ins if self._source[i] in self._real_ports]
            typed_ins = [i for i in ins if self._source[i] in self.typed_slot]
            last = max((k for k, p in enumerate(plan) if self._step_unit(p) == name), default=None)
            if last is not None and not typed_local and self._sets_all(plan[last], real_ins, typed_ins):
                got = plan[last].real_get
                outs = [] if got is None else self._ports_of(got)
                plan[last].real_get = self._transfer(unit, outs + local, [self.slot[p] for p in outs + local])
                continue
            rules = [RULES.index("grid" if self._link_rule.get(i) == "grid" else "fresh") for i in real_ins]
            plan.append(_PropagationStep(
                self._transfer(unit, real_ins, [self.slot[self._source[i]] for i in real_ins]) if real_ins else None,
                self._typed_transfers(unit, typed_ins, [True] * len(typed_ins), [self._source[i] for i in typed_ins]),
                self._transfer(unit, local, [self.slot[p] for p in local]) if local else None,
                self._typed_transfers(unit, typed_local, [False] * len(typed_local)),
                np.asarray(rules, dtype=np.intp) if real_ins else None,
            ))
        return plan

    @staticmethod
    def _step_unit(p: _PropagationStep) -> str:
        return (p.real_set or p.real_get or (p.typed_set or p.typed_get)[0]).unit.name

    def _ports_of(self, tr: _Transfer) -> list[Port]:
        port_of = {k: p for p, k in self.slot.items()}
        return [port_of[k] for k in tr.slots.tolist()]

    def _sets_all(self, p: _PropagationStep, real_ins: list[Port], typed_ins: list[Port]) -> bool:
        """Whether propagation step ``p`` sets every one of a unit's connected Real and typed inputs."""
        real_set = set() if p.real_set is None else set(p.real_set.slots.tolist())
        typed_set = {port for tr in p.typed_set for port in tr.ports}
        return (real_set == {self.slot[self._source[i]] for i in real_ins}
                and typed_set == set(typed_ins))

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
        pos, slots = plan.grid
        if len(pos):
            buf[pos] = self._grid[slots]
        peeked = self._peeked
        for r in plan.restarting:
            s = r.slot
            if len(r.fresh) and bool(np.any(self.values[r.fresh] != now[r.fresh])):
                buf[r.position] = peeked[s]  # the source's value at t with the new held input
                continue
            usable = usable_history(now, before, earlier, r.drivers)
            if usable < 3 and len(r.fresh) == len(r.drivers):
                # the value peeked at the jump (at t+ of the point the history restarted at) stands in for the
                # history value there, computed with the old held input: one more value, the same polynomial
                c0, c1, c2 = _EXTRAPOLATION[usable]
                buf[r.position] = (c0 * now[s] + c1 * (peeked[s] if usable == 1 else before[s])
                                   + c2 * (peeked[s] if usable == 2 else earlier[s]))
                continue
            c0, c1, c2 = _EXTRAPOLATION[min(self._known, usable) - 1]
            buf[r.position] = c0 * now[s] + c1 * before[s] + c2 * earlier[s]
        plan.unit.set_real(plan.handle, buf)

    def _peek(self, op: ProgramOp) -> None:
        """After a fresh held input jumped: the source output at t with the new value (a set and a get at t)."""
        values = self.values
        if bool(np.any(values[op.slots] != self._history[0][op.slots])):
            op.unit.set_real(op.handle, values[op.slots])
            self._peeked[op.out_slot] = op.unit.get_real(op.out_handle)[0]

    def _set_all_current(self, name: str) -> None:
        """Set a unit's connected inputs to the present values (initialization)."""
        for tr in self._typed_inputs.get(name, ()):
            tr.unit.set_values(tr.fmi_type, tr.refs, [self.typed[s] for s in tr.slots])
        plan = self._input_plans.get(name)
        if plan is None:
            return
        restarting = np.asarray([(r.position, r.slot) for r in plan.restarting], dtype=np.intp).reshape(-1, 2)
        positions = np.concatenate([getattr(plan, rule)[0] for rule in RULES] + [restarting[:, 0]])
        slots = np.concatenate([getattr(plan, rule)[1] for rule in RULES] + [restarting[:, 1]])
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

    def initialize(self, start_time: float, stop_time: float, step: float | None = None) -> None:
        """Set up every unit, make the values at the start time consistent, leave initialization.

        ``step``: the base step [s], needed when a unit has its own step (its steps end on
        t_k = start + k * step, the last exactly on the stop time).
        """
        self._time = start_time
        self._k = 0
        coarse = {name: m for name, m in self.periods.items() if m > 1}
        if coarse:
            if step is None:
                raise ValueError("units with their own step need the base step: initialize(start, stop, step)")
            n = round((stop_time - start_time) / step)
            uneven = [f"{name} ({m} base steps)" for name, m in coarse.items() if n % m]
            if uneven:
                raise ValueError(f"{n} base steps are not a whole number of the own steps of {', '.join(uneven)}")

            def t_of(k: int) -> float:
                return stop_time if k == n else start_time + k * step

            self._t_of = t_of
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
        self._grid[:] = self.values
        self._typed_now[:] = self.typed
        self._known = 1

    def _consistent_outputs(self) -> None:
        for name in self.units:
            self._get_outputs(name)
        self.propagate()

    def step(self, t: float, h: float) -> None:
        """One communication step from t to t + h [s]: the ops of :meth:`program`, then the history shift.

        A unit with its own step of m base steps steps from t to t(k + m) in the base steps k
        with k % m == 0 (ops with ``every`` = m run where k % m == ``phase``).
        """
        values = self.values
        k = self._k
        self._time = t + h
        for op in self._program:
            if op.every > 1 and k % op.every != op.phase:
                continue
            if op.kind == "step":
                op.unit.step(t, h if op.every == 1 else self._t_of(k + op.every) - t)
            elif op.kind == "get":
                values[op.slots] = op.unit.get_real(op.handle)
            elif op.plan is not None:
                self._set_inputs(op.plan)
            elif op.kind == "set":
                buf = values[op.slots]
                if op.grid_positions is not None:
                    buf[op.grid_positions] = self._grid[op.slots[op.grid_positions]]
                op.unit.set_real(op.handle, buf)
            elif op.kind == "latch":
                self._grid[op.slots] = values[op.slots]
            elif op.kind == "peek":
                self._peek(op)
            elif op.transfer is not None:
                if op.kind == "tget":
                    self._get_typed(op.transfer)
                else:
                    self._set_typed(op.transfer)
        # history shifts by one step (the arrays stay in place: the native executor holds them)
        now, before, earlier = self._history
        earlier[:] = before
        before[:] = now
        now[:] = values
        if self.typed:
            self._typed_now[:] = self.typed
        self._known += 1
        self._k += 1

    def program(self) -> list[ProgramOp]:
        """One communication step as a flat list of operations, the one :meth:`step` carries out.

        Jacobi: every unit's inputs, then every step, then every output read; Gauss-Seidel:
        per unit in order, its inputs, its step, its outputs. Then feedthrough propagation
        (inputs from the end-of-step values, outputs re-read). A ``set`` op forms each input
        by its rule (``RULES``) from the value arrays; a ``get`` op writes outputs into slots.
        An output the propagation re-reads before anything uses it is not read after its unit's
        step as well (one FMI call fewer per such unit and step). The native executor runs the same list.
        """
        return self._program

    def _timing(self, name: str, at_end: bool = False) -> _Timing:
        """A unit with its own step of m base steps: its step's ops run at k % m == 0, its propagation at the
        end of its steps (k % m == m - 1)."""
        m = self.periods[name]
        return {"every": m, "phase": m - 1 if at_end else 0}

    def _set_op(self, plan: _InputPlan) -> ProgramOp:
        """The ``set`` op of a unit's connected inputs: per value its slot, its rule and its restart drivers."""
        rules = np.zeros(len(plan.buffer), dtype=np.intp)
        slots = np.zeros(len(plan.buffer), dtype=np.intp)
        drivers = [np.zeros(0, dtype=np.intp)] * len(plan.buffer)
        fresh = [np.zeros(0, dtype=np.intp)] * len(plan.buffer)
        for rule in RULES:
            pos, group_slots = getattr(plan, rule)
            rules[pos] = RULES.index(rule)
            slots[pos] = group_slots
        for r in plan.restarting:
            rules[r.position], slots[r.position] = RULES.index("extrapolated"), r.slot
            drivers[r.position], fresh[r.position] = r.drivers, r.fresh
        return ProgramOp("set", plan.unit, plan.handle, slots, rules, plan, **self._timing(plan.unit.name),
                         drivers=drivers, fresh_drivers=fresh)

    def _get_ops(self, name: str) -> list[ProgramOp]:
        """Read a unit's slotted outputs after its step: the Reals, then each other type."""
        tr = self._outputs.get(name)
        real = [] if tr is None else [ProgramOp("get", tr.unit, tr.handle, tr.slots, **self._timing(name))]
        return real + [ProgramOp("tget", t.unit, transfer=t, **self._timing(name))
                       for t in self._typed_outputs.get(name, ())]

    def _set_ops(self, name: str) -> list[ProgramOp]:
        """Set a unit's connected inputs before its step: its peeks, its Reals, then each other type."""
        plan = self._input_plans.get(name)
        peeks = [r.peek for r in plan.restarting if r.peek is not None] if plan is not None else []
        real = [*peeks, self._set_op(plan)] if plan is not None else []
        return real + [ProgramOp("tset", t.unit, transfer=t, **self._timing(name))
                       for t in self._typed_inputs.get(name, ())]

    def _step_ops(self) -> list[ProgramOp]:
        """Inputs, steps and output reads in the scheme's order (Jacobi: all sets, all steps, all gets)."""
        ops: list[ProgramOp] = []
        if self.scheme == "jacobi":
            for unit in self.order:
                ops += self._set_ops(unit.name)
            ops += [ProgramOp("step", u, **self._timing(u.name)) for u in self.order]
            for unit in self.order:
                ops += self._get_ops(unit.name)
        else:
            for unit in self.order:
                ops += self._set_ops(unit.name)
                ops.append(ProgramOp("step", unit, **self._timing(unit.name)))
                ops += self._get_ops(unit.name)
        return ops

    def _latch_ops(self) -> list[ProgramOp]:
        """Units with their own step: their outputs as they are at the end of their steps, for the "grid" rule.

        Outputs the propagation re-reads are latched after that read (:meth:`_propagation_ops`), the
        others here, before the propagation.
        """
        propagated = {o for p in self._propagation if p.real_get is not None for o in p.real_get.slots.tolist()}
        ops = []
        for name, m in self.periods.items():
            tr = self._outputs.get(name)
            if m > 1 and tr is not None:
                kept = [k for k in tr.slots.tolist() if k not in propagated]
                if kept:
                    ops.append(ProgramOp("latch", tr.unit, None, np.asarray(kept, dtype=np.intp),
                                         **self._timing(name, at_end=True)))
        return ops

    def _propagation_ops(self) -> list[ProgramOp]:
        """Feedthrough propagation: per level and unit, its inputs from the end-of-step values, its outputs re-read."""
        ops: list[ProgramOp] = []
        for p in self._propagation:
            name = self._step_unit(p)
            when = self._timing(name, at_end=True)
            if p.real_set is not None:
                ops.append(ProgramOp("set", p.real_set.unit, p.real_set.handle, p.real_set.slots, p.set_rules, **when))
            ops += [ProgramOp("tset", t.unit, transfer=t, **when) for t in p.typed_set]
            if p.real_get is not None:
                ops.append(ProgramOp("get", p.real_get.unit, p.real_get.handle, p.real_get.slots, **when))
                if self.periods[name] > 1:
                    ops.append(ProgramOp("latch", p.real_get.unit, None, p.real_get.slots, **when))
            ops += [ProgramOp("tget", t.unit, transfer=t, **when) for t in p.typed_get]
        return ops

    def _build_program(self) -> list[ProgramOp]:
        return self._without_dead_reads(self._step_ops() + self._latch_ops() + self._propagation_ops())

    def _without_dead_reads(self, ops: list[ProgramOp]) -> list[ProgramOp]:
        """Drop from each ``get`` the outputs a later ``get`` of the step overwrites before anything reads them.

        Typically a feedthrough output read right after its unit steps and read again, with the
        end-of-step inputs, by the propagation (a force fed back to the unit that drives it): the first read is never
        used. A ``get`` left with nothing to read is removed, one with fewer outputs gets its
        own handle. The values at the end of the step are the same, with fewer FMI calls. A later
        ``get`` overwrites only when it runs in every step the earlier one runs in (same timing, or every step).
        """
        reads_values = (RULES.index("fresh"), RULES.index("mean"))  # start/extrapolated read the history
        port_of = {k: p for p, k in self.slot.items()}
        overwritten: dict[int, set[tuple[int, int]]] = {}  # slot -> timings of the later gets that overwrite it
        kept: list[ProgramOp] = []
        for op in reversed(ops):
            if op.kind == "get":
                when = (op.every, op.phase)
                live = [k for k, s in enumerate(op.slots.tolist())
                        if not ({when, (1, 0)} & overwritten.get(s, set()))]
                for s in op.slots.tolist():
                    overwritten.setdefault(s, set()).add(when)
                if not live:
                    continue
                if len(live) < len(op.slots):
                    slots = op.slots[live].tolist()
                    narrowed = self._transfer(op.unit, [port_of[k] for k in slots], slots)
                    op = ProgramOp("get", op.unit, narrowed.handle, narrowed.slots, every=op.every, phase=op.phase)
            elif op.kind == "set" and op.rules is not None:  # every set has rules; tset/tget use the typed slots
                for s, rule in zip(op.slots.tolist(), op.rules.tolist(), strict=True):
                    if rule in reads_values:
                        overwritten.pop(s, None)
            elif op.kind in ("latch", "peek"):  # they read the latest values of their slots
                for s in op.slots.tolist():
                    overwritten.pop(s, None)
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

    @property
    def steps_done(self) -> int:
        """Steps done since initialization (the native executor sets it after its runs)."""
        return self._k

    @steps_done.setter
    def steps_done(self, value: int) -> None:
        self._k = value

    @property
    def peeked(self) -> np.ndarray:
        """Per slot: the value a ``peek`` op read (the source output at t with its new held inputs)."""
        return self._peeked

    @property
    def grid(self) -> np.ndarray:
        """Per slot: its value at its unit's last grid point (the array latch ops write, the "grid" rule reads)."""
        return self._grid

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
