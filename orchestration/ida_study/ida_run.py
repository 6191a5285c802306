"""Incremental dynamic analysis and fragility: ``python orchestration/ida.py scenarios/ida.yaml``.

Every component of a record suite (:mod:`orchestration.ida_study.suites`), cut to its
strong-motion window and played at the study's time scale, is scaled to each level of an
intensity ladder (PGA, or Sa at the isolated period: :mod:`orchestration.ida_study.intensity`)
and run as a co-simulation through the master for each strategy, on the Dask batch pool
(:mod:`orchestration.batch.pool`), each run in a child process of a worker. The study
folder gets:

| file | content |
|---|---|
| ``results.parquet``, ``.csv`` | a row per run: record, component, intensity, strategy, peaks, indices, status, time |
| ``fragility.csv`` | per limit state and strategy: stripes, the lognormal fit (median, beta, its interval) |
| ``collapse.csv`` | with a ``collapse`` limit state: S_CT per strategy, its margin (FEMA P695's CMR with S_MT) |
| ``figures/`` | ``ida_curves.png`` (per strategy), ``fragility.png`` (per limit state), ``spectra.png`` (spectra) |
| ``report.md``, ``report.html`` | settings, fits, a verdict per limit state, failed runs |
| ``ida.json`` | configuration, suite, windows, period, intensities, provenance, batch pool |
| ``records/`` | the windowed components the runs played (``time_s,accel_g``) |
| ``jobs/`` | each finished run's result under its content key (``--resume``) |

Exit codes: 0 every run ended (complete, or stopped by the scenario's divergence limit, or
collapsed: the OpenSees building did not converge; both count as exceeding every limit
state); 1 some runs failed or were lost, or the study was interrupted (the report says
which; the rest is complete); 2 configuration error, unreachable scheduler (nothing
computed, nothing written).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mre_common.guard import invoked_as
from orchestration.batch.pool import BatchPool, BatchUnavailable, JobResult, ProgressBar, scheduler_address
from orchestration.batch.portable import file_bytes, job_key, plan_content
from orchestration.batch.store import ResultStore, StoreError, check_folder, open_for_resume
from orchestration.building_studies.pool_arguments import add_pool_arguments
from orchestration.building_studies.study_file import key_files
from orchestration.figure_options import add_figure_arguments, figure_files
from orchestration.ida_study import ida_jobs
from orchestration.ida_study.ida_config import IdaSpec, LoadedIda, load_ida
from orchestration.ida_study.ida_figures import IDA_DPI
from orchestration.ida_study.ida_jobs import IdaInputs, ida_job
from orchestration.ida_study.ida_metrics import ENDED, read_rows, result_rows, run_label
from orchestration.ida_study.ida_plan import PreparedIda, RecordComponent, prepare_ida
from orchestration.ida_study.ida_records import ComponentInfo, IdaInfo, RunOutcome, utc_now
from orchestration.ida_study.ida_report import write_outputs
from orchestration.ida_study.intensity import MEASURES
from orchestration.master.errors import Problem, ScenarioError
from orchestration.master.figure_files import PNG_ONLY, FigureFiles
from orchestration.master.runfolder import RunFolderExists, new_run_folder, write_json
from orchestration.provenance import provenance


@dataclass(frozen=True)
class PendingRun:
    """A run whose result is not stored yet: its content key, component, strategy and amplitude scale."""

    key: str
    component: RecordComponent
    strategy: str
    scale: float


def new_info(prepared: PreparedIda, pool: BatchPool, command: list[str], resumed: IdaInfo | None) -> IdaInfo:
    """The study's description as it starts (``resumed``: the ida.json of an earlier run of the folder)."""
    spec = prepared.study.spec
    info = IdaInfo(
        name=spec.name, description=spec.description, study_file=str(prepared.study.path), started=utc_now(),
        config=spec.model_dump(mode="json"), measure=spec.intensity.measure,
        measure_label=MEASURES[spec.intensity.measure], period_s=prepared.period_s,
        strategies={s: list(o) for s, o in prepared.strategies.items()}, masses_kg=prepared.masses,
        gains=prepared.gains, planning_s=prepared.planning_s,
        components=[ComponentInfo(c.rec.id, c.rec.record, c.rec.component, c.rec.source,
                                  (c.window.start, c.window.end), c.stop_time_s, c.im, c.rec.pga_g)
                    for c in prepared.components],
        batch={"scheduler": pool.scheduler, "workers": pool.n_workers, "dashboard": pool.dashboard},
        provenance={**provenance(), "command": command},
        strategy_flags={s: (prepared.named[s].flags() if s in prepared.named else {"label": s})
                        for s in prepared.strategies},
        extra={**({"gains_fig15": prepared.gain_sets["sosm-fig15"]} if "sosm-fig15" in prepared.gain_sets else {}),
               **({"no_controller_i_max": prepared.unlimited} if prepared.unlimited else {})})
    if resumed is not None:
        info.started = resumed.started
        info.resumed = [*(resumed.resumed or []), utc_now()]
    return info


def plan_runs(prepared: PreparedIda, store: ResultStore) -> tuple[list[PendingRun], dict[str, RunOutcome],
                                                                  dict[str, str]]:
    """Every run, longest first: those to compute, the stored results (by label) and {content key: label}."""
    spec = prepared.study.spec
    pending, stored, labels = [], {}, {}
    for c in sorted(prepared.components, key=lambda c: -c.stop_time_s):
        for level in spec.intensity.levels:
            for s in prepared.strategies:
                pp = prepared.plans[(c.rec.id, s)]
                label = run_label(c.rec.id, level, s)
                scale = level / c.im
                inputs = IdaInputs(scale, prepared.masses, prepared.storeys)
                key = job_key("ida", {"job": label, "plan": plan_content(pp), **inputs.to_json()},
                              ida_jobs.CODE_SOURCES)
                labels[key] = label
                old = store.get(key)
                if old is not None:
                    stored[label] = RunOutcome.from_json(old)
                else:
                    pending.append(PendingRun(key, c, s, scale))
    return pending, stored, labels


def payloads(prepared: PreparedIda, pool: BatchPool, pending: list[PendingRun]) -> list[dict[str, Any]]:
    """The jobs' payloads, every file and plan shared once on the pool."""
    plans = {(run.component.rec.id, run.strategy): prepared.plans[(run.component.rec.id, run.strategy)]
             for run in pending}
    files = {sha: pool.share(path.read_bytes()) for sha, path in file_bytes(list(plans.values())).items()}
    shared = {k: pool.share(pp, dedupe=False) for k, pp in plans.items()}
    return [{"plan": shared[(run.component.rec.id, run.strategy)],
             "files": {sha: files[sha] for sha in plans[(run.component.rec.id, run.strategy)].shas},
             **IdaInputs(run.scale, prepared.masses, prepared.storeys).to_json()} for run in pending]


def compute(prepared: PreparedIda, pool: BatchPool, pending: list[PendingRun], labels: dict[str, str],
            store: ResultStore, results: dict[str, RunOutcome], bar: ProgressBar) -> bool:
    """Run the pending runs on the pool, each result stored as it ends; True if interrupted (Ctrl-C)."""

    def done(res: JobResult) -> None:
        outcome = RunOutcome(label=labels[res.key], ok=res.ok, status=res.status, value=res.value, error=res.error,
                             wall_time_s=res.wall_time_s, worker=res.worker)
        store.put(res.key, outcome.to_json())
        results[outcome.label] = outcome
        bar.done(outcome.run_status in ENDED)
        if outcome.run_status not in ENDED:
            bar.write(f"FAILED {outcome.label}: {res.error or res.value.get('error')}")

    try:
        if pending:
            costs = [prepared.plans[(run.component.rec.id, run.strategy)].plan.loaded.scenario.simulation.n_steps
                     for run in pending]
            pool.map(ida_job, payloads(prepared, pool, pending), [run.key for run in pending], isolate=True,
                     timeout_s=prepared.study.spec.timeout_s, on_done=done, costs=costs)
    except KeyboardInterrupt:
        bar.write("interrupted: writing the report of the finished runs")
        return True
    return False


def run_ida(prepared: PreparedIda, folder: Path, pool: BatchPool, progress: bool, command: list[str],
            resumed: IdaInfo | None = None, files: FigureFiles = PNG_ONLY) -> int:
    """Run every run of a prepared study into ``folder`` (its figures as ``files`` says); returns the exit code."""
    spec = prepared.study.spec
    (folder / "records").mkdir(exist_ok=True)
    for c in prepared.components:
        shutil.copyfile(c.csv, folder / "records" / c.csv.name)
    info = new_info(prepared, pool, command, resumed)
    write_json(folder / "ida.json", info.to_json())
    store = ResultStore(folder)
    pending, results, labels = plan_runs(prepared, store)
    total = len(prepared.components) * len(spec.intensity.levels) * len(prepared.strategies)
    bar = ProgressBar(total, spec.name, initial=total - len(pending), enabled=progress)
    bar.write(pool.describe())
    if len(pending) < total:
        bar.write(f"resumed: {total - len(pending)} of {total} runs already stored")
    t0 = time.perf_counter()
    interrupted = compute(prepared, pool, pending, labels, store, results, bar)
    bar.close()
    info.finished = utc_now()
    info.interrupted = interrupted
    info.wall_time_s = time.perf_counter() - t0
    info.runs_computed = sum(1 for run in pending if labels[run.key] in results)
    write_json(folder / "ida.json", info.to_json())
    rows = result_rows(info.components, info.measure, results, list(spec.intensity.levels), list(prepared.strategies),
                       info.uncontrolled)
    write_outputs(folder, info, rows, files)
    bad = [r for r in rows if r["status"] not in ENDED]
    print(f"IDA {'interrupted' if interrupted else 'done'}: {folder} ({len(rows)} runs, {len(bad)} not ended: "
          f"failed, lost or not run; {info.wall_time_s:.0f} s)")
    return 1 if bad or interrupted else 0


# -- command line ---------------------------------------------------------------------------------

def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """Command-line arguments."""
    parser = argparse.ArgumentParser(prog=invoked_as("ida.py"),
                                     description="Incremental dynamic analysis and fragility.")
    parser.add_argument("study", type=Path, nargs="?", help="IDA study YAML file (scenarios/ida.yaml)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a study key (VALUE as YAML), e.g. --set 'intensity.levels=[0.1, 0.2]'")
    parser.add_argument("--out", type=Path, help="study folder to create (must not exist or be empty)")
    add_pool_arguments(parser)
    parser.add_argument("--resume", type=Path, metavar="DIR", help="finish a study folder: compute what is missing")
    parser.add_argument("--report", type=Path, metavar="DIR", help="regenerate tables, figures and report of DIR")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    add_figure_arguments(parser, default_note=str(IDA_DPI))
    args = parser.parse_args(argv)
    if sum(x is not None for x in (args.study, args.report, args.resume)) != 1:
        parser.error("give a study file, or --resume DIR, or --report DIR")
    args.figure_files = figure_files(args)
    return args


def regenerate(folder: Path, files: FigureFiles = PNG_ONLY) -> int:
    """``--report DIR``: tables, figures and report of a study folder again, from its data; the exit code."""
    try:
        info = IdaInfo.from_json(json.loads((folder / "ida.json").read_text()))
        rows = read_rows(folder)
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        print(f"error: cannot read the study folder {folder}: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    try:
        write_outputs(folder, info, rows, files)
    except OSError as exc:
        print(f"error: cannot write the report into {folder}: {exc.strerror or exc}"
              f"{f' ({exc.filename})' if exc.filename else ''}", file=sys.stderr)
        return 2
    except (ValueError, KeyError, TypeError, IndexError, AttributeError) as exc:  # data edited by hand
        print(f"error: the data of {folder} (ida.json, results) is not what ida.py wrote: {type(exc).__name__}: "
              f"{exc}", file=sys.stderr)
        return 2
    print(f"report regenerated: {folder / 'report.md'}")
    return 0


def load(args: argparse.Namespace) -> tuple[PreparedIda, IdaInfo | None]:
    """The study the arguments name (a file, or the folder to resume), prepared; ScenarioError if unusable."""
    resumed = None
    if args.resume is not None:
        try:
            resumed = IdaInfo.from_json(json.loads((args.resume / "ida.json").read_text()))
            study_file = Path(resumed.study_file)
            loaded = LoadedIda(IdaSpec.model_validate(resumed.config), study_file, key_files(study_file))
            problems, raw = [], None
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
            raise ScenarioError(f"{args.resume} is not an IDA study folder that can be resumed: "
                                f"{type(exc).__name__}: {exc}") from None
    else:
        study_file = args.study.resolve()
        loaded, problems, raw = load_ida(study_file, tuple(args.overrides))
    return prepare_ida(study_file, loaded, problems, raw), resumed


def start_pool(args: argparse.Namespace, spec: IdaSpec) -> BatchPool:
    """The batch pool of the IDA's jobs (``--scheduler``, ``--workers``, else the study's); ScenarioError for
    ``--workers`` below 1, BatchUnavailable when no cluster can be had."""
    if args.workers is not None and args.workers < 1:
        raise ScenarioError(Problem("--workers must be at least 1", "", "command line"))
    pool = BatchPool(scheduler_address(args.scheduler), args.workers or spec.workers,
                     max_worker_deaths=spec.max_worker_deaths, preload=(ida_jobs.__name__,))
    pool.start()
    return pool


def main(argv: list[str] | None = None) -> int:
    """CLI entry point; returns the exit code."""
    args = parse_args(argv)
    if args.report is not None:
        return regenerate(args.report, args.figure_files)
    prepared = claim = None
    try:
        prepared, resumed = load(args)
        spec = prepared.study.spec
        if args.resume is not None:
            _store, claim = open_for_resume(args.resume, "ida.json", "ida.py")
        else:  # names and paths the file system cannot hold: exit 2 before any work
            study = prepared.study
            check_folder(spec.name, Path(spec.output), args.out, study.lines, study.path)
        pool = start_pool(args, spec)
    except (ScenarioError, BatchUnavailable, StoreError) as exc:
        if prepared is not None:
            prepared.cleanup()
        if claim is not None:
            claim.unlink(missing_ok=True)
        print(exc.report() if isinstance(exc, ScenarioError) else f"error: {exc} (nothing computed)", file=sys.stderr)
        return 2
    try:
        folder = args.resume if args.resume is not None else new_run_folder(Path(spec.output), spec.name, args.out)
    except RunFolderExists as exc:
        pool.close()
        prepared.cleanup()
        print(f"error: {exc}", file=sys.stderr)
        return 2

    # SIGTERM raises KeyboardInterrupt here already (mre_common.guard.guarded): handled as Ctrl-C, report written
    try:
        return run_ida(prepared, folder, pool, not args.quiet, [sys.executable, *sys.argv], resumed,
                       args.figure_files)
    finally:
        pool.close()
        prepared.cleanup()
        if claim is not None:
            claim.unlink(missing_ok=True)
