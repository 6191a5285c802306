"""The constant-current sweep of the case study's best-constant strategy: J of every current on one record.

In-process physics for the paper's system (:func:`orchestration.case_study.objective.evaluate_setting`); a
co-simulation of the scenario's FMUs per current for any other plant.
"""

from __future__ import annotations

import dataclasses
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from orchestration.building_studies.in_process_model import monolithic_problem
from orchestration.case_study.case_config import ObjectiveSpec
from orchestration.case_study.objective import evaluate_setting, objective
from orchestration.master.resolve import SystemPlan


def cosimulated_peaks(plan: SystemPlan, current: float) -> dict[str, float]:
    """Peaks and current statistics of a co-simulation of the plan's FMUs at a constant current [A] (the scenario's
    controller unit in ``mode: passive``): for a plant the in-process model does not represent. ValueError if
    the run does not complete; ``valid`` and ``invalid_reasons`` as the run's summary says (an invalid run is not
    ranked by :func:`sweep_currents`)."""
    from orchestration.master.session import run_plan

    params = {u: dict(v) for u, v in plan.parameters.items()}
    params.setdefault("controller", {}).update({"mode": "passive", "i_passive": float(current)})
    with tempfile.TemporaryDirectory(prefix="mre-cosim-sweep-") as tmp:
        outcome = run_plan(dataclasses.replace(plan, parameters=params), Path(tmp) / "run", plots=False)
        if not outcome.result.complete:
            raise ValueError(f"the co-simulation at {current:g} A did not complete: {outcome.result.error}")
        validity = {"valid": bool(outcome.summary.get("valid", True)),
                    "invalid_reasons": list(outcome.summary.get("invalid_reasons") or [])}
        rec = outcome.recorder
        cols = {name: rec.column(name) for name in ("building.a_3", "building.x_0", "controller.i")}
        drifts = [rec.column(f"building.drift_{j}") for j in (1, 2, 3)]
    i = cols["controller.i"]
    return {"a3": float(np.max(np.abs(cols["building.a_3"]))), "d": float(max(np.max(np.abs(d)) for d in drifts)),
            "x0": float(np.max(np.abs(cols["building.x_0"]))), "i_mean": float(np.mean(i)),
            "i_min": float(np.min(i)), "i_max": float(np.max(i)), "i_limit": float(np.max(i)),
            "s_bound": float(np.mean(i >= np.max(i) - 1e-6)), "s_zero": float(np.mean(i <= 1e-6)), **validity}


def sweep_currents(plan: SystemPlan, currents: list[float], obj: ObjectiveSpec) -> dict[str, Any]:
    """Objective of every constant current [A] on one planned record; the best is the lowest J (ties: lower current).

    In-process physics for the paper's system; a co-simulation of the scenario's FMUs per current for any other
    plant (:func:`monolithic_problem`: e.g. the nominal plant's Bouc-Wen isolators and coil lag)."""
    evaluate: Callable[[float], dict[str, float]]
    if monolithic_problem(plan) is None:
        def evaluate(i: float) -> dict[str, float]:
            return evaluate_setting(plan, i)
    else:
        def evaluate(i: float) -> dict[str, float]:
            return cosimulated_peaks(plan, i)
    off = evaluate(0.0)
    rows = []
    for i in currents:
        p = off if i == 0.0 else evaluate(i)
        rows.append({"current_A": i, **p, "J": objective(p, off, obj)})
    valid = [r for r in rows if r.get("valid", True)]  # a co-simulation that says it is invalid is not ranked
    if not valid:
        raise ValueError("no constant current gave a valid run: " + "; ".join(
            f"{r['current_A']:g} A: {', '.join(r.get('invalid_reasons', []))}" for r in rows))
    best = min(valid, key=lambda r: (r["J"], r["current_A"]))
    return {"rows": rows, "best_current_A": best["current_A"], "best_J": best["J"]}
