"""The peaks of one control setting on one record, in-process, and the case study's objective J.

Both the constant-current sweep (:mod:`orchestration.case_study.current_sweep`) and the SOSM gain tuning
(:mod:`orchestration.case_study.tuning`) rank settings by J, dimensionless, against passive-off (0 A)::

    J = w_acc * a3 / a3_off + w_drift * d / d_off + penalty * max(0, x0 / x_limit - 1)
        + w_saturation * s_bound + w_zero * s_zero + w_mean_current * i_mean / i_max

a3: peak absolute top-floor acceleration [m/s^2]; d: peak inter-storey drift over all
storeys [m]; x0: peak base (isolator) displacement [m]; x_limit: the device limit (15 mm);
s_bound: share of the time the current sits at the controller's limit i_max; s_zero: share
at 0 A; i_mean: mean current [A] (the current weights are 0 for the study's first gain set).

A setting is simulated with :func:`orchestration.inprocess.simulate_coupled`, which steps in-process units over the
same physics cores with the engine's own coupling algorithm, the same step and scheme as a co-simulation of the
FMUs (about 10x faster than one).
"""

from __future__ import annotations

import math

import numpy as np

from components.physics.monolithic import SystemSetup, Trajectory
from components.physics.sosm_controller_core import SosmGains
from orchestration.building_studies.in_process_model import system_setup
from orchestration.case_study.case_config import ObjectiveSpec
from orchestration.inprocess import simulate_coupled
from orchestration.master.resolve import SystemPlan


def peak_values(tr: Trajectory, i_limit: float | None = None) -> dict[str, float]:
    """Peaks and current statistics of a trajectory.

    a3: peak top-floor absolute acceleration [m/s^2]; d: peak drift, all storeys [m]; x0: peak
    base displacement [m]; i_mean, i_min, i_max: current [A]; s_bound: share of the time at
    ``i_limit`` [A] (the controller's limit; None: the largest current of the run), s_zero:
    share at 0 A (both within 1e-6 A).
    """
    i = tr.i
    limit = float(np.max(i)) if i_limit is None else float(i_limit)
    return {"a3": float(np.max(np.abs(tr.a[:, -1]))), "d": float(np.max(np.abs(tr.drift))),
            "x0": float(np.max(np.abs(tr.x[:, 0]))), "i_mean": float(np.mean(i)), "i_min": float(np.min(i)),
            "i_max": float(np.max(i)), "i_limit": limit, "s_bound": float(np.mean(i >= limit - 1e-6)),
            "s_zero": float(np.mean(i <= 1e-6))}


def objective(peaks: dict[str, float], off: dict[str, float], obj: ObjectiveSpec) -> float:
    """The dimensionless objective J of the module docstring (lower is better; passive-off has J = 1 + penalty)."""
    if not all(math.isfinite(peaks[k]) for k in ("a3", "d", "x0")):
        return math.inf
    j = (obj.w_acc * peaks["a3"] / off["a3"] + obj.w_drift * peaks["d"] / off["d"]
         + obj.penalty * max(0.0, peaks["x0"] / obj.x_limit - 1.0))
    if obj.w_saturation:
        j += obj.w_saturation * peaks["s_bound"]
    if obj.w_zero:
        j += obj.w_zero * peaks["s_zero"]
    if obj.w_mean_current:
        j += obj.w_mean_current * peaks["i_mean"] / peaks["i_limit"]
    return j


def simulate(setup: SystemSetup, plan: SystemPlan, stop_time: float | None = None) -> Trajectory:
    sim = plan.loaded.scenario.simulation
    t_stop = sim.stop_time if stop_time is None else min(stop_time, sim.stop_time)
    extra = {"inputs": sim.inputs} if hasattr(sim, "inputs") else {}  # the master's input estimate, if it has one
    return simulate_coupled(setup, sim.step, round((t_stop - sim.start_time) / sim.step), sim.algorithm, **extra)


def evaluate_setting(plan: SystemPlan, setting: float | SosmGains, stop_time: float | None = None
                     ) -> dict[str, float]:
    """Peaks and current statistics of one setting: a passive current [A] (a float) or SOSM gains."""
    if isinstance(setting, SosmGains):
        return peak_values(simulate(system_setup(plan, None, setting), plan, stop_time), setting.i_max)
    setup = system_setup(plan, float(setting))
    return peak_values(simulate(setup, plan, stop_time), setup.i_max)
