"""FMI 2.0 co-simulation shell of the ground-motion source.

Parameters: ``record`` (path of a ``time_s,accel_g`` CSV/text or PEER ``.AT2`` file),
``scale`` (amplitude factor; the paper uses 0.5) and ``time_scale``. Output ``ag``
[m/s^2] at the unit's current time: linear interpolation, zero after the record ends.
The record is read when the unit enters initialization mode, and again when it leaves it
if a parameter was set in between (FMI 2.0 allows that); a problem with it is logged as
an error and makes the first ``fmi2DoStep`` fail (pythonfmu would turn an
exception into fmi2Fatal, after which a host may not even free the instance).
"""

from __future__ import annotations

import copy

import fast_exchange
import shared_copies
from fast_exchange import FastExchange
from ground_motion_core import GroundMotion, RecordError, read_record
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real, String
from pythonfmu.enums import Fmi2Status

FMU_CORE_MODULES = ("ground_motion_core", "shared_copies", "fast_exchange")
FMU_REQUIREMENTS: tuple[str, ...] = ("numpy",)  # besides Python >= 3.11
FMU_FAILED_STEP_STATUS = "error"  # a do_step that returns False (an error it logged) is fmi2Error


class GroundMotionSource(FastExchange, Fmi2Slave):
    """Plays a ground-acceleration record."""

    description = "Ground-acceleration record player (linear interpolation, zero after the end)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._slave_attrs = frozenset(vars(self)) | {"_slave_attrs"}
        self.record = ""
        self.scale = 1.0
        self.time_scale = 1.0
        self.duration = 0.0
        self._time = 0.0
        self._motion: GroundMotion | None = None
        self._loaded: tuple | None = None  # (record, scale, time_scale) of _motion
        self._initializing = False
        self._failed = ""
        self.fmi_units = {"scale": "1", "time_scale": "1", "ag": "m/s2", "duration": "s"}
        self.fmi_dependencies = {}
        par = {"causality": Fmi2Causality.parameter, "variability": Fmi2Variability.fixed}
        self.register_variable(String("record", description="record file (time_s,accel_g CSV or PEER AT2)", **par))
        self.register_variable(Real("scale", description="amplitude scale factor", **par))
        self.register_variable(
            Real("time_scale", description="time scale factor (record time to simulation time)", **par)
        )
        self.register_variable(
            Real("duration", description="simulation time at which the record ends",
                 causality=Fmi2Causality.calculatedParameter, variability=Fmi2Variability.fixed)
        )
        self.register_variable(
            Real("ag", description="ground acceleration", causality=Fmi2Causality.output,
                 variability=Fmi2Variability.continuous, getter=self._acceleration)
        )
        # The master reads ag every step: a fast path for it (fast_exchange).
        self.exchange_fast(outputs=("ag",))


    def _acceleration(self) -> float:
        if self._initializing:
            self._load()  # parameters may still change in initialization mode
        return 0.0 if self._motion is None else self._motion.acceleration(self._time)

    _exchanged_value = _acceleration  # the fast output (fast_exchange)

    def setup_experiment(self, start_time, stop_time, tolerance):
        self._time = start_time

    def _load(self) -> None:
        """(Re)read the record when record, scale or time_scale differ from what was loaded.

        FMI 2.0 lets a host set fixed parameters in initialization mode too (ecos does), so
        the record is read on entering it and again on leaving it if a parameter changed.
        Problems are logged and fail the first step: an exception here would be fmi2Fatal.
        """
        key = (self.record, self.scale, self.time_scale)
        if key == self._loaded:
            return
        self._loaded, self._failed, self._motion, self.duration = key, "", None, 0.0
        if not self.record:
            self._failed = "parameter 'record' is not set: name a record file"
        else:
            try:
                self._motion = GroundMotion(read_record(self.record), self.scale, self.time_scale)
                self.duration = self._motion.duration
            except (RecordError, ValueError) as exc:
                self._failed = f"cannot use the ground-motion record: {exc}"
        if self._failed:
            self.log(self._failed, Fmi2Status.error)

    def enter_initialization_mode(self):
        self._initializing = True
        self._load()

    def exit_initialization_mode(self):
        self._load()
        self._initializing = False
        # another FMU's copy of the shared fast paths with other code: refused (shared_copies), the first step fails
        problem = shared_copies.copy_problem((fast_exchange,), self.resources)
        if problem:
            self._failed = problem
            self.log(problem, Fmi2Status.error)

    def do_step(self, current_time: float, step_size: float) -> bool:
        if self._failed:
            self.log(self._failed, Fmi2Status.error)
            return False
        self._time = current_time + step_size
        return True

    # FMU state (fmi2GetFMUstate/fmi2SetFMUstate): every instance attribute the shell added,
    # registered or not, deep-copied; pythonfmu's own bookkeeping is left alone.
    def _get_fmu_state(self) -> dict:
        memo = {id(self._motion): self._motion}  # the record is read-only once loaded: shared, not copied
        return {k: copy.deepcopy(v, memo) for k, v in vars(self).items() if k not in self._slave_attrs}

    def _set_fmu_state(self, state: dict) -> None:
        memo = {id(state.get("_motion")): state.get("_motion")}
        vars(self).update(copy.deepcopy(state, memo))
