"""A deliberately failing FMI 2.0 unit for reliability tests (not part of the product).

Output y follows input u (y = u, direct feedthrough) until the simulation time reaches
``fail_at`` [s]; then, by ``failure``: "discard" (fmi2DoStep returns fmi2Discard with a
logged error), "nan" (y becomes NaN), "raise" (do_step raises: pythonfmu reports fmi2Fatal)
or "none".
"""

from __future__ import annotations

import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real, String
from pythonfmu.enums import Fmi2Status

FMU_CORE_MODULES: tuple[str, ...] = ()


class FailingUnit(Fmi2Slave):
    """Fails on purpose at a chosen time."""

    description = "Test unit that fails at a chosen time"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.fail_at = 1.0
        self.failure = "discard"
        self._broken = False
        self.fmi_units = {"u": "m", "y": "m", "fail_at": "s"}
        self.fmi_dependencies = {"y": ("u",)}
        self.register_variable(Real("u", causality=Fmi2Causality.input, variability=Fmi2Variability.continuous))
        par = {"causality": Fmi2Causality.parameter, "variability": Fmi2Variability.fixed}
        self.register_variable(Real("fail_at", **par))
        self.register_variable(String("failure", **par))
        self.register_variable(Real("y", causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                                    getter=lambda: math.nan if self._broken else self.u))

    def do_step(self, current_time: float, step_size: float) -> bool:
        if current_time + 1e-12 < self.fail_at:
            return True
        if self.failure == "discard":
            self.log(f"deliberate failure at t = {current_time:.6g} s", Fmi2Status.error)
            return False
        if self.failure == "nan":
            self._broken = True
            return True
        if self.failure == "raise":
            raise RuntimeError(f"deliberate exception at t = {current_time:.6g} s")
        return True
