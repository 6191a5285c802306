"""The native executor: the master's inner loop in C, for runs whose units are FMI 2.0 FMUs.

It moves Real values only: a system that connects or records values of any other type
(Integer, Boolean, String, ...) is refused with :class:`NativeUnavailable`, so ``auto`` runs
it with the Python executor and ``summary.json`` says why (``executor_note``).

:class:`~orchestration.master.algorithm.CouplingAlgorithm` describes one communication step as a
flat program (:meth:`~orchestration.master.algorithm.CouplingAlgorithm.program`); the Python
executor (:meth:`~orchestration.master.algorithm.CouplingAlgorithm.step`) and this one carry out
the same calls in the same order with the same floating-point operations, so both give
identical results (a test checks every scheme bit for bit). What the C loop saves is the
master's own per-step work (benchmarks/results.md has the measurements).

The kernel (``orchestration/master/native/step_kernel.c``) is compiled with the system C compiler
(``$CC``, default ``cc``) on first use into a cache folder (``$MRE_COSIM_CACHE``, default
``~/.cache/mre-cosim``) and reused while its source is unchanged. It runs a range of steps
between progress ticks, copies the recorder's row and runs the monitor's checks after each
step. FMI status values come back raw and are translated by the unit (the one place that
does it); a monitor hit is handed to the Monitor, which raises its usual error. The same
library formats ``timeseries.csv`` (:func:`csv_formatter`, used by
:func:`orchestration.master.recorder.write_timeseries`).
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable, Sequence
from ctypes import POINTER, Structure, c_double, c_int64, c_void_p
from pathlib import Path
from typing import Any

import numpy as np

from mre_common import c_compile
from orchestration.master.algorithm import CouplingAlgorithm, ProgramOp
from orchestration.master.monitor import Monitor
from orchestration.master.value_buffer import ValueBuffer

SOURCE = Path(__file__).resolve().parent / "native" / "step_kernel.c"
CFLAGS = ("-shared", "-fPIC", "-O2", "-ffp-contract=off", "-std=c99", "-Wall", "-Wextra")
_KINDS = {"set": 0, "step": 1, "get": 2, "latch": 3, "peek": 4}
_FUNCTIONS = {"set": "fmi2SetReal", "step": "fmi2DoStep", "get": "fmi2GetReal"}
_DONE, _FMI_FAILED, _MONITOR = 0, 1, 2


class NativeUnavailable(RuntimeError):
    """The native executor cannot run this system (no C compiler, or a unit it cannot drive)."""


class _Op(Structure):
    _fields_ = [
        ("kind", c_int64), ("unit", c_int64), ("n", c_int64),
        ("vrs", c_void_p), ("buf", c_void_p), ("slots", c_void_p), ("rules", c_void_p),
        ("every", c_int64), ("phase", c_int64), ("dfirst", c_void_p), ("dslots", c_void_p),
        ("ffirst", c_void_p), ("fslots", c_void_p), ("n2", c_int64), ("out", c_int64), ("vrs2", c_void_p),
        ("buf2", c_void_p),
    ]


class _Kernel(Structure):
    _fields_ = [
        ("n_units", c_int64), ("components", c_void_p), ("set_real", c_void_p), ("get_real", c_void_p),
        ("do_step", c_void_p), ("unit_time", c_void_p),
        ("n_ops", c_int64), ("ops", c_void_p),
        ("n_values", c_int64), ("values", c_void_p), ("now", c_void_p), ("before", c_void_p),
        ("earlier", c_void_p), ("grid", c_void_p), ("peeked", c_void_p), ("known", c_int64),
        ("extrapolation", c_void_p),
        ("start", c_double), ("stop", c_double), ("step", c_double), ("n_steps", c_int64),
        ("n_record", c_int64), ("record_slots", c_void_p), ("record_time", c_void_p), ("record_data", c_void_p),
        ("check_finite", c_int64), ("n_limits", c_int64), ("limit_slots", c_void_p), ("limits", c_void_p),
        ("failed_op", c_int64), ("failed_status", c_int64), ("failed_get", c_int64),
    ]


_LIBRARY: Any = None


def kernel_library() -> Any:
    """The compiled kernel (compiled on first use; NativeUnavailable if that fails)."""
    global _LIBRARY
    if _LIBRARY is not None:
        return _LIBRARY
    try:
        folder = c_compile.cache_dir()
        target = c_compile.compile_cached(SOURCE, CFLAGS, ("-lm",), name="step_kernel", folder=folder)
    except (c_compile.NoCacheFolder, c_compile.CompilerMissing, c_compile.CompileFailed) as exc:
        raise NativeUnavailable(str(exc)) from None
    except OSError as exc:  # an unwritable cache folder
        raise NativeUnavailable(f"cannot compile the kernel into {folder}: {exc}") from None
    try:
        # PyDLL: the kernel runs holding the GIL, so a pythonfmu unit's PyGILState_Ensure in each
        # FMI call finds it held instead of taking it back (the loop calls no Python itself).
        library = ctypes.PyDLL(str(target))
    except OSError as exc:
        raise NativeUnavailable(f"cannot load the compiled kernel {target}: {exc}") from None
    library.run_steps.argtypes = [POINTER(_Kernel), c_int64, c_int64, POINTER(c_int64)]
    library.run_steps.restype = ctypes.c_int
    library.format_csv_rows.argtypes = [c_void_p, c_int64, c_int64, c_void_p]
    library.format_csv_rows.restype = c_int64
    library.csv_bytes_per_value.argtypes = []
    library.csv_bytes_per_value.restype = c_int64
    _LIBRARY = library
    return library


def csv_formatter() -> Callable[[np.ndarray], bytes] | None:
    """The kernel's CSV formatter, or None where the kernel cannot be compiled.

    ``format(block)`` turns a C-contiguous float64 block into its CSV lines, every number
    exactly as Python's ``'%.12g' % x`` writes it (a test compares the two).
    """
    try:
        library = kernel_library()
    except NativeUnavailable:
        return None
    per_value = library.csv_bytes_per_value()

    def format_rows(block: np.ndarray) -> bytes:
        if block.dtype != np.float64 or block.ndim != 2 or not block.flags.c_contiguous:
            raise ValueError("format_rows needs a C-contiguous 2-D float64 block")
        out = np.empty(block.size * per_value + 1, dtype=np.uint8)
        n = library.format_csv_rows(block.ctypes.data, block.shape[0], block.shape[1], out.ctypes.data)
        return out[:n].tobytes()

    return format_rows


def _value_buffer(handle: object) -> ValueBuffer:
    """A prepared handle as the kernel reads it (an FMU unit's ValueBuffer)."""
    if not isinstance(handle, ValueBuffer):
        raise NativeUnavailable(f"a prepared value handle the kernel cannot read ({type(handle).__name__})")
    return handle


def _address(array: Any) -> int:
    if isinstance(array, np.ndarray):
        return array.ctypes.data
    return ctypes.addressof(array)


def _native_functions(algorithm: CouplingAlgorithm) -> list[tuple[int, int, int, int]]:
    """Each unit's FMI function addresses, in unit order; NativeUnavailable where the kernel cannot run the system."""
    if any(op.kind not in _KINDS for op in algorithm.program()):
        desc = algorithm.descriptions
        ports = [f"{u}.{v} ({desc[u].variables[v].fmi_type})" for u, v in algorithm.typed_ports]
        shown = ", ".join(ports[:5]) + (f" and {len(ports) - 5} more" if len(ports) > 5 else "")
        raise NativeUnavailable(f"the system exchanges or records values that are not Real ({shown}); "
                                "the native kernel moves Real values only")
    natives = []
    for unit in algorithm.units.values():
        # a unit from outside the engine (an in-process Python unit) may not implement the whole Unit protocol
        functions = getattr(unit, "native_functions", lambda: None)()
        if functions is None:
            raise NativeUnavailable("a unit is not an FMI 2.0 co-simulation FMU")
        natives.append(functions)
    return natives


def _recorder_and_monitor(algorithm: CouplingAlgorithm, observers: Sequence[Any]) -> tuple[Any, Monitor | None]:
    """The one Recorder and the one Monitor among the observers (either may be absent); NativeUnavailable else."""
    # The Recorder is known by its rows_to_fill() (recorder.py imports this module for its CSV writer).
    recorders = [o for o in observers if callable(getattr(o, "rows_to_fill", None))]
    monitors = [o for o in observers if isinstance(o, Monitor)]
    if len(recorders) + len(monitors) != len(observers) or len(recorders) > 1 or len(monitors) > 1:
        raise NativeUnavailable("observers other than one Recorder and one Monitor")
    arrays = [algorithm.values, *algorithm.history, algorithm.grid, algorithm.peeked,
              *(a for r in recorders for a in r.rows_to_fill()[1:])]
    if not all(a.dtype == np.float64 and a.flags.c_contiguous for a in arrays):
        raise NativeUnavailable("value or recording arrays that are not contiguous float64")
    return (recorders[0] if recorders else None), (monitors[0] if monitors else None)


class NativeStepper:
    """Runs an initialized CouplingAlgorithm's steps in C, with a Recorder and a Monitor."""

    def __init__(self, algorithm: CouplingAlgorithm, observers: Sequence[Any], start: float, stop: float,
                 step: float, n_steps: int) -> None:
        natives = _native_functions(algorithm)
        recorder, monitor = _recorder_and_monitor(algorithm, observers)
        self._library = kernel_library()
        self._algorithm = algorithm
        self._units = list(algorithm.units.values())
        self._observers = list(observers)
        self._recorder = recorder
        self._keep: list[Any] = []  # every array the kernel points into stays alive with it
        self._program: list[ProgramOp] = algorithm.program()
        self._ops = self._kernel_ops()
        self._unit_time = np.array([u.time for u in self._units], dtype=np.float64)
        self._kernel = self._kernel_of(natives, monitor)
        k = self._kernel
        k.start, k.stop, k.step, k.n_steps = start, stop, step, n_steps
        self.done = 0  # steps finished after the last run()

    def _array(self, values: Any, dtype: Any) -> int:
        """The address of ``values`` as a contiguous array of ``dtype``, kept alive with the kernel."""
        a = np.ascontiguousarray(values, dtype=dtype)
        self._keep.append(a)
        return a.ctypes.data

    def _kernel_ops(self) -> Any:
        """The program as the kernel's op structs (value references, buffers and slots by address)."""
        array = self._array
        index = {u.name: k for k, u in enumerate(self._units)}
        ops = (_Op * len(self._program))()
        for op, p in zip(ops, self._program, strict=True):
            op.kind, op.unit = _KINDS[p.kind], index[p.unit.name]
            op.every, op.phase = p.every, p.phase
            if p.kind == "latch":
                op.n, op.slots = len(p.slots), array(p.slots, np.int64)
            elif p.kind != "step":
                handle = _value_buffer(p.handle)
                op.n = handle.n
                op.vrs, op.buf = _address(handle.vrs), _address(handle.buf)
                op.slots = array(p.slots, np.int64)
                op.rules = array(p.rules, np.int64) if p.rules is not None else None
                if p.drivers is not None and any(len(d) for d in p.drivers):
                    op.dfirst = array(np.cumsum([0] + [len(d) for d in p.drivers]), np.int64)
                    op.dslots = array(np.concatenate(p.drivers), np.int64)
                if p.kind == "set" and p.fresh_drivers is not None and any(len(d) for d in p.fresh_drivers):
                    op.ffirst = array(np.cumsum([0] + [len(d) for d in p.fresh_drivers]), np.int64)
                    op.fslots = array(np.concatenate(p.fresh_drivers), np.int64)
                if p.kind == "peek":
                    out = _value_buffer(p.out_handle)
                    op.n2, op.out = out.n, p.out_slot
                    op.vrs2, op.buf2 = _address(out.vrs), _address(out.buf)
        return ops

    def _kernel_of(self, natives: list[tuple[int, int, int, int]], monitor: Monitor | None) -> _Kernel:
        """The kernel's state: the units' functions, the ops, the algorithm's value arrays, the recorder's rows
        and the monitor's limits (the time grid is set by the caller)."""
        array, algorithm = self._array, self._algorithm
        k = _Kernel()
        k.n_units = len(self._units)
        k.components = array([n[0] for n in natives], np.uintp)
        k.set_real = array([n[1] for n in natives], np.uintp)
        k.get_real = array([n[2] for n in natives], np.uintp)
        k.do_step = array([n[3] for n in natives], np.uintp)
        k.unit_time = self._unit_time.ctypes.data
        k.n_ops, k.ops = len(self._ops), ctypes.addressof(self._ops)
        values = algorithm.values
        now, before, earlier = algorithm.history
        k.n_values = len(values)
        k.values, k.now, k.before, k.earlier = (a.ctypes.data for a in (values, now, before, earlier))
        k.grid = algorithm.grid.ctypes.data
        k.peeked = algorithm.peeked.ctypes.data
        k.known = algorithm.known
        k.extrapolation = array(algorithm.extrapolation, float)
        if self._recorder is not None:
            ports, time, data = self._recorder.rows_to_fill()
            k.n_record = len(ports)
            k.record_slots = array([algorithm.slot[p] for p in ports], np.int64)
            k.record_time, k.record_data = time.ctypes.data, data.ctypes.data
        if monitor is not None:
            limits = monitor.limits
            k.check_finite = 1
            k.n_limits = len(limits)
            k.limit_slots = array([algorithm.slot[p] for p in limits], np.int64)
            k.limits = array(list(limits.values()), float)
        return k

    def run(self, first: int, last: int, t_of: Any) -> None:
        """Steps ``first`` .. ``last - 1``, then ``done`` = steps finished; raises as the Python path would."""
        done = c_int64(first)
        code = self._library.run_steps(ctypes.byref(self._kernel), first, last, ctypes.byref(done))
        self.done = done.value
        self._algorithm.known = self._kernel.known
        self._algorithm.steps_done = done.value
        for unit, t in zip(self._units, self._unit_time.tolist(), strict=True):
            unit.time = t
        if self._recorder is not None:
            self._recorder.count = done.value + 1
        if code == _FMI_FAILED:
            op = self._program[self._kernel.failed_op]
            kind = op.kind if op.kind != "peek" else ("get" if self._kernel.failed_get else "set")
            op.unit.raise_status(_FUNCTIONS[kind], self._kernel.failed_status)
        elif code == _MONITOR:
            self.done = done.value - 1  # as in Python: the step whose values the monitor rejects is not done
            for observer in self._observers:
                observer.record(done.value, t_of(done.value))  # the Monitor raises its own error
            self.done = done.value
