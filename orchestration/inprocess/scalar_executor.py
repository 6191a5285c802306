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
(tests/test_inprocess.py checks every scheme and input estimate).
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
}


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
            unit = op.unit
            if op.kind == "step":
                namespace[f"step_{n}"] = unit.step
                lines.append(f"step_{n}(t, h)")
            elif op.kind == "get":
                if not callable(getattr(unit, "getter", None)):
                    raise ScalarUnavailable(f"unit {unit.name} has no getter fast path")
                namespace[f"get_{n}"] = unit.getter(op.handle)
                targets = "".join(f"v[{s}], " for s in op.slots.tolist())
                lines.append(f"{targets}= get_{n}()")
            elif op.kind == "set":
                if not callable(getattr(unit, "setter", None)):
                    raise ScalarUnavailable(f"unit {unit.name} has no setter fast path")
                namespace[f"set_{n}"] = unit.setter(op.handle)
                terms = [_EXPRESSIONS[RULES[r]].format(s=s)
                         for s, r in zip(op.slots.tolist(), op.rules.tolist(), strict=True)]
                lines.append(f"set_{n}([{', '.join(terms)}])")
            else:
                raise ScalarUnavailable(f"operation {op.kind} (values that are not Real) of unit {unit.name}")
        picks = ", ".join(f"v[{s}]" for s in self._record_slots)
        body = "\n".join(f"        {line}" for line in lines)
        self.source = f'''\
def run_steps(first, last, t_of, v, now, before, earlier, known, weights, out):
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

    def _record_now(self) -> None:
        values = self.algorithm.values
        self._out.extend(values[s] for s in self._record_slots)

    def run(self, first: int, last: int, t_of: Callable[[int], float]) -> None:
        """Steps ``first`` .. ``last - 1`` (t(k) = ``t_of(k)``); the algorithm's values and history follow."""
        alg = self.algorithm
        values = alg.values
        history = alg.history
        v = values.tolist()
        now, before, earlier = (h.tolist() for h in history)
        now, before, earlier, known = self._run(first, last, t_of, v, now, before, earlier, alg.known,
                                                alg.extrapolation, self._out)
        values[:] = v
        for target, source in zip(history, (now, before, earlier), strict=True):
            target[:] = source
        alg.known = known

    def rows(self) -> np.ndarray:
        """The recorded outputs, one row per communication point (the first at initialization)."""
        return np.frombuffer(self._out, dtype=float).reshape(-1, self._n_record)
