"""The physical units of a connection's two ends: refused when they differ, a warning when the output has none.

Variables carry the unit of their FMU's model description (``unit`` of the variable or its
declared type). The master converts no unit, so a connection joins ends in the same unit:

* two different non-empty units (``m`` into ``mm``): refused, a scenario error (exit 2);
* an output without a unit into an input with one: accepted, with a one-line warning naming
  both ends (FMUs exported by other tools often declare no units; the value is taken to be
  in the input's unit);
* an output with a unit into an input without one, or neither with a unit: accepted.
"""

from __future__ import annotations

import sys

_WARNED: set[str] = set()


def connection_units(source: str, target: str, source_unit: str | None, target_unit: str | None
                     ) -> tuple[str | None, str | None]:
    """(problem, warning) of a connection ``source -> target`` by its ends' units; each None if there is none."""
    if source_unit and target_unit and source_unit != target_unit:
        return f"unit mismatch: {source} is in {source_unit}, {target} in {target_unit}", None
    if not source_unit and target_unit:
        return None, (f"{source} declares no unit and is connected to {target} in {target_unit}: its values are "
                      f"taken to be in {target_unit}")
    return None, None


def warn_once(text: str) -> None:
    """``warning: <text>`` on stderr, once per process (a study checks the same connection for every run)."""
    if text not in _WARNED:
        _WARNED.add(text)
        print(f"warning: {text}", file=sys.stderr, flush=True)
