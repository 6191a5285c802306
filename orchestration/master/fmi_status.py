"""FMI status codes and log messages: the one place where an FMI status becomes an exception.

:func:`check_status` serves FMI 2.0 (:mod:`orchestration.master.fmi2_cosim_unit`) and FMI 3.0
(:mod:`orchestration.master.fmi3_cosim_unit`) units alike.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from orchestration.master.errors import UnitCallError

UNIT_LOGGER = "mre_cosim.units"
"""The :mod:`logging` logger that run sessions report the units' messages to (see
:func:`orchestration.master.session.run_plan`); nothing is printed unless a handler is attached."""
STATUS_LABELS = ("ok", "warning", "discard", "error", "fatal", "pending")
FMI3_STATUS = STATUS_LABELS[:5]  # fmi3Status has no "pending"


def check_status(
    unit: str,
    function: str,
    status: int,
    time: float | None,
    log: Sequence[LogRecord],
    labels: Sequence[str] = STATUS_LABELS,
) -> None:
    """Raise UnitCallError for an FMI status worse than warning, with the unit's recent messages."""
    if status > 1:
        label = labels[status] if 0 <= status < len(labels) else f"illegal status {status}"
        recent = tuple(f"[{r.status}] {r.message}" for r in log[-5:] if r.status != "ok")
        raise UnitCallError(unit, function, label, time, recent)


@dataclass(frozen=True)
class LogRecord:
    """One message an FMU logged."""

    status: str
    category: str
    message: str
