"""FMI 2.0 co-simulation units through fmpy.

FMI status codes become :class:`~orchestration.master.errors.UnitCallError` only through
:func:`orchestration.master.fmi_status.check_status`, called by the shared
:class:`~orchestration.master.fmi_unit_base.FmiUnitBase` (checks, log, teardown). The
hot path (get, set, step) calls the FMU's C functions through fmpy's ctypes bindings with
value-reference and value arrays prepared once.
"""

from __future__ import annotations

import itertools
import weakref
from collections.abc import Callable, Sequence
from ctypes import byref, c_double, c_uint, c_void_p, cast
from pathlib import Path
from typing import Any

import numpy as np

from orchestration.master.errors import SimulationError, UnitCallError
from orchestration.master.fmi_status import LogRecord
from orchestration.master.fmi_unit_base import FmiUnitBase
from orchestration.master.fmu_description import read_description
from orchestration.master.fmu_loading import load_slave
from orchestration.master.value_buffer import ValueBuffer

# fmpy's native logger proxy (it formats printf-style messages) keeps ONE target function
# for the whole process, so all units share one Python logger; it dispatches each message
# to its unit through the componentEnvironment pointer the unit passed at instantiation.
_LOG_TARGETS: dict[int, weakref.ref] = {}
# declared type -> the FMI 2.0 get/set function suffix
_FMI2_FUNCTION = {"Real": "Real", "Integer": "Integer", "Enumeration": "Integer", "Boolean": "Boolean",
                  "String": "String"}
_ENV_KEYS = itertools.count(1)
_CALLBACKS = None


def _dispatch_log(env, instance, status, category, message) -> None:
    ref = _LOG_TARGETS.get(env or 0)
    unit = ref() if ref is not None else None
    if unit is not None:
        unit._receive_log(status, category, message)
    else:  # an instance made elsewhere with fmpy's default callbacks: print as fmpy would
        from fmpy.fmi1 import printLogMessage

        printLogMessage(env, instance, status, category, message)


def _shared_callbacks():
    global _CALLBACKS
    if _CALLBACKS is None:
        from fmpy.fmi2 import (
            calloc,
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
            free,
        )
        from fmpy.logging import addLoggerProxy

        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(_dispatch_log)
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        addLoggerProxy(byref(callbacks))
        _CALLBACKS = callbacks
    return _CALLBACKS


class FmuUnit(FmiUnitBase):
    """An FMI 2.0 co-simulation FMU driven through fmpy."""

    def __init__(
        self,
        name: str,
        path: Path,
        parameters: dict[str, Any] | None = None,
        on_log: Callable[[str, LogRecord], None] | None = None,
    ) -> None:
        super().__init__(name, path, parameters, on_log)
        self.description, self._md = read_description(self.path, name)
        self._callbacks = None
        self._typed_cache: dict[tuple[str, tuple[int, ...]], tuple[str, Any, Any]] = {}

    # -- logging: one shared fmpy logger proxy, dispatched to the unit by componentEnvironment -----------
    def _make_callbacks(self):
        callbacks = _shared_callbacks()
        self._env_key = next(_ENV_KEYS)
        _LOG_TARGETS[self._env_key] = weakref.ref(self)
        # A copy of the shared struct whose componentEnvironment identifies this unit.
        from fmpy.fmi2 import fmi2CallbackFunctions

        own = fmi2CallbackFunctions()
        own.logger = callbacks.logger
        own.allocateMemory = callbacks.allocateMemory
        own.freeMemory = callbacks.freeMemory
        own.componentEnvironment = c_void_p(self._env_key)
        return own

    # -- Unit interface --------------------------------------------------------------------------
    interface = "co-simulation"  # the FMU interface this class drives
    _fmpy_class = "FMU2Slave"  # fmpy.fmi2's class for it

    def setup(self, start_time: float, stop_time: float) -> None:
        """Extract, load, instantiate, apply parameters, set up the experiment, enter initialization."""
        import fmpy.fmi2

        self._time = self._start_time = start_time
        self._stop_time = stop_time
        self._dir, self._fmu = load_slave(getattr(fmpy.fmi2, self._fmpy_class), self.path, self._md, self.name,
                                          start_time, self.interface)
        self._f = self._fmu._functions
        self._callbacks = self._make_callbacks()
        try:
            self._fmu.instantiate(callbacks=self._callbacks, loggingOn=True)
        except Exception as exc:
            raise SimulationError(f"fmi2Instantiate ({self.interface}) failed: {exc}", unit=self.name,
                                  time=start_time) from exc
        self._instantiated = True
        for name, value in self.parameters.items():
            self._set_parameter(name, value)
        self._call("fmi2SetupExperiment", 0, 0.0, start_time, 1, stop_time)
        self._call("fmi2EnterInitializationMode")

    def _set_parameter(self, name: str, value: Any) -> None:
        var = self.description.variables[name]
        vr = (c_uint * 1)(var.vr)
        try:
            if var.type == "Real":
                self._call("fmi2SetReal", vr, 1, (c_double * 1)(float(value)))
            elif var.type in ("Integer", "Enumeration"):
                self._call("fmi2SetInteger", vr, 1, (self._int_type() * 1)(int(value)))
            elif var.type == "Boolean":
                self._call("fmi2SetBoolean", vr, 1, (self._int_type() * 1)(1 if value else 0))
            else:
                from fmpy.fmi2 import fmi2String

                self._call("fmi2SetString", vr, 1, (fmi2String * 1)(str(value).encode("utf-8")))
        except UnitCallError as exc:
            raise SimulationError(
                f"setting parameter to {value!r} failed: {exc.reason}", self.name, name, self._time, exc.details
            ) from None

    @staticmethod
    def _int_type():
        from fmpy.fmi2 import fmi2Integer

        return fmi2Integer

    def exit_initialization(self) -> None:
        self._call("fmi2ExitInitializationMode")
        self._initialized = True

    def get_real(self, handle: ValueBuffer) -> np.ndarray:
        self._check("fmi2GetReal", self._f["fmi2GetReal"](self._fmu.component, handle.vrs, handle.n, handle.buf))
        return handle.view

    def set_real(self, handle: ValueBuffer, values: np.ndarray) -> None:
        handle.view[:] = values
        self._check("fmi2SetReal", self._f["fmi2SetReal"](self._fmu.component, handle.vrs, handle.n, handle.buf))

    def step(self, t: float, h: float) -> None:
        self._time = t
        self._check("fmi2DoStep", self._f["fmi2DoStep"](self._fmu.component, t, h, 1))
        self._time = t + h

    # -- for the native executor (orchestration.master.native_stepper) ----------------------------------
    def native_functions(self) -> tuple[int, int, int, int] | None:
        """Addresses of (component, fmi2SetReal, fmi2GetReal, fmi2DoStep) while instantiated."""
        if self._fmu is None or not self._instantiated:
            return None
        return (self._fmu.component, *(cast(self._f[name], c_void_p).value
                                       for name in ("fmi2SetReal", "fmi2GetReal", "fmi2DoStep")))

    # -- every other type (the generic path of the Unit protocol) ------------------------------------
    def _typed_buffers(self, fmi_type: str, refs: Sequence[int]) -> tuple[str, Any, Any]:
        """(FMI function suffix, value references, value array) for ``refs``, made once per reference list."""
        key = (fmi_type, tuple(refs))
        cached = self._typed_cache.get(key)
        if cached is None:
            from fmpy.fmi2 import fmi2Boolean, fmi2Integer, fmi2String

            suffix = _FMI2_FUNCTION.get(fmi_type)
            if suffix is None:
                raise SimulationError(f"FMI 2.0 has no type {fmi_type}", unit=self.name, time=self._time)
            ctype = {"Real": c_double, "Integer": fmi2Integer, "Boolean": fmi2Boolean, "String": fmi2String}[suffix]
            cached = (suffix, (c_uint * max(len(refs), 1))(*refs), ctype * max(len(refs), 1))
            self._typed_cache[key] = cached
        suffix, vrs, array_type = cached
        return suffix, vrs, array_type()

    def get_values(self, fmi_type: str, refs: Sequence[int]) -> list[Any]:
        """Values of ``refs`` of type ``fmi_type`` as plain Python values (int, bool, str, float)."""
        suffix, vrs, values = self._typed_buffers(fmi_type, refs)
        self._check(f"fmi2Get{suffix}", self._f[f"fmi2Get{suffix}"](self._fmu.component, vrs, len(refs), values))
        out = list(values)[: len(refs)]
        if suffix == "Boolean":
            return [bool(v) for v in out]
        if suffix == "String":
            return [(v or b"").decode("utf-8", "replace") for v in out]
        return out

    def set_values(self, fmi_type: str, refs: Sequence[int], values: Sequence[Any]) -> None:
        """Set ``refs`` of type ``fmi_type`` to plain Python values."""
        suffix, vrs, buf = self._typed_buffers(fmi_type, refs)
        for k, v in enumerate(values):
            buf[k] = str(v).encode("utf-8") if suffix == "String" else (int(bool(v)) if suffix == "Boolean" else v)
        self._check(f"fmi2Set{suffix}", self._f[f"fmi2Set{suffix}"](self._fmu.component, vrs, len(refs), buf))

    def _forget_logger(self) -> None:
        _LOG_TARGETS.pop(getattr(self, "_env_key", 0), None)
