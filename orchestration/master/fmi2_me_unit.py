"""FMI 2.0 Model Exchange FMUs as co-simulation units: integrated with CVode between communication points.

:class:`MeUnit` is an :class:`~orchestration.master.fmi2_cosim_unit.FmuUnit` (the same loading,
logging, parameters, Real fast path, typed values and teardown; FMI status becomes an
exception in :func:`orchestration.master.fmi_status.check_status` through ``_check``) whose
``step(t, h)`` integrates the FMU's continuous states from t to t + h with fmpy's CVode
(``fmpy.sundials.CVodeSolver``: BDF, dense linear solver, absolute tolerance = relative
tolerance × the states' nominal values, largest step (stop − start)/50), in the loop of
``fmpy.simulation.simulateME``:

* **time events**: the solver stops at ``nextEventTime`` (from ``fmi2NewDiscreteStates``);
* **state events**: CVode finds the zero crossings of the event indicators;
* **step events**: ``fmi2CompletedIntegratorStep`` after each solver call, when the FMU needs it;
* at an event: ``fmi2EnterEventMode``, ``fmi2NewDiscreteStates`` until no new discrete states
  are needed, ``fmi2EnterContinuousTimeMode``, and the solver restarts from the new states.

Inputs are held constant over a communication step (sample-and-hold, as co-simulation units
see them). An input set to a new value after initialization is an event at that time, as
fmpy treats a jump of an input signal: the unit enters Event Mode when the value is set and
the event iteration runs at the start of the next step, before the solver restarts.
With no input change and no event the solver is not restarted at communication points, so a
unit driven on the grid t_k = t_0 + k·h takes the same solver steps as
``fmpy.simulate_fmu(..., output_interval=h)``.

``terminateSimulation`` from the FMU ends the run with a SimulationError naming the unit and
the time. The native executor cannot run these units (:meth:`MeUnit.native_functions` is None).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from ctypes import byref
from pathlib import Path
from typing import Any

import numpy as np

from orchestration.master.errors import SimulationError
from orchestration.master.fmi2_cosim_unit import FmuUnit
from orchestration.master.fmi_status import LogRecord
from orchestration.master.fmu_description import read_description, run_interface
from orchestration.master.value_buffer import ValueBuffer

DEFAULT_RELATIVE_TOLERANCE = 1e-6
"""CVode's relative tolerance unless the scenario sets ``relative_tolerance`` (fmpy's default is 1e-5)."""
MAX_EVENT_ITERATIONS = 1000
"""Most ``fmi2NewDiscreteStates`` calls at one event before the unit fails (the iteration must converge)."""
MAX_EVENTS_PER_STEP = 10_000
"""Most events in one communication step before the unit fails (chattering or Zeno behaviour)."""

_SOLVER_CLASS: type | None = None


def runs_as_model_exchange(path: Path, requested: str | None = None) -> bool:
    """Does the FMU at ``path`` run as model exchange: asked for, or an FMU without co-simulation?"""
    if requested is not None:
        return requested == "model-exchange"
    from fmpy import read_model_description

    return run_interface(read_model_description(str(path), validate=False)) == "model-exchange"


class _NoInput:
    """fmpy's solver applies input signals at root-function calls; a unit's inputs are held instead."""

    @staticmethod
    def apply(*args: Any, **kwargs: Any) -> None:
        return None


def _solver_class() -> type:
    """fmpy's CVodeSolver whose callbacks keep the first exception (a ctypes callback cannot raise) and fail."""
    global _SOLVER_CLASS
    if _SOLVER_CLASS is None:
        from fmpy.sundials import CVodeSolver

        class Solver(CVodeSolver):
            failure: BaseException | None = None

            def f(self, t, y, ydot, user_data):  # fmpy's ctypes callback signature
                try:
                    return super().f(t, y, ydot, user_data)
                except BaseException as exc:  # re-raised by MeUnit._integrate
                    self.failure = self.failure or exc
                    return -1

            def g(self, t, y, gout, user_data):
                try:
                    return super().g(t, y, gout, user_data)
                except BaseException as exc:
                    self.failure = self.failure or exc
                    return -1

        _SOLVER_CLASS = Solver
    return _SOLVER_CLASS


class MeUnit(FmuUnit):
    """An FMI 2.0 Model Exchange FMU stepped as a co-simulation unit (CVode between communication points).

    ``setup`` is FmuUnit's, loading the Model Exchange library through fmpy's FMU2Model.
    """

    interface = "model-exchange"
    _fmpy_class = "FMU2Model"

    def __init__(
        self,
        name: str,
        path: Path,
        parameters: dict[str, Any] | None = None,
        on_log: Callable[[str, LogRecord], None] | None = None,
        relative_tolerance: float | None = None,
    ) -> None:
        super().__init__(name, path, parameters, on_log)
        if self._md.coSimulation is not None:  # FmuUnit described it as co-simulation; FmuFormatError if not ME
            self.description, self._md = read_description(self.path, name, "model-exchange")
        self.relative_tolerance = DEFAULT_RELATIVE_TOLERANCE if relative_tolerance is None else relative_tolerance
        self._solver: Any = None
        self._event_mode = False  # inside Event Mode, waiting for the event iteration
        self._next_event: float | None = None
        self._set_before: dict[int, np.ndarray] = {}  # per Real handle: the values last set
        self._completed_step_needed = bool(self._md.modelExchange.needsCompletedIntegratorStep)
        self._nx = self._md.numberOfContinuousStates
        self._nz = self._md.numberOfEventIndicators
        self._stop_time = math.inf
        self._start_time = 0.0
        self.events = 0  # events handled after initialization (time, state, step and input events)

    # -- lifecycle -------------------------------------------------------------------------------------
    def exit_initialization(self) -> None:
        """Leave initialization, run the initial event iteration, enter Continuous-Time Mode, start the solver."""
        self._call("fmi2ExitInitializationMode")
        self._initialized = True
        self._update_discrete_states()
        self._call("fmi2EnterContinuousTimeMode")
        self._solver = self._make_solver(self._start_time)  # initialization happens at the start time

    def terminate(self) -> None:
        """Free the solver, then terminate and free the FMU as FmuUnit does; never raises."""
        self._solver = None
        super().terminate()

    def native_functions(self) -> None:
        """None: the native executor steps co-simulation FMUs only."""
        return None

    # -- values: a changed input is an event ---------------------------------------------------------
    def set_real(self, handle: ValueBuffer, values: np.ndarray) -> None:
        before = self._set_before.get(id(handle))
        if self._initialized and (before is None or not np.array_equal(before, values)):
            self._enter_event_mode()
        if before is None:
            self._set_before[id(handle)] = before = np.empty(handle.n)
        before[:] = values
        super().set_real(handle, values)

    def set_values(self, fmi_type: str, refs: Sequence[int], values: Sequence[Any]) -> None:
        """Set ``refs`` of type ``fmi_type``; after initialization in Event Mode when a value changes."""
        if self._initialized and list(self.get_values(fmi_type, refs)) != list(values):
            self._enter_event_mode()
        super().set_values(fmi_type, refs, values)

    def _enter_event_mode(self) -> None:
        if not self._event_mode:
            self._call("fmi2EnterEventMode")
            self._event_mode = True

    # -- stepping --------------------------------------------------------------------------------------
    def step(self, t: float, h: float) -> None:
        """Integrate from t to t + h [s], handling every event on the way (as fmpy's simulateME does)."""
        end = t + h
        self._time = t
        if self._event_mode:  # an input changed at t
            self._handle_event(t)
        time = t
        events = 0
        while time < end and not math.isclose(time, end):
            target = end
            next_event = self._next_event
            if next_event is not None and (next_event < time or math.isclose(next_event, time)):
                raise SimulationError(f"the FMU's next time event ({next_event!r} s) is not after the current time",
                                      unit=self.name, time=time)
            if next_event is not None and target > next_event and not math.isclose(target, next_event):
                target = next_event
            time_event = next_event is not None and math.isclose(target, next_event)
            state_event, time = self._integrate(time, target)
            self._time = time
            self._check("fmi2SetTime", self._f["fmi2SetTime"](self._fmu.component, time))
            step_event = self._completed_step() if self._completed_step_needed else False
            if time_event or state_event or step_event:
                events += 1
                if events > MAX_EVENTS_PER_STEP:
                    raise SimulationError(f"more than {MAX_EVENTS_PER_STEP} events in one communication step "
                                          "(chattering or Zeno behaviour?)", unit=self.name, time=time)
                self._enter_event_mode()
                self._handle_event(time)
        self._time = end

    def _integrate(self, time: float, target: float) -> tuple[bool, float]:
        """One solver call from ``time`` towards ``target``: (stopped at a state event, time reached)."""
        solver = self._solver
        try:
            state_event, _, reached = solver.step(time, target)
        except Exception as exc:
            failure, solver.failure = solver.failure, None
            if failure is not None:
                raise failure from None  # an FMI status turned exception, or an interruption
            info = solver.error_info
            why = f"{info[1]}: {info[3]} (code {info[0]})" if info else str(exc)
            raise SimulationError(f"CVode failed: {why}", unit=self.name, time=self._time) from None
        if solver.failure is not None:
            failure, solver.failure = solver.failure, None
            raise failure
        return bool(state_event), reached

    def _completed_step(self) -> bool:
        from fmpy.fmi2 import fmi2Boolean

        enter, terminate = fmi2Boolean(), fmi2Boolean()
        self._call("fmi2CompletedIntegratorStep", 1, byref(enter), byref(terminate))
        if terminate.value:
            raise SimulationError("the FMU asked to terminate the simulation (fmi2CompletedIntegratorStep)",
                                  unit=self.name, time=self._time)
        return bool(enter.value)

    def _handle_event(self, time: float) -> None:
        """In Event Mode at ``time``: the event iteration, back to Continuous-Time Mode, restart the solver."""
        self._update_discrete_states()
        self._call("fmi2EnterContinuousTimeMode")
        self._event_mode = False
        self.events += 1
        self._solver.reset(time)

    def _update_discrete_states(self) -> None:
        """``fmi2NewDiscreteStates`` until the FMU needs no more; keeps its next time event."""
        from fmpy.fmi2 import fmi2EventInfo

        info = fmi2EventInfo()
        for _ in range(MAX_EVENT_ITERATIONS):
            self._call("fmi2NewDiscreteStates", byref(info))
            if info.terminateSimulation:
                raise SimulationError("the FMU asked to terminate the simulation (fmi2NewDiscreteStates)",
                                      unit=self.name, time=self._time)
            if not info.newDiscreteStatesNeeded:
                break
        else:
            raise SimulationError(f"the event iteration did not converge in {MAX_EVENT_ITERATIONS} "
                                  "fmi2NewDiscreteStates calls", unit=self.name, time=self._time)
        self._next_event = float(info.nextEventTime) if info.nextEventTimeDefined else None

    def _make_solver(self, start_time: float) -> Any:
        """fmpy's CVode solver on this FMU's states and event indicators (settings of fmpy's simulateME)."""
        f, component, check = self._f, self._fmu.component, self._check

        def get_x(x: Any, n: int) -> None:
            check("fmi2GetContinuousStates", f["fmi2GetContinuousStates"](component, x, n))

        def set_x(x: Any, n: int) -> None:
            check("fmi2SetContinuousStates", f["fmi2SetContinuousStates"](component, x, n))

        def get_dx(dx: Any, n: int) -> None:
            check("fmi2GetDerivatives", f["fmi2GetDerivatives"](component, dx, n))

        def get_z(z: Any, n: int) -> None:
            check("fmi2GetEventIndicators", f["fmi2GetEventIndicators"](component, z, n))

        def get_nominals(x: Any, n: int) -> None:
            check("fmi2GetNominalsOfContinuousStates", f["fmi2GetNominalsOfContinuousStates"](component, x, n))

        def set_time(t: float) -> None:
            self._time = t
            check("fmi2SetTime", f["fmi2SetTime"](component, t))

        try:
            return _solver_class()(nx=self._nx, nz=self._nz, get_x=get_x, set_x=set_x, get_dx=get_dx, get_z=get_z,
                                   get_nominals=get_nominals, set_time=set_time, input=_NoInput(),
                                   startTime=start_time, maxStep=(self._stop_time - self._start_time) / 50.0,
                                   relativeTolerance=self.relative_tolerance)
        except SimulationError:
            raise
        except Exception as exc:  # the SUNDIALS libraries or CVode's set-up
            raise SimulationError(f"cannot set up the CVode solver: {exc}", unit=self.name, time=start_time) from exc
