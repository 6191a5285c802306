"""SOSM gain tuning of the case study (in-process physics), against the objective J of
:mod:`orchestration.case_study.objective`.

Tuning (one record, by default El Centro, or several: J is then their mean): the gains are
searched in log space over (lambda, rho, theta, ratio) with zeta = ratio * rho / theta, so
that zeta * theta > rho (Eq. 39) holds by construction, and, if the tuning's bounds name it,
the release band s_release [m/s] (a designer's extension, not in the paper; see
sosm_controller_core) as a fifth log dimension: the README default gains (s_release at its
lower bound), then a seeded Latin hypercube, then bounded Nelder-Mead from the best point. The gains are then
checked, not re-tuned, on every record. Every evaluation (gains, peaks, current statistics)
is written to the gains file, with the constant currents on the same window, for the
report's Pareto plot. Run::

    python orchestration/tune.py scenarios/case_study.yaml [--gain-set sosm-fig15] [--force]

It writes the gains file named by the study (``scenarios/sosm_gains.yaml``; the second gain
set ``scenarios/sosm_gains_fig15.yaml``).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from components.physics.sosm_controller_core import SosmGains
from mre_common.guard import invoked_as
from mre_common.project_paths import git
from orchestration.building_studies.in_process_model import DEFAULT_GAINS, NotMonolithic, system_setup
from orchestration.building_studies.pool_arguments import add_pool_arguments
from orchestration.building_studies.run_settings import run_overrides
from orchestration.case_study.case_config import LoadedStudy, ObjectiveSpec, TuningSpec, load_study
from orchestration.case_study.objective import evaluate_setting, objective
from orchestration.engine_hooks import plan_scenario
from orchestration.master.errors import ScenarioError
from orchestration.master.resolve import SystemPlan
from orchestration.master.runfolder import write_text

TUNED = ("lam", "rho", "theta", "ratio")  # the tuned dimensions; "s_release" follows if the bounds name it


def tuned_keys(tuning: TuningSpec) -> tuple[str, ...]:
    """The dimensions of the search: lam, rho, theta, ratio and, if its bounds are given, s_release."""
    return (*TUNED, "s_release") if "s_release" in tuning.bounds else TUNED


def gains_from_vector(q: np.ndarray, i_max: float) -> SosmGains:
    """Gains from q = log(lambda, rho, theta, ratio[, s_release]), zeta = ratio * rho / theta."""
    lam, rho, theta, ratio, *rest = (float(v) for v in np.exp(q))
    return SosmGains(lam=lam, rho=rho, zeta=ratio * rho / theta, theta=theta, i_max=i_max,
                     s_release=rest[0] if rest else 0.0)


# evaluate(settings, stop_time) -> peaks of each setting on one record: a passive current [A] (float) or SOSM gains
Evaluate = Callable[[list[float | SosmGains], float | None], list[dict[str, float]]]
# evaluate_many([(record, setting), ...], stop_time) -> peaks of each, any records of the tuning
EvaluateMany = Callable[[list[tuple[str, float | SosmGains]], float | None], list[dict[str, float]]]


def _row(g: SosmGains, j: float, per_record: dict[str, dict[str, float]]) -> dict[str, Any]:
    return {"lam": g.lam, "rho": g.rho, "zeta": g.zeta, "theta": g.theta, "s_release": g.s_release, "J": j,
            "records": per_record}


def _evaluate_many(plans: dict[str, SystemPlan], evaluate: Evaluate | None, evaluate_many: EvaluateMany | None
                   ) -> EvaluateMany:
    """The batch evaluator :func:`tune` uses: ``evaluate_many``, else ``evaluate`` (one record), else here."""
    if evaluate_many is not None:
        return evaluate_many
    if evaluate is not None:
        if len(plans) != 1:
            raise ValueError("evaluate runs one record: pass evaluate_many for several")
        one = evaluate

        def many_of_one(jobs: list[tuple[str, float | SosmGains]], stop: float | None) -> list[dict[str, float]]:
            return one([s for _, s in jobs], stop)

        return many_of_one

    def here(jobs: list[tuple[str, float | SosmGains]], stop: float | None) -> list[dict[str, float]]:
        return [evaluate_setting(plans[r], s, stop) for r, s in jobs]

    return here


class _Search:
    """The state of one tuning: every point evaluated (history, cache) in log-gain space within the bounds."""

    def __init__(self, plans: dict[str, SystemPlan], tuning: TuningSpec, obj: ObjectiveSpec, i_max: float,
                 many: EvaluateMany, progress: bool) -> None:
        self.plans, self.tuning, self.obj, self.i_max, self.many = plans, tuning, obj, i_max, many
        self.off = dict(zip(plans, many([(r, 0.0) for r in plans], tuning.stop_time), strict=True))
        self.keys = tuned_keys(tuning)
        self.lo = np.log([tuning.bounds[k][0] for k in self.keys])
        self.hi = np.log([tuning.bounds[k][1] for k in self.keys])
        self.history: list[dict[str, Any]] = []
        self.cache: dict[tuple[float, ...], float] = {}
        self.bar = None
        if progress:
            from tqdm import tqdm

            self.bar = tqdm(total=len(plans) * (1 + tuning.n_samples + tuning.max_evals), desc="tuning", unit="sim",
                            file=sys.stderr)

    def record(self, q: np.ndarray, per_record: dict[str, dict[str, float]]) -> float:
        """J of a point from its per-record peaks, recorded once (history, cache)."""
        key = tuple(np.round(q, 12))
        if key not in self.cache:  # the batch and f(q) record a point the same way, in the same order
            g = gains_from_vector(q, self.i_max)
            self.cache[key] = j = float(np.mean([objective(per_record[r], self.off[r], self.obj) for r in self.plans]))
            self.history.append(_row(g, j, per_record))
            if self.bar is not None:
                self.bar.update(len(self.plans))
        return self.cache[key]

    def f(self, q: np.ndarray) -> float:
        """J of a point (clipped to the bounds), evaluated on every record unless known."""
        q = np.clip(q, self.lo, self.hi)
        key = tuple(np.round(q, 12))
        if key in self.cache:
            return self.cache[key]
        g = gains_from_vector(q, self.i_max)
        return self.record(q, dict(zip(self.plans, self.many([(r, g) for r in self.plans], self.tuning.stop_time),
                                       strict=True)))

    def starts(self) -> list[np.ndarray]:
        """The default gains and the Latin-hypercube samples, evaluated as one batch."""
        d = DEFAULT_GAINS
        start = [d.lam, d.rho, d.theta, d.zeta * d.theta / d.rho]
        if "s_release" in self.keys:
            start.append(self.tuning.bounds["s_release"][0])  # the band at its narrowest: closest to the paper's law
        q_default = np.clip(np.log(start), self.lo, self.hi)
        lhs = qmc_samples(len(self.keys), self.tuning.seed, self.tuning.n_samples)
        starts = [q_default, *(self.lo + (self.hi - self.lo) * lhs)]
        batch = [np.clip(q, self.lo, self.hi) for q in starts]
        n = len(self.plans)
        flat = self.many([(r, gains_from_vector(q, self.i_max)) for q in batch for r in self.plans],
                         self.tuning.stop_time)
        for k, q in enumerate(batch):
            self.record(q, dict(zip(self.plans, flat[k * n:(k + 1) * n], strict=True)))
        return starts

    def nelder_mead(self, q0: np.ndarray) -> None:
        """Nelder-Mead from the best start, its first simplex a step of 0.4 in log space towards the middle."""
        from scipy.optimize import minimize

        lo, hi, n = self.lo, self.hi, len(self.keys)
        simplex = np.array([q0] + [q0 + np.where(np.arange(n) == k, 0.4 * (1 if q0[k] < (lo[k] + hi[k]) / 2 else -1),
                                                 0) for k in range(n)])
        if self.tuning.max_evals > 0:
            minimize(self.f, q0, method="Nelder-Mead", bounds=list(zip(lo, hi, strict=True)),
                     options={"maxfev": self.tuning.max_evals, "initial_simplex": simplex, "xatol": 1e-3,
                              "fatol": 1e-4})


def qmc_samples(d: int, seed: int, n: int) -> np.ndarray:
    """``n`` Latin-hypercube samples in the unit cube of dimension ``d``."""
    from scipy.stats import qmc

    return qmc.LatinHypercube(d=d, seed=seed).random(n)


def tune(plan: SystemPlan | Mapping[str, SystemPlan], tuning: TuningSpec, obj: ObjectiveSpec, i_max: float,
         progress: bool = False, evaluate: Evaluate | None = None, evaluate_many: EvaluateMany | None = None
         ) -> dict[str, Any]:
    """Tune the SOSM gains on the tuning records; returns gains, objective and the evaluation history.

    ``plan``: one planned record, or a mapping record -> plan (J is the mean over them).
    ``i_max``: the controller's current limit [A]. ``evaluate`` (one plan) or ``evaluate_many``
    (any) runs a batch of simulations: the passive-off references, the Latin-hypercube points
    and each Nelder-Mead point on all records fan out through it (e.g. on the Dask batch pool); by
    default they run here, one by one. The result is the same either way. Each history row holds the gains, J and, per
    record, the peaks and current statistics of :func:`peak_values`.
    """
    plans = dict(plan) if isinstance(plan, Mapping) else {tuning.records[0]: plan}
    started = time.time()
    search = _Search(plans, tuning, obj, i_max, _evaluate_many(plans, evaluate, evaluate_many), progress)
    starts = search.starts()
    values = [search.f(q) for q in starts]
    n_before = len(search.history)
    search.nelder_mead(starts[int(np.argmin(values))])
    if search.bar is not None:
        search.bar.close()
    history = search.history
    best = min(history, key=lambda r: r["J"])
    gains = SosmGains(lam=best["lam"], rho=best["rho"], zeta=best["zeta"], theta=best["theta"], i_max=i_max,
                      s_release=best["s_release"])
    return {"gains": gains, "objective": best["J"], "objective_default_gains": history[0]["J"],
            "passive_off": search.off, "evaluations": len(history),
            "nelder_mead_evaluations": len(history) - n_before, "history": history,
            "wall_time_s": time.time() - started}


def check_gains(plan: SystemPlan, gains: SosmGains, obj: ObjectiveSpec,
                peaks: list[dict[str, float]] | None = None) -> dict[str, float]:
    """Objective, ratios against passive-off and current statistics of the given and the default gains
    on one record (full length).

    ``peaks``: the three simulations (passive-off, tuned, default gains) already run elsewhere.
    """
    default = SosmGains(**{**asdict(DEFAULT_GAINS), "i_max": gains.i_max})
    if peaks is None:
        peaks = [evaluate_setting(plan, s) for s in (0.0, gains, default)]
    off = peaks[0]
    out: dict[str, float] = {}
    for label, p in zip(("tuned", "default"), peaks[1:], strict=True):
        out[f"J_{label}"] = objective(p, off, obj)
        out[f"a3_ratio_{label}"] = p["a3"] / off["a3"]
        out[f"drift_ratio_{label}"] = p["d"] / off["d"]
        for k in ("i_min", "i_max", "i_mean", "s_bound", "s_zero"):
            out[f"{k}_{label}"] = p[k]
    return out


EVALUATION_COLUMNS = ("lambda", "rho", "zeta", "theta", "J")
RECORD_COLUMNS = ("a3", "d", "x0", "i_mean", "s_bound", "s_zero")


def evaluations_table(result: dict[str, Any], passive: dict[str, list[dict[str, float]]], currents: list[float]
                      ) -> dict[str, Any]:
    """The tuning's evaluations and the constant currents on the same window, as compact tables."""
    records = list(passive)
    release = any(h.get("s_release") for h in result["history"])  # a column only if the band was tuned
    cols = [*EVALUATION_COLUMNS[:4], *(("s_release",) if release else ()), EVALUATION_COLUMNS[4],
            *(f"{r}.{k}" for r in records for k in RECORD_COLUMNS)]
    rows = [[h["lam"], h["rho"], h["zeta"], h["theta"], *((h["s_release"],) if release else ()), h["J"],
             *(h["records"][r][k] for r in records for k in RECORD_COLUMNS)] for h in result["history"]]
    pcols = ["current_A", *(f"{r}.{k}" for r in records for k in RECORD_COLUMNS)]
    prows = [[c, *(passive[r][n][k] for r in records for k in RECORD_COLUMNS)] for n, c in enumerate(currents)]
    return {"sosm": {"columns": cols, "rows": rows}, "passive": {"columns": pcols, "rows": prows}}


def read_table(table: dict[str, Any]) -> list[dict[str, float]]:
    """Rows of a compact table (``columns``, ``rows``) as dictionaries."""
    return [dict(zip(table["columns"], row, strict=True)) for row in table["rows"]]


def gains_document(study: LoadedStudy, result: dict[str, Any], checks: dict[str, dict[str, float]],
                   strategy: str = "sosm", evaluations: dict[str, Any] | None = None) -> str:
    """YAML text of the gains file: gains, procedure, objective on the tuning records, check on every record,
    and (for the Pareto plot) every evaluation of the tuning."""
    g: SosmGains = result["gains"]
    _, obj, tuning = study.gain_set(strategy)
    release = "s_release" in tuning.bounds
    doc = {
        "gains": {"lambda": g.lam, "rho": g.rho, "zeta": g.zeta, "theta": g.theta, "i_max": g.i_max,
                  **({"s_release": g.s_release} if release else {})},
        "units": {"lambda": "1/s", "rho": "A/s", "zeta": "A s^0.5 m^-0.5", "theta": "m^0.5 s^-1.5", "i_max": "A",
                  **({"s_release": "m/s"} if release else {})},
        "procedure": {
            "study": str(study.path.name),
            "strategy": strategy,
            "record": tuning.record,
            "stop_time_s": tuning.stop_time,
            "seed": tuning.seed,
            "n_samples": tuning.n_samples,
            "max_evals": tuning.max_evals,
            "bounds": {k: list(v) for k, v in tuning.bounds.items()},
            "objective": obj.model_dump(),
            "overrides": list(gain_set_overrides(study, strategy)),
            "method": "README default gains + seeded Latin hypercube, then bounded Nelder-Mead in log space "
                      "over (lambda, rho, theta, zeta*theta/rho" + (", s_release" if release else "") + "); "
                      "J averaged over the tuning records; simulate_coupled (in-process, same step/scheme)"
                      + ("; s_release is the release band, a designer's extension not in the paper"
                         if release else ""),
        },
        "result": {
            "objective": result["objective"],
            "objective_default_gains": result["objective_default_gains"],
            "evaluations": result["evaluations"],
            "wall_time_s": round(result["wall_time_s"], 1),
            "zeta_theta_over_rho": g.zeta * g.theta / g.rho,
        },
        "check_other_records": checks,
        "created": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "commit": git("rev-parse", "HEAD"),  # None outside a git checkout
        "uncommitted_changes": bool(git("status", "--porcelain", "--", "components", "orchestration")),
    }
    if evaluations is not None:
        doc["evaluations"] = evaluations
    option = "" if strategy == "sosm" else f" --gain-set {strategy}"
    head = ("# SOSM gains written by the tuning procedure (docs/case_study.md); do not edit by hand.\n"
            f"# Reproduce: python orchestration/tune.py scenarios/{study.path.name}{option} --force\n")
    return head + yaml.safe_dump(doc, sort_keys=False, width=100000, default_flow_style=None)


def gain_set_overrides(study: LoadedStudy, strategy: str) -> tuple[str, ...]:
    """Overrides of the tuning runs of a gain set: the study's runs, then the controller's own current limit."""
    i_max, _, _ = study.gain_set(strategy)
    base = run_overrides(study.spec)
    if strategy == "sosm":
        return base
    # the controller's own limit replaces the study's (one effective assignment, recorded as such)
    return (*(o for o in base if not o.startswith("controller.i_max=")), f"controller.i_max={i_max}")


def tuning_job(payload: dict[str, Any]) -> dict[str, float]:
    """One simulation on a worker: peaks and current statistics at a passive current [A] or with SOSM gains."""
    from orchestration.batch.portable import relocate

    plan, _ = relocate(payload["plan"], payload["files"])
    return evaluate_setting(plan, payload["setting"], payload["stop_time"])


def pool_evaluate_many(pool: Any, plans: Mapping[str, SystemPlan]) -> EvaluateMany:
    """An ``evaluate_many`` for :func:`tune` that fans a batch out on a Dask pool (in the workers' processes)."""
    from orchestration.batch.portable import file_bytes, portable

    pps = {r: portable(p) for r, p in plans.items()}
    files = {sha: pool.share(path.read_bytes()) for sha, path in file_bytes(list(pps.values())).items()}
    shared = {r: pool.share(pp, dedupe=False) for r, pp in pps.items()}

    def evaluate(jobs: list[tuple[str, float | SosmGains]], stop: float | None) -> list[dict[str, float]]:
        results = pool.map(tuning_job, [{"plan": shared[r], "files": {sha: files[sha] for sha in pps[r].shas},
                                           "setting": s, "stop_time": stop} for r, s in jobs])
        bad = [r for r in results if not r.ok]
        if bad:
            raise RuntimeError(f"tuning simulation {bad[0].status}: {bad[0].error}\n{bad[0].details}")
        return [r.value for r in results]

    return evaluate


def pool_evaluate(pool: Any, plan: SystemPlan) -> Evaluate:
    """An ``evaluate`` for :func:`tune` on one record, on a Dask pool."""
    many = pool_evaluate_many(pool, {"record": plan})
    return lambda settings, stop: many([("record", s) for s in settings], stop)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """Command-line arguments of tune.py."""
    parser = argparse.ArgumentParser(prog=invoked_as("tune.py"), description="Tune the SOSM gains of a study.")
    parser.add_argument("study", type=Path, help="study YAML file (scenarios/case_study.yaml)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a study key (e.g. tuning.max_evals=10)")
    parser.add_argument("--gain-set", choices=("sosm", "sosm-fig15"), default="sosm",
                        help="which gain set: the study's 'gains' (sosm, default) or 'fig15.gains' (sosm-fig15: "
                             "the controller limit, objective and tuning of the study's 'fig15' section)")
    parser.add_argument("--out", type=Path, help="gains file to write (default: the gain set's file)")
    parser.add_argument("--force", action="store_true", help="replace an existing gains file")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    add_pool_arguments(parser)  # the sample evaluations and checks fan out on the pool
    return parser.parse_args(argv)


def tune_and_check(study: LoadedStudy, gain_set: str, plans: dict[str, SystemPlan], pool: Any, progress: bool
                   ) -> tuple[dict[str, Any], dict[str, Any], str]:
    """Tune a gain set on the pool, then check it on every record; the tuning result, the checks and the
    gains file's text."""
    spec = study.spec
    i_max, obj, tuning = study.gain_set(gain_set)
    tuned_on = {r: plans[r] for r in tuning.records}
    many = pool_evaluate_many(pool, plans)
    result = tune(tuned_on, tuning, obj, i_max, progress=progress, evaluate_many=many)
    g = result["gains"]
    currents = spec.sweep.currents(spec.i_max)
    flat = many([(r, c) for r in tuned_on for c in currents], tuning.stop_time)  # the passive points
    passive = {r: flat[k * len(currents):(k + 1) * len(currents)] for k, r in enumerate(tuned_on)}
    default = SosmGains(**{**asdict(DEFAULT_GAINS), "i_max": g.i_max})
    flat = many([(r, s) for r in plans for s in (0.0, g, default)], None)  # every record, whole length
    checks = {r: check_gains(plans[r], g, obj, flat[3 * k:3 * k + 3]) for k, r in enumerate(plans)}
    return result, checks, gains_document(study, result, checks, gain_set, evaluations_table(result, passive, currents))


def main(argv: list[str] | None = None) -> int:
    """CLI: tune the SOSM gains of a study (or its second gain set) and write the gains file."""
    from orchestration.batch.pool import BatchPool, BatchUnavailable, scheduler_address

    args = parse_args(argv)
    try:
        study = load_study(args.study, tuple(args.overrides))
        spec = study.spec
        tuning = study.gain_set(args.gain_set)[2]
        where = "tuning" if args.gain_set == "sosm" else "fig15.tuning"
        unknown = [r for r in tuning.records if r not in spec.records]
        if unknown:
            raise ScenarioError(f"{where}.record {unknown} is not one of the records {list(spec.records)}")
        out = args.out if args.out is not None else study.gain_set_path(args.gain_set)
        from mre_common.fs_limits import path_problem, writable_problem

        # the atomic write's temporary name is longer; a file that cannot be written is said before the tuning
        if (problem := path_problem(out, 32) or writable_problem(out)) is not None:
            raise ScenarioError(f"{'--out' if args.out is not None else 'gains'}: {problem}")
        if out.exists() and not args.force:
            print(f"error: {out} exists: pass --force to replace it", file=sys.stderr)
            return 2
        overrides = gain_set_overrides(study, args.gain_set)
        plans = {r: plan_scenario(study.scenario_path(r), overrides) for r in spec.records}
        for plan in plans.values():
            system_setup(plan, 0.0)  # NotMonolithic before any work
        pool = BatchPool(scheduler_address(args.scheduler), args.workers or spec.workers,
                         max_worker_deaths=spec.max_worker_deaths)
        pool.start()
    except (ScenarioError, NotMonolithic, BatchUnavailable, ValueError) as exc:
        print(exc.report() if isinstance(exc, ScenarioError) else f"error: {exc}", file=sys.stderr)
        return 2
    with pool:
        print(pool.describe(), file=sys.stderr)
        result, checks, document = tune_and_check(study, args.gain_set, plans, pool, not args.quiet)
    g = result["gains"]
    values = (result["objective"], g.lam, g.rho, g.zeta, g.theta, g.s_release)
    if not all(np.isfinite(v) for v in values):
        print(f"error: the tuning ended with J = {result['objective']} and gains lambda = {g.lam}, rho = {g.rho}, "
              f"zeta = {g.zeta}, theta = {g.theta}: not finite (a simulation without finite peaks?); {out} not "
              "written", file=sys.stderr)
        return 1
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text(out, document)
    _summary(result, checks, tuning.records, out)
    return 0


def _summary(result: dict[str, Any], checks: dict[str, Any], records: list[str], out: Path) -> None:
    """What the tuning found, on stdout."""
    g = result["gains"]
    print(f"tuned on {', '.join(records)}: J = {result['objective']:.4f} "
          f"(default gains {result['objective_default_gains']:.4f}), "
          f"{result['evaluations']} points, {result['wall_time_s']:.0f} s")
    print(f"lambda = {g.lam:.4g} 1/s, rho = {g.rho:.4g} A/s, zeta = {g.zeta:.4g}, theta = {g.theta:.4g}: {out}")
    for r, c in checks.items():
        print(f"  {r}: J tuned {c['J_tuned']:.4f}, default {c['J_default']:.4f}; current {c['i_min_tuned']:.3g}-"
              f"{c['i_max_tuned']:.3g} A, mean {c['i_mean_tuned']:.3g} A, at the limit "
              f"{100 * c['s_bound_tuned']:.0f} % of the time")
