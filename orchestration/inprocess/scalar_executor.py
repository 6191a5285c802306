"""The scalar executor: the coupling algorithm's program as one Python function over floats.

:class:`~orchestration.master.algorithm.CouplingAlgorithm` describes a communication step as a flat
program (:meth:`~orchestration.master.algorithm.CouplingAlgorithm.program`): which unit is set,
stepped or read, in which order, and by which rule (``RULES``) each input is formed from the
values at t, t - h, t - 2h and the latest ones. The engine carries it out with numpy arrays
(:meth:`CouplingAlgorithm.step`) or in C for FMUs (``master/native_stepper.py``). For the small
in-process units most of that time is numpy's per-call cost on arrays of one to eight values,
so this third executor turns the same program into the source of one Python function whose
values are floats in lists, calls the units' ``setter``/``getter`` fast paths
(:mod:`orchestration.inprocess.units`) and records each communication point into a flat buffer.

It decides nothing itself: order, rules, dead reads and feedthrough propagation come from the
program, the extrapolation weights and the history from the algorithm. Each input is the same
floating-point expression as in :meth:`CouplingAlgorithm.step` (``0.5 * (now + latest)``,
``c0 * now + c1 * before + c2 * earlier``), so both executors give identical results, bit for bit
(tests/engine/test_inprocess.py checks every scheme and input estimate).
"""

from __future__ import annotations

from array import array
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from orchestration.master.algorithm import RULES, CouplingAlgorithm
from orchestration.master.graph import Port

_EXPRESSIONS = {
    "start": "now[{s}]",
    "fresh": "v[{s}]",
    "mean": "0.5 * (now[{s}] + v[{s}])",
    "extrapolated": "c0 * now[{s}] + c1 * before[{s}] + c2 * earlier[{s}]",
    "grid": "g[{s}]",
}


def _jumped(drivers: Sequence[int]) -> str:
    """Did one of the drivers change in this step (latest value != value at t)?"""
    return " or ".join(f"v[{d}] != now[{d}]" for d in drivers)


def _restarting(slot: int, drivers: Sequence[int], fresh: Sequence[int]) -> str:
    """The extrapolation of ``slot`` with its history restarted after a held driver changed
    (:func:`~orchestration.master.algorithm.usable_history`), or its peeked value after a fresh
    driver jumped in this step, as one expression."""
    changed_now = " or ".join(f"now[{d}] != before[{d}]" for d in drivers)
    changed_before = " or ".join(f"before[{d}] != earlier[{d}]" for d in drivers)
    usable = f"(1 if ({changed_now}) else 2 if ({changed_before}) else 3)"
    if len(fresh) == len(drivers):  # the peeked value stands in for the history value at the restart
        expression = (f"(lambda u: (lambda w: w[0] * now[{slot}] + w[1] * (p[{slot}] if u == 1 else before[{slot}]) "
                      f"+ w[2] * (p[{slot}] if u == 2 else earlier[{slot}]))(weights[u]) if u < 3 else "
                      f"(lambda w: w[0] * now[{slot}] + w[1] * before[{slot}] + w[2] * earlier[{slot}])"
                      f"(weights[min(known, 3) - 1]))({usable})")
    else:
        w = f"weights[min(known, {usable}) - 1]"
        expression = f"(lambda w: w[0] * now[{slot}] + w[1] * before[{slot}] + w[2] * earlier[{slot}])({w})"
    return f"(p[{slot}] if ({_jumped(fresh)}) else {expression})" if len(fresh) else expression


class ScalarUnavailable(RuntimeError):
    """The program has an operation or a unit this executor cannot run (values of other types, no fast path)."""


class ScalarExecutor:
    """Runs the steps of an initialized CouplingAlgorithm whose units have ``setter``/``getter`` fast paths.

    ``record`` names the slotted outputs kept at every communication point (:meth:`rows`).
    """

    def __init__(self, algorithm: CouplingAlgorithm, record: Sequence[Port]) -> None:
        self.algorithm = algorithm
        self._record_slots = [algorithm.slot[p] for p in record]
        self._n_record = len(self._record_slots)
        namespace: dict[str, Any] = {"array": array}
        lines: list[str] = []
        for n, op in enumerate(algorithm.program()):
            if op.every > 1:  # a unit with its own step: the op runs where k % every == phase
                lines.append(f"if k % {op.every} == {op.phase}:")
                lines.append("    " + self._line(op, n, namespace))
            else:
                lines.append(self._line(op, n, namespace))
        picks = ", ".join(f"v[{s}]" for s in self._record_slots)
        body = "\n".join(f"        {line}" for line in lines)
        self.source = f'''\
def run_steps(first, last, t_of, v, now, before, earlier, g, p, known, weights, out):
    extend = out.extend
    for k in range(first, last):
        t = t_of(k)
        t_next = t_of(k + 1)
        h = t_next - t
        c0, c1, c2 = weights[min(known, 3) - 1]
{body}
        earlier, before, now = before, now, earlier
        now[:] = v
        known += 1
        extend(({picks}{"," if self._n_record == 1 else ""}))
    return now, before, earlier, known
'''
        exec(compile(self.source, f"<scalar program of {len(lines)} operations>", "exec"), namespace)
        self._run: Callable[..., tuple] = namespace["run_steps"]
        self._out = array("d")
        self._record_now()

    @staticmethod
    def _line(op: Any, n: int, namespace: dict[str, Any]) -> str:
        """One op of the program as a line of Python (its callables put into ``namespace``)."""
        unit = op.unit
        if op.kind == "step":
            namespace[f"step_{n}"] = unit.step
            return f"step_{n}(t, h)" if op.every == 1 else f"step_{n}(t, t_of(k + {op.every}) - t)"
        if op.kind == "latch":
            return "; ".join(f"g[{s}] = v[{s}]" for s in op.slots.tolist())
        if op.kind == "peek":
            if not (callable(getattr(unit, "setter", None)) and callable(getattr(unit, "getter", None))):
                raise ScalarUnavailable(f"unit {unit.name} has no setter/getter fast path")
            namespace[f"peek_set_{n}"] = unit.setter(op.handle)
            namespace[f"peek_get_{n}"] = unit.getter(op.out_handle)
            drivers = op.slots.tolist()
            values = ", ".join(f"v[{d}]" for d in drivers)
            return (f"if {_jumped(drivers)}: peek_set_{n}([{values}]); p[{op.out_slot}] = peek_get_{n}()[0]")
        if op.kind == "get":
            if not callable(getattr(unit, "getter", None)):
                raise ScalarUnavailable(f"unit {unit.name} has no getter fast path")
            namespace[f"get_{n}"] = unit.getter(op.handle)
            targets = "".join(f"v[{s}], " for s in op.slots.tolist())
            return f"{targets}= get_{n}()"
        if op.kind == "set":
            if not callable(getattr(unit, "setter", None)):
                raise ScalarUnavailable(f"unit {unit.name} has no setter fast path")
            namespace[f"set_{n}"] = unit.setter(op.handle)
            drivers = op.drivers or [()] * len(op.slots)
            fresh = op.fresh_drivers or [()] * len(op.slots)
            terms = [_restarting(s, list(d), list(f)) if len(d) else _EXPRESSIONS[RULES[r]].format(s=s)
                     for s, r, d, f in zip(op.slots.tolist(), op.rules.tolist(), drivers, fresh, strict=True)]
            return f"set_{n}([{', '.join(terms)}])"
        raise ScalarUnavailable(f"operation {op.kind} (values that are not Real) of unit {unit.name}")

    def _record_now(self) -> None:
        values = self.algorithm.values
        self._out.extend(values[s] for s in self._record_slots)

    def run(self, first: int, last: int, t_of: Callable[[int], float]) -> None:
        """Steps ``first`` .. ``last - 1`` (t(k) = ``t_of(k)``); the algorithm's values and history follow."""
        alg = self.algorithm
        values = alg.values
        history = alg.history
        v = values.tolist()
        g = alg.grid.tolist()
        p = alg.peeked.tolist()
        now, before, earlier = (h.tolist() for h in history)
        now, before, earlier, known = self._run(first, last, t_of, v, now, before, earlier, g, p, alg.known,
                                                alg.extrapolation, self._out)
        values[:] = v
        alg.grid[:] = g
        alg.peeked[:] = p
        for target, source in zip(history, (now, before, earlier), strict=True):
            target[:] = source
        alg.known = known
        alg.steps_done = last

    def rows(self) -> np.ndarray:
        """The recorded outputs, one row per communication point (the first at initialization)."""
        return np.frombuffer(self._out, dtype=float).reshape(-1, self._n_record)
