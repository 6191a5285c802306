"""The switching-law accuracy cases: a shipped strategy on a shipped record, by the co-simulation and by the
sampled-data reference (:mod:`tests.sampled_reference`), and the comparison of their peaks.

The co-simulation runs the FMUs through :func:`orchestration.api.run` on the record's scenario
(``scenarios/<record>.yaml``) with the strategy's controller unit, parameters and sensor connections
(``scenarios/strategies.yaml``, i_max = 3 A, the tuned SOSM gains of ``scenarios/sosm_gains.yaml``), the plant
coupled at ``plant_step`` and the controller stepping at ``controller_step`` (``units.controller.step``). The
reference drives the same controller core with the same parameters, sampled at ``controller_step`` with the
co-simulation's timing (the current computed from the samples at t_k acts over [t_k, t_k + H]), and records
at the plant step.
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from components.physics.ground_motion_core import GroundMotion, read_record
from components.physics.sosm_controller_core import SosmGains
from tests.support import sampled_reference as ref

PROJECT = Path(__file__).resolve().parents[2]
SCENARIOS = PROJECT / "scenarios"
RECORDS = ("elcentro", "hachinohe", "northridge", "kobe")
STRATEGIES = ("passive-on", "sosm", "on-off", "clipped-optimal", "lyapunov", "frequency")
I_MAX = 3.0  # A, the studies' current limit
PEAKS = ("x_0", "a_3", "drift_1", "F")  # compared peaks (reference names)
COSIM_NAMES = {"x_0": "building.x_0", "a_3": "building.a_3", "drift_1": "building.drift_1", "F": "isolator.F"}


def multirate_supported() -> bool:
    """Whether a scenario may give a unit its own step (``units.NAME.step``)."""
    from orchestration.master.scenario import UnitSpec

    return "step" in UnitSpec.model_fields


def sosm_gains() -> dict[str, float]:
    """The tuned gain set the ``sosm`` strategy uses (lambda, rho, zeta, theta, i_max)."""
    return yaml.safe_load((SCENARIOS / "sosm_gains.yaml").read_text())["gains"]


def _strategy(name: str) -> Any:
    from orchestration.building_studies.strategies import builtin_strategies

    return builtin_strategies()[name]


def overrides(record: str, strategy: str, plant_step: float, controller_step: float, stop_time: float | None
              ) -> tuple[str, ...]:
    """Scenario overrides of one co-simulation run (``run.py --set`` form)."""
    from orchestration.master.yaml_source import load_tree

    s = _strategy(strategy)
    gains = sosm_gains() if s.entry.gains is not None else None
    conns = () if s.entry.connections is None else s.wiring_overrides(
        list(load_tree(SCENARIOS / f"{record}.yaml")[0].get("connections") or []))
    out = [*s.overrides(I_MAX, gains, None), *conns, f"simulation.step={plant_step!r}"]
    if not math.isclose(plant_step, controller_step, rel_tol=1e-12):
        out.append(f"units.controller.step={controller_step!r}")
    if stop_time is not None:
        out.append(f"simulation.stop_time={stop_time!r}")
    return tuple(out)


@dataclass
class CosimRun:
    """Peaks (SI, reference names), run status, validity verdict if the run gives one, wall time [s]."""

    peaks: dict[str, float]
    status: str
    valid: bool | None
    reasons: list[str]
    seconds: float
    stop_time: float
    controller_grid_peaks: dict[str, float]  # the same peaks over the controller's sample instants only


def cosimulate(record: str, strategy: str, plant_step: float, controller_step: float, stop_time: float | None,
               out: Path) -> CosimRun:
    """One co-simulation run through the FMUs and the engine: ``orchestration/run.py`` in a fresh process (the
    pythonfmu FMUs of different controllers share one interpreter; a process of their own keeps each run's
    modules its own). Peaks from its ``timeseries.csv``; status, validity from its ``summary.json``."""
    import json
    import subprocess
    import sys

    import numpy as np
    import pandas as pd

    from orchestration.api import load_scenario

    sets = overrides(record, strategy, plant_step, controller_step, stop_time)
    plan = load_scenario(SCENARIOS / f"{record}.yaml", sets)  # a scenario error here, before anything runs
    command = [sys.executable, str(PROJECT / "orchestration" / "run.py"), str(SCENARIOS / f"{record}.yaml"),
               *(a for kv in sets for a in ("--set", kv)), "--out", str(out), "--no-plots", "--quiet"]
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    seconds = time.perf_counter() - start
    if done.returncode not in (0, 1):
        raise RuntimeError(f"run.py exited {done.returncode}: {(done.stderr or done.stdout).strip()[-500:]}")
    s = json.loads((out / "summary.json").read_text())
    data = pd.read_csv(out / "timeseries.csv", usecols=list(COSIM_NAMES.values()))
    complete = bool(s.get("complete", done.returncode == 0))
    stride = max(1, round(controller_step / plant_step))
    peaks, on_controller_grid = ({k: float(np.max(np.abs(data[name].to_numpy()[::n]))) if complete else math.nan
                                  for k, name in COSIM_NAMES.items()} for n in (1, stride))
    return CosimRun(peaks, str(s.get("status", "complete" if complete else "failed")), s.get("valid"),
                    list(s.get("invalid_reasons") or []) + ([str(s["error"])] if s.get("error") else []), seconds,
                    float(plan.loaded.scenario.simulation.stop_time), on_controller_grid)


@functools.lru_cache(maxsize=8)
def record_of(record: str) -> tuple[GroundMotion, float]:
    """The record's playback (its scenario's record and scale) and the scenario's stop time [s]."""
    from orchestration.api import load_scenario

    plan = load_scenario(SCENARIOS / f"{record}.yaml")
    ground = plan.parameters["ground"]
    path = plan.data_files.get(str(ground["record"]), ground["record"]) if plan.data_files else ground["record"]
    gm = GroundMotion(read_record(Path(str(path))), scale=float(ground.get("scale", 0.5)))
    return gm, float(plan.loaded.scenario.simulation.stop_time)


def reference_controller(strategy: str, period: float) -> ref.SampledController:
    """The strategy's controller core with the strategy's parameters (i_max = 3 A), sampled every period [s]."""
    s = _strategy(strategy)
    values = s.values(I_MAX, None)
    fmu = Path(s.entry.fmu).stem if s.entry.fmu is not None else None
    if fmu is None and values.get("mode") == "passive":
        return ref.ConstantCurrent(min(max(float(values.get("i_passive", 0.0)), 0.0), I_MAX))
    if fmu is None:
        g = sosm_gains()
        gains = SosmGains(lam=g["lambda"], rho=g["rho"], zeta=g["zeta"], theta=g["theta"], i_max=I_MAX)
        return ref.SosmCurrent(gains, period)
    if fmu == "SwitchingCurrentController":
        return ref.SwitchingCurrent(float(values["i_high"]), float(values["i_low"]), I_MAX)
    if fmu == "ClippedOptimalCurrentController":
        return ref.EstimatedCurrent("clipped-optimal", values, period)
    if fmu == "LyapunovCurrentController":
        return ref.EstimatedCurrent("lyapunov", values, period)
    if fmu == "FrequencyCurrentController":
        return ref.FrequencyCurrent(values, period)
    raise ValueError(f"no reference controller for strategy {strategy!r} ({fmu})")


def reference(record: str, strategy: str, controller_step: float, record_every: int, stop_time: float | None,
              substeps: int = 8, omega_h: float = 0.05, latency: int | None = None, scale: float = 1.0
              ) -> tuple[ref.SampledRun, float, float]:
    """The sampled-data reference of one case: (finer run, largest peak change on halving the sub-step, seconds).

    ``latency`` in recorded steps (default 0, the co-simulation's: :func:`tests.sampled_reference.simulate_sampled`);
    ``scale`` multiplies the ground acceleration (a perturbation, to measure the case's conditioning)."""
    gm, full = record_of(record)
    T = full if stop_time is None else stop_time
    n = round(T / controller_step)
    motion = ref.record_motion(gm)
    plant = ref.Plant(motion if scale == 1.0 else (lambda t: scale * motion(t)))
    start = time.perf_counter()
    fine, change = ref.converged(lambda s, w: ref.simulate_sampled(
        plant, reference_controller(strategy, controller_step), controller_step, n, record_every=record_every,
        latency=latency, substeps=s, omega_h=w), substeps, omega_h)
    return fine, change, time.perf_counter() - start


def variant_change(run: ref.SampledRun, record: str, strategy: str, controller_step: float, record_every: int,
                   stop_time: float | None, latency: int | None = None, scale: float = 1.0) -> float:
    """Largest relative change of a compared peak of the reference ``run`` (the finer run of :func:`reference`)
    when it is run again with another ``latency`` [recorded steps] or the ground acceleration scaled by ``scale``.

    With scale = 1 + 1e-4 this is the case's conditioning: about 1e-4 when well-conditioned, far more where a
    small change flips switching decisions (no co-simulation can be held closer than that to any reference)."""
    gm, full = record_of(record)
    T = full if stop_time is None else stop_time
    motion = ref.record_motion(gm)
    plant = ref.Plant(motion if scale == 1.0 else (lambda t: scale * motion(t)))
    other = ref.simulate_sampled(plant, reference_controller(strategy, controller_step), controller_step,
                                 round(T / controller_step), record_every=record_every, latency=latency,
                                 substeps=16, omega_h=0.025).peaks()
    base = run.peaks()
    return max(abs(other[k] - base[k]) / base[k] for k in PEAKS)


def relative_errors(got: dict[str, float], expected: dict[str, float]) -> dict[str, float]:
    """(got - expected) / expected per compared peak."""
    return {k: (got[k] - expected[k]) / expected[k] for k in PEAKS}
