"""The case study behind ``python orchestration/study.py scenarios/case_study.yaml``.

Every record x strategy runs as a co-simulation through the master, on the Dask batch pool
(:mod:`orchestration.batch.pool`: a local cluster, or ``--scheduler ADDRESS``), each in
a child process of a worker; the current sweeps and Radau references run in the workers.
The study folder gets ``peaks.csv``, ``indices.csv``, ``sweep.csv``, ``reference.csv``,
``figures/``, ``report.md``, ``report.html``, ``study.json``, the run folders (``runs/``,
sent back by the workers), the jobs' output (``logs/``) and every job's result under its
content key (``jobs/``). A study folder is never overwritten; every file is written
atomically. ``--resume DIR`` finishes an interrupted study (only the jobs whose results are
missing run); ``--report DIR`` regenerates the tables, figures and report from its data.

The monolithic Radau references of the passive runs (the coupling-error check, ``reference.csv``)
do not change between studies of the same inputs and code, and cost three quarters of the study:
by default a study takes them from the user's cache of results (``$MRE_COSIM_CACHE/results``,
keyed by content like ``jobs/``) and computes none; ``--verify`` computes the missing ones (and
caches them for every later study, whatever its folder).

Exit codes: 0 every job succeeded; 1 some jobs failed or the study was interrupted (the
report lists them; the other results are complete); 2 configuration error or no usable
Dask cluster (nothing written).
"""

from __future__ import annotations

import argparse
import dataclasses
import shlex
import sys
from pathlib import Path
from typing import Any

from mre_common.guard import invoked_as
from orchestration.batch.jobs import write_run_files
from orchestration.batch.pool import BatchPool, BatchUnavailable, JobResult, ProgressBar, scheduler_address
from orchestration.batch.portable import PortablePlan, file_bytes
from orchestration.batch.store import ResultStore, StoredResult, check_folder, open_for_resume
from orchestration.building_studies.gains_file import read_gains
from orchestration.building_studies.in_process_model import NotMonolithic, monolithic_problem
from orchestration.building_studies.pool_arguments import add_pool_arguments
from orchestration.building_studies.run_settings import run_overrides
from orchestration.building_studies.study_file import key_files
from orchestration.case_study import case_jobs
from orchestration.case_study.case_config import GAIN_SETS, LoadedStudy, StudySpec, load_study, variant_strategies
from orchestration.case_study.case_figures import STUDY_DPI
from orchestration.case_study.case_jobs import (
    BENCHMARK_OUTPUTS_OVERRIDE,
    OUTPUTS_OVERRIDE,
    CosimResult,
    ReferenceInputs,
    SweepInputs,
    cosim_job,
    reference_job,
    sweep_job,
)
from orchestration.case_study.case_plan import (
    PlannedJob,
    number_inputs,
    plan_cosim,
    plan_job,
    prepare,
    run_strategy_overrides,
)
from orchestration.case_study.case_records import (
    CaseStudyRecord,
    PreparedStudy,
    ReferenceOutcome,
    RunEntry,
    SweepOutcome,
    utc_now,
)
from orchestration.case_study.case_report import read_study, write_outputs
from orchestration.case_study.robustness_plan import VariantPlanner, variants
from orchestration.case_study.run_numbers import RunFileError
from orchestration.engine_hooks import require_kind
from orchestration.figure_options import add_figure_arguments, figure_files
from orchestration.master.errors import ScenarioError
from orchestration.master.figure_files import PNG_ONLY, FigureFiles
from orchestration.master.runfolder import RunFolderExists, new_run_folder, write_json
from orchestration.provenance import provenance


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """Command-line arguments."""
    parser = argparse.ArgumentParser(prog=invoked_as("study.py"),
                                     description="Run a case study (records x strategies).")
    parser.add_argument("study", type=Path, nargs="?", help="study YAML file (scenarios/case_study.yaml)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a study key, e.g. --set 'overrides=[simulation.stop_time=5]' or "
                             "--set 'strategies=[passive-off, sosm]'")
    parser.add_argument("--out", type=Path, help="study folder to create (must not exist or be empty)")
    add_pool_arguments(parser)
    parser.add_argument("--verify", action="store_true",
                        help="compute the Radau references of the passive runs that are not cached yet (by default "
                             "only cached ones are reported: they do not change between studies)")
    parser.add_argument("--verify-step", action="store_true",
                        help="run every co-simulation again with the plant's step halved and the controller's period "
                             "fixed: each criterion's change goes into criteria.csv and the report, a verdict closer "
                             "than it is a tie, a run whose peaks move more than 1 %% is not converged (invalid)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    add_figure_arguments(parser, default_note=str(STUDY_DPI))
    parser.add_argument("--report", type=Path, metavar="DIR", help="regenerate the report of a study folder")
    parser.add_argument("--resume", type=Path, metavar="DIR",
                        help="finish an interrupted study folder: compute only the jobs whose results are missing")
    parser.add_argument("--base-sensitivity", action="store_true",
                        help="instead of the study: its comparisons for base-floor variants (m_b, k_b, c_b), "
                             "in-process, on a window of each record (orchestration/case_study/base_sensitivity.py)")
    parser.add_argument("--window", type=float, default=None, metavar="S",
                        help="--base-sensitivity: seconds of each record (default 40)")
    args = parser.parse_args(argv)
    if args.base_sensitivity and args.study is None:
        parser.error("--base-sensitivity needs a study file")
    if sum(x is not None for x in (args.study, args.report, args.resume)) != 1:
        parser.error("give a study file, or --report DIR, or --resume DIR")
    args.figure_files = figure_files(args)
    return args


def open_pool(args: argparse.Namespace, workers: int | None, max_worker_deaths: int) -> BatchPool:
    """The pool the arguments ask for, started; BatchUnavailable or ValueError if it cannot be had."""
    if args.workers is not None and args.workers < 1:
        raise ValueError("--workers must be at least 1")
    pool = BatchPool(scheduler_address(args.scheduler), args.workers if args.workers is not None else workers,
                     max_worker_deaths=max_worker_deaths, preload=(case_jobs.__name__,))
    pool.start()
    return pool


def new_record(study: LoadedStudy, prepared: PreparedStudy, pool: BatchPool, command: list[str],
               resumed: CaseStudyRecord | None) -> CaseStudyRecord:
    """The study's record as it starts (``resumed``: the study.json of an earlier run of the folder)."""
    spec = study.spec
    record = CaseStudyRecord(
        name=spec.name, description=spec.description, study_file=str(study.path), started=utc_now(),
        config={**spec.model_dump(), "sweep_currents": spec.sweep.currents(spec.i_max)},
        strategies=list(spec.strategies), records=dict(prepared.records), run_overrides=list(run_overrides(spec)),
        gains=prepared.gains, gains_file=str(study.gains_path) if prepared.gains else None,
        gain_sets=dict(prepared.gain_sets), gains_files={s: str(study.gain_set_path(s)) for s in prepared.gain_sets},
        provenance={**provenance(), "command": command, "algorithms": prepared.algorithms, "step_s": prepared.step},
        batch={"scheduler": pool.scheduler, "workers": pool.n_workers},
        strategy_flags={s: study.strategy(s).flags() for s in spec.strategies})
    if resumed is not None:
        record.started = resumed.started
        record.resumed = [*(resumed.resumed or []), utc_now()]
    return record


def shared_store() -> ResultStore | None:
    """The results kept across studies (``$MRE_COSIM_CACHE/results/jobs``, by content key), or None if no cache."""
    from mre_common.c_compile import NoCacheFolder, cache_dir
    from orchestration.batch.store import open_shared_store

    try:
        return open_shared_store(cache_dir() / "results")  # private, verified; a damaged entry computed again
    except NoCacheFolder:
        return None


def count_jobs(study: LoadedStudy, verify: bool = True, verify_step: bool = False) -> int:
    """Jobs of a study: sweeps, co-simulations (twice with ``verify_step``) and (``verify``) references."""
    spec = study.spec
    n = len(spec.records)
    references = len(reference_strategies(study)) * spec.reference.enabled * verify
    n_variants = len(spec.robustness.variant_names()) if spec.robustness is not None else 0
    return (n * study.needs_sweep + n * len(spec.strategies) * (1 + verify_step)
            + n * len(variant_strategies(spec)) * n_variants + n * references)


def reference_strategies(study: LoadedStudy) -> list[str]:
    """The listed strategies whose constant current the Radau reference checks (``radau_reference: true``)."""
    return [s for s in study.spec.strategies if study.strategy(s).entry.radau_reference]


class JobRunner:
    """Runs a study's jobs on the pool: stored results reused, each new result stored, run folders written."""

    def __init__(self, folder: Path, record: CaseStudyRecord, spec: StudySpec, pool: BatchPool, bar: ProgressBar
                 ) -> None:
        self.folder, self.record, self.spec, self.pool, self.bar = folder, record, spec, pool, bar
        self.store = ResultStore(folder)
        self.collected: dict[str, JobResult] = {}  # label -> every finished job, also when interrupted
        self.labels: dict[str, str] = {}  # content key -> job label (record/strategy[/reference])
        self.shared: dict[str, Any] = {}  # SHA-256 -> handle of the file's bytes on the cluster
        self.cache_for: dict[str, ResultStore] = {}  # content key -> the store across studies its result goes to
        self.untracked: set[str] = set()  # content keys the progress bar does not count

    def files_of(self, pp: PortablePlan) -> dict[str, Any]:
        """The handles of a plan's files on the cluster (each file shared once)."""
        for sha, path in file_bytes([pp]).items():
            if sha not in self.shared:
                self.shared[sha] = self.pool.share(path.read_bytes())
        return {sha: self.shared[sha] for sha in pp.shas}

    def done(self, res: JobResult, stored: bool = False) -> None:
        """A job ended (or its stored result was found): files, log, store, progress, messages."""
        content_key = res.key
        label = self.labels.get(content_key, content_key)
        res = dataclasses.replace(res, key=label)
        cosim = CosimResult.from_json(res.value) if res.ok and CosimResult.describes(res.value) else None
        if cosim is not None and cosim.files is not None:
            write_run_files(self.folder / self.record.run(label).folder, cosim.files)
            cosim = dataclasses.replace(cosim, files=None)
            res = dataclasses.replace(res, value=cosim.to_json())
        if res.output or res.details:
            (self.folder / "logs" / f"{label.replace('/', '-')}.log").write_text(res.output + res.details)
        if not stored:
            result = StoredResult(label, res.ok, res.status, res.value, res.error, res.wall_time_s, res.worker)
            self.store.put(content_key, result.to_json())
            if res.ok and content_key in self.cache_for:
                self.cache_for[content_key].put(content_key, result.to_json())
        self.collected[label] = res
        if content_key not in self.untracked:
            self.bar.done(res.ok and not (cosim is not None and not cosim.complete))
        if not res.ok:
            self.bar.write(f"FAILED {label}: {res.error}")
        elif cosim is not None:
            self.warn(label, cosim)

    def warn(self, label: str, v: CosimResult) -> None:
        """Messages on a co-simulation's end: incomplete, or beyond the isolator's identified range."""
        spec = self.spec
        if not v.complete:
            self.bar.write(f"FAILED {label}: run {v.status}: {v.error}")
        if (v.time_beyond_identified_range_s or 0) > 0:
            limit = (f"; beyond the {1e3 * spec.x_limit:g} mm device limit for "
                     f"{v.time_beyond_device_limit_s:.3g} s" if v.time_beyond_device_limit_s else "")
            self.bar.write(f"warning: {label}: base displacement {1e3 * (v.peak_base_displacement_m or 0):.2f} mm, "
                           f"beyond the identified ±{1e3 * spec.x_identified:g} mm for "
                           f"{v.time_beyond_identified_range_s:.3g} s (isolator model extrapolated){limit}")

    def run(self, fn: Any, jobs: list[PlannedJob], isolate: bool, cache: ResultStore | None = None,
            compute: bool = True) -> list[str]:
        """Jobs (label, key, plan, inputs): stored results reused, the others run on the pool.

        ``cache``: a store kept across studies, looked up after the study's own (a result found there is
        copied into the study's ``jobs/``, marked ``reused_from``) and given every new successful result.
        ``compute=False``: jobs found in neither store are not run; returns their labels.
        """
        todo, skipped = [], []
        for label, key, pp, extra in jobs:
            self.labels[key] = label
            old = self.store.get(key)
            if old is None and cache is not None:
                old = cache.get(key, strict=False)  # the cache across studies: a damaged entry is computed again
                if old is not None and old.get("ok"):
                    self.store.put(key, {**old, "label": label, "reused_from": str(cache.folder)})
                else:
                    old = None
            if cache is not None:
                self.cache_for[key] = cache
            if not compute:
                self.untracked.add(key)
            if old is not None:
                kept = StoredResult.from_json(old)
                self.done(JobResult(key, kept.ok, kept.value, kept.error, "", kept.wall_time_s or 0.0, kept.status,
                                    kept.worker), stored=True)
            elif compute:
                todo.append((key, {"plan": pp, "files": self.files_of(pp), **extra}))
            else:
                skipped.append(label)
        if todo:
            self.record.jobs_computed += len(todo)
            self.pool.map(fn, [p for _, p in todo], [k for k, _ in todo], isolate=isolate,
                          timeout_s=self.spec.timeout_s, on_done=self.done)
        return skipped


def run_sweeps(study: LoadedStudy, runner: JobRunner) -> None:
    """The constant-current sweep of every record (for the strategies that take its best current): into the
    record's sweep and best current."""
    spec, record = study.spec, runner.record
    extra = SweepInputs(spec.sweep.currents(spec.i_max), spec.objective.model_dump()).to_json()
    base = run_overrides(spec)
    jobs = [plan_job(study, f"{r}/sweep", "sweep", base, extra) for r in record.records]
    # in the worker for the in-process physics; in a child process when a plant's sweep co-simulates its FMUs
    runner.run(sweep_job, jobs, isolate=any(monolithic_problem(pp.plan) is not None for _, _, pp, _ in jobs))
    for r in record.records:
        res = runner.collected.get(f"{r}/sweep")
        if res is not None:
            sweep = record.sweep[r] = SweepOutcome.from_json({"ok": res.ok, "error": res.error, **(res.value or {})})
            if sweep.ok and sweep.best_current_A is not None:
                record.best_current[r] = sweep.best_current_A


def plan_run(study: LoadedStudy, runner: JobRunner, entry: RunEntry, outputs: str,
             planner: VariantPlanner | None = None) -> PlannedJob | None:
    """One record x strategy co-simulation, nominal or (``planner``) under ``entry.variant``: its entry filled in
    (current, overrides) and its job planned; None if it cannot run (the sweep it needs failed: the entry and
    the record say so). The strategies keep their nominal design (parameters, gains, the nominal sweep's current)."""
    spec, record = study.spec, runner.record
    r, s = entry.record, entry.strategy
    if study.strategy(s).needs_sweep and r not in record.best_current:
        sweep = record.sweep.get(r)
        entry.error = (f"current sweep failed: {sweep.error if sweep else None}" if entry.variant is None
                       else "current sweep failed")
        runner.done(JobResult(entry.key, False, error=entry.error, status="failed"), stored=True)
        return None
    strategy, best = study.strategy(s), record.best_current.get(r)
    doc = record.gain_sets.get(strategy.entry.gains or "")
    extra = run_strategy_overrides(study, s, study.scenario_path(r), spec.i_max, doc["gains"] if doc else None, best)
    if planner is not None and entry.variant is not None:
        extra = (*extra, *planner.overrides(r, entry.variant, extra))
    entry.current_A = strategy.constant_current(spec.i_max, best)
    entry.overrides = list(extra)
    numbers = number_inputs(study, record, entry, figures=entry.variant is None)
    return plan_cosim(study, entry.key, (*strategy.common(run_overrides(spec)), *extra), strategy.recorded(outputs),
                      numbers)


def longest_first(record: CaseStudyRecord) -> list[str]:
    """The study's records, longest first (the pool starts the longest jobs first)."""
    return sorted(record.records, key=lambda r: -record.records[r].stop_time_s)


def plan_runs(study: LoadedStudy, runner: JobRunner) -> tuple[list[PlannedJob], list[PlannedJob]]:
    """Every co-simulation (its run entry added to the record) and every Radau reference, longest record first."""
    spec, record = study.spec, runner.record
    outputs = OUTPUTS_OVERRIDE if spec.benchmark is None else BENCHMARK_OUTPUTS_OVERRIDE
    runs, references = [], []
    for r in longest_first(record):
        for s in spec.strategies:
            entry = RunEntry(f"{r}/{s}", r, s, f"runs/{r}-{s}")
            record.runs.append(entry)
            if (job := plan_run(study, runner, entry, outputs)) is not None:
                runs.append(job)
        if spec.reference.enabled:
            for s in reference_strategies(study):
                current = study.strategy(s).constant_current(spec.i_max, None)
                if current is not None:  # checked when the study was read (case_config.reference_problems)
                    inputs = ReferenceInputs(current, spec.reference.rtol)
                    references.append(plan_job(study, f"{r}/{s}/reference", "reference", run_overrides(spec),
                                               inputs.to_json()))
    return runs, references


def plan_variant_runs(study: LoadedStudy, runner: JobRunner) -> list[PlannedJob]:
    """Every record x strategy under every robustness variant (run entries added to the record), longest record
    first."""
    spec, record = study.spec, runner.record
    if not variants(study):
        return []
    if spec.robustness is not None and spec.robustness.plant_samples is not None:
        from orchestration.case_study.plant_uncertainty import write_design

        write_design(runner.folder, study)
    planner = VariantPlanner(study, run_overrides(spec))
    jobs = []
    for r in longest_first(record):
        for v in variants(study):
            for s in variant_strategies(spec):
                entry = RunEntry(f"{r}/{s}/{v}", r, s, f"runs/{r}-{s}--{v}", variant=v)
                record.variant_runs.append(entry)
                if (job := plan_run(study, runner, entry, BENCHMARK_OUTPUTS_OVERRIDE, planner)) is not None:
                    jobs.append(job)
    return jobs


def plan_half_step_runs(study: LoadedStudy, runner: JobRunner, runs: list[PlannedJob]) -> list[PlannedJob]:
    """``--verify-step``: every co-simulation again with the plant's step halved and the controller's period pinned
    (:func:`orchestration.step_check.half_step_overrides`), its entry ``record/strategy/half-step`` added."""
    from orchestration.step_check import half_step_overrides

    record, jobs = runner.record, []
    for label, _key, pp, _extra in runs:
        entry = record.run(label)
        extra, _pinned = half_step_overrides(pp.plan)
        half = RunEntry(f"{label}/half-step", entry.record, entry.strategy, f"{entry.folder}--half-step",
                        current_A=entry.current_A, overrides=[*(entry.overrides or []), *extra])
        record.half_step_runs.append(half)
        outputs = OUTPUTS_OVERRIDE if study.spec.benchmark is None else BENCHMARK_OUTPUTS_OVERRIDE
        strategy = study.strategy(entry.strategy)
        try:
            jobs.append(plan_cosim(study, half.key, (*strategy.common(run_overrides(study.spec)),
                                                     *(entry.overrides or []), *extra), strategy.recorded(outputs),
                                   number_inputs(study, record, half, figures=False)))
        except ScenarioError as exc:  # e.g. a controller that cannot step at its own rate: this check only fails
            half.error = f"the half-step run cannot be made: {exc}"
            runner.done(JobResult(half.key, False, error=half.error, status="failed"), stored=True)
    return jobs


def collect(record: CaseStudyRecord, results: dict[str, JobResult]) -> None:
    """The finished jobs into the run entries and references (a run without a result: not run)."""
    for entry in [*record.runs, *record.variant_runs, *record.half_step_runs]:
        res = results.get(entry.key)
        if res is None:
            entry.error = entry.error or "not run (interrupted)"
        elif not res.ok:
            entry.error = res.error
        else:
            v = CosimResult.from_json(res.value)
            entry.ok = v.complete
            entry.error = None if v.complete else f"run {v.status}: {v.error}"
            entry.status, entry.wall_time_s, entry.unit_warnings = v.status, v.wall_time_s, v.unit_warnings
    for r in record.records:  # in the study's order (not the order the jobs ended in): reference.csv is stable
        for s in record.strategies:
            res = results.get(f"{r}/{s}/reference")
            if res is not None:
                record.reference[f"{r}/{s}"] = ReferenceOutcome(ok=res.ok, error=res.error, value=res.value)


@dataclasses.dataclass(frozen=True)
class RunOptions:
    """How a study runs: its command line (for the record), a progress bar, ``--verify``, ``--verify-step``."""

    command: list[str]
    progress: bool = True
    verify: bool = False  # compute the Radau references the cache lacks
    verify_step: bool = False  # every co-simulation again at half the plant's step
    figures: FigureFiles = PNG_ONLY  # the report's figures: PNG resolution, vector formats beside


def run_study(study: LoadedStudy, folder: Path, prepared: PreparedStudy, pool: BatchPool, options: RunOptions,
              resumed: CaseStudyRecord | None = None) -> int:
    """Run every job of a prepared study into ``folder`` on ``pool``; returns the exit code.

    Each job's result is stored under its content key (:class:`ResultStore`); with ``resumed``
    (the study.json of an earlier, unfinished run of this folder) stored results are reused.
    The Radau references come from the cache across studies (:func:`shared_store`); ``options.verify``
    computes the ones it lacks.
    """
    spec = study.spec
    command, progress, verify, verify_step = options.command, options.progress, options.verify, options.verify_step
    record = new_record(study, prepared, pool, command, resumed)
    (folder / "logs").mkdir(exist_ok=True)
    (folder / "runs").mkdir(exist_ok=True)
    write_json(folder / "study.json", record.to_json())
    bar = ProgressBar(count_jobs(study, verify, verify_step), spec.name, enabled=progress)
    bar.write(pool.describe())
    runner = JobRunner(folder, record, spec, pool, bar)
    interrupted = False
    try:
        if study.needs_sweep:
            run_sweeps(study, runner)
        runs, references = plan_runs(study, runner)
        half = plan_half_step_runs(study, runner, runs) if verify_step else []
        runner.run(cosim_job, [*runs, *plan_variant_runs(study, runner), *half], isolate=True)
        skipped = runner.run(reference_job, references, isolate=False, cache=shared_store(), compute=verify)
        record.provenance["references_not_computed"] = skipped  # neither cached nor asked for (--verify)
    except KeyboardInterrupt:
        interrupted = True
        bar.write("interrupted: writing the report of the finished runs")
    collect(record, runner.collected)
    record.finished = utc_now()
    record.interrupted = interrupted
    write_json(folder / "study.json", record.to_json())
    bar.close()
    try:
        write_outputs(folder, record, options.figures)
    except RunFileError as exc:  # a resumed folder's run file damaged by hand: its runs and jobs/ are kept
        print(f"error: the report could not be written: {exc}", file=sys.stderr)
        return 1
    failed = [e.key for e in [*record.runs, *record.variant_runs, *record.half_step_runs] if not e.ok]
    failed += [k for k, v in {**record.sweep, **record.reference}.items() if not v.ok]
    print(f"study {'interrupted' if interrupted else 'done'}: {folder} ({len(failed)} failed)")
    return 1 if failed or interrupted else 0


def resumed_study(folder: Path) -> tuple[LoadedStudy, CaseStudyRecord]:
    """The study of an existing study folder, as it was configured; ScenarioError if unusable."""
    try:
        data = read_study(folder)
        config = {k: v for k, v in data.config.items() if k != "sweep_currents"}
        spec = StudySpec.model_validate(config)
        return LoadedStudy(spec, Path(data.study_file), config, key_files(Path(data.study_file))), data
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise ScenarioError(f"{folder}: not a study folder that can be resumed ({type(exc).__name__}: {exc})"
                            ) from None


def _base_sensitivity(args: argparse.Namespace, study: LoadedStudy, argv: list[str]) -> int:
    """``--base-sensitivity``: the study's comparisons for base-floor variants into a new folder."""
    from orchestration.case_study.base_sensitivity import WINDOW_S, run_sensitivity, write_sensitivity

    window = WINDOW_S if args.window is None else args.window
    if not window > 0:
        raise ValueError(f"--window must be positive, got {window}")
    for gain_set in GAIN_SETS:
        read_gains(study.gain_set_path(gain_set))  # ScenarioError before anything is written
    pool = open_pool(args, study.spec.workers, study.spec.max_worker_deaths)
    with pool:
        try:
            folder = new_run_folder(Path(study.spec.output), f"{study.spec.name}-base-sensitivity", args.out)
        except RunFolderExists as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        data = run_sensitivity(study, pool, window)
    write_sensitivity(folder, data, "python orchestration/study.py " + shlex.join(argv))
    print(f"base-floor sensitivity done: {folder / 'base_sensitivity.md'} ({data['wall_time_s']:.0f} s)")
    return 0


def main(argv: list[str] | None = None) -> int:
    """CLI entry point; returns the exit code."""
    args = parse_args(argv)
    if args.report is not None:
        try:
            data = read_study(args.report)
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
            print(f"error: cannot read {args.report / 'study.json'}: {type(exc).__name__}: {exc}", file=sys.stderr)
            return 2
        try:
            write_outputs(args.report, data, args.figure_files)
        except RunFileError as exc:  # a run's numbers or figure series edited or damaged: nothing was written
            print(f"error: {exc}; nothing written", file=sys.stderr)
            return 2
        except OSError as exc:
            print(f"error: cannot write the report into {args.report}: {exc.strerror or exc}"
                  f"{f' ({exc.filename})' if exc.filename else ''}", file=sys.stderr)
            return 2
        except (ValueError, KeyError, TypeError, IndexError, AttributeError) as exc:  # study.json edited by hand
            print(f"error: {args.report / 'study.json'} is not what study.py wrote: {type(exc).__name__}: {exc}",
                  file=sys.stderr)
            return 2
        print(f"report regenerated: {args.report / 'report.md'}")
        return 0
    resumed = None
    claim = None
    try:
        if args.resume is not None:
            study, resumed = resumed_study(args.resume)
            _store, claim = open_for_resume(args.resume, "study.json", "study.py")  # StoreError: exit 2
        else:
            try:
                study = load_study(args.study, tuple(args.overrides))
            except ScenarioError:
                require_kind(args.study, "study")  # a run scenario: name run.py instead
                raise
        if args.resume is None:  # names and paths the file system cannot hold: exit 2 before any work
            check_folder(study.spec.name, Path(study.spec.output), args.out, study.lines, study.path)
        if args.base_sensitivity:
            return _base_sensitivity(args, study, sys.argv[1:] if argv is None else argv)
        prepared = prepare(study)
        pool = open_pool(args, study.spec.workers, study.spec.max_worker_deaths)
    except ScenarioError as exc:
        print(exc.report(), file=sys.stderr)
        return 2
    except (NotMonolithic, BatchUnavailable, ValueError) as exc:  # StoreError is a ValueError
        if claim is not None:
            claim.unlink(missing_ok=True)
        print(f"error: {exc}", file=sys.stderr)
        return 2
    try:
        folder = args.resume if args.resume is not None else new_run_folder(Path(study.spec.output),
                                                                             study.spec.name, args.out)
    except RunFolderExists as exc:
        pool.close()
        print(f"error: {exc}", file=sys.stderr)
        return 2

    # SIGTERM raises KeyboardInterrupt here already (mre_common.guard.guarded): handled as Ctrl-C, report written
    try:
        options = RunOptions([sys.executable, *sys.argv], progress=not args.quiet, verify=args.verify,
                             verify_step=args.verify_step or bool(resumed and resumed.half_step_runs),
                             figures=args.figure_files)
        return run_study(study, folder, prepared, pool, options, resumed)
    finally:
        pool.close()
        if claim is not None:
            claim.unlink(missing_ok=True)
