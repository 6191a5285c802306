"""The IDA's job, as it runs on a Dask worker (:mod:`orchestration.batch`): one record component at one scale."""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path
from typing import Any

from orchestration.batch.jobs import job_plan

LIMIT_MARK = "exceeds the limit"  # the master's message when a limits.max_abs bound stops a run
# The code that decides this job's numbers, besides the engine's (orchestration.batch.portable.job_key).
CODE_SOURCES = ("components/physics", "orchestration/ida_study/ida_jobs.py", "orchestration/case_study/analysis.py")


def ida_job(payload: dict[str, Any]) -> dict[str, Any]:
    """One IDA run: the plan at ``payload["scale"]``; peaks and RMS values (units of peaks.csv), status, timing."""
    from orchestration.case_study.analysis import run_metrics
    from orchestration.master.session import run_plan

    plan, _ = job_plan(payload, {"ground": {"scale": float(payload["scale"])}})
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="mre-cosim-ida-") as tmp:
        outcome = run_plan(plan, Path(tmp) / "run", plots=False, progress=False)
    rec = outcome.recorder
    ts = {"time": rec.times[: rec.count].copy()}
    ts.update({name: rec.data[: rec.count, k].copy() for k, name in enumerate(rec.names)})
    result = outcome.result
    error = str(result.error) if result.error else None
    status = "ok" if result.complete else ("diverged" if error and LIMIT_MARK in error else result.status)
    try:
        metrics = run_metrics(ts, payload["masses"]) if rec.count > 1 else {}
    except KeyError as exc:  # a swapped unit without one of the variables
        metrics = {}
        error = error or f"variable {exc} not recorded"
    clean = {k: (float(v) if v is not None and math.isfinite(v) else None) for k, v in metrics.items()}
    return {"status": status, "error": error, "end_time_s": float(result.end_time), "steps": result.steps_done,
            "run_wall_time_s": time.perf_counter() - started, "metrics": clean}
