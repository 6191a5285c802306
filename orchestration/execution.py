"""Execution: initialize, step on an integer time grid, notify observers, always tear down.

Time is counted in whole steps: t_k = start + k h, and the last step ends exactly on
the stop time. Every unit is terminated and freed on every exit path (success, unit
failure, a raising observer, Ctrl-C or SIGTERM).
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

from orchestration.algorithm import CouplingAlgorithm
from orchestration.errors import SimulationError


class Observer(Protocol):
    def record(self, k: int, t: float) -> None:
        """Called after initialization (k = 0) and after step k ends at time t [s]."""


class StopRequest:
    """Set by signal handlers (SIGINT, SIGTERM); the run stops cleanly at the next step boundary.

    Handlers only set this flag: an exception raised from a handler could surface inside an
    FMU's own Python code (pythonfmu units run in this interpreter) and corrupt it.
    """

    def __init__(self) -> None:
        self.reason = ""

    def set(self, reason: str) -> None:
        self.reason = reason

    def __bool__(self) -> bool:
        return bool(self.reason)


class Interrupted(Exception):
    """A run stopped on request."""


@dataclass
class ExecutionResult:
    """How a run ended."""

    status: str  # "complete", "failed", "interrupted"
    steps_done: int
    n_steps: int
    end_time: float
    wall_time: float
    error: SimulationError | None = None

    @property
    def complete(self) -> bool:
        return self.status == "complete"


def time_grid(start: float, stop: float, step: float) -> tuple[int, Callable[[int], float]]:
    """Number of steps n and t(k) = start + k * step for k < n, with t(n) == stop exactly.

    The span must be a whole number of steps (to 1e-9 relative); scenarios check this.
    """
    n = round((stop - start) / step)
    if n < 1 or abs(n * step - (stop - start)) > 1e-9 * max(1.0, abs(stop - start)):
        raise ValueError(f"[{start}, {stop}] s is not a whole number of {step} s steps")

    def t(k: int) -> float:
        return stop if k == n else start + k * step

    return n, t


def execute(
    algorithm: CouplingAlgorithm,
    start: float,
    stop: float,
    step: float,
    observers: Sequence[Observer] = (),
    progress: Callable[[int], None] | None = None,
    progress_every: int = 1000,
    stop_request: StopRequest | None = None,
) -> ExecutionResult:
    """Run the algorithm from start to stop [s] with communication step ``step`` [s].

    Never leaves a unit allocated, whatever happens.
    """
    n_steps, t_of = time_grid(start, stop, step)
    wall = _time.perf_counter()
    k = 0
    t = start
    status, error = "complete", None
    try:
        algorithm.initialize(start, stop)
        for obs in observers:
            obs.record(0, start)
        for k in range(n_steps):
            t = t_of(k)
            t_next = t_of(k + 1)
            if stop_request:
                raise Interrupted(stop_request.reason)
            algorithm.step(t, t_next - t)
            for obs in observers:
                obs.record(k + 1, t_next)
            if progress is not None and (k + 1) % progress_every == 0:
                progress(k + 1)
        k = n_steps
        t = stop
    except SimulationError as exc:
        status, error = "failed", exc
    except (KeyboardInterrupt, Interrupted) as exc:
        status = "interrupted"
        error = SimulationError(f"interrupted ({exc or 'KeyboardInterrupt'})", time=t)
    finally:
        for unit in algorithm.units.values():
            unit.terminate()
    if progress is not None:
        progress(k)
    return ExecutionResult(status, k, n_steps, t if status != "complete" else stop,
                           _time.perf_counter() - wall, error)
