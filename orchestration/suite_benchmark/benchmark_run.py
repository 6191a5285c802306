"""The suite benchmark, whole: ``python orchestration/study.py scenarios/controller_suite_benchmark.yaml``.

1. **Split** the suite by event (:mod:`orchestration.suite_benchmark.event_split`): the training records and the
   scored ones, both components of a station on one side.
2. **Tune** every strategy of ``benchmark.tune`` alike on the training records' components at the study's
   intensity levels (:mod:`orchestration.suite_benchmark.suite_tuning`), and write them as ``<name>-tuned``
   entries (``tuning/tuned_strategies.yaml``, each saying what it was tuned on; ``tuning/history.csv``: every
   setting tried).
3. **Score** the study's strategies and the tuned ones on the scored records: an IDA study folder
   (``score/``: ``results.csv``, figures, report; :mod:`orchestration.ida_study.ida_run`).
4. **Compare** (``verdict/``, :mod:`orchestration.verdict`): each criterion's median over records with its 95 %
   bootstrap interval (``summary.csv``), every pair by a paired Wilcoxon signed-rank test over records,
   Holm-corrected (``pairs.csv``), each record's criteria (``criteria.csv``).

``benchmark.json`` holds the split, the tuned settings and the cost (each phase's wall time, runs and parallel
efficiency: the runs' own wall times over wall time x workers); ``benchmark.md`` is written last, so a folder with
it has its verdict (it names any scored run that failed first). An interrupted benchmark has neither verdict nor
``benchmark.md``, and ``benchmark.json`` says where it stopped. Exit codes: 0 done; 1 a run failed or the study was
interrupted; 2 configuration error (nothing written).
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
import sys
import time
from contextlib import redirect_stdout
from pathlib import Path
from typing import Any

import yaml

from mre_common.guard import invoked_as
from mre_common.project_paths import git
from orchestration.batch.pool import BatchUnavailable
from orchestration.batch.store import check_folder
from orchestration.building_studies.pool_arguments import add_pool_arguments
from orchestration.case_study.strategy_tuner import entry_document, shown_path
from orchestration.ida_study.ida_config import LoadedIda
from orchestration.ida_study.ida_metrics import ENDED
from orchestration.ida_study.ida_plan import PreparedIda, prepare_ida
from orchestration.ida_study.ida_records import utc_now
from orchestration.ida_study.ida_run import run_ida, start_pool
from orchestration.ida_study.paired_verdict import min_records_for, read_results, record_values
from orchestration.ida_study.suites import load_suite
from orchestration.master.errors import Problem, ScenarioError
from orchestration.master.runfolder import RunFolderExists, new_run_folder, write_json, write_text
from orchestration.provenance import provenance
from orchestration.suite_benchmark.benchmark_config import SuiteBenchmarkSpec, load_benchmark
from orchestration.suite_benchmark.event_split import EventSplit, split_events
from orchestration.suite_benchmark.suite_tuning import METHOD, SuiteRunner, SuiteTarget, plan_targets, tune_all

TUNED = "-tuned"  # a tuned strategy's name: <name>-tuned


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog=invoked_as("study.py"), description="A suite benchmark: strategies tuned "
                                     "alike on some events of a record suite, scored on the others.")
    parser.add_argument("study", type=Path, help="suite benchmark YAML file (an IDA study with benchmark:)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a study key, e.g. --set benchmark.budget=8")
    parser.add_argument("--out", type=Path, help="study folder to create (must not exist or be empty)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")
    add_pool_arguments(parser)
    return parser.parse_args(argv)


def _at(loaded: LoadedIda, *key: Any) -> tuple[str, int | None]:
    return loaded.lines.get(tuple(key)) or loaded.lines.get(tuple(key[:-1])) or (str(loaded.path), None)


def _located(loaded: LoadedIda, problems: list[Problem]) -> list[Problem]:
    """Problems keyed ``benchmark.x.k`` given the file and line of that key."""
    out = []
    for p in problems:
        key = tuple(int(k) if k.isdigit() else k for k in p.key.split("."))
        out.append(Problem(p.message, p.key, *_at(loaded, *key)) if not p.file else p)
    return out


def the_split(loaded: LoadedIda, bench: SuiteBenchmarkSpec) -> EventSplit:
    """The suite's records split as the section says; ScenarioError (located) otherwise."""
    spec = loaded.spec
    suite = spec.suite if isinstance(spec.suite, str) else spec.suite.model_dump()
    records, problems = load_suite(suite, loaded.base_dir("suite", "folder"))
    if problems:
        raise ScenarioError(problems)
    events = list(dict.fromkeys(r.record for r in records))
    groups = None
    if bench.split_by == "earthquake":
        named = {r.record: r.meta.get("earthquake") for r in records}
        if any(v is None for v in named.values()):
            raise ScenarioError(Problem("split_by: earthquake needs a suite that names each record's earthquake "
                                        "(the FEMA P695 far-field set does; a folder suite does not): use split_by: "
                                        "record", "benchmark.split_by", *_at(loaded, "benchmark", "split_by")))
        groups = {e: str(g) for e, g in named.items()}
    split, problems = split_events(events, bench.train, bench.split_seed, bench.score, bench.overlap, groups)
    if split is None:
        raise ScenarioError(_located(loaded, problems))
    return split


def check_names(loaded: LoadedIda, bench: SuiteBenchmarkSpec) -> list[str]:
    """The strategies scored (the study's, then each tuned one); ScenarioError for an unknown strategy to tune, a
    tuned name already taken, or too few scored records for the first paired test to pass."""
    library, problems = loaded.library, []
    for k, name in enumerate(bench.tune):
        if name not in library:
            problems.append(Problem(f"unknown strategy {name!r} (known: {', '.join(library)})",
                                    f"benchmark.tune.{k}", *_at(loaded, "benchmark", "tune", k)))
        elif name + TUNED in library or name + TUNED in loaded.spec.strategy_names:
            problems.append(Problem(f"{name + TUNED!r} is already a strategy: the benchmark names its tuned entries "
                                    "<name>-tuned (leave that file out of strategy_files)", f"benchmark.tune.{k}",
                                    *_at(loaded, "benchmark", "tune", k)))
    if problems:
        raise ScenarioError(problems)
    return [*loaded.spec.strategy_names, *(n + TUNED for n in bench.tune)]


def enough_records(split: EventSplit, scored: list[str], bench: SuiteBenchmarkSpec, loaded: LoadedIda) -> None:
    """ScenarioError when the scored records are too few for any Holm-corrected signed-rank test to pass."""
    compared = len([s for s in scored if s != loaded.uncontrolled])
    family = compared * (compared - 1) // 2 * len(bench.criteria)
    need = min_records_for(bench.alpha / max(1, family))
    if len(split.score) < need:
        raise ScenarioError(Problem(
            f"{len(split.score)} scored records cannot carry the verdict: {family} paired comparisons "
            f"(Holm, alpha {bench.alpha:g}) need at least {need} records for the first to pass. Score more records, "
            "or compare fewer strategies or criteria", "benchmark.score", *_at(loaded, "benchmark")))


def training_study(loaded: LoadedIda, bench: SuiteBenchmarkSpec, split: EventSplit) -> PreparedIda:
    """The training records' components planned for the uncontrolled strategy and every strategy to tune."""
    spec = loaded.spec.model_copy(update={"events": split.train, "strategies": [loaded.uncontrolled, *bench.tune]})
    return prepare_ida(loaded.path, LoadedIda(spec, loaded.path, loaded.lines), [], None)


def scoring_study(loaded: LoadedIda, split: EventSplit, scored: list[str], tuned_file: Path) -> PreparedIda:
    """The scored records' components planned for the study's strategies and the tuned ones."""
    spec = loaded.spec.model_copy(update={"events": split.score, "strategies": scored,
                                          "strategy_files": [*loaded.spec.strategy_files, str(tuned_file)]})
    return prepare_ida(loaded.path, LoadedIda(spec, loaded.path, loaded.lines), [], None)


def tuned_document(loaded: LoadedIda, bench: SuiteBenchmarkSpec, split: EventSplit, prepared: PreparedIda,
                   targets: dict[str, SuiteTarget], results: dict[str, dict[str, Any]], out: Path) -> str:
    """YAML text of the tuned strategy file: one entry ``<name>-tuned`` per strategy, saying what it was tuned on."""
    entries = {}
    for name, target in targets.items():
        r = results[name]
        doc = entry_document(target.strategy, r["parameters"], out)
        doc["tuned"] = {
            "from": f"{name} ({shown_path(target.strategy.file)})", "study": shown_path(loaded.path),
            "suite": loaded.spec.suite if isinstance(loaded.spec.suite, str) else shown_path(
                loaded.resolve(loaded.spec.suite.folder, "suite", "folder")),
            "records": split.train, "split": split.how,
            "components": [c.rec.id for c in prepared.components], "levels": list(loaded.spec.intensity.levels),
            "measure": loaded.spec.intensity.measure, "period_s": prepared.period_s,
            "objective": bench.objective.model_dump(), "J": r["J"], "J_start": r["J_start"], "budget": bench.budget,
            "evaluations": r["evaluations"], "runs": r["runs"], "population": r["population"],
            "generations": r["generations"], "failed_runs": r["failed_runs"], "seed": bench.seed, "method": METHOD,
            "wall_time_s": round(r["wall_time_s"], 1), "created": utc_now(), "commit": git("rev-parse", "HEAD"),
            "uncommitted_changes": bool(git("status", "--porcelain", "--", "components", "orchestration"))}
        entries[name + TUNED] = doc
    head = ("# Strategies tuned by orchestration/suite_benchmark (docs/controllers.md, \"The suite benchmark\") on the "
            "training records of the suite; do not edit by hand.\n")
    body = {"description": f"strategies tuned alike on {', '.join(split.train)} ({loaded.path.name})",
            "strategies": entries}
    return head + yaml.safe_dump(body, sort_keys=False, width=100000, default_flow_style=None)


def history_csv(results: dict[str, dict[str, Any]]) -> str:
    """Every setting tried, a row each: strategy, evaluation, parameters, J."""
    names = sorted({k for r in results.values() for h in r["history"] for k in h if k != "J"})
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["strategy", "evaluation", *names, "J"])
    for s, r in results.items():
        for k, h in enumerate(r["history"]):
            w.writerow([s, k, *(repr(h[n]) if n in h else "" for n in names), repr(h["J"])])
    return buf.getvalue()


def criteria_csv(rows: list[dict[str, str]], level: float, strategies: list[str], criteria: list[str]) -> str:
    """Each record's value of each criterion per strategy (the geometric mean of its valid components)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["record", "strategy", *criteria])
    values = {c: record_values(rows, level, c) for c in criteria}
    records = sorted({rec for c in criteria for s in values[c].values() for rec in s})
    for rec in records:
        for s in strategies:
            cells = [values[c].get(s, {}).get(rec) for c in criteria]
            w.writerow([rec, s, *("" if v is None else repr(v) for v in cells)])
    return buf.getvalue()


def scoring_times(folder: Path) -> tuple[list[float], list[float]]:
    """Each scored job's wall time (fork to result) and its run's own (``run_plan``) [s], from ``jobs/``."""
    jobs, runs = [], []
    for p in sorted((folder / "jobs").glob("*.json")):
        d = json.loads(p.read_text())
        jobs.append(float(d.get("wall_time_s") or 0.0))
        runs.append(float((d.get("value") or {}).get("run_wall_time_s") or 0.0))
    return jobs, runs


def efficiency(run_times: list[float], wall: float, workers: int) -> float:
    """Parallel efficiency: the jobs' (or runs') wall times summed over the phase's wall time x workers (1: no
    worker ever idle, and, with the runs' own times, no time spent starting a job or passing its result)."""
    return sum(run_times) / (wall * workers) if wall > 0 and workers > 0 else math.nan


def report(info: dict[str, Any], verdict_md: str) -> str:
    """benchmark.md: the split, the tuning, the cost, then the verdict."""
    split, cost = info["split"], info["cost"]
    failed = info.get("failed_runs") or []
    warning = [f"**{len(failed)} scored runs failed** (their records count with their other valid runs only): "
               + "; ".join(failed[:10]), ""] if failed else []
    lines = [f"# Suite benchmark: {info['name']}", "", info.get("description", ""), "", *warning,
             f"- Trained on {len(split['train'])} records ({split['how']}): {', '.join(split['train'])}.",
             f"- Scored on {len(split['score'])} records: {', '.join(split['score'])}.",
             f"- Intensity: {info['measure']} at {', '.join(f'{x:g}' for x in info['levels'])} g, "
             f"T1 = {info['period_s']:.4f} s." if info["period_s"] else "", "",
             "| strategy tuned | J (tuned) | J (its own setting) | settings | runs | failed runs | wall [s] |",
             "|---|---|---|---|---|---|---|"]
    for name, r in info["tuning"].items():
        own = "-" if r["J_start"] is None else f"{r['J_start']:.4f}"
        lines.append(f"| {name} | {r['J']:.4f} | {own} | {r['evaluations']} | {r['runs']} | {r['failed_runs']} | "
                     f"{r['wall_time_s']:.0f} |")
    lines += ["", f"Cost on {cost['workers']} workers (parallel efficiency: the jobs' wall times, and the runs' "
              "own, over the phase's wall time x workers):", "",
              "| phase | wall [s] | runs | efficiency, jobs | efficiency, runs |", "|---|---|---|---|---|",
              f"| tuning | {cost['tuning_s']:.0f} | {cost['tuning_runs']} | {cost['tuning_efficiency']:.2f} | "
              f"{cost['tuning_run_efficiency']:.2f} |",
              f"| scoring | {cost['scoring_s']:.0f} | {cost['scoring_runs']} | {cost['scoring_efficiency']:.2f} | "
              f"{cost['scoring_run_efficiency']:.2f} |",
              f"| whole command | {cost['total_s']:.0f} | | | |", "", verdict_md.replace("# Verdict", "## Verdict", 1)]
    return "\n".join(lines) + "\n"


def _prepare(args: argparse.Namespace) -> tuple[LoadedIda, SuiteBenchmarkSpec, EventSplit, list[str], PreparedIda,
                                                dict[str, SuiteTarget]]:
    loaded, bench = load_benchmark(args.study, tuple(args.overrides))
    scored = check_names(loaded, bench)
    split = the_split(loaded, bench)
    enough_records(split, scored, bench, loaded)
    train = training_study(loaded, bench, split)
    try:
        targets = plan_targets(train, bench.tune, bench.budget)
    except BaseException:
        train.cleanup()
        raise
    return loaded, bench, split, scored, train, targets


def main(argv: list[str] | None = None) -> int:
    """CLI: the whole suite benchmark; returns the exit code."""
    args = parse_args(argv)
    t_start = time.perf_counter()
    train = None
    try:
        loaded, bench, split, scored, train, targets = _prepare(args)
        spec = loaded.spec
        check_folder(spec.name, Path(spec.output), args.out, loaded.lines, loaded.path)
        pool = start_pool(args, spec)
    except (ScenarioError, BatchUnavailable) as exc:
        if train is not None:
            train.cleanup()
        print(exc.report() if isinstance(exc, ScenarioError) else f"error: {exc} (nothing computed)", file=sys.stderr)
        return 2
    try:
        folder = new_run_folder(Path(spec.output), spec.name, args.out)
    except RunFolderExists as exc:
        pool.close()
        train.cleanup()
        print(f"error: {exc}", file=sys.stderr)
        return 2
    progress = not args.quiet
    info: dict[str, Any] = {"name": spec.name, "description": spec.description, "study_file": str(loaded.path),
                            "started": utc_now(), "benchmark": bench.model_dump(mode="json"),
                            "split": {"train": split.train, "score": split.score, "how": split.how},
                            "measure": spec.intensity.measure, "levels": list(spec.intensity.levels),
                            "period_s": train.period_s, "complete": False,
                            "provenance": {**provenance(), "command": [sys.executable, *sys.argv]}}
    write_json(folder / "benchmark.json", info)
    score = None
    try:
        if progress:
            print(f"{pool.describe()}\nsplit ({split.how}): train on {', '.join(split.train)}; score "
                  f"{len(split.score)} records", file=sys.stderr)
        runner = SuiteRunner(train, train.components, list(spec.intensity.levels), pool)
        t0 = time.perf_counter()
        try:
            results, off = tune_all(train, targets, runner, bench.objective, bench.budget, bench.seed, progress)
        except KeyboardInterrupt:
            info["interrupted"] = "tuning"
            write_json(folder / "benchmark.json", info)
            print(f"interrupted while tuning: nothing scored ({folder})", file=sys.stderr)
            return 1
        except RuntimeError as exc:  # the uncontrolled strategy failed on a training run: no J can be formed
            info["error"] = str(exc)
            write_json(folder / "benchmark.json", info)
            print(f"error: {exc}; nothing scored ({folder})", file=sys.stderr)
            return 1
        tuning_s = time.perf_counter() - t0
        unfit = [n for n, r in results.items() if not math.isfinite(r["J"])]
        if unfit:
            info["error"] = f"no finite objective for {', '.join(unfit)}: every setting had a failed or invalid run"
            info["tuning_errors"] = runner.errors[:50]
            write_json(folder / "benchmark.json", info)
            print(f"error: {info['error']} ({runner.errors[:1]}); nothing scored ({folder})", file=sys.stderr)
            return 1
        (folder / "tuning").mkdir()
        tuned_file = folder / "tuning" / "tuned_strategies.yaml"
        write_text(tuned_file, tuned_document(loaded, bench, split, train, targets, results, tuned_file))
        write_text(folder / "tuning" / "history.csv", history_csv(results))
        write_json(folder / "tuning" / "passive_off.json", off)
        info["tuning"] = {n: {k: v for k, v in r.items() if k != "history"} for n, r in results.items()}
        info["tuning_errors"] = runner.errors[:50]
        write_json(folder / "benchmark.json", info)
        score = scoring_study(loaded, split, scored, tuned_file.resolve())
        (folder / "score").mkdir()
        t1 = time.perf_counter()
        code = run_ida(score, folder / "score", pool, progress, [sys.executable, *sys.argv])
        scoring_s = time.perf_counter() - t1
    finally:
        pool.close()
        train.cleanup()
        if score is not None:
            score.cleanup()
    if json.loads((folder / "score" / "ida.json").read_text()).get("interrupted"):
        info["interrupted"] = "scoring"
        write_json(folder / "benchmark.json", info)
        print(f"interrupted while scoring: no verdict ({folder}; the finished runs are in score/)", file=sys.stderr)
        return 1
    rows = read_results(folder / "score" / "results.csv")
    failed = [r for r in rows if r["status"] not in ENDED]
    info["failed_runs"] = [f"{r['record_id']}/{r['strategy']}: {r['status']} {r['error']}" for r in failed]
    level = min(float(r["intensity"]) for r in rows)
    compared = [s for s in scored if s != loaded.uncontrolled]
    from orchestration.verdict import main as verdict_main

    buf = io.StringIO()
    with redirect_stdout(buf):
        verdict_code = verdict_main([str(folder / "score"), "--out", str(folder / "verdict"), "--level", repr(level),
                                     "--alpha", repr(bench.alpha), "--criteria", *bench.criteria, "--strategies",
                                     *compared])
    if verdict_code != 0:
        print(f"error: the verdict of {folder / 'score'} failed (exit {verdict_code})", file=sys.stderr)
        return 1
    write_text(folder / "verdict" / "criteria.csv", criteria_csv(rows, level, scored, bench.criteria))
    score_jobs, score_runs = scoring_times(folder / "score")
    w = pool.n_workers
    info["cost"] = {"workers": w, "tuning_s": tuning_s, "tuning_runs": len(runner.run_times),
                    "tuning_runs_per_strategy": {n: r["runs"] for n, r in results.items()},
                    "tuning_efficiency": efficiency(runner.run_times, tuning_s, w),
                    "tuning_run_efficiency": efficiency(runner.stepping_times, tuning_s, w),
                    "scoring_s": scoring_s, "scoring_runs": len(rows),
                    "scoring_efficiency": efficiency(score_jobs, scoring_s, w),
                    "scoring_run_efficiency": efficiency(score_runs, scoring_s, w),
                    "total_s": time.perf_counter() - t_start}
    info.update(finished=utc_now(), complete=code == 0)
    write_json(folder / "benchmark.json", info)
    text = report(info, (folder / "verdict" / "verdict.md").read_text())
    write_text(folder / "benchmark.md", text)  # last: the folder is complete
    print(text if progress else f"suite benchmark done: {folder}")
    print(f"suite benchmark {'done' if code == 0 else 'done with failed runs'}: {folder}", file=sys.stderr)
    return code
