"""The Python API for scripts and notebooks: load a scenario, run it, get arrays back.

>>> from orchestration.api import load_scenario, run
>>> plan = load_scenario("scenarios/kobe.yaml", overrides=["simulation.stop_time=5"])
>>> results = run(plan, out="runs/kobe-5s")  # doctest: +SKIP
>>> results.complete, results["building.a_3"].max()  # doctest: +SKIP

:func:`load_scenario` reads and checks a scenario YAML file or an SSP package (building
the project's FMUs when they are missing or stale) and raises
:class:`~orchestration.master.errors.ScenarioError` listing every problem.
:func:`run` executes a checked plan, writes its run folder like ``run.py`` and returns
:class:`Results`: the time series as numpy arrays (SI units) and the summary, with the run's two
verdicts kept apart: ``results.valid`` / ``results.invalid_reasons`` (numerical validity) and
``results.physical`` (the physical outcome).

Unit messages (an FMU's warnings and errors) are not printed: they go to the standard
:mod:`logging` logger ``"mre_cosim.units"`` as ``[unit] status: message`` (a unit's first 20
warnings at WARNING, later ones at DEBUG, discard/error/fatal at ERROR; each record has
``unit`` and ``fmi_status`` attributes), and all of them are kept in the run folder's
``manifest.json`` (``unit_messages``). The caller decides what to show, e.g.

>>> import logging
>>> logging.getLogger("mre_cosim.units").addHandler(logging.StreamHandler())  # doctest: +SKIP

or ``logging.basicConfig()`` for everything. ``progress=True`` draws a progress bar on stderr.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from orchestration.engine_hooks import plan_scenario
from orchestration.master.errors import ScenarioError, SimulationError
from orchestration.master.execution import StopRequest
from orchestration.master.figure_files import FigureFiles
from orchestration.master.resolve import SystemPlan
from orchestration.master.session import run_plan

__all__ = ["FigureFiles", "Results", "ScenarioError", "SimulationError", "SystemPlan", "load_scenario", "run"]


def _path(value: Any, argument: str, function: str) -> Path:
    """``value`` as a Path: TypeError naming the argument unless it is a str or os.PathLike."""
    if isinstance(value, str | os.PathLike) and not isinstance(value, bytes):
        text = os.fspath(value)
        if isinstance(text, str) and text and "\x00" not in text:
            return Path(text)
        if isinstance(text, str):
            raise ValueError(f"{function}(): {argument} must be a non-empty path without NUL characters, "
                             f"got {text!r}")
    raise TypeError(f"{function}(): {argument} must be a path (str or pathlib.Path), got {type(value).__name__}")


def _strings(value: Any, argument: str, function: str, item: Callable[[Any, str, str], Any]) -> tuple[Any, ...]:
    """An iterable of strings or paths as a tuple; a single string or path is one item, not its characters."""
    if isinstance(value, str | os.PathLike):
        value = (value,)
    if isinstance(value, bytes | Mapping) or not isinstance(value, Iterable):
        raise TypeError(f"{function}(): {argument} must be a list of strings, got {type(value).__name__}")
    return tuple(item(v, f"{argument}[{k}]", function) for k, v in enumerate(value))


def _override(value: Any, argument: str, function: str) -> str:
    if not isinstance(value, str):
        raise TypeError(f"{function}(): {argument} must be a 'KEY=VALUE' string, got {type(value).__name__}")
    return value


def load_scenario(
    path: Path | str,
    overrides: Iterable[str] = (),
    data_dirs: Iterable[Path | str] = (),
) -> SystemPlan:
    """Read and check a scenario (``.yaml``) or SSP package (``.ssp``); raises ScenarioError.

    ``overrides`` are ``KEY=VALUE`` strings as with ``run.py --set``; ``data_dirs`` are
    searched first for ``!record`` files. A single string is taken as one override or one
    folder. An argument of the wrong type is a TypeError naming it.
    """
    where = "load_scenario"
    return plan_scenario(_path(path, "path", where), _strings(overrides, "overrides", where, _override),
                         _strings(data_dirs, "data_dirs", where, _path))


@dataclass(frozen=True)
class Results(Mapping[str, np.ndarray]):
    """A finished (or stopped) run: ``results["unit.variable"]`` is that variable's array over ``time``."""

    folder: Path  # the run folder written (timeseries.csv, summary.json, manifest.json, plots)
    time: np.ndarray  # communication points [s]
    columns: dict[str, np.ndarray]  # recorded variables, SI units
    summary: dict[str, Any]  # as in summary.json
    status: str  # "complete", "failed" or "interrupted"
    error: str | None  # why the run stopped early, if it did

    @property
    def complete(self) -> bool:
        return self.status == "complete"

    @property
    def valid(self) -> bool | None:
        """Numerical validity (summary.json's ``valid``): False when the energy balance does not close, the
        coupling's energy error is above the tolerance, a value is not finite, or the step did not converge
        where that was checked. A complete run may be invalid: its numbers are not to be ranked."""
        return self.summary.get("valid")

    @property
    def invalid_reasons(self) -> list[str]:
        """Why the run is numerically invalid (empty when it is valid)."""
        return list(self.summary.get("invalid_reasons") or [])

    @property
    def physical(self) -> dict[str, Any]:
        """The physical outcome, a result and not a defect (summary.json's ``physical``: time beyond the
        isolator's identified range and at its device limit, peak force), where the report gives one."""
        return dict(self.summary.get("physical") or {})

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.columns[name]
        except KeyError:
            raise KeyError(f"{name!r} was not recorded (recorded: {', '.join(self.columns)})") from None

    def __iter__(self) -> Iterator[str]:
        return iter(self.columns)

    def __len__(self) -> int:
        return len(self.columns)


def run(
    plan: SystemPlan | Path | str,
    out: Path | str | None = None,
    plots: bool = False,
    progress: bool = False,
    stop: StopRequest | None = None,
    figure_files: FigureFiles | None = None,
) -> Results:
    """Run a checked plan and write its run folder (``out``, or a new one under the scenario's results dir).

    ``figure_files`` (with ``plots``): the PNG resolution and the vector formats written beside each PNG
    (``FigureFiles(dpi=300, formats=("svg",))``); a bad value is a ValueError before anything is written.

    ``plan`` may also be a scenario file or SSP package path (loaded with :func:`load_scenario`).
    A unit failure does not raise, nor does a unit that cannot be loaded (its FMU changed or
    was damaged after it was checked): the partial results come back with ``complete`` False
    and ``error`` saying which unit failed, when and why (as ``run.py`` reports it). Arguments of
    the wrong type are a TypeError naming the argument, before anything is written.
    """
    where = "run"
    if isinstance(plan, str | os.PathLike):
        plan = load_scenario(plan)
    if not isinstance(plan, SystemPlan):
        raise TypeError(f"run(): plan must be a SystemPlan (from load_scenario) or a scenario path, "
                        f"got {type(plan).__name__}")
    folder = None if out is None else _path(out, "out", where)
    for name, value in (("plots", plots), ("progress", progress)):
        if not isinstance(value, bool):
            raise TypeError(f"run(): {name} must be True or False, got {value!r}")
    if stop is not None and not isinstance(stop, StopRequest):
        raise TypeError(f"run(): stop must be a StopRequest or None, got {type(stop).__name__}")
    if figure_files is not None and not isinstance(figure_files, FigureFiles):
        raise TypeError(f"run(): figure_files must be a FigureFiles or None, got {type(figure_files).__name__}")
    outcome = run_plan(plan, folder, plots, progress, stop, figure_files)
    rec = outcome.recorder
    columns = {name: rec.data[: rec.count, k].copy() for k, name in enumerate(rec.names)}
    result = outcome.result
    return Results(outcome.folder, rec.times.copy(), columns, outcome.summary, result.status,
                   str(result.error) if result.error else None)
