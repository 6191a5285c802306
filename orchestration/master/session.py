"""One checked plan run into a run folder: execute, record, write results.

:func:`run_plan` takes a :class:`~orchestration.master.resolve.SystemPlan` (from
:func:`~orchestration.master.resolve.resolve`); loading a scenario file and building the
project's FMUs is the application's part (:mod:`orchestration.engine_hooks`, :mod:`orchestration.api`).
"""

from __future__ import annotations

import logging
import platform
import sys
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from orchestration.master.errors import SimulationError
from orchestration.master.execution import ExecutionResult, StopRequest, execute
from orchestration.master.fmi_status import UNIT_LOGGER, LogRecord
from orchestration.master.monitor import Monitor
from orchestration.master.recorder import CsvProcess, Recorder, RowStorage, column_kind, write_results
from orchestration.master.report import PlotFailed, PlotProcess, RunDescription, caption, plot, report_summary
from orchestration.master.resolve import SystemPlan
from orchestration.master.runfolder import (
    new_run_folder,
    package_versions,
    run_id,
    sha256,
    write_json,
)
from orchestration.master.scenario import rows_written
from orchestration.master.yaml_source import DataFile

WARNINGS_SHOWN = 20
"""Warnings of one unit reported at WARNING level; later ones at DEBUG (all are kept in the manifest)."""
_UNIT_LOG = logging.getLogger(UNIT_LOGGER)
logging.getLogger(UNIT_LOGGER.split(".")[0]).addHandler(logging.NullHandler())  # silent unless a handler is added


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


def _checked_hash(plan: SystemPlan, path: Path) -> str | None:
    """The SHA-256 of an input as it was checked (a plan made without hashes: as it is now)."""
    if str(path) in plan.input_hashes:
        return plan.input_hashes[str(path)]
    try:
        return sha256(path)
    except OSError:
        return None


def describe_run(plan: SystemPlan) -> RunDescription:
    """Each unit's parameter values as the run uses them (set in the scenario, else declared), for captions."""
    values = {}
    for unit, desc in plan.descriptions.items():
        declared = {v.name: _typed(v.fmi_type, v.start) for v in desc.variables.values()
                    if v.causality == "parameter" and v.start is not None}
        values[unit] = declared | plan.parameters.get(unit, {})
    names = {unit: desc.model_identifier or desc.name for unit, desc in plan.descriptions.items()}
    held = frozenset(f"{unit}.{v.name}" for unit, desc in plan.descriptions.items() for v in desc.variables.values()
                     if v.causality == "output" and (v.variability == "discrete" or plan.periods.get(unit, 1) > 1))
    return RunDescription(values, names, dict(plan.report.labels), held)


def _plot_inline(recorder: Recorder, plan: SystemPlan, folder: Path, described: RunDescription) -> None:
    """The figures drawn in this process; a failure costs the figures only, said as a plot process says it."""
    try:
        plot(recorder, plan.report, plan.report_hook, folder, plan.loaded.scenario.name, described)
    except OSError:
        raise
    except Exception as exc:  # a bug in the application's figures: the run keeps its other results
        last = traceback.format_exception_only(exc)[-1].strip()
        raise PlotFailed(f"the figures could not be drawn ({last})") from exc


def _plot_process(plan: SystemPlan, folder: Path, described: RunDescription,
                  kinds: list[str]) -> tuple[RowStorage | None, PlotProcess | None]:
    """Row storage shared with a forked process that draws the figures when the run ends (:class:`PlotProcess`):
    it imports matplotlib while the units step and draws once they are done (while the summary is computed and
    the CSV process writes its last rows). ``(None, None)``
    where that cannot be (no hook that draws, String columns, no safe fork): the figures are drawn in-process."""
    hook, sc = plan.report_hook, plan.loaded.scenario
    if hook is None or hook.plot is None or "string" in kinds or not PlotProcess.available():
        return None, None
    storage = RowStorage(sc.simulation.n_steps + 1, len(plan.recorded), folder, shared=True)

    def draw(rows: int, share: tuple[int, int]) -> list[Path]:
        return plot(Recorder.view(plan.recorded, kinds, storage, rows), plan.report, hook, folder, sc.name, described,
                    share)

    return storage, PlotProcess.start(draw)


def run_plan(
    plan: SystemPlan,
    out: Path | None = None,
    plots: bool = True,
    progress: bool = False,
    stop: StopRequest | None = None,
) -> RunOutcome:
    """Execute a checked plan and write its run folder (partial results if it fails or is stopped).

    The units' messages go to the ``mre_cosim.units`` logger (:data:`~orchestration.master.fmi_status.UNIT_LOGGER`)
    as ``[unit] status: message``: a unit's first :data:`WARNINGS_SHOWN` warnings at WARNING, later
    ones at DEBUG, discard, error and fatal at ERROR; each record carries ``unit`` and
    ``fmi_status`` attributes. Nothing is printed unless the caller attaches a handler (the
    command-line tools do). ``progress`` draws a progress bar on stderr.
    """
    sc = plan.loaded.scenario
    folder = new_run_folder(Path(sc.results.dir), sc.name, out)
    described = describe_run(plan)
    kinds = [column_kind(plan.descriptions[u].variables[v]) for u, v in plan.recorded]
    storage, plotter = _plot_process(plan, folder, described, kinds) if plots else (None, None)  # before any thread
    csv_process = None  # timeseries.csv written by a forked process while the units step (CsvProcess)
    output = sc.simulation.output_interval, sc.simulation.output_format
    if output == (1, "csv") and CsvProcess.wanted(sc.simulation.n_steps + 1, kinds):
        if storage is None:
            storage = RowStorage(sc.simulation.n_steps + 1, len(plan.recorded), folder, shared=True)
        csv_process = CsvProcess.start(folder / "timeseries.csv", [f"{u}.{v}" for u, v in plan.recorded], storage,
                                       plotter.parent_fds() if plotter is not None else ())
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
            if record.status == "warning":
                level = logging.WARNING if warnings[unit] <= WARNINGS_SHOWN else logging.DEBUG
            else:
                level = logging.ERROR
            _UNIT_LOG.log(level, "%s", text, extra={"unit": unit, "fmi_status": record.status})
            if record.status == "warning" and warnings[unit] == WARNINGS_SHOWN + 1:
                _UNIT_LOG.warning("[%s] more warnings than %d: the rest are not shown here; every one is in the run "
                                  "folder's manifest.json (unit_messages)", unit, WARNINGS_SHOWN,
                                  extra={"unit": unit, "fmi_status": "warning"})

    def tick(k: int) -> None:
        if bar is not None:
            bar.update(k - bar.n)
        if csv_process is not None:
            csv_process.rows(recorder.count)

    units = plan.create_units(on_log)
    algorithm = plan.create_algorithm(units)
    recorder = Recorder(algorithm, plan.recorded, sc.simulation.n_steps, spill_dir=folder, storage=storage)
    monitor = Monitor(algorithm, plan.limits)
    started = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    def inputs_unchanged() -> None:  # the units have read their FMUs and data: it must be what was checked
        changed = plan.changed_inputs()
        if changed:
            raise SimulationError("input changed between the checks and the units' initialization: "
                                  + "; ".join(changed), time=sc.simulation.start_time)

    result = execute(algorithm, sc.simulation.start_time, sc.simulation.stop_time, sc.simulation.step,
                     [recorder, monitor], progress=tick, stop_request=stop, executor=sc.simulation.executor,
                     after_initialization=inputs_unchanged)
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

    if csv_process is not None:
        csv_process.finish(recorder.count)  # the last rows: the file is in place when wait() returns
    if plotter is not None and recorder.count <= 1:
        plotter.cancel()
    elif plotter is not None:
        plotter.draw(recorder.count)  # drawn while the summary and the manifest are made (and the CSV finished)
    if csv_process is None:
        save(f"timeseries.{output[1]}", lambda: write_results(folder, recorder, *output))
    if plots and plotter is None and recorder.count > 1:
        save("plots (*.png)", lambda: _plot_inline(recorder, plan, folder, described))
    run = run_id(folder)
    summary: dict[str, Any] = {
        "scenario": sc.name,
        "caption": caption(plan.report, described, sc.name),
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
        "results_file": {"file": f"timeseries.{output[1]}", "every_nth_step": output[0],
                         "rows": rows_written(recorder.count, output[0])},
    }
    summary |= report_summary(recorder, plan.report, plan.report_hook, described, set(summary))
    manifest = {
        "complete": result.complete,
        "status": result.status,
        "run_id": run,
        "started": started,
        "command": sys.argv,
        **({"provenance": plan.provenance} if plan.provenance else {}),
        "scenario_file": str(plan.loaded.path),
        "scenario": _plain(plan.loaded.raw),
        # hashed when checked, and the same after the units read them (inputs_unchanged): what the run played
        "fmus": {name: {"path": str(p), "sha256": _checked_hash(plan, p)} for name, p in plan.fmu_paths.items()},
        "data_files": {key: {"path": str(p), "sha256": _checked_hash(plan, p)} for key, p in plan.data_files.items()},
        "python": platform.python_version(),
        "platform": platform.platform(),
        "packages": package_versions(),
        "unit_messages": messages[-200:],
    }
    if csv_process is not None:
        save("timeseries.csv", csv_process.wait)
    if plotter is not None and recorder.count > 1:
        save("plots (*.png)", plotter.wait)
    if write_errors:
        mark_failed()
    if not save("manifest.json", lambda: write_json(folder / "manifest.json", manifest)):
        mark_failed()
    if not save("summary.json", lambda: write_json(folder / "summary.json", summary)):
        mark_failed()
        save("manifest.json", lambda: write_json(folder / "manifest.json", manifest))  # best effort: not complete
    return RunOutcome(folder, result, summary, recorder, units)
