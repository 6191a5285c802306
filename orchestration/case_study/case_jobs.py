"""The case study's jobs, as they run on a Dask worker (:mod:`orchestration.batch`).

Co-simulations run in a child process of the worker (``isolate=True``) and send their run
folder back; the in-process physics (current sweep, Radau reference) runs in the worker.
Values are plain data. The IDA's job (:mod:`orchestration.ida_study.ida_jobs`) records the
same variables.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from orchestration.batch.jobs import job_plan, run_folder

# Recorded variables of every co-simulation of a study (the report roles are added by the master).
RECORDED = ("building.x_0", "building.v_0", "building.drift_1", "building.drift_2", "building.drift_3",
            "building.a_0", "building.a_1", "building.a_2", "building.a_3", "building.shear_1",
            "building.shear_2", "building.shear_3", "isolator.F", "controller.i")
OUTPUTS_OVERRIDE = "outputs=[" + ", ".join(RECORDED) + "]"
# A controller benchmark records the floors' velocities too (the input energy of its criterion J9).
BENCHMARK_OUTPUTS_OVERRIDE = ("outputs=[" + ", ".join((*RECORDED, "building.v_1", "building.v_2", "building.v_3",
                                                       "ground.ag")) + "]")
# The code that decides these jobs' numbers, besides the engine's (orchestration.batch.portable.job_key): every
# project module this one imports, directly or through others, also inside the job functions (code_sources).
CODE_SOURCES = ("module:orchestration.case_study.case_jobs",)


def cosim_job(payload: dict[str, Any]) -> dict[str, Any]:
    """One case-study co-simulation; returns how it ended and its run folder's files (zlib-compressed)."""
    outcome, files = run_folder(payload)
    s = outcome.summary
    return {"complete": outcome.result.complete, "status": outcome.result.status,
            "error": str(outcome.result.error) if outcome.result.error else None,
            "wall_time_s": s.get("wall_time_s"), "unit_warnings": s.get("unit_warnings", {}),
            "time_beyond_identified_range_s": s.get("time_beyond_identified_range_s"),
            "time_beyond_device_limit_s": s.get("time_beyond_device_limit_s"),
            "peak_base_displacement_m": s.get("peak_base_displacement_m"), "files": files}


def sweep_job(payload: dict[str, Any]) -> dict[str, Any]:
    """Constant-current sweep of one record (in-process physics): payload plan, files, currents, objective."""
    from orchestration.case_study.case_config import ObjectiveSpec
    from orchestration.case_study.tuning import sweep_currents

    plan, _ = job_plan(payload)
    return sweep_currents(plan, list(payload["currents"]), ObjectiveSpec(**payload["objective"]))


def reference_job(payload: dict[str, Any]) -> dict[str, Any]:
    """Monolithic Radau reference at a constant current: peaks in the units of peaks.csv."""
    from components.physics.monolithic import simulate_radau
    from orchestration.case_study.tuning import system_setup

    plan, _ = job_plan(payload)
    sim = plan.loaded.scenario.simulation
    setup = system_setup(plan, float(payload["current"]))
    n = sim.n_steps
    t_eval = sim.start_time + np.arange(n + 1) * sim.step
    t_eval[-1] = sim.stop_time
    if sim.start_time != 0.0:
        raise ValueError("the Radau reference starts at t = 0")
    tr = simulate_radau(setup, sim.stop_time, t_eval, rtol=float(payload["rtol"]))
    p = tr.peaks()
    out = {"x_base_mm": 1e3 * p["x_0"]}
    out.update({f"drift_{j}_mm": 1e3 * p[f"drift_{j}"] for j in range(1, tr.x.shape[1])})
    out.update({f"acc_{j}": p[f"a_{j}"] for j in range(tr.x.shape[1])})
    out["base_shear_N"] = float(np.max(np.abs(tr.F)))
    return out
