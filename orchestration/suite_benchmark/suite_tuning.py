"""Every listed strategy tuned alike on the training records of a suite, each run an IDA run.

The search is the strategy tuner's (:func:`orchestration.case_study.strategy_tuner.optimise`: differential
evolution over the unit cube of the ``tunable:`` ranges, a seeded Latin-hypercube first generation with the entry's
own setting first, the same budget and seed for every strategy). A setting's J is the case study's objective
(:func:`orchestration.case_study.objective.objective`) of each training component at each of the study's
intensity levels, against passive-off on the same component and level, averaged. Every run is the IDA's own (its
strong-motion window, its scale to the level, on the batch pool): a run that fails, or whose run does not say it
is valid, makes the setting's J infinite.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from orchestration.batch.pool import BatchPool
from orchestration.batch.portable import file_bytes
from orchestration.building_studies.strategies import CONTROLLER, I_MAX, Strategy, TunableRange, tunable_problems
from orchestration.case_study.case_config import ObjectiveSpec
from orchestration.case_study.objective import objective
from orchestration.case_study.strategy_tuner import budget_problem, folded, optimise, parameter_values, start_point
from orchestration.ida_study.ida_jobs import IdaInputs, IdaRunResult, ida_job
from orchestration.ida_study.ida_plan import PreparedIda, RecordComponent
from orchestration.master.errors import Problem, ScenarioError

METHOD = ("scipy.optimize.differential_evolution over the unit cube of the tunable ranges (log or linear), seeded "
          "Latin-hypercube first generation with the entry's own setting first, tol 0, no polish; J the mean over "
          "the training components and levels, each an IDA run against passive-off on the same component and level")


@dataclass(frozen=True)
class SuiteTarget:
    """One strategy to tune: its entry (gains folded in), ranges, Integer parameters, limit [A] and start point."""

    name: str
    strategy: Strategy
    integer: frozenset[str]
    i_limit: float
    start: list[float] | None

    @property
    def ranges(self) -> dict[str, TunableRange]:
        return dict(self.strategy.entry.tunable)


def plan_targets(prepared: PreparedIda, names: list[str], budget: int, key: str = "benchmark.tune"
                 ) -> dict[str, SuiteTarget]:
    """The strategies ``names`` of a study prepared with them, checked for tuning; ScenarioError listing every
    problem (no tunable ranges, a budget below the parameters + 1, a range the controller FMU lacks)."""
    study, problems, targets = prepared.study, [], {}
    first = prepared.components[0].rec.id
    for k, name in enumerate(names):
        entry = study.library[name].entry
        gains = prepared.gain_sets[entry.gains]["gains"] if entry.gains is not None else None
        strategy = folded(study.library[name], gains)
        here = study.lines.get((*tuple(key.split(".")), k), (str(study.path), None))
        if not strategy.entry.tunable:
            problems.append(Problem(f"strategy {name!r} declares no tunable: parameters (its entry in "
                                    f"{strategy.file})", f"{key}.{k}", *here))
            continue
        if problem := budget_problem(len(strategy.entry.tunable), budget):
            problems.append(Problem(f"strategy {name!r}: {problem}", "benchmark.budget",
                                    *study.lines.get(("benchmark", "budget"), here)))
            continue
        unit = prepared.plans[(first, name)].plan.descriptions[CONTROLLER]
        found = tunable_problems(strategy, unit)
        if found:
            problems += found
            continue
        limit = strategy.entry.parameters.get(strategy.limit_parameter() or "i_max", study.spec.i_max)
        i_limit = study.spec.i_max if limit == I_MAX or not isinstance(limit, int | float) else float(limit)
        starts = {n: v.start for n, v in unit.variables.items()}
        targets[name] = SuiteTarget(name, strategy, frozenset(n for n in strategy.entry.tunable
                                                              if unit.variables[n].type == "Integer"),
                                    i_limit, start_point(strategy, starts, study.spec.i_max))
    if problems:
        raise ScenarioError(problems)
    return targets


def peaks_of(result: IdaRunResult, top: int) -> dict[str, float] | None:
    """The objective's peaks of one IDA run (a3 top-floor [m/s^2], d drift [m], x0 base [m]), or None for a run
    that did not end ``ok`` or does not say it is valid."""
    m = result.metrics
    if result.status != "ok" or result.valid is False:
        return None
    values = (m.get(f"acc_{top}"), m.get("drift_max_mm"), m.get("x_base_mm"))
    if any(v is None or not math.isfinite(v) for v in values):
        return None
    a3, d, x0 = values
    return {"a3": float(a3), "d": 1e-3 * float(d), "x0": 1e-3 * float(x0)}  # type: ignore[arg-type]


class SuiteRunner:
    """Runs settings of one strategy on the training components x levels, on a pool (plans and files shared once);
    keeps every job's wall time [s] (fork to result), every run's own (``run_plan``: loading and stepping) and
    why each failed run failed."""

    def __init__(self, prepared: PreparedIda, components: list[RecordComponent], levels: list[float],
                 pool: BatchPool) -> None:
        self.prepared, self.components, self.levels, self.pool = prepared, components, levels, pool
        self.errors: list[str] = []
        self.run_times: list[float] = []
        self.stepping_times: list[float] = []
        self._shared: dict[tuple[str, str], tuple[Any, dict[str, Any]]] = {}

    def _handle(self, component: str, strategy: str) -> tuple[Any, dict[str, Any]]:
        if (component, strategy) not in self._shared:
            pp = self.prepared.plans[(component, strategy)]
            files = {sha: self.pool.share(path.read_bytes()) for sha, path in file_bytes([pp]).items()}
            self._shared[(component, strategy)] = (self.pool.share(pp, dedupe=False), files)
        return self._shared[(component, strategy)]

    @property
    def cells(self) -> list[tuple[RecordComponent, float]]:
        """The (component, level) of each run of one setting, in order."""
        return [(c, level) for c in self.components for level in self.levels]

    def __call__(self, strategy: str, settings: list[dict[str, Any]]) -> list[list[dict[str, float] | None]]:
        """Peaks of each setting's runs (one per cell, None where the run failed or is not valid)."""
        p = self.prepared
        payloads, costs = [], []
        for values in settings:
            for c, level in self.cells:
                plan, files = self._handle(c.rec.id, strategy)
                payloads.append({"plan": plan, "files": files, "parameters": {CONTROLLER: dict(values)} if values
                                 else {}, **IdaInputs(level / c.im, p.masses, p.storeys).to_json()})
                costs.append(p.plans[(c.rec.id, strategy)].plan.loaded.scenario.simulation.n_steps)
        results = self.pool.map(ida_job, payloads, isolate=True, timeout_s=p.study.spec.timeout_s, costs=costs)
        top = len(p.masses) - 1
        out, n = [], len(self.cells)
        for r in results:
            self.run_times.append(r.wall_time_s)
            run = IdaRunResult.from_json(r.value) if r.ok and r.value else None
            if run is not None and run.run_wall_time_s is not None:
                self.stepping_times.append(run.run_wall_time_s)
            peaks = peaks_of(run, top) if run is not None else None
            if peaks is None:
                why = r.error if run is None else (run.error or f"{run.status}, valid {run.valid}: "
                                                   f"{'; '.join(run.invalid_reasons)}")
                self.errors.append(f"{strategy} {r.key}: {why}")
            out.append(peaks)
        return [out[k * n:(k + 1) * n] for k in range(len(settings))]


def tune_one(target: SuiteTarget, runner: SuiteRunner, off: list[dict[str, float]], obj: ObjectiveSpec,
             budget: int, seed: int) -> dict[str, Any]:
    """Tune one strategy: its best parameters, J, J of its own setting, and every setting tried with its J."""
    ranges, failed, runs = target.ranges, [0], [0]

    def evaluate(points: np.ndarray) -> list[float]:
        settings = [parameter_values(list(q), ranges, target.integer) for q in points]
        values = []
        for per in runner(target.name, settings):
            runs[0] += len(per)
            failed[0] += sum(p is None for p in per)
            values.append(math.inf if any(p is None for p in per) else
                          float(np.mean([objective(p, o, obj) for p, o in zip(per, off, strict=True)])))
        return values

    started = time.time()
    found = optimise(evaluate, len(ranges), budget, seed, target.start)
    history = [{**parameter_values(list(q), ranges, target.integer), "J": j}
               for q, j in zip(found.points, found.values, strict=True)]
    return {"parameters": parameter_values(list(found.best), ranges, target.integer), "J": found.value,
            "J_start": found.values[0] if target.start is not None else None, "evaluations": len(found.points),
            "runs": runs[0], "population": found.population, "generations": found.generations,
            "failed_runs": failed[0], "history": history, "wall_time_s": time.time() - started}


def tune_all(prepared: PreparedIda, targets: Mapping[str, SuiteTarget], runner: SuiteRunner, obj: ObjectiveSpec,
             budget: int, seed: int, progress: bool) -> tuple[dict[str, dict[str, Any]], dict[str, Any]]:
    """The uncontrolled strategy (passive-off in the shipped file) on every training cell, then every target with the
    same budget and seed: each result, and the uncontrolled runs' peaks (RuntimeError if one of those failed: no J
    can be formed)."""
    uncontrolled = prepared.study.uncontrolled
    if uncontrolled is None:  # refused when the file was read (benchmark_config)
        raise RuntimeError("the training study lists no uncontrolled strategy")
    off = runner(uncontrolled, [{}])[0]
    if any(p is None for p in off):
        raise RuntimeError(f"a run of {uncontrolled} on the training records failed: {runner.errors[:1]}")
    results = {}
    for name, target in targets.items():
        results[name] = r = tune_one(target, runner, [p for p in off if p is not None], obj, budget, seed)
        if progress:
            own = "" if r["J_start"] is None else f" (its own setting {r['J_start']:.4f})"
            print(f"tuned {name}: J = {r['J']:.4f}{own}, {r['evaluations']} settings x {len(runner.cells)} runs, "
                  f"{r['wall_time_s']:.0f} s: {r['parameters']}", file=sys.stderr)
    cells = [{"component": c.rec.id, "level": level, **(p or {})} for (c, level), p in zip(runner.cells, off,
                                                                                            strict=True)]
    return results, {"passive_off": cells}
