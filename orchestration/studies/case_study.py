"""The case study behind ``python orchestration/study.py scenarios/case_study.yaml``.

Every record x strategy runs as a co-simulation through the master, each in its own
process, and the study folder gets ``peaks.csv``, ``indices.csv``, ``sweep.csv``,
``reference.csv``, ``figures/``, ``report.md``, ``report.html``, ``study.json``, the run
folders (``runs/``) and the processes' logs (``logs/``). A study folder is never
overwritten; every file is written atomically. ``--report DIR`` regenerates the tables,
figures and report of an existing study folder from its data.

Exit codes: 0 every job succeeded; 1 some jobs failed or the study was interrupted (the
report lists them; the other results are complete); 2 configuration error (nothing written).
"""

from __future__ import annotations

import argparse
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from components.physics.shear_building_core import BuildingParams
from orchestration.master.errors import ScenarioError
from orchestration.master.runfolder import RunFolderExists, new_run_folder, write_json
from orchestration.project import PROJECT_DIR as PROJECT
from orchestration.project import plan_scenario, require_kind
from orchestration.studies.config import UNCONTROLLED, LoadedStudy, load_study
from orchestration.studies.jobs import cosim_job, reference_job, sweep_job
from orchestration.studies.report import read_study, write_outputs
from orchestration.studies.runner import Job, JobResult, run_jobs
from orchestration.studies.tuning import NotMonolithic, read_gains, run_overrides, system_setup


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """Command-line arguments."""
    parser = argparse.ArgumentParser(prog="study.py", description="Run a case study (records x strategies).")
    parser.add_argument("study", type=Path, nargs="?", help="study YAML file (scenarios/case_study.yaml)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a study key, e.g. --set 'overrides=[simulation.stop_time=5]' or "
                             "--set 'strategies=[passive-off, sosm]'")
    parser.add_argument("--out", type=Path, help="study folder to create (must not exist or be empty)")
    parser.add_argument("--workers", type=int, help="parallel processes (default: the study's 'workers')")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--report", type=Path, metavar="DIR", help="regenerate the report of a study folder")
    args = parser.parse_args(argv)
    if (args.study is None) == (args.report is None):
        parser.error("give a study file, or --report DIR")
    return args


def _git(*args: str) -> str:
    try:
        return subprocess.run(["git", *args], cwd=PROJECT, capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def strategy_overrides(strategy: str, i_max: float, gains: dict[str, float] | None, best: float | None
                       ) -> tuple[str, ...]:
    """Scenario overrides that make a run follow a strategy."""
    if strategy == "sosm":
        assert gains is not None
        return ("controller.mode=sosm", f"controller.lambda={gains['lambda']!r}", f"controller.rho={gains['rho']!r}",
                f"controller.zeta={gains['zeta']!r}", f"controller.theta={gains['theta']!r}")
    if strategy == "on-off":
        return (f"units.controller.fmu={PROJECT / 'fmus' / 'SwitchingCurrentController.fmu'}",
                f"controller.i_high={i_max!r}", "controller.i_low=0.0")
    current = {"passive-off": 0.0, "passive-on": i_max, "best-constant": best}[strategy]
    return ("controller.mode=passive", f"controller.i_passive={current!r}")


def prepare(study: LoadedStudy) -> dict[str, Any]:
    """Check every run of the study before anything is written; raises ScenarioError or NotMonolithic."""
    spec = study.spec
    gains_doc = None
    if "sosm" in spec.strategies:
        gains, gains_doc = read_gains(study.gains_path)
        if abs(gains.i_max - spec.i_max) > 1e-12:
            raise ScenarioError(f"{study.gains_path}: gains tuned for i_max = {gains.i_max} A, the study uses "
                                f"{spec.i_max} A: re-run the tuning")
    records: dict[str, Any] = {}
    algorithms: dict[str, str] = {}
    step = None
    for r in spec.records:
        path = study.scenario_path(r)
        base = run_overrides(spec)
        for s in sorted({"passive-off", *(s for s in ("sosm", "on-off") if s in spec.strategies)}):
            plan = plan_scenario(path, (*base, *strategy_overrides(s, spec.i_max, gains_doc["gains"] if gains_doc
                                                                   else None, 0.0)))
        sim = plan.loaded.scenario.simulation
        algorithms[r], step = sim.algorithm, sim.step
        needs_model = "best-constant" in spec.strategies or spec.reference.enabled
        setup = system_setup(plan, 0.0) if needs_model else None
        masses = list(setup.building.m) if setup else list(BuildingParams.dyke().m)
        records[r] = {"scenario": str(path), "stop_time_s": sim.stop_time, "masses_kg": masses,
                      "record_file": str(plan.data_files.get("ground.record", "")),
                      "scale": plan.parameters.get("ground", {}).get("scale")}
    return {"records": records, "gains": gains_doc, "algorithms": algorithms, "step": step}


def run_study(study: LoadedStudy, folder: Path, prepared: dict[str, Any], workers: int, progress: bool,
              command: list[str]) -> int:
    """Run every job of a prepared study into ``folder``; returns the exit code."""
    spec = study.spec
    base = run_overrides(spec)
    records = prepared["records"]
    data: dict[str, Any] = {
        "name": spec.name, "description": spec.description, "study_file": str(study.path),
        "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "finished": None,
        "config": {**spec.model_dump(), "sweep_currents": spec.sweep.currents(spec.i_max)},
        "strategies": list(spec.strategies), "records": records, "run_overrides": list(base),
        "gains": prepared["gains"], "gains_file": str(study.gains_path) if prepared["gains"] else None,
        "best_current": {}, "sweep": {}, "reference": {}, "runs": [], "indices": {},
        "provenance": {"commit": _git("rev-parse", "HEAD"), "dirty": bool(_git("status", "--porcelain", "--",
                                                                                "components", "orchestration")),
                       "command": command, "algorithms": prepared["algorithms"], "step_s": prepared["step"]},
    }
    (folder / "logs").mkdir()
    (folder / "runs").mkdir()
    write_json(folder / "study.json", data)
    bar = None
    n_jobs = (len(records) * ("best-constant" in spec.strategies) + len(records) * len(spec.strategies)
              + len(records) * len([s for s in ("passive-off", "passive-on") if s in spec.strategies])
              * spec.reference.enabled)
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n_jobs, unit="job", desc=spec.name, file=sys.stderr, disable=None)

    def say(text: str) -> None:
        (bar.write if bar is not None else print)(text, file=sys.stderr)

    def payload(r: str, extra: tuple[str, ...] = ()) -> dict[str, Any]:
        return {"scenario": records[r]["scenario"], "overrides": (*base, *extra)}

    collected: dict[str, JobResult] = {}  # every finished job, also when the study is interrupted

    def done(res: JobResult) -> None:
        collected[res.key] = res
        if bar is not None:
            bar.update(1)
        if not res.ok:
            say(f"FAILED {res.key}: {res.error}")
        elif isinstance(res.value, dict) and "time_beyond_identified_range_s" in res.value:
            v = res.value
            if not v["complete"]:
                say(f"FAILED {res.key}: run {v['status']}: {v['error']}")
            if (v["time_beyond_identified_range_s"] or 0) > 0:
                limit = (f"; beyond the {1e3 * spec.x_limit:g} mm device limit for "
                         f"{v['time_beyond_device_limit_s']:.3g} s" if v["time_beyond_device_limit_s"] else "")
                say(f"warning: {res.key}: base displacement {1e3 * v['peak_base_displacement_m']:.2f} mm, beyond the "
                    f"identified ±{1e3 * spec.x_identified:g} mm for {v['time_beyond_identified_range_s']:.3g} s "
                    f"(isolator model extrapolated){limit}")

    interrupted = False
    try:
        if "best-constant" in spec.strategies:
            currents = spec.sweep.currents(spec.i_max)
            jobs = [Job(f"{r}/sweep", sweep_job, {**payload(r), "currents": currents,
                                                   "objective": spec.objective.model_dump()},
                        folder / "logs" / f"{r}-sweep.log") for r in records]
            for key, res in run_jobs(jobs, workers, done, spec.timeout_s).items():
                r = key.split("/")[0]
                data["sweep"][r] = {"ok": res.ok, "error": res.error, **(res.value or {})}
                if res.ok:
                    data["best_current"][r] = res.value["best_current_A"]
        gains = prepared["gains"]["gains"] if prepared["gains"] else None
        jobs = []
        order = sorted(records, key=lambda r: -records[r]["stop_time_s"])  # longest first
        for r in order:
            for s in spec.strategies:
                key = f"{r}/{s}"
                entry: dict[str, Any] = {"key": key, "record": r, "strategy": s, "folder": f"runs/{r}-{s}",
                                         "ok": False, "error": None}
                data["runs"].append(entry)
                if s == "best-constant" and r not in data["best_current"]:
                    entry["error"] = f"current sweep failed: {data['sweep'].get(r, {}).get('error')}"
                    done(JobResult(key, False, error=entry["error"]))
                    continue
                extra = strategy_overrides(s, spec.i_max, gains, data["best_current"].get(r))
                entry["current_A"] = None if s in ("sosm", "on-off") else float(extra[-1].split("=")[1])
                entry["overrides"] = list(extra)
                jobs.append(Job(key, cosim_job, {**payload(r, extra), "out": str(folder / entry["folder"])},
                                folder / "logs" / f"{r}-{s}.log"))
            if spec.reference.enabled:
                for s in ("passive-off", "passive-on"):
                    if s in spec.strategies:
                        current = 0.0 if s == UNCONTROLLED else spec.i_max
                        jobs.append(Job(f"{r}/{s}/reference", reference_job,
                                        {**payload(r), "current": current, "rtol": spec.reference.rtol},
                                        folder / "logs" / f"{r}-{s}-reference.log"))
        run_jobs(jobs, workers, done, spec.timeout_s)
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
    if bar is not None:
        bar.close()
    write_outputs(folder, data)
    failed = [e for e in data["runs"] if not e["ok"]]
    failed += [k for k, v in {**data["sweep"], **data["reference"]}.items() if not v["ok"]]
    print(f"study {'interrupted' if interrupted else 'done'}: {folder} ({len(failed)} failed)")
    return 1 if failed or interrupted else 0


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
    try:
        try:
            study = load_study(args.study, tuple(args.overrides))
        except ScenarioError:
            require_kind(args.study, "study")  # a run scenario: name run.py instead
            raise
        prepared = prepare(study)
        folder = new_run_folder(Path(study.spec.output), study.spec.name, args.out)
    except ScenarioError as exc:
        print(exc.report(), file=sys.stderr)
        return 2
    except (NotMonolithic, RunFolderExists) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    workers = args.workers if args.workers is not None else study.spec.workers
    if workers < 1:
        print("error: --workers must be at least 1", file=sys.stderr)
        return 2

    def on_sigterm(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, on_sigterm)
    try:
        return run_study(study, folder, prepared, workers, not args.quiet, [sys.executable, *sys.argv])
    finally:
        signal.signal(signal.SIGTERM, previous)
