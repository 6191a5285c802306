"""FMI 2.0 co-simulation unit that holds a constant current: a drop-in passive controller.

It has no inputs; output i [A] equals the parameter ``current``. Scenarios swap it in
for the SOSM controller to run the passive structure with another unit.
"""

from __future__ import annotations

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

FMU_CORE_MODULES: tuple[str, ...] = ()


class ConstantCurrent(Fmi2Slave):
    """Constant current source."""

    description = "Constant isolator current (passive control)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.current = 0.0
        self.fmi_units = {"current": "A", "i": "A"}
        self.fmi_dependencies = {}
        self.register_variable(
            Real("current", description="current to hold", causality=Fmi2Causality.parameter,
                 variability=Fmi2Variability.fixed)
        )
        self.register_variable(
            Real("i", description="command current", causality=Fmi2Causality.output,
                 variability=Fmi2Variability.continuous, getter=lambda: self.current)
        )

    def do_step(self, current_time: float, step_size: float) -> bool:
        return True
