"""First-order lag between the commanded and the device current (a coil's inductance).

The current in an electromagnet's coil does not follow its command instantly: with the coil's
inductance L and the drive's resistance R it obeys tau di/dt = i_cmd - i, tau = L/R (e.g. Yang,
Spencer, Jung & Carlson 2004, "Dynamic modeling of large-scale magnetorheological damper
systems for civil engineering applications", J. Eng. Mech. 130(9), 1107-1114: the current
driver's response time). The nominal plant's value (scenarios/nominal_plant.yaml) is tau = 1/eta with
eta = 50 1/s (tau = 20 ms), the first-order filter between command and device of the MR damper model of
Dyke, Spencer, Sain & Carlson (1996), Smart Mater. Struct. 5, 565-575, the nearest published device (the
MRE isolator's own coil is not characterised in the paper). With the command held over a
communication step of length h (the master holds every input over a step), the exact discretisation is

    i_{n+1} = i_n + (1 - exp(-h/tau)) (i_cmd - i_n),

so a unit step of the command gives i(t) = 1 - exp(-t/tau) at every communication point. tau = 0
means no lag (i_{n+1} = i_cmd); tau < 0 is refused. Units: currents [A], tau and h [s].
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any


def lag_factor(h: float, tau: float) -> float:
    """1 - exp(-h/tau) [-] for a step h [s] (1 for tau = 0), computed as -expm1(-h/tau)."""
    if not (math.isfinite(tau) and tau >= 0.0):
        raise ValueError(f"tau must be >= 0 and finite (s), got {tau}")
    if not (math.isfinite(h) and h > 0.0):
        raise ValueError(f"step must be positive (s), got {h}")
    return 1.0 if tau == 0.0 else -math.expm1(-h / tau)


class CurrentLag:
    """The device current i [A] following the command with time constant ``tau`` [s]."""

    def __init__(self, tau: float, i0: float = 0.0) -> None:
        if not (math.isfinite(tau) and tau >= 0.0):
            raise ValueError(f"tau must be >= 0 and finite (s), got {tau}")
        if not math.isfinite(i0):
            raise ValueError(f"initial current must be finite (A), got {i0}")
        self.tau = float(tau)
        self.i = float(i0)
        self._h = math.nan
        self._a = 1.0

    def step(self, i_cmd: float, h: float) -> float:
        """Advance one step of h [s] with the command i_cmd [A] held; returns the current at its end [A]."""
        if h != self._h:
            self._a, self._h = lag_factor(h, self.tau), h
        self.i = i_cmd if self._a == 1.0 else self.i + self._a * (i_cmd - self.i)
        return self.i


def parameter_problem(values: Mapping[str, Any], n_levels: int = 0) -> tuple[str, str] | None:
    """(parameter, message) for the unit's parameter out of its domain (``tau`` [s] >= 0 and finite), or None:
    the check before any run that :class:`CurrentLag` makes when the unit initializes."""
    tau = values.get("tau", 0.0)
    try:
        ok = not isinstance(tau, bool) and math.isfinite(float(tau)) and float(tau) >= 0.0
    except (TypeError, ValueError):
        ok = False
    return None if ok else ("tau", f"time constant tau must be >= 0 s and finite, got {tau!r}")
