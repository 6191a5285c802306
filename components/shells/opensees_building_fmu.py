"""FMI 2.0 co-simulation shell of a building modelled in OpenSees (OpenSeesPy), a drop-in for ShearBuilding.

Parameter ``script``: an OpenSeesPy model script (a Python file) that builds the model and
declares ``BASE_NODE``, ``FLOOR_NODES`` and the masses (``ops.mass``), by the convention of
:mod:`opensees_building_core` (docs/structures.md, "OpenSees unit"). ``substeps`` [1]:
Newmark (average acceleration) steps per communication step; ``zoh``: hold the inputs over
the whole step (a short first sub-step takes the jump), as ShearBuilding's exact ZOH does.

Inputs ag [m/s^2] (ground acceleration) and F [N] (isolator restoring force, applied to
the base against x_0). Outputs, named and in units as ShearBuilding's: per level j
(0 = base floor) x_j [m], v_j [m/s] relative to the ground, a_j [m/s^2] absolute and
arel_j [m/s^2] relative acceleration; per storey j >= 1 drift_j [m] and shear_j [N].

The script runs when the unit leaves initialization mode. A script that raises or breaks
the convention, and a step OpenSees cannot converge, are logged as errors naming the
script and line or the time and OpenSees' message, and fail the step (fmi2Error).
OpenSees keeps one model per process: a second instance in a process is refused at
instantiation (fmi2Instantiate fails; pythonfmu prints the reason on stderr), and the
modelDescription says canBeInstantiatedOnlyOncePerProcess.

The number of storeys is fixed at build time (``N_STOREYS``; the build renders variants).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Status

try:
    import fast_exchange
    import opensees_building_core as core
    import shared_copies
    from fast_exchange import FastExchange
except ImportError as exc:  # the host's Python lacks a package: say which (the build's logging shim shows it)
    raise ImportError(f"the OpenSeesBuilding unit needs the Python package numpy in the host's "
                      f"interpreter ({sys.executable}): {exc}") from exc

N_STOREYS = 3
FMU_CORE_MODULES = ("opensees_building_core", "shared_copies", "fast_exchange")
FMU_REQUIREMENTS: tuple[str, ...] = ("numpy", "openseespy")  # besides Python >= 3.11
FMU_FAILED_STEP_STATUS = "error"  # a do_step that returns False (an error it logged) is fmi2Error
FMU_ONCE_PER_PROCESS = True  # OpenSees keeps one model per process: canBeInstantiatedOnlyOncePerProcess


class OpenSeesBuilding(FastExchange, Fmi2Slave):
    """A building on a base floor modelled by an OpenSeesPy script, stepped by OpenSees' transient analysis."""

    description = "Building on a base floor modelled in OpenSees (OpenSeesPy script; Newmark transient analysis)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        if self.instance_name != "build":  # the build instantiates the class to read its variables
            reason = core.busy_reason()
            if reason is not None:  # pythonfmu prints the exception, and fmi2Instantiate fails
                raise RuntimeError(f"OpenSeesBuilding refused: {reason}")
        self.n_levels = N_STOREYS + 1
        self.script = ""
        self.substeps = 1
        self.zoh = True
        self.ag = 0.0
        self.F = 0.0
        self._model: core.OpenSeesBuilding | None = None
        self._built_for: tuple | None = None
        self._failed = ""
        self._run_failed = ""  # a step failed: the model is left mid-step, no further steps
        self._cache_key: tuple | None = None
        self._values: list[float] = []

        inp = {"causality": Fmi2Causality.input, "variability": Fmi2Variability.continuous}
        par = {"causality": Fmi2Causality.parameter, "variability": Fmi2Variability.fixed}
        self.register_variable(Real("ag", description="ground acceleration", **inp))
        self.register_variable(
            Real("F", description="isolator restoring force, acts on the base against x_0", **inp)
        )
        self.register_variable(String("script", description="OpenSeesPy model script (Python file)", **par))
        self.register_variable(Integer("substeps", description="Newmark steps per communication step", **par))
        self.register_variable(Boolean("zoh", description="hold the inputs over the whole step", **par))
        self.fmi_units = {"ag": "m/s2", "F": "N"}
        self.fmi_dependencies = {}
        levels = range(self.n_levels)
        storeys = range(1, self.n_levels)

        def where(j):
            return "base floor" if j == 0 else f"floor {j}"

        outputs = (
            [(f"x_{j}", "m", f"displacement of the {where(j)} relative to the ground") for j in levels]
            + [(f"v_{j}", "m/s", f"velocity of the {where(j)} relative to the ground") for j in levels]
            + [(f"a_{j}", "m/s2", f"absolute acceleration of the {where(j)}") for j in levels]
            + [(f"arel_{j}", "m/s2", f"acceleration of the {where(j)} relative to the ground") for j in levels]
            + [(f"drift_{j}", "m", f"inter-storey drift x_{j} - x_{j - 1}") for j in storeys]
            + [(f"shear_{j}", "N", f"shear force in storey {j} (inertia of the floors above)") for j in storeys]
        )
        for index, (name, unit, text) in enumerate(outputs):
            self.register_variable(Real(name, description=text, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        getter=lambda index=index: self._exchanged_outputs()[index]))
            self.fmi_units[name] = unit
            if name.startswith(("a_", "arel_")):
                self.fmi_dependencies[name] = ("ag", "F")
        # The master exchanges the same value references every step: fast paths for them (fast_exchange).
        self.exchange_fast(inputs=("ag", "F"), outputs=[name for name, _, _ in outputs])

    # -- the model ---------------------------------------------------------------------------------------
    def _building(self) -> core.OpenSeesBuilding | None:
        """The model for the present parameters, built once (None, logged, if it cannot be)."""
        key = (self.script, self.substeps, self.zoh)
        if self._built_for == key:
            return self._model
        self._close_model()
        self._built_for = key
        self._failed = ""
        if not self.script:
            self._failed = "parameter 'script' is not set: name an OpenSeesPy model script"
        else:
            try:
                self._model = core.OpenSeesBuilding(Path(self.script), N_STOREYS, self.substeps, self.zoh)
            except (core.ModelScriptError, core.OpenSeesUnavailable, core.ProcessBusy, ValueError) as exc:
                self._failed = f"parameter 'script': {exc}"
            except Exception as exc:  # an exception out of here would be fmi2Fatal: log it, fail the step
                self._failed = f"cannot build the OpenSees model from {self.script}: {type(exc).__name__}: {exc}"
        if self._failed:
            self.log(self._failed, Fmi2Status.error)
        self._cache_key = None
        return self._model

    def _close_model(self) -> None:
        model, self._model = self._model, None
        if model is not None:
            model.close()

    def _exchanged_outputs(self) -> list[float]:
        model = self._model
        if model is None:
            return [math.nan] * len(self._fast_output_index)
        key = (self.ag, self.F, model.steps)
        if key != self._cache_key:
            self._values = model.output_vector(self.ag, self.F).tolist()
            self._cache_key = key
        return self._values

    def exit_initialization_mode(self):
        # another FMU's copy of the shared fast paths with other code: refused (shared_copies), every step fails
        problem = shared_copies.copy_problem((fast_exchange,), self.resources)
        if problem:
            self._run_failed = problem
            self.log(problem, Fmi2Status.error)
            return
        self._building()  # logs a bad script; an exception here would be fmi2Fatal

    def do_step(self, current_time: float, step_size: float) -> bool:
        if self._run_failed:
            self.log(self._run_failed, Fmi2Status.error)
            return False
        model = self._building()
        if model is None:
            self.log(self._failed, Fmi2Status.error)
            return False
        if not (math.isfinite(self.ag) and math.isfinite(self.F)):
            self.log(f"input ag = {self.ag} or F = {self.F} is not finite at t = {current_time:.6g} s",
                     Fmi2Status.error)
            return False
        try:
            model.step(self.ag, self.F, step_size)
        except core.StepFailure as exc:
            self._run_failed = f"OpenSees building ({self.script}) at t = {current_time:.6g} s: {exc}"
            self.log(self._run_failed, Fmi2Status.error)
            return False
        return True

    def terminate(self):
        self._close_model()

    def __del__(self):
        if "_model" in vars(self):  # not if __init__ refused the instance
            self._close_model()
