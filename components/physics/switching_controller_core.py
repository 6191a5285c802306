"""Lyapunov-based on-off (switching-stiffness) current law for the MRE isolator.

For a variable-stiffness isolator, the rate of the energy V = 1/2 m v^2 + 1/2 k x^2 of the
base gets the term -dk(i) x v from the controllable stiffness. V falls fastest with the
largest stiffness while the base moves away from its centre (x v > 0) and the smallest
while it returns (x v < 0): the spring stores energy stiff and gives it back soft.
This is the classic on-off semi-active stiffness law (e.g. Nagarajaiah and Narasimhan's
SAIVS, Jansen and Dyke's Lyapunov/bang-bang laws for smart dampers), used in the case
study to place the SOSM controller. Inputs: base displacement x [m], velocity v [m/s];
output: current [A], decided from the measurements at the start of each step and held.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class SwitchingLaw:
    """i_high [A] while |x| grows (x v > 0), i_low [A] otherwise; both clipped to [0, i_max]."""

    i_high: float = 3.0  # A
    i_low: float = 0.0  # A
    i_max: float = 3.0  # A

    def __post_init__(self) -> None:
        for name in ("i_high", "i_low", "i_max"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{name} must be finite")
        if self.i_max <= 0:
            raise ValueError(f"i_max must be positive, got {self.i_max}")

    def current(self, x: float, v: float) -> float:
        """Command current [A] for base displacement x [m] and velocity v [m/s]."""
        i = self.i_high if x * v > 0.0 else self.i_low
        return min(max(i, 0.0), self.i_max)
