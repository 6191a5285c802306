"""FMI 2.0 co-simulation unit that holds a constant current: a drop-in passive controller.

It has no inputs; output i [A] equals the parameter ``current``. Scenarios swap it in
for the SOSM controller to run the passive structure with another unit.
"""

from __future__ import annotations

import copy

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

FMU_CORE_MODULES: tuple[str, ...] = ()
FMU_REQUIREMENTS: tuple[str, ...] = ()  # besides Python >= 3.11
FMU_FAILED_STEP_STATUS = "error"  # a do_step that returns False (an error it logged) is fmi2Error


class ConstantCurrent(Fmi2Slave):
    """Constant current source."""

    description = "Constant isolator current (passive control)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._slave_attrs = frozenset(vars(self)) | {"_slave_attrs"}
        self.current = 0.0
        self.fmi_units = {"current": "A", "i": "A"}
        self.fmi_dependencies = {}
        self.register_variable(
            Real("current", description="current to hold", causality=Fmi2Causality.parameter,
                 variability=Fmi2Variability.fixed)
        )
        self.register_variable(
            Real("i", description="command current", causality=Fmi2Causality.output,
                 variability=Fmi2Variability.discrete, getter=lambda: self.current)
        )

    def do_step(self, current_time: float, step_size: float) -> bool:
        return True

    # FMU state (fmi2GetFMUstate/fmi2SetFMUstate): every instance attribute the shell added,
    # registered or not, deep-copied; pythonfmu's own bookkeeping is left alone.
    def _get_fmu_state(self) -> dict:
        return {k: copy.deepcopy(v) for k, v in vars(self).items() if k not in self._slave_attrs}

    def _set_fmu_state(self, state: dict) -> None:
        vars(self).update(copy.deepcopy(state))
