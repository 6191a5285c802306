"""Fast ``set_real``/``get_real`` of the pythonfmu shells, for the value references a master exchanges every step.

pythonfmu's own paths look every value reference up and call its variable's setter or getter, one at a time; a
master sets and reads the same few references at every communication point. A shell derives from
:class:`FastExchange` (before ``Fmi2Slave``), names the inputs and outputs it exchanges fast at the end of its
``__init__`` (:meth:`FastExchange.exchange_fast`) and gives the values of all those outputs in one list
(``_exchanged_outputs``: one evaluation serves every output of a request), or, with one fast output, its value
(``_exchanged_value``). Everything else takes pythonfmu's path.

- Setting the named inputs in their declared order is one tuple assignment, compiled once per list of names (as
  :mod:`dataclasses` compiles an ``__init__``), so it costs what the hand-written ``self.x, self.v = values``
  did; any other choice of them is assigned one by one. The inputs are plain attributes (pythonfmu's default
  setter does the same ``setattr``).
- A request of named outputs, in any order or subset, is picked out of the one list; the picker is kept per
  request (the first :data:`MAX_PICKERS`). The request of a shell's only fast output is
  ``[self._exchanged_value()]``, as it was hand-written.

Not an FMU itself (no ``_fmu.py``): listed in ``FMU_CORE_MODULES`` of every shell that uses it, beside
``shared_copies``, and imported by its bare name. pythonfmu FMUs share one interpreter, so the copy loaded first
serves every FMU: each shell passes this module to ``shared_copies.copy_problem``, which refuses another FMU's
copy with other code. The module keeps no state: the fast-path tables live on the shell instance (so they are
part of its FMU state, like any attribute the shell adds).
"""

from __future__ import annotations

import functools
import operator
from collections.abc import Callable, Sequence
from typing import Any

with open(__file__, "rb") as _source:
    LOADED_SOURCE = _source.read()

MAX_PICKERS = 8  # output requests whose picker is kept; a master makes one or two

Picker = Callable[[Sequence[float]], list[float]]


@functools.cache
def _assigner(names: tuple[str, ...]) -> Callable[[Any, Sequence[float]], None]:
    """``assign(obj, values)``: ``obj.<names[0]>, obj.<names[1]>, ... = values`` in one tuple assignment."""
    if not names or not all(name.isidentifier() for name in names):
        raise ValueError(f"fast inputs must be attribute names, got {names}")
    namespace: dict[str, Any] = {}
    targets = "".join(f"obj.{name}, " for name in names)
    exec(f"def assign(obj, values):\n    {targets}= values\n", namespace)
    return namespace["assign"]


def _picker(indices: Sequence[int]) -> Picker:
    """The values at ``indices`` of a list, as a new list."""
    if len(indices) == 1:
        (k,) = indices
        return lambda values: [values[k]]
    get = operator.itemgetter(*indices)
    return lambda values: list(get(values))


class FastExchange:
    """Mixin of an ``Fmi2Slave`` shell (``class Unit(FastExchange, Fmi2Slave)``): fast paths for the inputs and
    outputs named by :meth:`exchange_fast`; the shell defines ``_exchanged_outputs``, or ``_exchanged_value`` if it
    names one output."""

    def exchange_fast(self, inputs: Sequence[str] = (), outputs: Sequence[str] = ()) -> None:
        """Fast paths for the Real ``inputs`` (plain attributes of the shell) and ``outputs`` (named in the order
        of ``_exchanged_outputs``); call it once every variable is registered."""
        vr = {v.name: v.value_reference for v in self.vars.values()}  # type: ignore[attr-defined]
        self._fast_inputs: list[int] | None = [vr[name] for name in inputs] or None
        self._fast_assign = _assigner(tuple(inputs)) if inputs else None
        self._fast_input_names = {vr[name]: name for name in inputs}
        self._fast_output_index = {vr[name]: k for k, name in enumerate(outputs)}
        self._fast_single: list[int] | None = [vr[outputs[0]]] if len(outputs) == 1 else None
        self._fast_pickers: list[tuple[list[int], Picker]] = []

    def _exchanged_value(self) -> float:
        """The present value of the only fast output (a shell with one defines this)."""
        raise NotImplementedError

    def _exchanged_outputs(self) -> Sequence[float]:
        """The present values of the fast outputs, in the order given to :meth:`exchange_fast`."""
        return [self._exchanged_value()]

    def set_real(self, vrs: list[int], values: list[float]) -> None:
        if vrs == self._fast_inputs:
            self._fast_assign(self, values)
            return
        names = self._fast_input_names
        if all(vr in names for vr in vrs):
            for vr, value in zip(vrs, values, strict=True):
                setattr(self, names[vr], value)
            return
        super().set_real(vrs, values)  # type: ignore[misc]

    def get_real(self, vrs: list[int]) -> list[float]:
        if vrs == self._fast_single:
            return [self._exchanged_value()]
        for known, picker in self._fast_pickers:
            if vrs == known:
                return picker(self._exchanged_outputs())
        index = self._fast_output_index
        if not vrs or not all(vr in index for vr in vrs):
            return super().get_real(vrs)  # type: ignore[misc]
        picker = _picker([index[vr] for vr in vrs])
        if len(self._fast_pickers) < MAX_PICKERS:
            self._fast_pickers.append((list(vrs), picker))
        return picker(self._exchanged_outputs())
