"""The case study behind ``python orchestration/study.py scenarios/case_study.yaml``.

Every record x strategy runs as a co-simulation through the master, on the Dask engine
(:mod:`orchestration.studies.engine`: a local cluster, or ``--scheduler ADDRESS``), each in
a child process of a worker; the current sweeps and Radau references run in the workers.
The study folder gets ``peaks.csv``, ``indices.csv``, ``sweep.csv``, ``reference.csv``,
``figures/``, ``report.md``, ``report.html``, ``study.json``, the run folders (``runs/``,
sent back by the workers), the jobs' output (``logs/``) and every job's result under its
content key (``jobs/``). A study folder is never overwritten; every file is written
atomically. ``--resume DIR`` finishes an interrupted study (only the jobs whose results are
missing run); ``--report DIR`` regenerates the tables, figures and report from its data.

Exit codes: 0 every job succeeded; 1 some jobs failed or the study was interrupted (the
report lists them; the other results are complete); 2 configuration error or no usable
Dask cluster (nothing written).
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from pathlib import Path
from typing import Any

from components.physics.shear_building_core import BuildingParams
from orchestration.master.errors import ScenarioError
from orchestration.master.runfolder import RunFolderExists, new_run_folder, write_json
from orchestration.project import plan_scenario, require_kind
from orchestration.provenance import provenance
from orchestration.studies.config import SOSM_STRATEGIES, UNCONTROLLED, LoadedStudy, StudySpec, load_study
from orchestration.studies.engine import Engine, EngineUnavailable, JobResult, StudyBar, scheduler_address
from orchestration.studies.jobs import OUTPUTS_OVERRIDE, cosim_job, reference_job, sweep_job, write_run_files
from orchestration.studies.portable import PortablePlan, file_bytes, job_key, plan_content, portable
from orchestration.studies.report import read_study, write_outputs
from orchestration.studies.store import ResultStore
from orchestration.studies.strategies import strategy_overrides
from orchestration.studies.tuning import NotMonolithic, read_gains, run_overrides, system_setup


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """Command-line arguments."""
    parser = argparse.ArgumentParser(prog="study.py", description="Run a case study (records x strategies).")
    parser.add_argument("study", type=Path, nargs="?", help="study YAML file (scenarios/case_study.yaml)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a study key, e.g. --set 'overrides=[simulation.stop_time=5]' or "
                             "--set 'strategies=[passive-off, sosm]'")
    parser.add_argument("--out", type=Path, help="study folder to create (must not exist or be empty)")
    add_engine_arguments(parser)
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--report", type=Path, metavar="DIR", help="regenerate the report of a study folder")
    parser.add_argument("--resume", type=Path, metavar="DIR",
                        help="finish an interrupted study folder: compute only the jobs whose results are missing")
    parser.add_argument("--base-sensitivity", action="store_true",
                        help="instead of the study: its comparisons for base-floor variants (m_b, k_b, c_b), "
                             "in-process, on a window of each record (orchestration/studies/base_sensitivity.py)")
    parser.add_argument("--window", type=float, default=None, metavar="S",
                        help="--base-sensitivity: seconds of each record (default 40)")
    args = parser.parse_args(argv)
    if args.base_sensitivity and args.study is None:
        parser.error("--base-sensitivity needs a study file")
    if sum(x is not None for x in (args.study, args.report, args.resume)) != 1:
        parser.error("give a study file, or --report DIR, or --resume DIR")
    return args


def add_engine_arguments(parser: argparse.ArgumentParser) -> None:
    """--scheduler and --workers, shared by the study tools."""
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="run on an existing Dask cluster (e.g. tcp://10.0.0.5:8786; default: the environment "
                             "variable DASK_SCHEDULER_ADDRESS, else a local cluster)")
    parser.add_argument("--workers", type=int, help="local cluster: worker processes (default: the study's "
                                                    "'workers', else one per core)")


def open_engine(args: argparse.Namespace, workers: int | None, max_worker_deaths: int) -> Engine:
    """The engine the arguments ask for, started; EngineUnavailable or ValueError if it cannot be had."""
    if args.workers is not None and args.workers < 1:
        raise ValueError("--workers must be at least 1")
    engine = Engine(scheduler_address(args.scheduler), args.workers if args.workers is not None else workers,
                    max_worker_deaths=max_worker_deaths)
    engine.start()
    return engine


def prepare(study: LoadedStudy) -> dict[str, Any]:
    """Check every run of the study before anything is written; raises ScenarioError or NotMonolithic."""
    spec = study.spec
    gain_sets: dict[str, Any] = {}
    for strategy in (s for s in SOSM_STRATEGIES if s in spec.strategies):
        path = study.gain_set_path(strategy)
        gains, gain_sets[strategy] = read_gains(path)
        i_max = study.gain_set(strategy)[0]
        if abs(gains.i_max - i_max) > 1e-12:
            key = "i_max" if strategy == "sosm" else "fig15.i_max"
            raise ScenarioError(f"{path}: gains tuned for i_max = {gains.i_max} A, the study's {key} is "
                                f"{i_max} A: re-run the tuning")
    records: dict[str, Any] = {}
    algorithms: dict[str, str] = {}
    step = None
    for r in spec.records:
        path = study.scenario_path(r)
        base = run_overrides(spec)
        for s in sorted({"passive-off", *(s for s in (*SOSM_STRATEGIES, "on-off") if s in spec.strategies)}):
            g = gain_sets[s]["gains"] if s in gain_sets else None
            plan = plan_scenario(path, (*base, *strategy_overrides(s, spec.i_max, g, 0.0)))
        sim = plan.loaded.scenario.simulation
        algorithms[r], step = sim.algorithm, sim.step
        needs_model = "best-constant" in spec.strategies or spec.reference.enabled
        setup = system_setup(plan, 0.0) if needs_model else None
        masses = list(setup.building.m) if setup else list(BuildingParams.dyke().m)
        records[r] = {"scenario": str(path), "stop_time_s": sim.stop_time, "masses_kg": masses,
                      "record_file": str(plan.data_files.get("ground.record", "")),
                      "scale": plan.parameters.get("ground", {}).get("scale"),
                      "time_scale": plan.parameters.get("ground", {}).get("time_scale", 1.0),
                      "n_isolators": plan.parameters.get("isolator", {}).get("n_isolators")}
    return {"records": records, "gains": gain_sets.get("sosm"), "gain_sets": gain_sets, "algorithms": algorithms,
            "step": step}


def _job(study: LoadedStudy, label: str, kind: str, overrides: tuple[str, ...], extra: dict[str, Any]
         ) -> tuple[str, str, PortablePlan, dict[str, Any]]:
    """Label, content key, portable plan and payload inputs of one job (label ``record/...``)."""
    plan = plan_scenario(study.scenario_path(label.split("/")[0]), overrides)
    pp = portable(plan)
    return label, job_key(kind, {"job": label, "plan": plan_content(pp), **extra}), pp, extra


def run_study(study: LoadedStudy, folder: Path, prepared: dict[str, Any], engine: Engine, progress: bool,
              command: list[str], resumed: dict[str, Any] | None = None) -> int:
    """Run every job of a prepared study into ``folder`` on ``engine``; returns the exit code.

    Each job's result is stored under its content key (:class:`ResultStore`); with ``resumed``
    (the study.json of an earlier, unfinished run of this folder) stored results are reused.
    """
    spec = study.spec
    base = run_overrides(spec)
    records = prepared["records"]
    data: dict[str, Any] = {
        "name": spec.name, "description": spec.description, "study_file": str(study.path),
        "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "finished": None,
        "config": {**spec.model_dump(), "sweep_currents": spec.sweep.currents(spec.i_max)},
        "strategies": list(spec.strategies), "records": records, "run_overrides": list(base),
        "gains": prepared["gains"], "gains_file": str(study.gains_path) if prepared["gains"] else None,
        "gain_sets": prepared.get("gain_sets", {}),
        "gains_files": {s: str(study.gain_set_path(s)) for s in prepared.get("gain_sets", {})},
        "best_current": {}, "sweep": {}, "reference": {}, "runs": [], "indices": {},
        "provenance": {**provenance(), "command": command, "algorithms": prepared["algorithms"],
                       "step_s": prepared["step"]},
    }
    data["engine"] = {"scheduler": engine.scheduler, "workers": engine.n_workers}
    data["jobs_computed"] = 0  # jobs sent to the engine (the others' results were stored already)
    if resumed is not None:
        data["started"] = resumed.get("started", data["started"])
        data["resumed"] = [*resumed.get("resumed", []), time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())]
    (folder / "logs").mkdir(exist_ok=True)
    (folder / "runs").mkdir(exist_ok=True)
    store = ResultStore(folder)
    write_json(folder / "study.json", data)
    n_jobs = (len(records) * ("best-constant" in spec.strategies) + len(records) * len(spec.strategies)
              + len(records) * len([s for s in ("passive-off", "passive-on") if s in spec.strategies])
              * spec.reference.enabled)
    bar = StudyBar(n_jobs, spec.name, enabled=progress)
    bar.write(engine.describe())
    say = bar.write
    collected: dict[str, JobResult] = {}  # every finished job, also when the study is interrupted
    labels: dict[str, str] = {}  # content key -> job label (record/strategy[/reference])
    shared: dict[str, Any] = {}  # SHA-256 -> handle of the file's bytes on the cluster

    def files_of(pp: PortablePlan) -> dict[str, Any]:
        for sha, path in file_bytes([pp]).items():
            if sha not in shared:
                shared[sha] = engine.share(path.read_bytes())
        return {sha: shared[sha] for sha in pp.shas}

    def done(res: JobResult, stored: bool = False) -> None:
        content_key = res.key
        label = labels.get(content_key, content_key)
        res = JobResult(label, res.ok, res.value, res.error, res.details, res.wall_time_s, res.status, res.worker,
                        res.output)
        value = res.value
        if res.ok and isinstance(value, dict) and "files" in value:
            entry = next(e for e in data["runs"] if e["key"] == label)
            write_run_files(folder / entry["folder"], value.pop("files"))
        if res.output or res.details:
            (folder / "logs" / f"{label.replace('/', '-')}.log").write_text(res.output + res.details)
        if not stored:
            store.put(content_key,
                      {"label": label, "ok": res.ok, "status": res.status, "value": value, "error": res.error,
                       "wall_time_s": res.wall_time_s, "worker": res.worker})
        collected[label] = res
        bar.done(res.ok and not (isinstance(value, dict) and value.get("complete") is False))
        if not res.ok:
            say(f"FAILED {label}: {res.error}")
        elif isinstance(value, dict) and "time_beyond_identified_range_s" in value:
            v = value
            if not v["complete"]:
                say(f"FAILED {label}: run {v['status']}: {v['error']}")
            if (v["time_beyond_identified_range_s"] or 0) > 0:
                limit = (f"; beyond the {1e3 * spec.x_limit:g} mm device limit for "
                         f"{v['time_beyond_device_limit_s']:.3g} s" if v["time_beyond_device_limit_s"] else "")
                say(f"warning: {label}: base displacement {1e3 * v['peak_base_displacement_m']:.2f} mm, beyond the "
                    f"identified ±{1e3 * spec.x_identified:g} mm for {v['time_beyond_identified_range_s']:.3g} s "
                    f"(isolator model extrapolated){limit}")

    def run_batch(fn: Any, jobs: list[tuple[str, str, PortablePlan, dict[str, Any]]], isolate: bool) -> None:
        """Jobs (label, key, plan, inputs): stored results reused, the others run on the engine."""
        todo = []
        for label, key, pp, extra in jobs:
            labels[key] = label
            old = store.get(key)
            if old is not None:
                done(JobResult(key, old["ok"], old.get("value"), old.get("error"), "", old.get("wall_time_s", 0.0),
                               old["status"], old.get("worker")), stored=True)
            else:
                todo.append((key, {"plan": pp, "files": files_of(pp), **extra}))
        if todo:
            data["jobs_computed"] += len(todo)
            engine.map(fn, [p for _, p in todo], [k for k, _ in todo], isolate=isolate, timeout_s=spec.timeout_s,
                       on_done=done)

    interrupted = False
    try:
        if "best-constant" in spec.strategies:
            currents = spec.sweep.currents(spec.i_max)
            extra = {"currents": currents, "objective": spec.objective.model_dump()}
            run_batch(sweep_job, [_job(study, f"{r}/sweep", "sweep", base, extra) for r in records], isolate=False)
            for r in records:
                res = collected.get(f"{r}/sweep")
                if res is not None:
                    data["sweep"][r] = {"ok": res.ok, "error": res.error, **(res.value or {})}
                    if res.ok:
                        data["best_current"][r] = res.value["best_current_A"]
        gain_sets = {s: doc["gains"] for s, doc in prepared.get("gain_sets", {}).items()}
        runs, references = [], []
        order = sorted(records, key=lambda r: -records[r]["stop_time_s"])  # longest first
        for r in order:
            for s in spec.strategies:
                key = f"{r}/{s}"
                entry: dict[str, Any] = {"key": key, "record": r, "strategy": s, "folder": f"runs/{r}-{s}",
                                         "ok": False, "error": None}
                data["runs"].append(entry)
                if s == "best-constant" and r not in data["best_current"]:
                    entry["error"] = f"current sweep failed: {data['sweep'].get(r, {}).get('error')}"
                    done(JobResult(key, False, error=entry["error"], status="failed"), stored=True)
                    continue
                extra = strategy_overrides(s, spec.i_max, gain_sets.get(s), data["best_current"].get(r))
                entry["current_A"] = None if s in (*SOSM_STRATEGIES, "on-off") else float(extra[-1].split("=")[1])
                entry["overrides"] = list(extra)
                runs.append(_job(study, key, "cosim", (*base, *extra, OUTPUTS_OVERRIDE), {}))
            if spec.reference.enabled:
                for s in ("passive-off", "passive-on"):
                    if s in spec.strategies:
                        current = 0.0 if s == UNCONTROLLED else spec.i_max
                        references.append(_job(study, f"{r}/{s}/reference", "reference", base,
                                               {"current": current, "rtol": spec.reference.rtol}))
        run_batch(cosim_job, runs, isolate=True)
        run_batch(reference_job, references, isolate=False)
    except KeyboardInterrupt:
        interrupted = True
        say("interrupted: writing the report of the finished runs")
    results = collected
    for entry in data["runs"]:
        res = results.get(entry["key"])
        if res is None:
            entry["error"] = entry["error"] or "not run (interrupted)"
            continue
        if not res.ok:
            entry["error"] = res.error
            continue
        v = res.value
        entry.update({"ok": bool(v["complete"]), "error": None if v["complete"] else f"run {v['status']}: "
                      f"{v['error']}", "status": v["status"], "wall_time_s": v["wall_time_s"],
                      "unit_warnings": v["unit_warnings"]})
    for key, res in results.items():
        if key.endswith("/reference"):
            data["reference"][key.removesuffix("/reference")] = {"ok": res.ok, "error": res.error, "value": res.value}
    data["finished"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    data["interrupted"] = interrupted
    write_json(folder / "study.json", data)
    bar.close()
    write_outputs(folder, data)
    failed = [e for e in data["runs"] if not e["ok"]]
    failed += [k for k, v in {**data["sweep"], **data["reference"]}.items() if not v["ok"]]
    print(f"study {'interrupted' if interrupted else 'done'}: {folder} ({len(failed)} failed)")
    return 1 if failed or interrupted else 0


def resumed_study(folder: Path) -> tuple[LoadedStudy, dict[str, Any]]:
    """The study of an existing study folder, as it was configured; ScenarioError if unusable."""
    try:
        data = read_study(folder)
        config = {k: v for k, v in data["config"].items() if k != "sweep_currents"}
        spec = StudySpec.model_validate(config)
        return LoadedStudy(spec, Path(data["study_file"]), config), data
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ScenarioError(f"{folder}: not a study folder that can be resumed ({type(exc).__name__}: {exc})"
                            ) from None


def _base_sensitivity(args: argparse.Namespace, study: LoadedStudy, argv: list[str]) -> int:
    """``--base-sensitivity``: the study's comparisons for base-floor variants into a new folder."""
    from orchestration.studies.base_sensitivity import WINDOW_S, run_sensitivity, write_sensitivity

    window = WINDOW_S if args.window is None else args.window
    if not window > 0:
        raise ValueError(f"--window must be positive, got {window}")
    for s in ("sosm", "sosm-fig15"):
        read_gains(study.gain_set_path(s))  # ScenarioError before anything is written
    engine = open_engine(args, study.spec.workers, study.spec.max_worker_deaths)
    with engine:
        try:
            folder = new_run_folder(Path(study.spec.output), f"{study.spec.name}-base-sensitivity", args.out)
        except RunFolderExists as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        data = run_sensitivity(study, engine, window)
    write_sensitivity(folder, data, "python orchestration/study.py " + shlex.join(argv))
    print(f"base-floor sensitivity done: {folder / 'base_sensitivity.md'} ({data['wall_time_s']:.0f} s)")
    return 0


def main(argv: list[str] | None = None) -> int:
    """CLI entry point; returns the exit code."""
    args = parse_args(argv)
    if args.report is not None:
        try:
            data = read_study(args.report)
        except (OSError, ValueError) as exc:
            print(f"error: cannot read {args.report / 'study.json'}: {exc}", file=sys.stderr)
            return 2
        write_outputs(args.report, data)
        print(f"report regenerated: {args.report / 'report.md'}")
        return 0
    resumed = None
    try:
        if args.resume is not None:
            study, resumed = resumed_study(args.resume)
        else:
            try:
                study = load_study(args.study, tuple(args.overrides))
            except ScenarioError:
                require_kind(args.study, "study")  # a run scenario: name run.py instead
                raise
        if args.base_sensitivity:
            return _base_sensitivity(args, study, sys.argv[1:] if argv is None else argv)
        prepared = prepare(study)
        engine = open_engine(args, study.spec.workers, study.spec.max_worker_deaths)
    except ScenarioError as exc:
        print(exc.report(), file=sys.stderr)
        return 2
    except (NotMonolithic, EngineUnavailable, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    try:
        folder = args.resume if args.resume is not None else new_run_folder(Path(study.spec.output),
                                                                             study.spec.name, args.out)
    except RunFolderExists as exc:
        engine.close()
        print(f"error: {exc}", file=sys.stderr)
        return 2

    # SIGTERM raises KeyboardInterrupt here already (components.cli.guarded): handled as Ctrl-C, report written
    try:
        return run_study(study, folder, prepared, engine, not args.quiet, [sys.executable, *sys.argv], resumed)
    finally:
        engine.close()
