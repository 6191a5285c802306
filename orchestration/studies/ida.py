"""Incremental dynamic analysis and fragility: ``python orchestration/ida.py scenarios/ida.yaml``.

Every component of a record suite (:mod:`orchestration.studies.suites`), cut to its
strong-motion window and played at the study's time scale, is scaled to each level of an
intensity ladder (PGA, or Sa at the isolated period: :mod:`orchestration.studies.intensity`)
and run as a co-simulation through the master for each strategy, on the Dask engine
(:mod:`orchestration.studies.engine`), each run in a child process of a worker. The study
folder gets:

| file | content |
|---|---|
| ``results.parquet``, ``.csv`` | a row per run: record, component, intensity, strategy, peaks, indices, status, time |
| ``fragility.csv`` | per limit state and strategy: stripes, the lognormal fit (median, beta, its interval) |
| ``figures/`` | ``ida_curves.png`` (per strategy), ``fragility.png`` (per limit state, strategies side by side) |
| ``report.md``, ``report.html`` | settings, fits, a verdict per limit state, failed runs |
| ``ida.json`` | configuration, suite, windows, period, intensities, provenance, engine |
| ``records/`` | the windowed components the runs played (``time_s,accel_g``) |
| ``jobs/`` | each finished run's result under its content key (``--resume``) |

Exit codes: 0 every run ended (complete, or stopped by the scenario's divergence limit,
which counts as exceeding every limit state); 1 some runs failed or were lost, or the
study was interrupted (the report says which; the rest is complete); 2 configuration
error, unreachable scheduler (nothing computed, nothing written).
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from components.physics.shear_building_core import BuildingParams
from orchestration.master.errors import Problem, ScenarioError
from orchestration.master.runfolder import RunFolderExists, new_run_folder, write_json, write_text
from orchestration.master.scenario import load_scenario
from orchestration.project import plan_scenario
from orchestration.provenance import provenance
from orchestration.studies.analysis import INDEX_COLUMNS, indices
from orchestration.studies.engine import Engine, EngineUnavailable, JobResult, StudyBar, scheduler_address
from orchestration.studies.ida_config import QUANTITIES, IdaSpec, LoadedIda, load_ida
from orchestration.studies.intensity import MEASURES, isolated_period, measure
from orchestration.studies.jobs import OUTPUTS_OVERRIDE, ida_job
from orchestration.studies.portable import PortablePlan, file_bytes, job_key, plan_content, portable
from orchestration.studies.store import ResultStore
from orchestration.studies.strategies import strategy_overrides
from orchestration.studies.suites import SuiteRecord, Window, choose_window, load_suite, record_csv, stop_time, windowed
from orchestration.studies.tuning import NotMonolithic, read_gains, system_setup

if TYPE_CHECKING:
    from orchestration.studies.fragility import Fit

PEAKS = ("x_base_mm", "drift_1_mm", "drift_2_mm", "drift_3_mm", "drift_max_mm", "acc_0", "acc_1", "acc_2", "acc_3",
         "acc_max", "base_shear_N", "structure_shear_N", "isolator_force_N", "current_max_A", "current_mean_A",
         "rms_x_base_mm", "rms_acc_max", "time_beyond_8mm_s", "time_beyond_15mm_s")
COLUMNS = ("record", "component", "record_id", "intensity_measure", "intensity", "im_unscaled", "scale",
           "strategy", *PEAKS, *INDEX_COLUMNS[2:], "status", "error", "wall_time_s", "end_time_s", "key")
ENDED = ("ok", "diverged")  # runs that count in the fragility stripes


@dataclass
class Component:
    """One record component as the study plays it."""

    rec: SuiteRecord
    window: Window
    stop_time_s: float
    im: float  # intensity of the windowed component at scale 1 [g]
    csv: Path  # staged record file


@dataclass
class PreparedIda:
    """Everything checked, every run planned: nothing is left that could be a configuration error."""

    study: LoadedIda
    components: list[Component]
    strategies: dict[str, tuple[str, ...]]
    period_s: float | None
    plans: dict[tuple[str, str], PortablePlan]
    masses: list[float]
    gains: dict[str, Any] | None
    staging: Path
    planning_s: float = 0.0
    notes: list[str] = field(default_factory=list)

    def cleanup(self) -> None:
        shutil.rmtree(self.staging, ignore_errors=True)


def _masses(plan: Any) -> list[float]:
    m = list(BuildingParams.dyke().m)
    for name, value in plan.parameters.get("building", {}).items():
        kind, _, j = name.partition("_")
        if kind == "m" and j.isdigit():
            while len(m) <= int(j):
                m.append(m[-1])
            m[int(j)] = float(value)
    return m


def prepare_ida(path: Path, loaded: LoadedIda | None, problems: list[Problem], raw: Any) -> PreparedIda:
    """Check the whole study and plan every run; ScenarioError listing every problem (nothing computed).

    ``path`` is the study file, ``problems`` those found reading it (``loaded`` is None then)
    and ``raw`` its data: a folder suite is checked even when other keys are wrong.
    """
    started = time.perf_counter()
    problems = list(problems)
    spec = loaded.spec if loaded is not None else None
    records: list[SuiteRecord] = []
    if spec is not None:
        suite = spec.suite if isinstance(spec.suite, str) else spec.suite.model_dump()
        records, found = load_suite(suite, path.parent)
        problems += found
    elif isinstance(raw, dict):
        if isinstance(raw.get("suite"), dict) and isinstance(raw["suite"].get("folder"), str):
            _, found = load_suite(raw["suite"], path.parent)
            problems += found
        for key, tool in (("records", "study.py"), ("units", "run.py")):
            if key in raw:
                problems.append(Problem(f"this looks like a file for {tool} (it has '{key}'), not an IDA study",
                                        key, str(path)))
    if spec is None or loaded is None:
        raise ScenarioError(problems)
    gains_doc = None
    if "sosm" in spec.strategy_names:
        try:
            gains, gains_doc = read_gains(loaded.resolve(spec.gains))
            if abs(gains.i_max - spec.i_max) > 1e-12:
                problems.append(Problem(f"gains tuned for i_max = {gains.i_max} A, the study uses {spec.i_max} A: "
                                        "re-run the tuning", "gains"))
        except ScenarioError as exc:
            problems += exc.problems
    strategies: dict[str, tuple[str, ...]] = {}
    for s in spec.strategies:
        if isinstance(s, str):
            if s == "sosm" and gains_doc is None:
                continue
            strategies[s] = strategy_overrides(s, spec.i_max, gains_doc["gains"] if gains_doc else None, None)
        else:
            strategies[s.name] = tuple(s.overrides)
    scenario = loaded.resolve(spec.scenario)
    common = (*spec.overrides, f"isolator.i_max={spec.i_max!r}", f"controller.i_max={spec.i_max!r}",
              f"ground.time_scale={spec.time_scale!r}")
    step = None
    try:
        step = load_scenario(scenario, (*common, "simulation.stop_time=1.0")).scenario.simulation.step
    except ScenarioError as exc:
        problems += exc.problems
    if problems or not records or step is None:
        raise ScenarioError(problems or [Problem("the suite has no record", "suite")])

    staging = Path(tempfile.mkdtemp(prefix="mre-cosim-ida-"))
    try:
        (staging / "records").mkdir()
        components = []
        for rec in records:
            window = choose_window(rec, spec.window.strong_motion)
            played = windowed(rec, window)
            csv = staging / "records" / f"{rec.id}.csv"
            csv.write_text(record_csv(played, f"{rec.source}\nwindow {window.start:.3f}-{window.end:.3f} s of the "
                                              f"record, shifted to t = 0 (strong motion: {spec.window.strong_motion})"))
            components.append(Component(rec, window, stop_time(window, spec.time_scale, spec.window.tail_s, step),
                                        math.nan, csv))
        plans: dict[tuple[str, str], PortablePlan] = {}
        failing: set[str] = set()
        for c in components:
            for name, extra in strategies.items():
                if name in failing:
                    continue
                try:
                    plan = plan_scenario(scenario, (*common, *extra, f"ground.record=!record {c.csv}",
                                                    f"simulation.stop_time={c.stop_time_s!r}", OUTPUTS_OVERRIDE))
                except ScenarioError as exc:
                    failing.add(name)
                    problems += [Problem(f"strategy {name}: {p.message}", p.key, p.file, p.line) for p in exc.problems]
                    continue
                plans[(c.rec.id, name)] = portable(plan)
        if problems:
            raise ScenarioError(problems)
        first = plans[(components[0].rec.id, next(iter(strategies)))].plan
        intensity = spec.intensity
        period = intensity.period_s
        if intensity.measure == "sa" and period is None:
            try:
                setup = system_setup(first, 0.0)
            except (NotMonolithic, KeyError) as exc:
                raise ScenarioError(Problem(f"the isolated period cannot be computed for this system ({exc}): "
                                            "give intensity.period_s", "intensity.period_s")) from None
            period = isolated_period(setup.building, setup.coeffs, setup.n_isolators, intensity.period_current_A,
                                     intensity.period_displacement_m)
        for c in components:
            c.im = measure(windowed(c.rec, c.window), intensity.measure, spec.time_scale, period, intensity.damping)
            if not (math.isfinite(c.im) and c.im > 0):
                problems.append(Problem(f"record {c.rec.id} has no motion ({intensity.measure} = {c.im})", "suite"))
        if problems:
            raise ScenarioError(problems)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return PreparedIda(loaded, components, strategies, period, plans, _masses(first), gains_doc, staging,
                       time.perf_counter() - started)


def _label(c: Component, level: float, strategy: str) -> str:
    return f"{c.rec.id}/{level:g}/{strategy}"


def result_rows(prepared_info: dict[str, Any], results: dict[str, dict[str, Any]], levels: list[float],
                strategies: list[str]) -> list[dict[str, Any]]:
    """One row per run (COLUMNS); indices against passive-off at the same component and level, if there is one."""
    rows = []
    for comp in prepared_info["components"]:
        for level in levels:
            off = results.get(f"{comp['id']}/{level:g}/passive-off")
            off_metrics = off["value"]["metrics"] if off and off.get("ok") and off["value"]["status"] == "ok" \
                else None
            for s in strategies:
                label = f"{comp['id']}/{level:g}/{s}"
                res = results.get(label)
                row: dict[str, Any] = {"record": comp["record"], "component": comp["component"],
                                       "record_id": comp["id"], "intensity_measure": prepared_info["measure"],
                                       "intensity": level, "im_unscaled": comp["im"], "scale": level / comp["im"],
                                       "strategy": s, "key": label}
                if res is None:
                    row.update(status="not run", error="not run (interrupted)")
                elif not res.get("ok"):
                    row.update(status=res.get("status", "failed"), error=res.get("error"),
                               wall_time_s=res.get("wall_time_s"))
                else:
                    v = res["value"]
                    m = v.get("metrics") or {}
                    row.update({k: m.get(k) for k in PEAKS})
                    row.update(status=v["status"], error=v.get("error"), wall_time_s=res.get("wall_time_s"),
                               end_time_s=v.get("end_time_s"))
                    if off_metrics and v["status"] == "ok" and m:
                        row.update(indices({k: (math.nan if x is None else x) for k, x in m.items()},
                                           {k: (math.nan if x is None else x) for k, x in off_metrics.items()}))
                rows.append({c: row.get(c) for c in COLUMNS})
    return rows


def exceeded(row: dict[str, Any], quantity: str, threshold: float) -> bool | None:
    """Did a run exceed a limit state? None if the run does not count (failed, not run)."""
    if row["status"] == "diverged":
        return True
    if row["status"] != "ok":
        return None
    column, factor, _ = QUANTITIES[quantity]
    value = row.get(column)
    return None if value is None else bool(value * factor > threshold)


def fragilities(rows: list[dict[str, Any]], spec: IdaSpec) -> dict[str, dict[str, Fit]]:
    """Limit state -> strategy -> fitted fragility."""
    from orchestration.studies.fragility import Stripe, fit_fragility  # scipy.stats: only when needed

    out: dict[str, dict[str, Fit]] = {}
    for name, ls in spec.limit_states.items():
        out[name] = {}
        for s in spec.strategy_names:
            stripes = []
            for level in spec.intensity.levels:
                marks = [exceeded(r, ls.quantity, ls.threshold) for r in rows
                         if r["strategy"] == s and r["intensity"] == level]
                counted = [m for m in marks if m is not None]
                stripes.append(Stripe(level, len(counted), sum(counted)))
            out[name][s] = fit_fragility(stripes, spec.confidence)
    return out


def fragility_rows(fits: dict[str, dict[str, Fit]], spec: IdaSpec) -> list[dict[str, Any]]:
    """The table of fragility.csv: one row per limit state and strategy."""
    rows = []
    for name, by_strategy in fits.items():
        ls = spec.limit_states[name]
        for s, fit in by_strategy.items():
            lo, hi = fit.theta_interval() if fit.ok else (math.nan, math.nan)
            rows.append({"limit_state": name, "quantity": ls.quantity, "threshold": ls.threshold, "strategy": s,
                         "fit": fit.kind, "median": fit.theta if fit.ok else None, "beta": fit.beta if fit.ok else None,
                         "median_low": lo, "median_high": hi, "confidence": fit.confidence,
                         "between_low": fit.bounds[0] if fit.kind == "separated" else None,
                         "between_high": fit.bounds[1] if fit.kind == "separated" else None,
                         "stripes": " ".join(f"{st.level:g}:{st.k}/{st.n}" for st in fit.stripes), "note": fit.note})
    return rows


def table_csv(columns: tuple[str, ...] | list[str], rows: list[dict[str, Any]]) -> str:
    """CSV text (quoted where needed; floats at full precision, missing as empty)."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        cells = []
        for c in columns:
            v = row.get(c)
            cells.append("" if v is None or (isinstance(v, float) and math.isnan(v)) else
                         repr(float(v)) if isinstance(v, float) else v)
        writer.writerow(cells)
    return buf.getvalue()


def write_tables(folder: Path, rows: list[dict[str, Any]]) -> None:
    """results.parquet (pyarrow) and results.csv, each written to a temporary name and renamed."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    schema = pa.schema([(c, pa.string() if c in ("record", "component", "record_id", "intensity_measure",
                                                  "strategy", "status", "error", "key") else pa.float64())
                        for c in COLUMNS])
    table = pa.Table.from_pylist([{c: (float(r[c]) if r[c] is not None and schema.field(c).type == pa.float64()
                                       else r[c]) for c in COLUMNS} for r in rows], schema=schema)
    fd, tmp = tempfile.mkstemp(prefix=".results.parquet.", suffix=".tmp", dir=folder)
    try:
        with open(fd, "wb") as f:
            pq.write_table(table, f)
        Path(tmp).replace(folder / "results.parquet")
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    write_text(folder / "results.csv", table_csv(COLUMNS, rows))


def read_rows(folder: Path) -> list[dict[str, Any]]:
    """The runs of a study folder (results.parquet)."""
    import pyarrow.parquet as pq

    rows = pq.read_table(folder / "results.parquet").to_pylist()
    for r in rows:
        for k, v in r.items():
            if isinstance(v, float) and math.isnan(v):
                r[k] = None
    return rows


def write_outputs(folder: Path, info: dict[str, Any], rows: list[dict[str, Any]]) -> dict[str, dict[str, Fit]]:
    """Tables, fragility, figures and report of a study folder from its data."""
    from orchestration.studies.ida_report import write_report

    spec = IdaSpec.model_validate(info["config"])
    write_tables(folder, rows)
    fits = fragilities(rows, spec)
    table = fragility_rows(fits, spec)
    write_text(folder / "fragility.csv", table_csv(tuple(table[0]), table))
    write_report(folder, info, spec, rows, fits)
    return fits


def run_ida(prepared: PreparedIda, folder: Path, engine: Engine, progress: bool, command: list[str],
            resumed: dict[str, Any] | None = None) -> int:
    """Run every run of a prepared study into ``folder``; returns the exit code."""
    spec = prepared.study.spec
    levels = list(spec.intensity.levels)
    strategies = list(prepared.strategies)
    (folder / "records").mkdir(exist_ok=True)
    for c in prepared.components:
        shutil.copyfile(c.csv, folder / "records" / c.csv.name)
    info: dict[str, Any] = {
        "name": spec.name, "description": spec.description, "study_file": str(prepared.study.path),
        "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "finished": None,
        "config": spec.model_dump(mode="json"), "measure": spec.intensity.measure,
        "measure_label": MEASURES[spec.intensity.measure], "period_s": prepared.period_s,
        "strategies": {s: list(o) for s, o in prepared.strategies.items()}, "masses_kg": prepared.masses,
        "gains": prepared.gains, "planning_s": prepared.planning_s,
        "components": [{"id": c.rec.id, "record": c.rec.record, "component": c.rec.component, "source": c.rec.source,
                        "window_s": [c.window.start, c.window.end], "stop_time_s": c.stop_time_s, "im": c.im,
                        "pga_g": c.rec.pga_g} for c in prepared.components],
        "engine": {"scheduler": engine.scheduler, "workers": engine.n_workers, "dashboard": engine.dashboard},
        "provenance": {**provenance(), "command": command},
    }
    if resumed is not None:
        info["started"] = resumed.get("started", info["started"])
        info["resumed"] = [*resumed.get("resumed", []), time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())]
    write_json(folder / "ida.json", info)
    store = ResultStore(folder)
    results: dict[str, dict[str, Any]] = {}
    labels: dict[str, str] = {}
    jobs = []
    order = sorted(prepared.components, key=lambda c: -c.stop_time_s)  # longest first
    for c in order:
        for level in levels:
            for s in strategies:
                pp = prepared.plans[(c.rec.id, s)]
                label = _label(c, level, s)
                scale = level / c.im
                key = job_key("ida", {"job": label, "plan": plan_content(pp), "scale": scale,
                                      "masses": prepared.masses})
                labels[key] = label
                old = store.get(key)
                if old is not None:
                    results[label] = old
                else:
                    jobs.append((key, c, s, scale))
    total = len(prepared.components) * len(levels) * len(strategies)
    bar = StudyBar(total, spec.name, initial=total - len(jobs), enabled=progress)
    bar.write(engine.describe())
    if len(jobs) < total:
        bar.write(f"resumed: {total - len(jobs)} of {total} runs already stored")
    t0 = time.perf_counter()
    interrupted = False

    def done(res: JobResult) -> None:
        label = labels[res.key]
        record = {"label": label, "ok": res.ok, "status": res.status, "value": res.value, "error": res.error,
                  "wall_time_s": res.wall_time_s, "worker": res.worker}
        store.put(res.key, record)
        results[label] = record
        status = res.value["status"] if res.ok else res.status
        bar.done(status in ENDED)
        if status not in ENDED:
            bar.write(f"FAILED {label}: {res.error or res.value.get('error')}")

    try:
        if jobs:
            shared_files = {sha: engine.share(path.read_bytes()) for sha, path in
                            file_bytes([prepared.plans[(c.rec.id, s)] for _, c, s, _ in jobs]).items()}
            shared_plans = {}
            payloads = []
            for _, c, s, scale in jobs:
                pp = prepared.plans[(c.rec.id, s)]
                if (c.rec.id, s) not in shared_plans:
                    shared_plans[(c.rec.id, s)] = engine.share(pp, dedupe=False)
                payloads.append({"plan": shared_plans[(c.rec.id, s)],
                                 "files": {sha: shared_files[sha] for sha in pp.shas},
                                 "scale": scale, "masses": prepared.masses})
            costs = [prepared.plans[(c.rec.id, s)].plan.loaded.scenario.simulation.n_steps for _, c, s, _ in jobs]
            engine.map(ida_job, payloads, [k for k, *_ in jobs], isolate=True, timeout_s=spec.timeout_s, on_done=done,
                       costs=costs)
    except KeyboardInterrupt:
        interrupted = True
        bar.write("interrupted: writing the report of the finished runs")
    bar.close()
    info["finished"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    info["interrupted"] = interrupted
    info["wall_time_s"] = time.perf_counter() - t0
    info["runs_computed"] = sum(1 for k, *_ in jobs if labels[k] in results)
    write_json(folder / "ida.json", info)
    rows = result_rows(info, results, levels, strategies)
    write_outputs(folder, info, rows)
    bad = [r for r in rows if r["status"] not in ENDED]
    print(f"IDA {'interrupted' if interrupted else 'done'}: {folder} ({len(rows)} runs, {len(bad)} not ended: "
          f"failed, lost or not run; {info['wall_time_s']:.0f} s)")
    return 1 if bad or interrupted else 0


# -- command line ---------------------------------------------------------------------------------

def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """Command-line arguments."""
    parser = argparse.ArgumentParser(prog="ida.py", description="Incremental dynamic analysis and fragility.")
    parser.add_argument("study", type=Path, nargs="?", help="IDA study YAML file (scenarios/ida.yaml)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a study key (VALUE as YAML), e.g. --set 'intensity.levels=[0.1, 0.2]'")
    parser.add_argument("--out", type=Path, help="study folder to create (must not exist or be empty)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="run on an existing Dask cluster (default: DASK_SCHEDULER_ADDRESS, else a local one)")
    parser.add_argument("--workers", type=int, help="local cluster: worker processes (default: one per core)")
    parser.add_argument("--resume", type=Path, metavar="DIR", help="finish a study folder: compute what is missing")
    parser.add_argument("--report", type=Path, metavar="DIR", help="regenerate tables, figures and report of DIR")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    if sum(x is not None for x in (args.study, args.report, args.resume)) != 1:
        parser.error("give a study file, or --resume DIR, or --report DIR")
    return args


def main(argv: list[str] | None = None) -> int:
    """CLI entry point; returns the exit code."""
    args = parse_args(argv)
    if args.report is not None:
        try:
            info = json.loads((args.report / "ida.json").read_text())
            rows = read_rows(args.report)
        except (OSError, ValueError) as exc:
            print(f"error: cannot read the study folder {args.report}: {exc}", file=sys.stderr)
            return 2
        write_outputs(args.report, info, rows)
        print(f"report regenerated: {args.report / 'report.md'}")
        return 0
    resumed = None
    prepared = None
    try:
        if args.resume is not None:
            try:
                resumed = json.loads((args.resume / "ida.json").read_text())
                study_file = Path(resumed["study_file"])
                loaded, problems, raw = LoadedIda(IdaSpec.model_validate(resumed["config"]), study_file), [], None
            except (OSError, ValueError, KeyError, TypeError) as exc:
                raise ScenarioError(f"{args.resume} is not an IDA study folder that can be resumed: "
                                    f"{type(exc).__name__}: {exc}") from None
        else:
            study_file = args.study.resolve()
            loaded, problems, raw = load_ida(study_file, tuple(args.overrides))
        prepared = prepare_ida(study_file, loaded, problems, raw)
        spec = prepared.study.spec
        if args.workers is not None and args.workers < 1:
            raise ScenarioError(Problem("--workers must be at least 1", "", "command line"))
        engine = Engine(scheduler_address(args.scheduler), args.workers or spec.workers,
                        max_worker_deaths=spec.max_worker_deaths)
        engine.start()
    except ScenarioError as exc:
        if prepared is not None:
            prepared.cleanup()
        print(exc.report(), file=sys.stderr)
        return 2
    except EngineUnavailable as exc:
        if prepared is not None:
            prepared.cleanup()
        print(f"error: {exc} (nothing computed)", file=sys.stderr)
        return 2
    try:
        folder = args.resume if args.resume is not None else new_run_folder(Path(spec.output), spec.name, args.out)
    except RunFolderExists as exc:
        engine.close()
        prepared.cleanup()
        print(f"error: {exc}", file=sys.stderr)
        return 2

    # SIGTERM raises KeyboardInterrupt here already (components.cli.guarded): handled as Ctrl-C, report written
    try:
        return run_ida(prepared, folder, engine, not args.quiet, [sys.executable, *sys.argv], resumed)
    finally:
        engine.close()
        prepared.cleanup()
