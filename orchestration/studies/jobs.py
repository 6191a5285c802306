"""The jobs of a study, each run in its own spawned process (orchestration.studies.runner).

Payloads and return values are plain data (picklable); paths are strings.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

# Recorded variables of every co-simulation of the study (the report roles are added by the master).
RECORDED = ("building.x_0", "building.v_0", "building.drift_1", "building.drift_2", "building.drift_3",
            "building.a_0", "building.a_1", "building.a_2", "building.a_3", "building.shear_1",
            "building.shear_2", "building.shear_3", "isolator.F", "controller.i")


def cosim_job(payload: dict[str, Any]) -> dict[str, Any]:
    """One co-simulation through the master: payload scenario, overrides, out. Returns how it ended."""
    import signal

    from orchestration.master.execution import Interrupted
    from orchestration.project import run_scenario

    def on_sigterm(signum: int, frame: Any) -> None:
        raise Interrupted()

    signal.signal(signal.SIGTERM, on_sigterm)  # terminated by the study: keep the partial results, marked incomplete
    outputs = "outputs=[" + ", ".join(RECORDED) + "]"
    outcome = run_scenario(Path(payload["scenario"]), (*payload["overrides"], outputs), out=Path(payload["out"]),
                           plots=False, progress=False)
    s = outcome.summary
    return {"complete": outcome.result.complete, "status": outcome.result.status,
            "error": str(outcome.result.error) if outcome.result.error else None, "folder": str(outcome.folder),
            "wall_time_s": s.get("wall_time_s"), "unit_warnings": s.get("unit_warnings", {}),
            "time_beyond_identified_range_s": s.get("time_beyond_identified_range_s"),
            "time_beyond_device_limit_s": s.get("time_beyond_device_limit_s"),
            "peak_base_displacement_m": s.get("peak_base_displacement_m")}


def _plan(payload: dict[str, Any]):
    from orchestration.project import plan_scenario

    return plan_scenario(Path(payload["scenario"]), tuple(payload["overrides"]))


def sweep_job(payload: dict[str, Any]) -> dict[str, Any]:
    """Constant-current sweep of one record (in-process physics): payload scenario, overrides, currents, objective."""
    from orchestration.studies.config import ObjectiveSpec
    from orchestration.studies.tuning import sweep_currents

    return sweep_currents(_plan(payload), list(payload["currents"]), ObjectiveSpec(**payload["objective"]))


def reference_job(payload: dict[str, Any]) -> dict[str, Any]:
    """Monolithic Radau reference at a constant current: peaks in the units of peaks.csv."""
    from components.physics.monolithic import simulate_radau
    from orchestration.studies.tuning import system_setup

    plan = _plan(payload)
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
