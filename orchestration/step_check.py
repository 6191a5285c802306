"""Step convergence of a run (``run.py --verify-step``): the same scenario again with the plant's coupling step
halved and the controller's own period fixed, each peak's change written into the run's ``summary.json``.

The controller is the unit whose output the report's ``current`` role names (``report.current:
controller.i``); its period is pinned with ``units.<controller>.step`` at the period it had in the run
(its own ``step``, else ``simulation.step``), so that halving the plant's step does not also make the
controller sample twice as often. A run whose largest peak change is above ``report.step_tolerance``
is not converged in the step: numerically invalid, with that reason. A verdict between two strategies
closer than the change is a tie.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from orchestration.building_report import DEFAULT_STEP_TOLERANCE, step_changes
from orchestration.master.errors import ScenarioError
from orchestration.master.resolve import SystemPlan
from orchestration.master.session import RunOutcome, run_plan
from orchestration.master.summary import write_summary


def controller_unit(plan: SystemPlan) -> str | None:
    """The unit whose output the report's ``current`` role names, or None."""
    current = getattr(plan.report, "current", None)
    return current.unit if current is not None else None


def half_step_overrides(plan: SystemPlan) -> tuple[list[str], dict[str, Any]]:
    """The ``--set`` overrides of the half-step run, and what they pin (plant step, controller and its period)."""
    sc = plan.loaded.scenario
    h = float(sc.simulation.step)
    overrides = [f"simulation.step={h / 2!r}"]
    pinned: dict[str, Any] = {"plant_step_s": h, "half_step_s": h / 2, "controller_unit": None,
                              "controller_step_s": None}
    unit = controller_unit(plan)
    if unit is not None and unit in sc.units:
        own = getattr(sc.units[unit], "step", None)
        period = float(own) if own is not None else h
        overrides.append(f"units.{unit}.step={period!r}")
        pinned.update(controller_unit=unit, controller_step_s=period)
    return overrides, pinned


def largest_change(changes: dict[str, float]) -> tuple[str | None, float]:
    """The peak that moved most (by |relative change|) and its change; (None, NaN) without any."""
    finite = {k: v for k, v in changes.items() if math.isfinite(v)}
    if not finite:
        return None, math.nan
    name = max(finite, key=lambda k: abs(finite[k]))
    return name, abs(finite[name])


def step_section(coarse: dict[str, Any], fine: dict[str, Any], pinned: dict[str, Any], tolerance: float,
                 half_step_run: str) -> tuple[dict[str, Any], list[str]]:
    """The ``step_convergence`` section of a summary from the run's and the half-step run's summaries, and the
    reasons it makes the run invalid."""
    changes = step_changes(coarse, fine)
    name, change = largest_change(changes)
    converged = bool(math.isfinite(change) and change <= tolerance) and fine.get("complete", True) is not False
    section = {"half_step_run": half_step_run, **pinned, "changes": changes, "largest": name,
               "largest_change": change, "tolerance": tolerance, "converged": converged,
               "half_step_valid": fine.get("valid"), "half_step_complete": fine.get("complete")}
    reasons = []
    if fine.get("complete") is False:
        reasons.append(f"step not converged: the run with the plant's step halved did not end ({fine.get('error')})")
    elif not converged:
        reasons.append(f"step not converged: {name} changed by {100 * change:.3g} % with the plant's step halved "
                       f"(tolerance {100 * tolerance:g} %, report.step_tolerance)")
    return section, reasons


def verify_step(scenario: Path, overrides: tuple[str, ...], data_dirs: tuple[Path, ...], plan: SystemPlan,
                outcome: RunOutcome, progress: bool = False) -> dict[str, Any]:
    """Run the scenario again at half the plant's step (controller period pinned) into ``<run folder>-half-step``,
    add ``step_convergence`` (and any reason) to the run's summary and rewrite its ``summary.json``."""
    from orchestration.engine_hooks import plan_scenario

    extra, pinned = half_step_overrides(plan)
    tolerance = float(getattr(plan.report, "step_tolerance", DEFAULT_STEP_TOLERANCE))
    summary = outcome.summary
    folder = Path(f"{outcome.folder}-half-step")
    try:
        fine_plan = plan_scenario(scenario, (*overrides, *extra), data_dirs)
    except ScenarioError as exc:
        section: dict[str, Any] = {**pinned, "error": f"the half-step run cannot be made: {exc}", "converged": None}
        reasons: list[str] = []
    else:
        try:
            fine = run_plan(fine_plan, folder, plots=False, progress=progress)
        finally:
            cleanup = getattr(fine_plan.loaded, "cleanup", None)
            if cleanup is not None:
                cleanup()
        section, reasons = step_section(summary, fine.summary, pinned, tolerance, str(fine.folder))
    summary["step_convergence"] = section
    if reasons:
        summary["invalid_reasons"] = [*summary.get("invalid_reasons", []), *reasons]
        summary["valid"] = False
    write_summary(outcome.folder / "summary.json", summary)
    return section
