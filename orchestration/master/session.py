"""One checked plan run into a run folder: execute, record, write results.

:func:`run_plan` takes a :class:`~orchestration.master.system.SystemPlan` (from
:func:`~orchestration.master.system.resolve`); loading a scenario file and building the
project's FMUs is the application's part (:mod:`orchestration.project`, :mod:`orchestration.api`).
"""

from __future__ import annotations

import platform
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from orchestration.master.errors import SimulationError
from orchestration.master.execution import ExecutionResult, StopRequest, execute
from orchestration.master.fmi_status import LogRecord
from orchestration.master.monitor import Monitor
from orchestration.master.recorder import Recorder, write_timeseries
from orchestration.master.report import RunDescription, caption, plot, summarize
from orchestration.master.runfolder import (
    new_run_folder,
    package_versions,
    run_id,
    sha256,
    write_json,
)
from orchestration.master.system import SystemPlan
from orchestration.master.yaml_source import DataFile


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


def _typed(fmi_type: str, start: Any) -> Any:
    """A declared start value (text in the model description) as a Python value of its type."""
    try:
        if fmi_type.startswith(("Real", "Float")):
            return float(start)
        if fmi_type.startswith(("Int", "UInt", "Enumeration")):
            return int(start)
    except (TypeError, ValueError):
        return start
    if fmi_type == "Boolean":
        return str(start).lower() in ("true", "1")
    return start


def describe_run(plan: SystemPlan) -> RunDescription:
    """Each unit's parameter values as the run uses them (set in the scenario, else declared), for captions."""
    values = {}
    for unit, desc in plan.descriptions.items():
        declared = {v.name: _typed(v.fmi_type, v.start) for v in desc.variables.values()
                    if v.causality == "parameter" and v.start is not None}
        values[unit] = declared | plan.parameters.get(unit, {})
    names = {unit: desc.model_identifier or desc.name for unit, desc in plan.descriptions.items()}
    return RunDescription(values, names, dict(plan.loaded.scenario.report.labels))


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
    recorder = Recorder(algorithm, plan.recorded, sc.simulation.n_steps, spill_dir=folder)
    monitor = Monitor(algorithm, plan.limits)
    started = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    result = execute(algorithm, sc.simulation.start_time, sc.simulation.stop_time, sc.simulation.step,
                     [recorder, monitor], progress=tick, stop_request=stop, executor=sc.simulation.executor)
    if bar is not None:
        bar.close()

    # A write failure after the simulation (disk full, folder removed, ...) must never leave
    # a summary that says complete: the run is reported failed, naming the file. The manifest
    # is written before the summary, and the summary last, so summary.json is either absent
    # or tells the truth; every file is still attempted so the failure is recorded if possible.
    write_errors: list[str] = []
    run_error = [str(result.error)] if result.error else []

    def save(name: str, action: Callable[[], None]) -> bool:
        try:
            action()
        except OSError as exc:
            write_errors.append(f"could not write {folder / name}: {exc.strerror or exc}")
            return False
        return True

    def mark_failed() -> None:
        nonlocal result
        result = replace(result, status="failed", error=SimulationError("; ".join(write_errors + run_error)))
        for doc in (summary, manifest):
            doc.update(complete=False, status=result.status)
        summary["error"] = str(result.error)

    described = describe_run(plan)
    save("timeseries.csv", lambda: write_timeseries(folder / "timeseries.csv", recorder.times, recorder.names,
                                                    recorder.data[: recorder.count], recorder.kinds,
                                                    recorder.strings))
    if plots and recorder.count > 1:
        save("plots (*.png)", lambda: plot(recorder, sc.report, folder, sc.name, described))
    run = run_id(folder)
    summary: dict[str, Any] = {
        "scenario": sc.name,
        "caption": caption(sc.report, described, sc.name),
        "complete": result.complete,
        "status": result.status,
        "error": str(result.error) if result.error else None,
        "run_id": run,
        "end_time_s": result.end_time,
        "steps_done": result.steps_done,
        "n_steps": result.n_steps,
        "wall_time_s": result.wall_time,
        "executor": result.executor,
        **({"executor_note": result.executor_note} if result.executor_note else {}),
        "unit_warnings": warnings,
        **summarize(recorder, sc.report),
    }
    manifest = {
        "complete": result.complete,
        "status": result.status,
        "run_id": run,
        "started": started,
        "command": sys.argv,
        **({"provenance": plan.provenance} if plan.provenance else {}),
        "scenario_file": str(plan.loaded.path),
        "scenario": _plain(plan.loaded.raw),
        "fmus": {name: {"path": str(p), "sha256": sha256(p)} for name, p in plan.fmu_paths.items()},
        "data_files": {key: {"path": str(p), "sha256": sha256(p)} for key, p in plan.data_files.items()},
        "python": platform.python_version(),
        "platform": platform.platform(),
        "packages": package_versions(),
        "unit_messages": messages[-200:],
    }
    if write_errors:
        mark_failed()
    if not save("manifest.json", lambda: write_json(folder / "manifest.json", manifest)):
        mark_failed()
    if not save("summary.json", lambda: write_json(folder / "summary.json", summary)):
        mark_failed()
        save("manifest.json", lambda: write_json(folder / "manifest.json", manifest))  # best effort: not complete
    return RunOutcome(folder, result, summary, recorder, units)
