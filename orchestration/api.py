"""The Python API for scripts and notebooks: load a scenario, run it, get arrays back.

>>> from orchestration.api import load_scenario, run
>>> plan = load_scenario("scenarios/kobe.yaml", overrides=["simulation.stop_time=5"])
>>> results = run(plan, out="runs/kobe-5s")  # doctest: +SKIP
>>> results.complete, results["building.a_3"].max()  # doctest: +SKIP

:func:`load_scenario` reads and checks a scenario YAML file or an SSP package (building
the project's FMUs when they are missing or stale) and raises
:class:`~orchestration.master.errors.ScenarioError` listing every problem.
:func:`run` executes a checked plan, writes its run folder like ``run.py`` and returns
:class:`Results`: the time series as numpy arrays (SI units) and the summary.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from orchestration.master.errors import ScenarioError, SimulationError
from orchestration.master.execution import StopRequest
from orchestration.master.session import run_plan
from orchestration.master.system import SystemPlan
from orchestration.project import plan_scenario

__all__ = ["Results", "ScenarioError", "SimulationError", "SystemPlan", "load_scenario", "run"]


def load_scenario(
    path: Path | str,
    overrides: Iterable[str] = (),
    data_dirs: Iterable[Path | str] = (),
) -> SystemPlan:
    """Read and check a scenario (``.yaml``) or SSP package (``.ssp``); raises ScenarioError.

    ``overrides`` are ``KEY=VALUE`` strings as with ``run.py --set``; ``data_dirs`` are
    searched first for ``!record`` files.
    """
    return plan_scenario(Path(path), tuple(overrides), tuple(Path(d) for d in data_dirs))


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
    plan: SystemPlan,
    out: Path | str | None = None,
    plots: bool = False,
    progress: bool = False,
    stop: StopRequest | None = None,
) -> Results:
    """Run a checked plan and write its run folder (``out``, or a new one under the scenario's results dir).

    A unit failure does not raise: the partial results come back with ``complete`` False
    and ``error`` saying which unit failed, when and why (as ``run.py`` reports it).
    """
    outcome = run_plan(plan, Path(out) if out is not None else None, plots, progress, stop)
    rec = outcome.recorder
    columns = {name: rec.data[: rec.count, k].copy() for k, name in enumerate(rec.names)}
    result = outcome.result
    return Results(outcome.folder, rec.times.copy(), columns, outcome.summary, result.status,
                   str(result.error) if result.error else None)
