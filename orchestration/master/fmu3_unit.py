"""FMI 3.0 co-simulation units through fmpy (``fmpy.fmi3.FMU3Slave``), and their descriptions.

The same :class:`~orchestration.master.unit.Unit` protocol as the FMI 2.0
:class:`~orchestration.master.fmu_unit.FmuUnit`. ``Float64`` values go through the Real fast path
(in the description an FMI 3.0 ``Float64`` is a ``Real`` and ``Int32``/``Int64`` are ``Integer``;
:attr:`~orchestration.master.unit.Variable.fmi_type` keeps the declared name); every other scalar
type (``Float32``, ``Int8`` ... ``UInt64``, ``Boolean``, ``String``, ``Enumeration``) through
``get_values``/``set_values``, which call the FMI 3.0 function of each variable's declared type.
Binary, clocks and array variables are refused by the scenario check. FMI status codes are translated by
:func:`orchestration.master.fmi_status.check_status`, the one place for both versions.

The instance is created with ``eventModeUsed = false`` and ``earlyReturnAllowed = false``
(the master has no Event Mode and steps on a fixed grid). ``fmi3DoStep``'s flags:
``terminateSimulation`` ends the run with a SimulationError naming the unit and the time;
``earlyReturn`` before the communication point is an error too (it was not allowed);
``eventHandlingNeeded`` is logged once as a warning of the unit (without Event Mode the
FMU handles its events itself).
"""

from __future__ import annotations

import shutil
import weakref
from collections.abc import Callable, Sequence
from ctypes import (
    byref,
    c_bool,
    c_char_p,
    c_double,
    c_float,
    c_int8,
    c_int16,
    c_int32,
    c_int64,
    c_uint,
    c_uint8,
    c_uint16,
    c_uint32,
    c_uint64,
)
from pathlib import Path
from typing import Any

import numpy as np

from orchestration.master.errors import SimulationError, UnitCallError
from orchestration.master.fmi_status import FMI3_STATUS, LogRecord, check_status
from orchestration.master.fmu_file import FmuFormatError, ValueBuffer, load_slave, read_description
from orchestration.master.unit import INTEGER_RANGES

# declared type -> (FMI 3.0 function suffix, C type)
_CTYPES: dict[str, tuple[str, Any]] = {
    "Float32": ("Float32", c_float), "Float64": ("Float64", c_double),
    "Int8": ("Int8", c_int8), "UInt8": ("UInt8", c_uint8), "Int16": ("Int16", c_int16),
    "UInt16": ("UInt16", c_uint16), "Int32": ("Int32", c_int32), "UInt32": ("UInt32", c_uint32),
    "Int64": ("Int64", c_int64), "UInt64": ("UInt64", c_uint64), "Enumeration": ("Int64", c_int64),
    "Boolean": ("Boolean", c_bool), "String": ("String", c_char_p),
}
_INT_RANGE = {**INTEGER_RANGES, "Enumeration": INTEGER_RANGES["Int64"]}


class Fmu3Unit:
    """An FMI 3.0 co-simulation FMU driven through fmpy."""

    def __init__(
        self,
        name: str,
        path: Path,
        parameters: dict[str, Any] | None = None,
        on_log: Callable[[str, LogRecord], None] | None = None,
    ) -> None:
        self.name = name
        self.path = Path(path)
        self.description, self._md = read_description(self.path, name)
        if not self.description.fmi_version.startswith("3."):
            raise FmuFormatError(f"{self.path}: FMI {self.description.fmi_version} FMU, not FMI 3.0")
        self._fmi_types = {v.name: v.type for v in self._md.modelVariables}
        self._vr_types = {v.valueReference: v.type for v in self._md.modelVariables}
        self._typed_cache: dict[tuple[int, ...], list[tuple[str, Any, Any, list[int]]]] = {}
        self.parameters = dict(parameters or {})
        self.log: list[LogRecord] = []
        self.warnings = 0
        self._on_log = on_log
        self._fmu = None
        self._dir: str | None = None
        self._time: float | None = None
        self._instantiated = False
        self._initialized = False
        self._f: dict[str, Any] = {}
        self._worst = 0  # worst FMI status returned so far
        self._event_noted = False
        # doStep's output arguments, allocated once
        self._event, self._terminate, self._early = c_bool(), c_bool(), c_bool()
        self._last = c_double()
        self._step_out = (byref(self._event), byref(self._terminate), byref(self._early), byref(self._last))

    # -- FMI status translation: orchestration.master.fmi_status.check_status -------------------
    def _check(self, function: str, status: int) -> None:
        if status > 1:
            self._worst = max(self._worst, status)
            check_status(self.name, function, status, self._time, self.log, FMI3_STATUS)

    def _call(self, function: str, *args: Any) -> None:
        self._check(function, self._f[function](self._fmu.component, *args))

    # -- logging (fmi3LogMessageCallback is not variadic: one Python callback per unit) -----------
    def _receive_log(self, status: int, category: bytes | None, message: bytes | None) -> None:
        label = FMI3_STATUS[status] if 0 <= status < len(FMI3_STATUS) else str(status)
        record = LogRecord(
            label,
            category.decode("utf-8", "replace") if category else "",
            message.decode("utf-8", "replace") if message else "",
        )
        self.log.append(record)
        if status == 1:
            self.warnings += 1
        if self._on_log is not None:
            self._on_log(self.name, record)

    def _log_callback(self) -> Callable[[Any, int, bytes | None, bytes | None], None]:
        ref = weakref.ref(self)  # the FMU object holds the callback: no cycle through the unit

        def log_message(env: Any, status: int, category: bytes | None, message: bytes | None) -> None:
            unit = ref()
            if unit is not None:
                unit._receive_log(status, category, message)

        return log_message

    # -- Unit interface --------------------------------------------------------------------------
    def setup(self, start_time: float, stop_time: float) -> None:
        """Extract, load, instantiate, apply parameters, enter initialization mode."""
        from fmpy.fmi3 import FMU3Slave

        self._time = start_time
        self._dir, self._fmu = load_slave(FMU3Slave, self.path, self._md, self.name, start_time)
        self._f = self._fmu._functions
        try:
            self._fmu.instantiate(visible=False, loggingOn=True, eventModeUsed=False, earlyReturnAllowed=False,
                                  logMessage=self._log_callback())
        except Exception as exc:
            recent = tuple(f"[{r.status}] {r.message}" for r in self.log[-5:] if r.status != "ok")
            raise SimulationError(f"fmi3InstantiateCoSimulation failed: {exc}", unit=self.name, time=start_time,
                                  details=recent) from exc
        self._instantiated = True
        for name, value in self.parameters.items():
            self._set_parameter(name, value)
        self._call("fmi3EnterInitializationMode", False, 0.0, start_time, True, stop_time)

    def _set_parameter(self, name: str, value: Any) -> None:
        fmi_type = self._fmi_types[name]
        try:
            if fmi_type in _INT_RANGE:
                low, high = _INT_RANGE[fmi_type]
                if not low <= int(value) <= high:
                    raise SimulationError(f"{value!r} is out of range for {fmi_type}", self.name, name, self._time)
            elif fmi_type not in _CTYPES:
                raise SimulationError(f"parameters of FMI 3.0 type {fmi_type} are not supported", self.name, name,
                                      self._time)
            self.set_values(fmi_type, [self.description.variables[name].vr], [value])
        except UnitCallError as exc:
            raise SimulationError(
                f"setting parameter to {value!r} failed: {exc.reason}", self.name, name, self._time, exc.details
            ) from None

    def exit_initialization(self) -> None:
        self._call("fmi3ExitInitializationMode")
        self._initialized = True

    def prepare(self, refs: Sequence[int]) -> ValueBuffer:
        n = len(refs)
        buf = (c_double * max(n, 1))()
        return ValueBuffer((c_uint * max(n, 1))(*refs), buf, np.ctypeslib.as_array(buf)[:n], n)

    def get_real(self, handle: ValueBuffer) -> np.ndarray:
        self._check("fmi3GetFloat64",
                    self._f["fmi3GetFloat64"](self._fmu.component, handle.vrs, handle.n, handle.buf, handle.n))
        return handle.view

    def set_real(self, handle: ValueBuffer, values: np.ndarray) -> None:
        handle.view[:] = values
        self._check("fmi3SetFloat64",
                    self._f["fmi3SetFloat64"](self._fmu.component, handle.vrs, handle.n, handle.buf, handle.n))

    def step(self, t: float, h: float) -> None:
        self._time = t
        self._event.value = self._terminate.value = self._early.value = False
        self._check("fmi3DoStep", self._f["fmi3DoStep"](self._fmu.component, t, h, True, *self._step_out))
        end = t + h
        if self._terminate.value:
            last = self._last.value
            when = last if t <= last <= end else end
            recent = tuple(f"[{r.status}] {r.message}" for r in self.log[-5:] if r.status != "ok")
            raise SimulationError("the FMU requested the end of the simulation (fmi3DoStep: terminateSimulation)",
                                  unit=self.name, time=when, details=recent)
        if self._early.value and self._last.value < end:
            raise SimulationError(f"fmi3DoStep returned early at t = {self._last.value:.9g} s, before the "
                                  f"communication point {end:.9g} s (early return was not allowed)",
                                  unit=self.name, time=t)
        if self._event.value and not self._event_noted:
            self._event_noted = True
            self._receive_log(1, b"master", f"fmi3DoStep asked for event handling at t = {end:.9g} s; this master "
                              "does not use Event Mode (eventModeUsed = false), reported once".encode())
        self._time = end

    # -- every other type (the generic path of the Unit protocol) ------------------------------------
    def _groups(self, refs: Sequence[int]) -> list[tuple[str, Any, Any, list[int]]]:
        """Per declared type of ``refs``: (function suffix, value references, array type, positions in refs)."""
        key = tuple(refs)
        groups = self._typed_cache.get(key)
        if groups is None:
            by_type: dict[str, list[int]] = {}
            for k, vr in enumerate(refs):
                declared = self._vr_types.get(vr)
                if declared not in _CTYPES:
                    raise SimulationError(f"value reference {vr} has FMI 3.0 type {declared}, which is not exchanged",
                                          unit=self.name, time=self._time)
                by_type.setdefault(declared, []).append(k)
            groups = []
            for declared, positions in by_type.items():
                suffix, ctype = _CTYPES[declared]
                groups.append((suffix, (c_uint * len(positions))(*(refs[k] for k in positions)),
                               ctype * len(positions), positions))
            self._typed_cache[key] = groups
        return groups

    def get_values(self, fmi_type: str, refs: Sequence[int]) -> list[Any]:
        """Values of ``refs`` as plain Python values (int, bool, str, float), each read with the FMI 3.0
        function of its declared type (``fmi_type`` may be that type or the master's name for it)."""
        out: list[Any] = [None] * len(refs)
        for suffix, vrs, array_type, positions in self._groups(refs):
            n = len(positions)
            buf = array_type()
            self._check(f"fmi3Get{suffix}", self._f[f"fmi3Get{suffix}"](self._fmu.component, vrs, n, buf, n))
            for k, v in zip(positions, buf, strict=True):
                out[k] = (v or b"").decode("utf-8", "replace") if suffix == "String" else v
        return out

    def set_values(self, fmi_type: str, refs: Sequence[int], values: Sequence[Any]) -> None:
        """Set ``refs`` to plain Python values, each with the FMI 3.0 function of its declared type."""
        for suffix, vrs, array_type, positions in self._groups(refs):
            n = len(positions)
            if suffix == "String":
                buf = array_type(*(str(values[k]).encode("utf-8") for k in positions))
            elif suffix == "Boolean":
                buf = array_type(*(bool(values[k]) for k in positions))
            elif suffix.startswith("Float"):
                buf = array_type(*(float(values[k]) for k in positions))
            else:
                buf = array_type(*(int(values[k]) for k in positions))
            self._check(f"fmi3Set{suffix}", self._f[f"fmi3Set{suffix}"](self._fmu.component, vrs, n, buf, n))

    def terminate(self) -> None:
        """Terminate (if initialized), free the instance and the extracted files; never raises.

        FMI 3.0 rules after a failure: after fmi3Error only fmi3FreeInstance (or fmi3Reset) is
        allowed; after fmi3Fatal no function at all, so such an instance is left to the process
        (and its library stays loaded). terminateSimulation (status OK or warning) is followed
        by fmi3Terminate, as the standard requires.
        """
        fmu, self._fmu = self._fmu, None
        if fmu is not None and self._worst >= 4:
            self._instantiated = self._initialized = False
            self._abandoned = fmu  # keep the library (and the log callback) alive: never freed
            if self._dir is not None:
                shutil.rmtree(self._dir, ignore_errors=True)
                self._dir = None
            return
        try:
            if fmu is not None and self._instantiated:
                if self._initialized and self._worst < 3:
                    try:
                        fmu.fmi3Terminate(fmu.component)
                    except Exception:  # a unit may refuse to terminate; free it anyway
                        pass
                fmu.fmi3FreeInstance(fmu.component)
            if fmu is not None:
                fmu.freeLibrary()
        except Exception:
            pass
        finally:
            self._instantiated = self._initialized = False
            if self._dir is not None:
                shutil.rmtree(self._dir, ignore_errors=True)
                self._dir = None

    @property
    def freed(self) -> bool:
        """True once the unit holds no FMU instance and no extracted files."""
        return self._fmu is None and self._dir is None
