"""The IDA's job, as it runs on a Dask worker (:mod:`orchestration.batch`): one record component at one scale.

Its payload and value are plain data (they cross into another process and into ``jobs/``), read and written
through their records: :class:`IdaInputs` (besides the plan and its files), :class:`IdaRunResult`.
"""

from __future__ import annotations

import math
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from orchestration.batch.jobs import job_plan

LIMIT_MARK = "exceeds the limit"  # the master's message when a limits.max_abs bound stops a run
# The OpenSees building unit's message when a step does not converge (also with 10x shorter steps): the
# structure has lost its stability, so the run counts as a collapse at its intensity, not as an error.
COLLAPSE_MARK = "OpenSees' transient analysis failed to converge"
COLLAPSED_STATUS = "collapsed"
# The code that decides this job's numbers, besides the engine's (orchestration.batch.portable.job_key): every
# project module this one imports, directly or through others (orchestration.batch.code_sources).
CODE_SOURCES = ("module:orchestration.ida_study.ida_jobs",)


@dataclass(frozen=True)
class IdaInputs:
    """The inputs of one IDA run besides its plan: the amplitude scale, the masses [kg] (base first) and a
    ShearBuilding's storey constants (``k``, ``c``, ``pdelta`` per storey: the residual drift; None: another
    building unit)."""

    scale: float
    masses: list[float]
    storeys: dict[str, list[float]] | None = None

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> IdaInputs:
        return cls(scale=float(d["scale"]), masses=d["masses"], storeys=d.get("storeys"))


@dataclass(frozen=True)
class IdaRunResult:
    """How one IDA run ended: its status (:func:`run_status`), peaks and RMS values (units of peaks.csv, None where
    not finite), timing and the run's numerical validity."""

    status: str
    error: str | None
    end_time_s: float | None = None  # [s]
    steps: int | None = None
    run_wall_time_s: float | None = None  # [s]
    metrics: dict[str, float | None] = field(default_factory=dict)
    valid: bool | None = None  # None: a result stored before runs said so
    invalid_reasons: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> IdaRunResult:
        return cls(status=d["status"], error=d.get("error"), end_time_s=d.get("end_time_s"), steps=d.get("steps"),
                   run_wall_time_s=d.get("run_wall_time_s"), metrics=d.get("metrics") or {}, valid=d.get("valid"),
                   invalid_reasons=list(d.get("invalid_reasons") or []))


def run_status(complete: bool, error: str | None, status: str) -> str:
    """A run's status in the stripes: ok; diverged (the scenario's divergence limit); collapsed (COLLAPSE_MARK);
    else the master's (failed, ...)."""
    if complete:
        return "ok"
    if error and LIMIT_MARK in error:
        return "diverged"
    if error and COLLAPSE_MARK in error:
        return COLLAPSED_STATUS
    return status


def residual_drifts(ts: dict[str, Any], storeys: dict[str, list[float]] | None) -> dict[str, float]:
    """Residual drift of each storey at the end of the run [mm] and the largest |value| (``residual_drift_max_mm``).

    With the storeys' constants (``storeys``: k_j [N/m], c_j [N s/m], pdelta_j = P_j/h_j [N/m], of a
    ShearBuilding), residual_j = drift_j - f_j / k_j at the last sample, f_j = shear_j - c_j (v_j - v_{j-1})
    + pdelta_j drift_j the storey law's force: the drift left when the storey is unloaded along k_j (the
    unit's ``residual_drift_j``). Without them (another building unit) it is drift_j at the end of the
    run, after the study's free-vibration tail: an upper bound that keeps the elastic sway left then.
    """
    out: dict[str, float] = {}
    j = 1
    while f"building.drift_{j}" in ts:
        drift = float(ts[f"building.drift_{j}"][-1])
        if storeys is not None:
            dv = float(ts[f"building.v_{j}"][-1] - ts[f"building.v_{j - 1}"][-1])
            force = float(ts[f"building.shear_{j}"][-1]) - storeys["c"][j - 1] * dv + storeys["pdelta"][j - 1] * drift
            drift -= force / storeys["k"][j - 1]
        out[f"residual_drift_{j}_mm"] = 1e3 * drift
        j += 1
    out["residual_drift_max_mm"] = max(abs(out[f"residual_drift_{i}_mm"]) for i in range(1, j)) if j > 1 else math.nan
    return out


def ida_job(payload: dict[str, Any]) -> dict[str, Any]:
    """One IDA run: the plan and its files, at the scale of its :class:`IdaInputs` (and the payload's
    ``parameters``, unit -> name -> value, set on top: a tuner's setting); an :class:`IdaRunResult`."""
    from orchestration.building_studies.run_metrics import recorded_series, run_metrics
    from orchestration.master.session import run_plan

    inputs = IdaInputs.from_json(payload)
    plan, _ = job_plan(payload, {**payload.get("parameters", {}), "ground": {"scale": inputs.scale}})
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="mre-cosim-ida-") as tmp:  # the metrics come from the recorder
        outcome = run_plan(plan, Path(tmp) / "run", plots=False, progress=False, results_file=False)
    rec = outcome.recorder
    current = getattr(plan.report, "current", None)
    ts = recorded_series(rec, None if current is None else str(current))
    result = outcome.result
    error = str(result.error) if result.error else None
    status = run_status(result.complete, error, result.status)
    try:
        metrics = run_metrics(ts, inputs.masses) if rec.count > 1 else {}
        if metrics:
            metrics.update(residual_drifts(ts, inputs.storeys))
    except KeyError as exc:  # a swapped unit without one of the variables
        metrics = {}
        error = error or f"variable {exc} not recorded"
    clean = {k: (float(v) if v is not None and math.isfinite(v) else None) for k, v in metrics.items()}
    return IdaRunResult(status=status, error=error, end_time_s=float(result.end_time), steps=result.steps_done,
                        run_wall_time_s=time.perf_counter() - started, metrics=clean,
                        valid=outcome.summary.get("valid"),
                        invalid_reasons=list(outcome.summary.get("invalid_reasons") or [])).to_json()
