"""Execution: initialize, step on an integer time grid, notify observers, always tear down.

Time is counted in whole steps: t_k = start + k h, and the last step ends exactly on
the stop time. Every unit is terminated and freed on every exit path (success, unit
failure, a raising observer, Ctrl-C or SIGTERM).
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal, Protocol

from orchestration.master.algorithm import CouplingAlgorithm
from orchestration.master.errors import SimulationError

Executor = Literal["auto", "native", "python"]


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
    executor: str = "python"  # which executor ran the steps
    executor_note: str = ""  # why the native executor was not used, if it was not

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


@dataclass(frozen=True)
class RunControls:
    """How a caller follows and steers a run: ``progress(k)`` after every ``progress_every`` steps (and at the end),
    ``stop_request`` checked before each step, ``after_initialization()`` once the units are initialized (it
    may raise SimulationError)."""

    progress: Callable[[int], None] | None = None
    progress_every: int = 1000
    stop_request: StopRequest | None = None
    after_initialization: Callable[[], None] | None = None


def execute(
    algorithm: CouplingAlgorithm,
    start: float,
    stop: float,
    step: float,
    observers: Sequence[Observer] = (),
    executor: Executor = "auto",
    controls: RunControls = RunControls(),
) -> ExecutionResult:
    """Run the algorithm from start to stop [s] with communication step ``step`` [s].

    ``executor``: ``python`` steps with :meth:`CouplingAlgorithm.step`; ``native`` runs the
    same program in C (:mod:`orchestration.master.native_stepper`); ``auto`` uses native when it
    can drive the units and falls back to python otherwise. Both give identical results.
    ``controls``: progress, stop request and the after-initialization check (:class:`RunControls`).
    Never leaves a unit allocated, whatever happens.
    """
    progress, progress_every = controls.progress, controls.progress_every
    stop_request, after_initialization = controls.stop_request, controls.after_initialization
    n_steps, t_of = time_grid(start, stop, step)
    wall = _time.perf_counter()
    k = 0
    t = start
    status, error = "complete", None
    used, note = "python", ""
    try:
        algorithm.initialize(start, stop, step)
        if after_initialization is not None:
            after_initialization()
        for obs in observers:
            obs.record(0, start)
        native = None
        if executor != "python":
            from orchestration.master.native_stepper import NativeStepper, NativeUnavailable

            try:
                native = NativeStepper(algorithm, observers, start, stop, step, n_steps)
                used = "native"
            except NativeUnavailable as exc:
                if executor == "native":
                    raise SimulationError(f"the native executor cannot run this system: {exc}", time=start) from None
                note = f"native executor unavailable: {exc}"
        while k < n_steps:
            t = t_of(k)
            if stop_request:
                raise Interrupted(stop_request.reason)
            if native is not None:
                try:
                    native.run(k, min(n_steps, (k // progress_every + 1) * progress_every), t_of)
                finally:
                    k = native.done
                    t = t_of(k)
            else:
                t_next = t_of(k + 1)
                algorithm.step(t, t_next - t)
                for obs in observers:
                    obs.record(k + 1, t_next)
                k += 1
            if progress is not None and k % progress_every == 0:
                progress(k)
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
                           _time.perf_counter() - wall, error, used, note)
