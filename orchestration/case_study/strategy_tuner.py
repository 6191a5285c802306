"""One tuner for every strategy: the ``tunable:`` parameters of strategy entries, searched alike.

A study file names the strategies under ``strategy_tuning:`` (:class:`~orchestration.case_study.case_config.
StrategyTuningSpec`); ``python orchestration/tune.py STUDY`` (or ``mre-cosim tune STUDY``) then tunes each of them
with the same objective, budget and seed, and writes the tuned entries as a new strategy file. Run::

    python orchestration/tune.py scenarios/strategy_tuning.yaml [--force] [--set strategy_tuning.budget=60]

**The search.** Each tunable parameter is a coordinate u in [0, 1], mapped to its range linearly or in log
(:func:`to_value`, :func:`to_unit`; an Integer parameter of the FMU is rounded). The optimiser is
``scipy.optimize.differential_evolution`` over that unit cube, because it is deterministic for a given seed, needs
no gradient (the objective is a co-simulation), keeps every point within the bounds, evaluates a whole generation
at once (``vectorized``: one batch of runs on the pool) and is already a dependency (no Optuna). Its first
generation is a seeded Latin hypercube whose first point is the entry's own setting where it lies in the ranges (so
the tuned J is never worse than the shipped one on the training records); the population has
:func:`population_size` members and the budget buys ``budget // population - 1`` generations, with ``tol = 0`` (no
early stop: every strategy spends the same budget) and no polishing (which would spend runs beyond it).

**The objective.** J of :func:`orchestration.case_study.objective.objective` (the study's ``objective``), each run
against passive-off on the same record and window, averaged over the training records. Every point is a
co-simulation of the strategy's FMUs (the engine's plan, parameters set on top, on the batch pool in a child
process each, as the case study's runs), the first ``stop_time`` seconds of each record; a run that fails counts
as J = inf. A budget below the number of parameters + 1 is a configuration error (exit 2).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from mre_common.guard import invoked_as
from mre_common.project_paths import git
from orchestration.building_studies.pool_arguments import add_pool_arguments
from orchestration.building_studies.run_metrics import CURRENT, recorded_series
from orchestration.building_studies.run_settings import RECORDED, run_overrides
from orchestration.building_studies.strategies import (
    BEST,
    COMMAND,
    CONTROLLER,
    I_MAX,
    Strategy,
    StrategyEntry,
    TunableRange,
    tunable_problems,
)
from orchestration.case_study.case_config import LoadedStudy, ObjectiveSpec, StrategyTuningSpec, load_study
from orchestration.case_study.objective import objective
from orchestration.master.errors import Problem, ScenarioError
from orchestration.master.resolve import SystemPlan
from orchestration.master.yaml_source import load_tree

KEY = "strategy_tuning"  # the study file's section that asks for this tuner
OUTPUTS_OVERRIDE = "outputs=[" + ", ".join(RECORDED) + "]"
MIN_DE_POPULATION = 5  # differential evolution's mutation draws distinct members: fewer, the Latin hypercube only


# -- the pure part: ranges, budget, optimiser ------------------------------------------------------------------
def to_value(u: float, rng: TunableRange) -> float:
    """The parameter value of a unit coordinate u in [0, 1] (clipped): linear, or geometric for a log range."""
    u = min(1.0, max(0.0, float(u)))
    if u in (0.0, 1.0):  # the ends exactly, not within rounding
        return rng.low if u == 0.0 else rng.high
    if rng.scale == "log":
        return math.exp(math.log(rng.low) + u * (math.log(rng.high) - math.log(rng.low)))
    return rng.low + u * (rng.high - rng.low)


def to_unit(value: float, rng: TunableRange) -> float:
    """The unit coordinate of a parameter value (the inverse of :func:`to_value`; outside the range: outside [0, 1])."""
    if rng.scale == "log":
        return (math.log(value) - math.log(rng.low)) / (math.log(rng.high) - math.log(rng.low))
    return (value - rng.low) / (rng.high - rng.low)


def parameter_values(u: Sequence[float], ranges: Mapping[str, TunableRange], integer: frozenset[str] = frozenset()
                     ) -> dict[str, float | int]:
    """Parameter name -> value of a point of the unit cube (``u`` in the order of ``ranges``); ``integer`` names are
    rounded (an FMU Integer parameter)."""
    out: dict[str, float | int] = {}
    for x, (name, rng) in zip(u, ranges.items(), strict=True):
        v = to_value(x, rng)
        out[name] = round(v) if name in integer else v
    return out


def budget_problem(n_parameters: int, budget: int) -> str | None:
    """Why ``budget`` settings cannot tune ``n_parameters`` (fewer than n + 1: not even one simplex), or None."""
    if budget < n_parameters + 1:
        return (f"a budget of {budget} settings cannot tune {n_parameters} parameters: it needs at least "
                f"{n_parameters + 1} (the parameters + 1)")
    return None


def population_size(n_parameters: int, budget: int) -> int:
    """Members of each generation: 10 per parameter, but at most a fifth of the budget (five generations or more),
    at least n + 1 and (if the budget allows) the 5 differential evolution needs."""
    return min(budget, max(n_parameters + 1, min(MIN_DE_POPULATION, budget), min(10 * n_parameters, budget // 5)))


# evaluate(points) -> J of each: points is an (S, n) array of the unit cube, one row per setting
BatchObjective = Callable[[np.ndarray], Sequence[float]]


@dataclass
class SearchResult:
    """What :func:`optimise` found: the best point (unit cube) and its J, and every point tried, in order."""

    best: np.ndarray
    value: float
    points: list[np.ndarray] = field(default_factory=list)
    values: list[float] = field(default_factory=list)
    population: int = 0
    generations: int = 0


def optimise(evaluate: BatchObjective, n_parameters: int, budget: int, seed: int,
             start: Sequence[float] | None = None) -> SearchResult:
    """Minimise ``evaluate`` over the unit cube [0, 1]^n with at most ``budget`` points (see the module docstring).

    ``start``: a point put first in the initial Latin hypercube (the entry's own setting). Deterministic for a
    seed; ValueError if the budget is below n + 1.
    """
    from scipy.optimize import differential_evolution
    from scipy.stats import qmc

    problem = budget_problem(n_parameters, budget)
    if problem is not None:
        raise ValueError(problem)
    p = population_size(n_parameters, budget)
    generations = budget // p - 1 if p >= MIN_DE_POPULATION else 0
    init = qmc.LatinHypercube(d=n_parameters, rng=np.random.default_rng(seed)).random(p)
    if start is not None:
        init[0] = np.clip(np.asarray(start, dtype=float), 0.0, 1.0)
    result = SearchResult(best=init[0], value=math.inf, population=p, generations=generations)

    def f(x: np.ndarray) -> np.ndarray:  # differential evolution's vectorized call: x is (n, S)
        points = np.atleast_2d(np.asarray(x, dtype=float).T).reshape(-1, n_parameters)
        if len(result.points) + len(points) > budget:  # never: the generations are counted to fit
            raise RuntimeError("the search would exceed its budget")
        values = np.asarray([float(v) if math.isfinite(float(v)) else math.inf for v in evaluate(points)])
        result.points.extend(np.array(q) for q in points)
        result.values.extend(float(v) for v in values)
        return values

    if generations <= 0:
        f(init.T)
    else:
        differential_evolution(f, [(0.0, 1.0)] * n_parameters, maxiter=generations, init=init, tol=0.0, atol=0.0,
                               polish=False, rng=np.random.default_rng(seed), vectorized=True, updating="deferred")
    k = int(np.argmin(result.values))
    result.best, result.value = result.points[k], result.values[k]
    return result


# -- what a strategy's runs are ----------------------------------------------------------------------------------
def run_peaks(columns: Mapping[str, np.ndarray], i_limit: float) -> dict[str, float]:
    """The peaks and current statistics :func:`~orchestration.case_study.objective.objective` reads, from a run's
    time series: a3 peak top-floor absolute acceleration [m/s^2], d peak drift over storeys [m], x0 peak base
    displacement [m], the current's mean, min, max [A], shares of the time at ``i_limit`` [A] and at 0 A."""
    floors = sorted(int(k.rsplit("_", 1)[1]) for k in columns if k.startswith("building.a_"))
    drifts = [np.abs(v) for k, v in columns.items() if k.startswith("building.drift_")]
    i = np.asarray(columns[CURRENT], dtype=float)
    return {"a3": float(np.max(np.abs(columns[f"building.a_{floors[-1]}"]))),
            "d": float(np.max([np.max(d) for d in drifts])), "x0": float(np.max(np.abs(columns["building.x_0"]))),
            "i_mean": float(np.mean(i)), "i_min": float(np.min(i)), "i_max": float(np.max(i)), "i_limit": i_limit,
            "s_bound": float(np.mean(i >= i_limit - 1e-6)), "s_zero": float(np.mean(i <= 1e-6))}


def strategy_run_job(payload: dict[str, Any]) -> dict[str, float]:
    """One training run on a worker: the payload's plan with ``parameters`` set on top; its :func:`run_peaks`."""
    from orchestration.batch.jobs import job_plan, run_folder_prefix
    from orchestration.master.session import run_plan

    plan, _ = job_plan(payload, payload["parameters"])
    with tempfile.TemporaryDirectory(prefix=run_folder_prefix(os.getpid())) as tmp:
        outcome = run_plan(plan, Path(tmp) / "run", plots=False, progress=False, results_file=False)
    if not outcome.result.complete:
        raise RuntimeError(f"run {outcome.result.status}: {outcome.result.error}")
    current = getattr(plan.report, "current", None)
    return run_peaks(recorded_series(outcome.recorder, None if current is None else str(current)),
                     float(payload["i_limit"]))


def folded(strategy: Strategy, gains: dict[str, float] | None) -> Strategy:
    """The strategy with its gain set's values written as parameters (a tuned parameter must win over the gain
    set, which :meth:`Strategy.overrides` applies last)."""
    e = strategy.entry
    if e.gains is None:
        return strategy
    if gains is None:
        raise ScenarioError(strategy.problem(f"no gains for the gain set {e.gains!r}", "gains"))
    params = {**e.parameters, **{k: float(gains[k]) for k in ("lambda", "rho", "zeta", "theta")}}
    if e.gains_limit:
        params[strategy.limit_parameter() or "i_max"] = float(gains["i_max"])
    if "s_release" in gains:
        params["s_release"] = float(gains["s_release"])
    entry = e.model_copy(update={"parameters": params, "gains": None, "gains_limit": False})
    return Strategy(strategy.name, entry, strategy.file, strategy.lines, strategy.prefix)


@dataclass
class Target:
    """One strategy to tune: its entry (gains folded in), its FMU's Integer parameters, its limit [A], the start
    point (unit cube, or None) and the planned runs per training record."""

    strategy: Strategy
    integer: frozenset[str]
    i_limit: float
    start: list[float] | None
    plans: dict[str, SystemPlan]

    @property
    def ranges(self) -> dict[str, TunableRange]:
        return dict(self.strategy.entry.tunable)


def _located(study: LoadedStudy, message: str, *key: Any) -> Problem:
    file, line = study.lines.get((KEY, *key)) or study.lines.get((KEY, key[0])) or study.lines.get((KEY,)) or (
        str(study.path), None)
    return Problem(message, ".".join(str(k) for k in (KEY, *key)), file or str(study.path), line)


def run_overrides_of(study: LoadedStudy, strategy: Strategy, record: str, values: Mapping[str, Any]
                     ) -> tuple[str, ...]:
    """The overrides of a training run: the study's, the strategy's controller and wiring with ``values`` set, the
    recorded variables and the window's stop time."""
    spec, tuning = study.spec, _tuning(study)
    path = study.scenario_path(record)
    entry = strategy.entry.model_copy(update={"parameters": {**strategy.entry.parameters, **values}})
    s = Strategy(strategy.name, entry, strategy.file, strategy.lines, strategy.prefix)
    rewired = entry.connections is not None or entry.current != COMMAND
    wiring = s.wiring_overrides(list(load_tree(path)[0].get("connections") or [])) if rewired else ()
    stop = () if tuning.stop_time is None else (f"simulation.stop_time={tuning.stop_time!r}",)
    return (*s.common(run_overrides(spec)), *s.overrides(spec.i_max, None, None), *wiring,
            s.recorded(OUTPUTS_OVERRIDE), *stop)


def _tuning(study: LoadedStudy) -> StrategyTuningSpec:
    if study.spec.strategy_tuning is None:
        raise ScenarioError(f"{study.path}: no {KEY} section: nothing to tune")
    return study.spec.strategy_tuning


def start_point(strategy: Strategy, unit_starts: Mapping[str, Any], i_max: float) -> list[float] | None:
    """The entry's own setting (its parameters, else the FMU's start values) in the unit cube, if inside it."""
    u = []
    for name, rng in strategy.entry.tunable.items():
        v = strategy.entry.parameters.get(name, unit_starts.get(name))
        v = i_max if v == I_MAX else v
        if isinstance(v, bool) or not isinstance(v, int | float) or (rng.scale == "log" and v <= 0):
            return None
        x = to_unit(float(v), rng)
        if not 0.0 <= x <= 1.0:
            return None
        u.append(x)
    return u


def plan_target(study: LoadedStudy, name: str, k: int, gains: dict[str, float] | None) -> Target:
    """Check one listed strategy and plan its runs (at its start point, and at both corners of its ranges, so that a
    range end the FMU's parameter check refuses is said now); ScenarioError located in the strategy entry or at
    ``strategy_tuning.strategies.k``."""
    from orchestration.engine_hooks import plan_scenario

    tuning = _tuning(study)
    strategy = folded(study.strategy(name), gains)
    ranges = strategy.entry.tunable
    if not ranges:
        raise ScenarioError(_located(study, f"strategy {name!r} declares no tunable: parameters (its entry in "
                                     f"{strategy.file})", "strategies", k))
    if problem := budget_problem(len(ranges), tuning.budget):
        raise ScenarioError(_located(study, f"strategy {name!r}: {problem}", "budget"))
    if any(v == BEST for v in strategy.entry.parameters.values()):
        raise ScenarioError(_located(study, f"strategy {name!r} uses {BEST}, which a tuning has no sweep for",
                                     "strategies", k))
    plans, problems = {}, []
    for r in tuning.records:
        try:
            plans[r] = plan_scenario(study.scenario_path(r), run_overrides_of(study, strategy, r, {}))
        except ScenarioError as exc:
            problems += exc.problems
    unit = next(iter(plans.values())).descriptions[CONTROLLER] if plans else None
    if unit is not None:
        problems = [*tunable_problems(strategy, unit), *problems]
    if problems or unit is None:
        raise ScenarioError(problems)
    integer = frozenset(n for n in ranges if unit.variables[n].type == "Integer")
    for r in plans:
        for end in (0.0, 1.0):
            try:
                plan_scenario(study.scenario_path(r), run_overrides_of(
                    study, strategy, r, parameter_values([end] * len(ranges), ranges, integer)))
            except ScenarioError as exc:
                problems += [strategy.problem(f"at the {'low' if end == 0 else 'high'} ends of the tunable ranges "
                                              f"(record {r}): {p.message}", "tunable") for p in exc.problems]
    if problems:
        raise ScenarioError(problems)
    limit = strategy.entry.parameters.get(strategy.limit_parameter() or "i_max", study.spec.i_max)
    i_limit = study.spec.i_max if limit == I_MAX or not isinstance(limit, int | float) else float(limit)
    starts = {n: v.start for n, v in unit.variables.items()}
    return Target(strategy, integer, i_limit, start_point(strategy, starts, study.spec.i_max), plans)


def plan_targets(study: LoadedStudy) -> dict[str, Target]:
    """Every listed strategy checked and planned, every problem collected (ScenarioError)."""
    from orchestration.building_studies.gains_file import read_gains

    tuning = _tuning(study)
    unknown = [r for r in tuning.records if r not in study.spec.records]
    if unknown:
        raise ScenarioError(_located(study, f"{unknown} is not one of the records {list(study.spec.records)}",
                                     "record"))
    targets, problems = {}, []
    for k, name in enumerate(tuning.strategies):
        gain_set = study.strategy(name).entry.gains
        gains = read_gains(study.gain_set_path(gain_set))[0] if gain_set else None
        values = None if gains is None else {"lambda": gains.lam, "rho": gains.rho, "zeta": gains.zeta,
                                             "theta": gains.theta, "i_max": gains.i_max, "s_release": gains.s_release}
        try:
            targets[name] = plan_target(study, name, k, values)
        except ScenarioError as exc:
            problems += exc.problems
    if problems:
        raise ScenarioError(problems)
    return targets


# -- running on the pool -------------------------------------------------------------------------------------------
Runner = Callable[[list[tuple[SystemPlan, dict[str, Any], float]]], list[dict[str, float] | None]]
"""runs([(plan, controller parameters, i_limit), ...]) -> peaks of each, or None for a run that failed."""


class PoolRunner:
    """A :data:`Runner` on a Dask pool: each run in a child process of a worker, each plan's files shared once;
    ``errors`` keeps why each failed run failed."""

    def __init__(self, pool: Any, timeout_s: float | None) -> None:
        self.pool, self.timeout_s = pool, timeout_s
        self.errors: list[str] = []
        self._shared: dict[int, tuple[Any, dict[str, Any]]] = {}

    def _handle(self, plan: SystemPlan) -> tuple[Any, dict[str, Any]]:
        from orchestration.batch.portable import file_bytes, portable

        if id(plan) not in self._shared:
            pp = portable(plan)
            files = {sha: self.pool.share(path.read_bytes()) for sha, path in file_bytes([pp]).items()}
            self._shared[id(plan)] = (self.pool.share(pp, dedupe=False), files)
        return self._shared[id(plan)]

    def __call__(self, jobs: list[tuple[SystemPlan, dict[str, Any], float]]) -> list[dict[str, float] | None]:
        payloads = []
        for plan, values, i_limit in jobs:
            pp, files = self._handle(plan)
            payloads.append({"plan": pp, "files": files, "parameters": {CONTROLLER: dict(values)}, "i_limit": i_limit})
        results = self.pool.map(strategy_run_job, payloads, isolate=True, timeout_s=self.timeout_s)
        self.errors.extend(f"{r.key} {r.status}: {r.error}" for r in results if not r.ok)
        return [r.value if r.ok else None for r in results]


def tune_target(target: Target, tuning: StrategyTuningSpec, obj: ObjectiveSpec, off: Mapping[str, dict[str, float]],
                runs: Runner) -> dict[str, Any]:
    """Tune one strategy: its best parameters, J, J of its own setting, and every setting tried with its J."""
    ranges, failed = target.ranges, [0]

    def evaluate(points: np.ndarray) -> list[float]:
        settings = [parameter_values(q, ranges, target.integer) for q in points]
        peaks = runs([(target.plans[r], s, target.i_limit) for s in settings for r in target.plans])
        n, out = len(target.plans), []
        for k in range(len(settings)):
            per = peaks[k * n:(k + 1) * n]
            failed[0] += sum(p is None for p in per)
            out.append(math.inf if any(p is None for p in per) else float(np.mean(
                [objective(p, off[r], obj) for p, r in zip(per, target.plans, strict=True) if p is not None])))
        return out

    started = time.time()
    found = optimise(evaluate, len(ranges), tuning.budget, tuning.seed, target.start)
    history = [{**parameter_values(q, ranges, target.integer), "J": j}
               for q, j in zip(found.points, found.values, strict=True)]
    return {"parameters": parameter_values(found.best, ranges, target.integer), "J": found.value,
            "J_start": found.values[0] if target.start is not None else None, "evaluations": len(found.points),
            "population": found.population, "generations": found.generations, "failed_runs": failed[0],
            "history": history, "wall_time_s": time.time() - started}


# -- the strategy file written -------------------------------------------------------------------------------------
def entry_document(s: Strategy, parameters: Mapping[str, Any], out: Path) -> dict[str, Any]:
    """A strategy's entry with ``parameters`` set on its own, labelled "(tuned)", as a strategy file ``out``
    writes it (``fmu`` relative to ``out``'s folder if both lie below one folder other than the root)."""
    entry: StrategyEntry = s.entry.model_copy(update={
        "label": f"{s.label} (tuned)", "parameters": {**s.entry.parameters, **parameters}, "tuned": None})
    doc = entry.model_dump(mode="json", exclude_defaults=True)
    if s.fmu_path is not None:
        folder = out.parent.resolve()
        near = Path(os.path.commonpath([s.fmu_path, folder])) != Path(folder.anchor)
        doc["fmu"] = os.path.relpath(s.fmu_path, folder) if near else str(s.fmu_path)
    return doc


def tuned_entry(target: Target, result: dict[str, Any], study: LoadedStudy, out: Path) -> dict[str, Any]:
    """The tuned entry as written (``fmu`` relative to ``out``'s folder), with what it was tuned on."""
    tuning = _tuning(study)
    s = target.strategy
    doc = entry_document(s, result["parameters"], out)
    doc["tuned"] = {
        "from": f"{s.name} ({shown_path(s.file)})", "study": shown_path(study.path), "records": tuning.records,
        "scenarios": {r: shown_path(study.scenario_path(r)) for r in tuning.records},
        "stop_time_s": tuning.stop_time, "objective": study.spec.objective.model_dump(),
        "J": result["J"], "J_start": result["J_start"], "budget": tuning.budget, "evaluations": result["evaluations"],
        "population": result["population"], "generations": result["generations"],
        "failed_runs": result["failed_runs"], "seed": tuning.seed,
        "method": "scipy.optimize.differential_evolution over the unit cube of the tunable ranges (log or linear), "
                  "seeded Latin-hypercube first generation with the entry's own setting first, tol 0, no polish; "
                  "J mean over the records, each run a co-simulation against passive-off on the same window",
        "wall_time_s": round(result["wall_time_s"], 1),
        "created": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "commit": git("rev-parse", "HEAD"),  # None outside a git checkout
        "uncommitted_changes": bool(git("status", "--porcelain", "--", "components", "orchestration")),
    }
    return doc


def shown_path(path: str | os.PathLike[str]) -> str:
    """A path as a tuned file records it: relative to the current folder when it lies below it (a checkout
    run from its root records ``scenarios/...``, the same on every machine), else absolute."""
    resolved, here = Path(path).resolve(), Path.cwd().resolve()
    return resolved.relative_to(here).as_posix() if resolved.is_relative_to(here) else str(resolved)


def tuned_document(study: LoadedStudy, entries: dict[str, dict[str, Any]]) -> str:
    """YAML text of the tuned strategy file: one entry ``<name>-tuned`` per tuned strategy."""
    head = ("# Strategies tuned by orchestration/case_study/strategy_tuner.py (docs/controllers.md, \"Tuning every "
            "strategy alike\"); do not edit by hand.\n"
            f"# Reproduce: python orchestration/tune.py {shown_path(study.path)} --force\n"
            "# Use: strategy_files: [this file] in a study, and list <name>-tuned under strategies.\n")
    doc = {"description": f"strategies tuned alike on {', '.join(_tuning(study).records)} ({study.path.name})",
           "strategies": {f"{name}-tuned": e for name, e in entries.items()}}
    return head + yaml.safe_dump(doc, sort_keys=False, width=100000, default_flow_style=None)


def output_path(study: LoadedStudy) -> Path:
    """The strategy file the tuning writes: ``strategy_tuning.output`` in the study's ``output`` folder."""
    folder = Path(study.spec.output)
    out = Path(_tuning(study).output)
    return out if out.is_absolute() else folder / out


# -- the command ---------------------------------------------------------------------------------------------------
def declares_tuning(argv: list[str] | None) -> bool:
    """Whether the study named on a ``tune.py`` command line has a ``strategy_tuning:`` section (or a ``--set`` of
    one): then this tuner runs, else the SOSM gain tuning (unchanged). False if the file cannot be read."""
    from orchestration.building_studies.study_file import declares_section

    return declares_section(sys.argv[1:] if argv is None else argv, KEY)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """Command-line arguments of tune.py for a study with ``strategy_tuning:``."""
    parser = argparse.ArgumentParser(prog=invoked_as("tune.py"),
                                     description="Tune the strategies of a study's strategy_tuning section alike.")
    parser.add_argument("study", type=Path, help="study YAML file with a strategy_tuning: section")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a study key (e.g. strategy_tuning.budget=20)")
    parser.add_argument("--out", type=Path, help="strategy file to write (default: strategy_tuning.output in the "
                                                 "study's output folder)")
    parser.add_argument("--force", action="store_true", help="replace an existing file")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")
    add_pool_arguments(parser)
    return parser.parse_args(argv)


def _prepared(args: argparse.Namespace) -> tuple[LoadedStudy, dict[str, Target], Path]:
    from mre_common.fs_limits import path_problem, writable_problem

    study = load_study(args.study, tuple(args.overrides))
    _tuning(study)
    out = args.out if args.out is not None else output_path(study)
    if (problem := path_problem(out, 32) or writable_problem(out)) is not None:
        raise ScenarioError(f"{'--out' if args.out is not None else KEY + '.output'}: {problem}")
    return study, plan_targets(study), out


def tune_all(study: LoadedStudy, targets: dict[str, Target], runs: Runner, out: Path, progress: bool
             ) -> tuple[dict[str, dict[str, Any]], str]:
    """Tune every target with the same budget and seed; each result and the strategy file's text."""
    from orchestration.engine_hooks import plan_scenario

    tuning, spec = _tuning(study), study.spec
    off_strategy = study.strategy(study.uncontrolled)  # the study's uncontrolled case: J is over its runs

    off_plans = {r: plan_scenario(study.scenario_path(r), run_overrides_of(study, off_strategy, r, {}))
                 for r in tuning.records}
    peaks = runs([(off_plans[r], {}, spec.i_max) for r in tuning.records])
    if any(p is None for p in peaks):
        raise RuntimeError(f"a run of the uncontrolled strategy ({off_strategy.name}) on the training records failed: "
                           f"{getattr(runs, 'errors', [])[:1]}")
    off = {r: p for r, p in zip(tuning.records, peaks, strict=True) if p is not None}
    results, entries = {}, {}
    for name, target in targets.items():
        results[name] = result = tune_target(target, tuning, spec.objective, off, runs)
        entries[name] = tuned_entry(target, result, study, out)
        if progress:
            start = "" if result["J_start"] is None else f" (its own setting {result['J_start']:.4f})"
            print(f"{name}: J = {result['J']:.4f}{start}, {result['evaluations']} settings x "
                  f"{len(tuning.records)} records, {result['wall_time_s']:.0f} s: {result['parameters']}",
                  file=sys.stderr)
    return results, tuned_document(study, entries)


def main(argv: list[str] | None = None) -> int:
    """CLI: tune the strategies a study lists under ``strategy_tuning:`` and write the tuned strategy file."""
    from orchestration.batch.pool import BatchPool, BatchUnavailable, scheduler_address
    from orchestration.master.runfolder import write_text

    args = parse_args(argv)
    try:
        study, targets, out = _prepared(args)
        if out.exists() and not args.force:
            print(f"error: {out} exists: pass --force to replace it", file=sys.stderr)
            return 2
        pool = BatchPool(scheduler_address(args.scheduler), args.workers or study.spec.workers,
                         max_worker_deaths=study.spec.max_worker_deaths)
        pool.start()
    except (ScenarioError, BatchUnavailable, ValueError) as exc:
        print(exc.report() if isinstance(exc, ScenarioError) else f"error: {exc}", file=sys.stderr)
        return 2
    with pool:
        print(pool.describe(), file=sys.stderr)
        results, document = tune_all(study, targets, PoolRunner(pool, study.spec.timeout_s), out, not args.quiet)
    bad = [n for n, r in results.items() if not math.isfinite(r["J"])]
    if bad:
        print(f"error: no finite objective for {', '.join(bad)} (every run failed?); {out} not written",
              file=sys.stderr)
        return 1
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text(out, document)
    print(f"tuned {', '.join(results)} on {', '.join(_tuning(study).records)}: {out}")
    return 0
