"""SOSM gain tuning and the constant-current sweep of the case study (in-process physics).

Both use :func:`components.physics.monolithic.simulate_coupled`, which steps the same physics cores
with the same communication step and transfer scheme as the master steps the FMUs (about
10x faster than a co-simulation). The objective, dimensionless, against passive-off (0 A)::

    J = w_acc * a3 / a3_off + w_drift * d / d_off + penalty * max(0, x0 / x_limit - 1)

a3: peak absolute top-floor acceleration [m/s^2]; d: peak inter-storey drift over all
storeys [m]; x0: peak base (isolator) displacement [m]; x_limit: the device limit (15 mm).

Tuning (one record, by default El Centro): the gains are searched in log space over
(lambda, rho, theta, ratio) with zeta = ratio * rho / theta, so that zeta * theta > rho
(Eq. 39) holds by construction: the README default gains, then a seeded Latin hypercube,
then bounded Nelder-Mead from the best point. The gains are then checked, not re-tuned,
on the other records. Run::

    python orchestration/tune.py scenarios/case_study.yaml [--force]

It writes the gains file named by the study (``scenarios/sosm_gains.yaml``).
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from components.physics.ground_motion_core import GroundMotion, read_record
from components.physics.monolithic import SystemSetup, Trajectory, simulate_coupled
from components.physics.mre_isolator_core import TABLE2, GeneralizedCoefficients
from components.physics.shear_building_core import BuildingParams
from components.physics.sosm_controller_core import HAND_PICKED_GAINS, SosmGains
from orchestration.master.errors import ScenarioError
from orchestration.master.runfolder import write_text
from orchestration.master.system import SystemPlan
from orchestration.project import PROJECT_DIR, plan_scenario
from orchestration.studies.config import LoadedStudy, ObjectiveSpec, StudySpec, TuningSpec, load_study

DEFAULT_GAINS = HAND_PICKED_GAINS  # the hand-picked gains: the tuning's first point
_IGNORED_ISOLATOR = {"x_identified", "x_limit", "i_max", "n_isolators"}


class NotMonolithic(ValueError):
    """The scenario sets parameters the in-process model does not represent."""


def run_overrides(spec: StudySpec) -> tuple[str, ...]:
    """Overrides every run of a study gets: the study's own, then the current limit of both units."""
    return (*spec.overrides, f"isolator.i_max={spec.i_max}", f"controller.i_max={spec.i_max}")


def system_setup(plan: SystemPlan, passive_current: float | None, gains: SosmGains | None = None) -> SystemSetup:
    """In-process model of a planned scenario; ``passive_current`` None means SOSM with ``gains``."""
    par = plan.parameters
    ground = par.get("ground", {})
    motion = GroundMotion(read_record(plan.data_files["ground.record"]), scale=float(ground.get("scale", 1.0)),
                          time_scale=float(ground.get("time_scale", 1.0)))
    b = BuildingParams.dyke()
    values = {"m": list(b.m), "k": list(b.k), "c": list(b.c)}
    for name, value in par.get("building", {}).items():
        kind, _, j = name.partition("_")
        if kind not in values or not j.isdigit() or int(j) >= len(values[kind]):
            raise NotMonolithic(f"building parameter {name} is not represented in the in-process model")
        values[kind][int(j)] = float(value)
    building = BuildingParams(m=tuple(values["m"]), k=tuple(values["k"]), c=tuple(values["c"]))
    iso = par.get("isolator", {})
    coeffs = TABLE2.as_dict()
    for name, value in iso.items():
        if name in coeffs:
            coeffs[name] = float(value)
        elif name not in _IGNORED_ISOLATOR:
            raise NotMonolithic(f"isolator parameter {name} is not represented in the in-process model")
    i_max = float(iso.get("i_max", 3.0))
    if gains is None:
        gains = DEFAULT_GAINS
    return SystemSetup(motion, building, GeneralizedCoefficients(**coeffs), int(iso.get("n_isolators", 2)), i_max,
                       passive_current, gains)


def peak_values(tr: Trajectory) -> dict[str, float]:
    """Peak top-floor acceleration a3 [m/s^2], peak drift d [m] (all storeys), peak base displacement x0 [m]."""
    return {"a3": float(np.max(np.abs(tr.a[:, -1]))), "d": float(np.max(np.abs(tr.drift))),
            "x0": float(np.max(np.abs(tr.x[:, 0])))}


def objective(peaks: dict[str, float], off: dict[str, float], obj: ObjectiveSpec) -> float:
    """The dimensionless objective J of the module docstring (lower is better; passive-off has J = 1 + penalty)."""
    if not all(math.isfinite(v) for v in peaks.values()):
        return math.inf
    return (obj.w_acc * peaks["a3"] / off["a3"] + obj.w_drift * peaks["d"] / off["d"]
            + obj.penalty * max(0.0, peaks["x0"] / obj.x_limit - 1.0))


def _simulate(setup: SystemSetup, plan: SystemPlan, stop_time: float | None = None) -> Trajectory:
    sim = plan.loaded.scenario.simulation
    t_stop = sim.stop_time if stop_time is None else min(stop_time, sim.stop_time)
    extra = {"inputs": sim.inputs} if hasattr(sim, "inputs") else {}  # the master's input estimate, if it has one
    return simulate_coupled(setup, sim.step, round((t_stop - sim.start_time) / sim.step), sim.algorithm, **extra)


def sweep_currents(plan: SystemPlan, currents: list[float], obj: ObjectiveSpec) -> dict[str, Any]:
    """Objective of every constant current [A] on one planned record; the best is the lowest J (ties: lower current)."""
    off = peak_values(_simulate(system_setup(plan, 0.0), plan))
    rows = []
    for i in currents:
        p = off if i == 0.0 else peak_values(_simulate(system_setup(plan, i), plan))
        rows.append({"current_A": i, **p, "J": objective(p, off, obj)})
    best = min(rows, key=lambda r: (r["J"], r["current_A"]))
    return {"rows": rows, "best_current_A": best["current_A"], "best_J": best["J"]}


def gains_from_vector(q: np.ndarray, i_max: float) -> SosmGains:
    """Gains from q = log(lambda, rho, theta, ratio), zeta = ratio * rho / theta."""
    lam, rho, theta, ratio = (float(v) for v in np.exp(q))
    return SosmGains(lam=lam, rho=rho, zeta=ratio * rho / theta, theta=theta, i_max=i_max)


# evaluate(settings, stop_time) -> peaks of each setting: a passive current [A] (float) or SOSM gains
Evaluate = Callable[[list[float | SosmGains], float | None], list[dict[str, float]]]


def tune(plan: SystemPlan, tuning: TuningSpec, obj: ObjectiveSpec, i_max: float, progress: bool = False,
         evaluate: Evaluate | None = None) -> dict[str, Any]:
    """Tune the SOSM gains on one planned record; returns gains, objective and the evaluation history.

    ``evaluate`` runs a batch of simulations (the passive-off reference and the Latin-hypercube
    points fan out through it, e.g. on the Dask engine); by default they run here, one by one.
    The result is the same either way.
    """
    from scipy.optimize import minimize
    from scipy.stats import qmc

    def run_here(settings: list[float | SosmGains], stop: float | None) -> list[dict[str, float]]:
        return [peak_values(_simulate(system_setup(plan, s) if isinstance(s, float) else system_setup(plan, None, s),
                                      plan, stop)) for s in settings]

    evaluate = evaluate or run_here
    started = time.time()
    off = evaluate([0.0], tuning.stop_time)[0]
    keys = ("lam", "rho", "theta", "ratio")
    lo = np.log([tuning.bounds[k][0] for k in keys])
    hi = np.log([tuning.bounds[k][1] for k in keys])
    history: list[dict[str, float]] = []
    cache: dict[tuple[float, ...], float] = {}
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=1 + tuning.n_samples + tuning.max_evals, desc="tuning", unit="sim", file=sys.stderr)

    def f(q: np.ndarray) -> float:
        q = np.clip(q, lo, hi)
        key = tuple(np.round(q, 12))
        if key in cache:
            return cache[key]
        g = gains_from_vector(q, i_max)
        p = peak_values(_simulate(system_setup(plan, None, g), plan, tuning.stop_time))
        cache[key] = j = objective(p, off, obj)
        history.append({"lam": g.lam, "rho": g.rho, "zeta": g.zeta, "theta": g.theta, **p, "J": j})
        if bar is not None:
            bar.update(1)
        return j

    d = DEFAULT_GAINS
    q_default = np.clip(np.log([d.lam, d.rho, d.theta, d.zeta * d.theta / d.rho]), lo, hi)
    starts = [q_default, *(lo + (hi - lo) * qmc.LatinHypercube(d=4, seed=tuning.seed).random(tuning.n_samples))]
    batch = [np.clip(q, lo, hi) for q in starts]
    for q, p in zip(batch, evaluate([gains_from_vector(q, i_max) for q in batch], tuning.stop_time), strict=True):
        key = tuple(np.round(q, 12))
        if key not in cache:  # as f(q) would record it, in the same order
            g = gains_from_vector(q, i_max)
            cache[key] = j = objective(p, off, obj)
            history.append({"lam": g.lam, "rho": g.rho, "zeta": g.zeta, "theta": g.theta, **p, "J": j})
            if bar is not None:
                bar.update(1)
    values = [f(q) for q in starts]
    q0 = starts[int(np.argmin(values))]
    simplex = np.array([q0] + [q0 + np.where(np.arange(4) == k, 0.4 * (1 if q0[k] < (lo[k] + hi[k]) / 2 else -1), 0)
                               for k in range(4)])
    n_before = len(history)
    if tuning.max_evals > 0:
        minimize(f, q0, method="Nelder-Mead", bounds=list(zip(lo, hi, strict=True)),
                 options={"maxfev": tuning.max_evals, "initial_simplex": simplex, "xatol": 1e-3, "fatol": 1e-4})
    if bar is not None:
        bar.close()
    best = min(history, key=lambda r: r["J"])
    gains = SosmGains(lam=best["lam"], rho=best["rho"], zeta=best["zeta"], theta=best["theta"], i_max=i_max)
    return {"gains": gains, "objective": best["J"], "objective_default_gains": history[0]["J"],
            "passive_off": off, "evaluations": len(history), "nelder_mead_evaluations": len(history) - n_before,
            "history": history, "wall_time_s": time.time() - started}


def check_gains(plan: SystemPlan, gains: SosmGains, obj: ObjectiveSpec,
                peaks: list[dict[str, float]] | None = None) -> dict[str, float]:
    """Objective and ratios against passive-off of the given and the default gains on one record (full length).

    ``peaks``: the three simulations (passive-off, tuned, default gains) already run elsewhere.
    """
    default = SosmGains(**{**asdict(DEFAULT_GAINS), "i_max": gains.i_max})
    if peaks is None:
        peaks = [peak_values(_simulate(system_setup(plan, 0.0), plan)),
                 *(peak_values(_simulate(system_setup(plan, None, g), plan)) for g in (gains, default))]
    off = peaks[0]
    out: dict[str, float] = {}
    for (label, _), p in zip((("tuned", gains), ("default", default)), peaks[1:], strict=True):
        out[f"J_{label}"] = objective(p, off, obj)
        out[f"a3_ratio_{label}"] = p["a3"] / off["a3"]
        out[f"drift_ratio_{label}"] = p["d"] / off["d"]
    return out


def read_gains(path: Path) -> tuple[SosmGains, dict[str, Any]]:
    """Gains and the whole document from a gains file; raises ScenarioError if missing or invalid."""
    if not path.is_file():
        raise ScenarioError(f"SOSM gains file {path} does not exist: run "
                            f"'python orchestration/tune.py <study.yaml>' first (see docs/case_study.md)")
    try:
        doc = yaml.safe_load(path.read_text())
        g = doc["gains"]
        gains = SosmGains(lam=float(g["lambda"]), rho=float(g["rho"]), zeta=float(g["zeta"]),
                          theta=float(g["theta"]), i_max=float(g["i_max"]))
    except (yaml.YAMLError, KeyError, TypeError, ValueError) as exc:
        raise ScenarioError(f"{path}: not a valid SOSM gains file ({exc})") from None
    return gains, doc


def gains_document(study: LoadedStudy, result: dict[str, Any], checks: dict[str, dict[str, float]]) -> str:
    """YAML text of the gains file: gains, procedure, objective on the tuning record, check on the others."""
    g: SosmGains = result["gains"]
    spec = study.spec
    doc = {
        "gains": {"lambda": g.lam, "rho": g.rho, "zeta": g.zeta, "theta": g.theta, "i_max": g.i_max},
        "units": {"lambda": "1/s", "rho": "A/s", "zeta": "A s^0.5 m^-0.5", "theta": "m^0.5 s^-1.5", "i_max": "A"},
        "procedure": {
            "study": str(study.path.name),
            "record": spec.tuning.record,
            "stop_time_s": spec.tuning.stop_time,
            "seed": spec.tuning.seed,
            "n_samples": spec.tuning.n_samples,
            "max_evals": spec.tuning.max_evals,
            "bounds": {k: list(v) for k, v in spec.tuning.bounds.items()},
            "objective": spec.objective.model_dump(),
            "overrides": list(run_overrides(spec)),
            "method": "README default gains + seeded Latin hypercube, then bounded Nelder-Mead in log space "
                      "over (lambda, rho, theta, zeta*theta/rho); simulate_coupled (in-process, same step/scheme)",
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
        "commit": _git("rev-parse", "HEAD"),
        "uncommitted_changes": bool(_git("status", "--porcelain", "--", "components", "orchestration")),
    }
    head = ("# SOSM gains written by the tuning procedure (docs/case_study.md); do not edit by hand.\n"
            f"# Reproduce: python orchestration/tune.py scenarios/{study.path.name} --force\n")
    return head + yaml.safe_dump(doc, sort_keys=False)


def _git(*args: str) -> str:
    try:
        return subprocess.run(["git", *args], cwd=PROJECT_DIR, capture_output=True,
                              text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def tuning_job(payload: dict[str, Any]) -> dict[str, float]:
    """One simulation on a worker: peaks (a3, d, x0) at a passive current [A] (a float) or with SOSM gains."""
    from orchestration.studies.portable import relocate

    plan, _ = relocate(payload["plan"], payload["files"])
    setting = payload["setting"]
    setup = system_setup(plan, setting) if isinstance(setting, float) else system_setup(plan, None, setting)
    return peak_values(_simulate(setup, plan, payload["stop_time"]))


def engine_evaluate(engine: Any, plan: SystemPlan) -> Evaluate:
    """An ``evaluate`` for :func:`tune` that fans a batch out on a Dask engine (in the workers' processes)."""
    from orchestration.studies.portable import file_bytes, portable

    pp = portable(plan)
    files = {sha: engine.share(path.read_bytes()) for sha, path in file_bytes([pp]).items()}
    shared = engine.share(pp, dedupe=False)

    def evaluate(settings: list[float | SosmGains], stop: float | None) -> list[dict[str, float]]:
        results = engine.map(tuning_job, [{"plan": shared, "files": files, "setting": s, "stop_time": stop}
                                          for s in settings])
        bad = [r for r in results if not r.ok]
        if bad:
            raise RuntimeError(f"tuning simulation {bad[0].status}: {bad[0].error}\n{bad[0].details}")
        return [r.value for r in results]

    return evaluate


def main(argv: list[str] | None = None) -> int:
    """CLI: tune the SOSM gains of a study and write its gains file."""
    from orchestration.studies.engine import Engine, EngineUnavailable, scheduler_address

    parser = argparse.ArgumentParser(prog="tune.py", description="Tune the SOSM gains of a study.")
    parser.add_argument("study", type=Path, help="study YAML file (scenarios/case_study.yaml)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a study key (e.g. tuning.max_evals=10)")
    parser.add_argument("--out", type=Path, help="gains file to write (default: the study's 'gains')")
    parser.add_argument("--force", action="store_true", help="replace an existing gains file")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--scheduler", metavar="ADDRESS", help="fan the sample evaluations and checks out on an "
                        "existing Dask cluster (default: DASK_SCHEDULER_ADDRESS, else a local one)")
    parser.add_argument("--workers", type=int, help="local cluster: worker processes (default: one per core)")
    args = parser.parse_args(argv)
    try:
        study = load_study(args.study, tuple(args.overrides))
        spec = study.spec
        if spec.tuning.record not in spec.records:
            raise ScenarioError(f"tuning.record {spec.tuning.record!r} is not one of the records {list(spec.records)}")
        out = args.out if args.out is not None else study.gains_path
        if out.exists() and not args.force:
            print(f"error: {out} exists: pass --force to replace it", file=sys.stderr)
            return 2
        plans = {r: plan_scenario(study.scenario_path(r), run_overrides(spec)) for r in spec.records}
        for plan in plans.values():
            system_setup(plan, 0.0)  # NotMonolithic before any work
        engine = Engine(scheduler_address(args.scheduler), args.workers or spec.workers,
                        max_worker_deaths=spec.max_worker_deaths)
        engine.start()
    except (ScenarioError, NotMonolithic, EngineUnavailable, ValueError) as exc:
        print(exc.report() if isinstance(exc, ScenarioError) else f"error: {exc}", file=sys.stderr)
        return 2
    with engine:
        print(engine.describe(), file=sys.stderr)
        result = tune(plans[spec.tuning.record], spec.tuning, spec.objective, spec.i_max, progress=not args.quiet,
                      evaluate=engine_evaluate(engine, plans[spec.tuning.record]))
        g = result["gains"]
        default = SosmGains(**{**asdict(DEFAULT_GAINS), "i_max": g.i_max})
        checks = {}
        for r, p in plans.items():  # passive-off, tuned, default gains of every record, all at once
            checks[r] = engine_evaluate(engine, p)([0.0, g, default], None)
        checks = {r: check_gains(plans[r], g, spec.objective, peaks) for r, peaks in checks.items()}
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text(out, gains_document(study, result, checks))
    print(f"tuned on {spec.tuning.record}: J = {result['objective']:.4f} "
          f"(default gains {result['objective_default_gains']:.4f}), "
          f"{result['evaluations']} simulations, {result['wall_time_s']:.0f} s")
    print(f"lambda = {g.lam:.4g} 1/s, rho = {g.rho:.4g} A/s, zeta = {g.zeta:.4g}, theta = {g.theta:.4g}: {out}")
    for r, c in checks.items():
        print(f"  {r}: J tuned {c['J_tuned']:.4f}, default {c['J_default']:.4f}")
    return 0
