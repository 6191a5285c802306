"""FMI 3.0 co-simulation units through fmpy (``fmpy.fmi3.FMU3Slave``), and their descriptions.

The same :class:`~orchestration.master.unit.Unit` protocol as the FMI 2.0
:class:`~orchestration.master.fmi2_cosim_unit.FmuUnit`. ``Float64`` values go through the Real fast path
(in the description an FMI 3.0 ``Float64`` is a ``Real`` and ``Int32``/``Int64`` are ``Integer``;
:attr:`~orchestration.master.unit.Variable.fmi_type` keeps the declared name); every other scalar
type (``Float32``, ``Int8`` ... ``UInt64``, ``Boolean``, ``String``, ``Enumeration``) through
``get_values``/``set_values``, which call the FMI 3.0 function of each variable's declared type.
Binary, clocks and array variables are refused by the scenario check. FMI status codes are translated by
:func:`orchestration.master.fmi_status.check_status`, the one place for both versions, through the shared
:class:`~orchestration.master.fmi_unit_base.FmiUnitBase` (checks, log, teardown).

The instance is created with ``eventModeUsed = false`` and ``earlyReturnAllowed = false``
(the master has no Event Mode and steps on a fixed grid). ``fmi3DoStep``'s flags:
``terminateSimulation`` ends the run with a SimulationError naming the unit and the time;
``earlyReturn`` before the communication point is an error too (it was not allowed);
``eventHandlingNeeded`` is logged once as a warning of the unit (without Event Mode the
FMU handles its events itself).
"""

from __future__ import annotations

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
from orchestration.master.fmi_status import FMI3_STATUS, LogRecord
from orchestration.master.fmi_unit_base import FmiUnitBase
from orchestration.master.fmu_description import FmuFormatError, read_description
from orchestration.master.fmu_loading import load_slave
from orchestration.master.unit import INTEGER_RANGES
from orchestration.master.value_buffer import ValueBuffer

# declared type -> (FMI 3.0 function suffix, C type)
_CTYPES: dict[str, tuple[str, Any]] = {
    "Float32": ("Float32", c_float), "Float64": ("Float64", c_double),
    "Int8": ("Int8", c_int8), "UInt8": ("UInt8", c_uint8), "Int16": ("Int16", c_int16),
    "UInt16": ("UInt16", c_uint16), "Int32": ("Int32", c_int32), "UInt32": ("UInt32", c_uint32),
    "Int64": ("Int64", c_int64), "UInt64": ("UInt64", c_uint64), "Enumeration": ("Int64", c_int64),
    "Boolean": ("Boolean", c_bool), "String": ("String", c_char_p),
}
_INT_RANGE = {**INTEGER_RANGES, "Enumeration": INTEGER_RANGES["Int64"]}


class Fmu3Unit(FmiUnitBase):
    """An FMI 3.0 co-simulation FMU driven through fmpy."""

    fmi_prefix = "fmi3"
    status_labels = FMI3_STATUS

    def __init__(
        self,
        name: str,
        path: Path,
        parameters: dict[str, Any] | None = None,
        on_log: Callable[[str, LogRecord], None] | None = None,
    ) -> None:
        super().__init__(name, path, parameters, on_log)
        self.description, self._md = read_description(self.path, name)
        if not self.description.fmi_version.startswith("3."):
            raise FmuFormatError(f"{self.path}: FMI {self.description.fmi_version} FMU, not FMI 3.0")
        self._fmi_types = {v.name: v.type for v in self._md.modelVariables}
        self._vr_types = {v.valueReference: v.type for v in self._md.modelVariables}
        self._typed_cache: dict[tuple[int, ...], list[tuple[str, Any, Any, list[int]]]] = {}
        self._event_noted = False
        # doStep's output arguments, allocated once
        self._event, self._terminate, self._early = c_bool(), c_bool(), c_bool()
        self._last = c_double()
        self._step_out = (byref(self._event), byref(self._terminate), byref(self._early), byref(self._last))

    # -- logging (fmi3LogMessageCallback is not variadic: one Python callback per unit) -----------
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
            recent = self.recent_messages()
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
            recent = self.recent_messages()
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
