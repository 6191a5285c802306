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
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from mre_common.hashing import file_sha256
from orchestration.master.errors import SimulationError
from orchestration.master.execution import ExecutionResult, RunControls, StopRequest, execute
from orchestration.master.figure_files import FigureFiles
from orchestration.master.fmi_status import UNIT_LOGGER, LogRecord
from orchestration.master.monitor import Monitor
from orchestration.master.recorder import CsvProcess, Recorder, RowStorage, column_kind, write_results
from orchestration.master.report import PlotFailed, PlotProcess, RunDescription, caption, plot, report_summary
from orchestration.master.resolve import FmiUnit, SystemPlan
from orchestration.master.runfolder import new_run_folder, package_versions, run_id, write_json
from orchestration.master.scenario import rows_written
from orchestration.master.summary import write_summary
from orchestration.master.unit import start_value
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
    units: list[FmiUnit]  # the units as left after the run (all terminated and freed)
    unit_errors: list[str] = field(default_factory=list)  # the units' error and fatal messages, in order


def _plain(data: Any) -> Any:
    if isinstance(data, dict):
        return {k: _plain(v) for k, v in data.items()}
    if isinstance(data, list):
        return [_plain(v) for v in data]
    if isinstance(data, DataFile):
        return str(data)
    return data


def _checked_hash(plan: SystemPlan, path: Path) -> str | None:
    """The SHA-256 of an input as it was checked (a plan made without hashes: as it is now)."""
    if str(path) in plan.input_hashes:
        return plan.input_hashes[str(path)]
    try:
        return file_sha256(path)
    except OSError:
        return None


def describe_run(plan: SystemPlan) -> RunDescription:
    """Each unit's parameter values as the run uses them (set in the scenario, else declared), for captions, and
    those the scenario set."""
    values = {}
    for unit, desc in plan.descriptions.items():
        declared = {v.name: start_value(v) for v in desc.variables.values()
                    if v.causality == "parameter" and v.start is not None}
        values[unit] = declared | plan.parameters.get(unit, {})
    names = {unit: desc.model_identifier or desc.name for unit, desc in plan.descriptions.items()}
    held = frozenset(f"{unit}.{v.name}" for unit, desc in plan.descriptions.items() for v in desc.variables.values()
                     if v.causality == "output" and (v.variability == "discrete" or plan.periods.get(unit, 1) > 1))
    set_values = {unit: dict(plan.parameters.get(unit, {})) for unit in plan.descriptions}
    return RunDescription(values, names, dict(plan.report.labels), held, set_values)


def _plot_inline(recorder: Recorder, plan: SystemPlan, folder: Path, described: RunDescription,
                 files: FigureFiles) -> None:
    """The figures drawn in this process; a failure costs the figures only, said as a plot process says it."""
    try:
        plot(recorder, plan.report, plan.report_hook, folder, plan.loaded.scenario.name, described, files=files)
    except OSError:
        raise
    except Exception as exc:  # a bug in the application's figures: the run keeps its other results
        last = traceback.format_exception_only(exc)[-1].strip()
        raise PlotFailed(f"the figures could not be drawn ({last})") from exc


def _plot_process(plan: SystemPlan, folder: Path, described: RunDescription, kinds: list[str],
                  files: FigureFiles) -> tuple[RowStorage | None, PlotProcess | None]:
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
                    share, files)

    return storage, PlotProcess.start(draw)


class _UnitMessages:
    """The units' log records as a run reports them: counted, kept for the manifest, logged (see :func:`run_plan`)."""

    def __init__(self, units: Iterable[str]) -> None:
        self.warnings: dict[str, int] = {name: 0 for name in units}
        self.messages: list[str] = []
        self.errors: list[str] = []  # error and fatal only

    def __call__(self, unit: str, record: LogRecord) -> None:
        if record.status == "warning":
            self.warnings[unit] += 1
        if record.status == "ok":
            return
        text = f"[{unit}] {record.status}: {record.message}"
        self.messages.append(text)
        if record.status != "warning":
            self.errors.append(text)
            _UNIT_LOG.log(logging.ERROR, "%s", text, extra={"unit": unit, "fmi_status": record.status})
            return
        count = self.warnings[unit]
        level = logging.WARNING if count <= WARNINGS_SHOWN else logging.DEBUG
        _UNIT_LOG.log(level, "%s", text, extra={"unit": unit, "fmi_status": record.status})
        if count == WARNINGS_SHOWN + 1:
            _UNIT_LOG.warning("[%s] more warnings than %d: the rest are not shown here; every one is in the run "
                              "folder's manifest.json (unit_messages)", unit, WARNINGS_SHOWN,
                              extra={"unit": unit, "fmi_status": "warning"})


@dataclass
class _Simulated:
    """What the simulation stage leaves for the writing stage."""

    result: ExecutionResult
    recorder: Recorder
    units: list[FmiUnit]
    started: str


class _PlanRun:
    """One run of a plan, in stages: :meth:`__init__` claims the folder and forks the writers, :meth:`simulate`
    steps the units, :meth:`write` writes the results, the manifest and the summary (see :func:`run_plan`)."""

    def __init__(self, plan: SystemPlan, out: Path | None, plots: bool, files: FigureFiles,
                 results_file: bool = True) -> None:
        self.plan = plan
        self.sc = sc = plan.loaded.scenario
        self.plots = plots
        self.files = files
        self.results_file = results_file
        self.folder = new_run_folder(Path(sc.results.dir), sc.name, out)
        self.described = describe_run(plan)
        self.kinds = [column_kind(plan.descriptions[u].variables[v]) for u, v in plan.recorded]
        self.output = sc.simulation.output_interval, sc.simulation.output_format
        self.rows = sc.simulation.n_steps + 1
        # forked before any thread
        self.storage, self.plotter = _plot_process(plan, self.folder, self.described, self.kinds, files) if plots \
            else (None, None)
        self.csv_process = self._start_csv_process()
        self.log = _UnitMessages(plan.descriptions)
        self.write_errors: list[str] = []

    def _start_csv_process(self) -> CsvProcess | None:
        """timeseries.csv written by a forked process while the units step (:class:`CsvProcess`), where it can be."""
        plan = self.plan
        if not self.results_file or self.output != (1, "csv") or not CsvProcess.wanted(self.rows, self.kinds):
            return None
        if self.storage is None:
            self.storage = RowStorage(self.rows, len(plan.recorded), self.folder, shared=True)
        return CsvProcess.start(self.folder / "timeseries.csv", [f"{u}.{v}" for u, v in plan.recorded], self.storage,
                                self.plotter.parent_fds() if self.plotter is not None else ())

    # -- simulating -------------------------------------------------------------------------------------
    def simulate(self, progress: bool, stop: StopRequest | None) -> _Simulated:
        """Create the units and the algorithm, and execute it (recorded and monitored)."""
        plan, sim = self.plan, self.sc.simulation
        bar = None
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=sim.n_steps, unit="step", desc=self.sc.name, file=sys.stderr,
                       mininterval=0.5, disable=None)
        units = plan.create_units(self.log)
        algorithm = plan.create_algorithm(units)
        recorder = Recorder(algorithm, plan.recorded, sim.n_steps, spill_dir=self.folder, storage=self.storage)
        monitor = Monitor(algorithm, plan.limits)
        started = time.strftime("%Y-%m-%dT%H:%M:%S%z")
        csv_process = self.csv_process

        def tick(k: int) -> None:
            if bar is not None:
                bar.update(k - bar.n)
            if csv_process is not None:
                csv_process.rows(recorder.count)

        controls = RunControls(progress=tick, stop_request=stop, after_initialization=self._inputs_unchanged)
        result = execute(algorithm, sim.start_time, sim.stop_time, sim.step, [recorder, monitor],
                         executor=sim.executor, controls=controls)
        if bar is not None:
            bar.close()
        return _Simulated(result, recorder, units, started)

    def _inputs_unchanged(self) -> None:
        """The units have read their FMUs and data: it must be what was checked."""
        changed = self.plan.changed_inputs()
        if changed:
            raise SimulationError("input changed between the checks and the units' initialization: "
                                  + "; ".join(changed), time=self.sc.simulation.start_time)

    # -- writing ------------------------------------------------------------------------------------------
    def _save(self, name: str, action: Callable[[], object]) -> bool:
        """Run a write; an OSError is recorded (naming the file) instead of raised."""
        try:
            action()
        except OSError as exc:
            self.write_errors.append(f"could not write {self.folder / name}: {exc.strerror or exc}")
            return False
        return True

    def _start_writing(self, recorder: Recorder) -> None:
        """The last rows to the CSV process, the figures started; results and figures written here where no
        process writes them."""
        folder, plotter, output = self.folder, self.plotter, self.output
        if self.csv_process is not None:
            self.csv_process.finish(recorder.count)  # the last rows: the file is in place when wait() returns
        if plotter is not None and recorder.count <= 1:
            plotter.cancel()
        elif plotter is not None:
            plotter.draw(recorder.count)  # drawn while the summary and the manifest are made (and the CSV finished)
        if self.csv_process is None and self.results_file:
            self._save(f"timeseries.{output[1]}", lambda: write_results(folder, recorder, *output))
        if self.plots and plotter is None and recorder.count > 1:
            self._save("plots (*.png)", lambda: _plot_inline(recorder, self.plan, folder, self.described, self.files))

    def _summary(self, result: ExecutionResult, recorder: Recorder, run: str | None) -> dict[str, Any]:
        plan, sc, output = self.plan, self.sc, self.output
        summary: dict[str, Any] = {
            "scenario": sc.name,
            "caption": caption(plan.report, self.described, sc.name),
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
            "unit_warnings": self.log.warnings,
            "results_file": {"file": f"timeseries.{output[1]}", "every_nth_step": output[0],
                             "rows": rows_written(recorder.count, output[0])} if self.results_file else
            {"file": None, "every_nth_step": output[0], "rows": 0},
        }
        summary |= report_summary(recorder, plan.report, plan.report_hook, self.described, set(summary))
        return summary

    def _manifest(self, result: ExecutionResult, run: str | None, started: str) -> dict[str, Any]:
        plan = self.plan
        return {
            "complete": result.complete,
            "status": result.status,
            "run_id": run,
            "started": started,
            "command": sys.argv,
            **({"provenance": plan.provenance} if plan.provenance else {}),
            "scenario_file": str(plan.loaded.path),
            "scenario": _plain(plan.loaded.raw),
            # hashed when checked, and the same after the units read them (_inputs_unchanged): what the run played
            "fmus": {name: {"path": str(p), "sha256": _checked_hash(plan, p)} for name, p in plan.fmu_paths.items()},
            "data_files": {key: {"path": str(p), "sha256": _checked_hash(plan, p)}
                           for key, p in plan.data_files.items()},
            "python": platform.python_version(),
            "platform": platform.platform(),
            "packages": package_versions(),
            "unit_messages": self.log.messages[-200:],
        }

    def write(self, done: _Simulated) -> RunOutcome:
        """Write the results, the manifest and the summary, in that order.

        A write failure after the simulation (disk full, folder removed, ...) must never leave
        a summary that says complete: the run is reported failed, naming the file. The manifest
        is written before the summary, and the summary last, so summary.json is either absent
        or tells the truth; every file is still attempted so the failure is recorded if possible.
        """
        result, recorder, folder = done.result, done.recorder, self.folder
        run_error = [str(result.error)] if result.error else []
        self._start_writing(recorder)
        run = run_id(folder)
        summary = self._summary(result, recorder, run)
        manifest = self._manifest(result, run, done.started)

        def mark_failed() -> None:
            nonlocal result
            result = replace(result, status="failed", error=SimulationError("; ".join(self.write_errors + run_error)))
            for doc in (summary, manifest):
                doc.update(complete=False, status=result.status)
            summary["error"] = str(result.error)

        if self.csv_process is not None:
            self._save("timeseries.csv", self.csv_process.wait)
        if self.plotter is not None and recorder.count > 1:
            self._save("plots (*.png)", self.plotter.wait)
        if self.write_errors:
            mark_failed()
        if not self._save("manifest.json", lambda: write_json(folder / "manifest.json", manifest)):
            mark_failed()
        if not self._save("summary.json", lambda: write_summary(folder / "summary.json", summary)):
            mark_failed()
            self._save("manifest.json", lambda: write_json(folder / "manifest.json", manifest))  # best effort
        return RunOutcome(folder, result, summary, recorder, done.units, list(self.log.errors))


def run_plan(
    plan: SystemPlan,
    out: Path | None = None,
    plots: bool = True,
    progress: bool = False,
    stop: StopRequest | None = None,
    figure_files: FigureFiles | None = None,
    results_file: bool = True,
) -> RunOutcome:
    """Execute a checked plan and write its run folder (partial results if it fails or is stopped).

    ``results_file=False``: no ``timeseries.*`` is written (``summary.json``'s ``results_file.file`` is null); every
    step is still recorded in :attr:`RunOutcome.recorder`, and the summary's peaks come from it as always. For a
    caller that computes what it needs from the recorder (the studies' jobs) and keeps no time series.

    ``figure_files`` says how the figures are written (PNG resolution, SVG or PDF beside it; default: PNG at
    :data:`~orchestration.master.report.RUN_DPI`); a bad value is a ``ValueError`` before anything is written.

    The units' messages go to the ``mre_cosim.units`` logger (:data:`~orchestration.master.fmi_status.UNIT_LOGGER`)
    as ``[unit] status: message``: a unit's first :data:`WARNINGS_SHOWN` warnings at WARNING, later
    ones at DEBUG, discard, error and fatal at ERROR; each record carries ``unit`` and
    ``fmi_status`` attributes. Nothing is printed unless the caller attaches a handler (the
    command-line tools do). ``progress`` draws a progress bar on stderr.
    """
    files = figure_files or FigureFiles()
    problem = files.problem()
    if problem:
        raise ValueError(f"figure_files: {problem}")
    run = _PlanRun(plan, out, plots, files, results_file)  # the folder claimed, the CSV and figure processes forked
    return run.write(run.simulate(progress, stop))
