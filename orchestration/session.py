"""One scenario run from file to run folder: load, check, execute, write results.

Used by ``run.py`` and by anything that runs scenarios programmatically (tests, studies).
"""

from __future__ import annotations

import platform
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from orchestration.execution import ExecutionResult, StopRequest, execute
from orchestration.fmu_unit import LogRecord
from orchestration.monitor import Monitor
from orchestration.recorder import Recorder
from orchestration.report import plot, summarize
from orchestration.runfolder import (
    new_run_folder,
    package_versions,
    sha256,
    write_json,
    write_timeseries,
)
from orchestration.scenario import load_scenario
from orchestration.system import SystemPlan, resolve
from orchestration.yaml_source import DataFile


@dataclass
class RunOutcome:
    """Where a run's results are and how it ended."""

    folder: Path
    result: ExecutionResult
    summary: dict[str, Any]
    recorder: Recorder
    units: list[Any]  # the units as left after the run (all terminated and freed)


def _plain(data: Any) -> Any:
    if isinstance(data, dict):
        return {k: _plain(v) for k, v in data.items()}
    if isinstance(data, list):
        return [_plain(v) for v in data]
    if isinstance(data, DataFile):
        return str(data)
    return data


def plan_scenario(path: Path, overrides: tuple[str, ...] = (), data_dirs: tuple[Path, ...] = ()) -> SystemPlan:
    """Load and check a scenario or SSP package (builds project FMUs if needed); raises ScenarioError."""
    if Path(path).suffix.lower() == ".ssp":
        from orchestration.ssp import load_ssp

        return resolve(load_ssp(path, overrides), data_dirs)
    return resolve(load_scenario(path, overrides), data_dirs)


def run_plan(
    plan: SystemPlan,
    out: Path | None = None,
    plots: bool = True,
    progress: bool = False,
    stop: StopRequest | None = None,
) -> RunOutcome:
    """Execute a checked plan and write its run folder (partial results if it fails or is stopped)."""
    sc = plan.loaded.scenario
    folder = new_run_folder(Path(sc.results.dir), sc.name, out)
    warnings: dict[str, int] = {name: 0 for name in plan.descriptions}
    messages: list[str] = []
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=sc.simulation.n_steps, unit="step", desc=sc.name, file=sys.stderr,
                   mininterval=0.5, disable=None)

    def on_log(unit: str, record: LogRecord) -> None:
        if record.status == "warning":
            warnings[unit] += 1
        if record.status != "ok":
            text = f"[{unit}] {record.status}: {record.message}"
            messages.append(text)
            if record.status == "warning" and warnings[unit] <= 20:
                (bar.write if bar is not None else print)(text, file=sys.stderr)

    def tick(k: int) -> None:
        if bar is not None:
            bar.update(k - bar.n)

    units = plan.create_units(on_log)
    algorithm = plan.create_algorithm(units)
    recorder = Recorder(algorithm, plan.recorded, sc.simulation.n_steps)
    monitor = Monitor(algorithm, plan.limits)
    started = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    result = execute(algorithm, sc.simulation.start_time, sc.simulation.stop_time, sc.simulation.step,
                     [recorder, monitor], progress=tick, stop_request=stop, executor=sc.simulation.executor)
    if bar is not None:
        bar.close()

    write_timeseries(folder / "timeseries.csv", recorder.times, recorder.names, recorder.data[: recorder.count])
    summary: dict[str, Any] = {
        "scenario": sc.name,
        "complete": result.complete,
        "status": result.status,
        "error": str(result.error) if result.error else None,
        "end_time_s": result.end_time,
        "steps_done": result.steps_done,
        "n_steps": result.n_steps,
        "wall_time_s": result.wall_time,
        "executor": result.executor,
        **({"executor_note": result.executor_note} if result.executor_note else {}),
        "unit_warnings": warnings,
        **summarize(recorder, sc.report),
    }
    if plots and recorder.count > 1:
        plot(recorder, sc.report, folder, sc.name)
    write_json(folder / "summary.json", summary)
    manifest = {
        "complete": result.complete,
        "status": result.status,
        "started": started,
        "command": sys.argv,
        "scenario_file": str(plan.loaded.path),
        "scenario": _plain(plan.loaded.raw),
        "fmus": {name: {"path": str(p), "sha256": sha256(p)} for name, p in plan.fmu_paths.items()},
        "data_files": {key: {"path": str(p), "sha256": sha256(p)} for key, p in plan.data_files.items()},
        "python": platform.python_version(),
        "platform": platform.platform(),
        "packages": package_versions(),
        "unit_messages": messages[-200:],
    }
    write_json(folder / "manifest.json", manifest)
    return RunOutcome(folder, result, summary, recorder, units)


def run_scenario(
    path: Path,
    overrides: tuple[str, ...] = (),
    out: Path | None = None,
    data_dirs: tuple[Path, ...] = (),
    plots: bool = True,
    progress: bool = False,
    stop: StopRequest | None = None,
) -> RunOutcome:
    """Load, check and run a scenario file; ScenarioError before anything is written."""
    plan = plan_scenario(path, overrides, data_dirs)
    return run_plan(plan, out, plots, progress, stop)
