"""What every FMU-backed unit shares: FMI calls checked, log messages kept and passed on, teardown.

:class:`FmiUnitBase` holds the plumbing of the FMI 2.0 co-simulation
(:class:`~orchestration.master.fmi2_cosim_unit.FmuUnit`), FMI 2.0 model-exchange
(:class:`~orchestration.master.fmi2_me_unit.MeUnit`, a FmuUnit) and FMI 3.0 co-simulation
(:class:`~orchestration.master.fmi3_cosim_unit.Fmu3Unit`) units: ``_check`` hands an FMI status
worse than warning to :func:`orchestration.master.fmi_status.check_status` (the one place a status
becomes an exception), ``_call`` calls an FMI function on the instance and checks it,
``_receive_log`` turns a message the FMU logged into a
:class:`~orchestration.master.fmi_status.LogRecord` for the unit's log and its ``on_log``
callback, and :meth:`FmiUnitBase.terminate` frees the instance by the standard's rules after a
failure. A subclass sets :attr:`FmiUnitBase.fmi_prefix` and :attr:`FmiUnitBase.status_labels`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from ctypes import c_double, c_uint
from pathlib import Path
from typing import Any

import numpy as np

from orchestration.master.fmi_status import STATUS_LABELS, LogRecord, check_status
from orchestration.master.fmu_loading import release
from orchestration.master.value_buffer import ValueBuffer

FATAL = 4  # fmi2Fatal / fmi3Fatal
ERROR = 3  # fmi2Error / fmi3Error


class FmiUnitBase:
    """The state and plumbing an FMU-backed unit shares (see the module docstring); not a unit by itself."""

    fmi_prefix = "fmi2"  # the FMI functions' name prefix: "fmi2" or "fmi3"
    status_labels: Sequence[str] = STATUS_LABELS  # status code -> label, as the FMI version defines them

    def __init__(
        self,
        name: str,
        path: Path,
        parameters: dict[str, Any] | None = None,
        on_log: Callable[[str, LogRecord], None] | None = None,
    ) -> None:
        self.name = name
        self.path = Path(path)
        self.parameters = dict(parameters or {})
        self.log: list[LogRecord] = []
        self.warnings = 0
        self._on_log = on_log
        self._fmu: Any = None
        self._dir: str | None = None
        self._time: float | None = None
        self._instantiated = False
        self._initialized = False
        self._f: dict[str, Any] = {}
        self._worst = 0  # worst FMI status returned so far

    # -- FMI status translation: orchestration.master.fmi_status.check_status, the only place ----------
    def _check(self, function: str, status: int) -> None:
        if status > 1:
            self._worst = max(self._worst, status)
            check_status(self.name, function, status, self._time, self.log, self.status_labels)

    def _call(self, function: str, *args: Any) -> None:
        self._check(function, self._f[function](self._fmu.component, *args))

    def raise_status(self, function: str, status: int) -> None:
        """Translate a status an FMI function of this unit returned elsewhere (raises above warning)."""
        self._check(function, status)

    def native_functions(self) -> tuple[int, int, int, int] | None:
        """None: the native executor drives FMI 2.0 co-simulation units only (FmuUnit says where it can)."""
        return None

    # -- logging -------------------------------------------------------------------------------------
    def _receive_log(self, status: int, category: bytes | None, message: bytes | None) -> None:
        labels = self.status_labels
        label = labels[status] if 0 <= status < len(labels) else str(status)
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

    def recent_messages(self, count: int = 5) -> tuple[str, ...]:
        """The unit's last ``count`` log messages that were not "ok", as ``[status] message``."""
        return tuple(f"[{r.status}] {r.message}" for r in self.log[-count:] if r.status != "ok")

    # -- the Real fast path's prepared arrays -------------------------------------------------------------
    def prepare(self, refs: Sequence[int]) -> ValueBuffer:
        n = len(refs)
        buf = (c_double * max(n, 1))()
        return ValueBuffer((c_uint * max(n, 1))(*refs), buf, np.ctypeslib.as_array(buf)[:n], n)

    @property
    def time(self) -> float | None:
        """The unit's time as error messages report it: t before a step, t + h after it [s]."""
        return self._time

    @time.setter
    def time(self, value: float) -> None:
        self._time = value

    # -- teardown ------------------------------------------------------------------------------------------
    def _forget_logger(self) -> None:
        """Stop routing the FMU's log messages to this unit (a subclass that registered a route drops it)."""

    def _remove_files(self) -> None:
        if self._dir is not None:
            release(self._dir)
            self._dir = None

    def terminate(self) -> None:
        """Terminate (if initialized), free the instance and the extracted files; never raises.

        The standard's rules after a failure (FMI 2.0 and 3.0 alike): after an Error status only
        FreeInstance is allowed; after Fatal no function at all, so such an instance is left to
        the process (its library stays loaded, with its log callback).
        """
        fmu, self._fmu = self._fmu, None
        if fmu is not None and self._worst >= FATAL:
            self._instantiated = self._initialized = False
            self._forget_logger()
            self._abandoned = fmu  # keep the library loaded: its instance was never freed
            release(self._dir, abandoned=True)
            self._dir = None
            return
        try:
            if fmu is not None and self._instantiated:
                if self._initialized and self._worst < ERROR:
                    try:
                        getattr(fmu, f"{self.fmi_prefix}Terminate")(fmu.component)
                    except Exception:  # a failed unit may refuse to terminate; free it anyway
                        pass
                getattr(fmu, f"{self.fmi_prefix}FreeInstance")(fmu.component)
            if fmu is not None:
                fmu.freeLibrary()
        except Exception:
            pass
        finally:
            self._instantiated = self._initialized = False
            self._forget_logger()
            self._remove_files()

    @property
    def freed(self) -> bool:
        """True once the unit holds no FMU instance and no extracted files."""
        return self._fmu is None and self._dir is None
