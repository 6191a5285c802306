"""The jobs of the studies, as they run on a Dask worker (:mod:`orchestration.studies.engine`).

Every payload carries a :class:`~orchestration.studies.portable.PortablePlan` and the bytes of
the files it names (``"files"``: SHA-256 -> bytes, shared handles resolved by Dask), so no
job reads the client's file system. Co-simulations run in a child process of the worker
(``isolate=True``); the in-process physics (sweep, Radau reference) runs in the worker.
Values are plain data.
"""

from __future__ import annotations

import math
import os
import tempfile
import time
import zlib
from pathlib import Path
from typing import Any

import numpy as np

# Recorded variables of every co-simulation of a study (the report roles are added by the master).
RECORDED = ("building.x_0", "building.v_0", "building.drift_1", "building.drift_2", "building.drift_3",
            "building.a_0", "building.a_1", "building.a_2", "building.a_3", "building.shear_1",
            "building.shear_2", "building.shear_3", "isolator.F", "controller.i")
OUTPUTS_OVERRIDE = "outputs=[" + ", ".join(RECORDED) + "]"
LIMIT_MARK = "exceeds the limit"  # the master's message when a limits.max_abs bound stops a run


def _plan(payload: dict[str, Any], parameters: dict[str, dict[str, Any]] | None = None):
    from orchestration.studies.portable import relocate

    return relocate(payload["plan"], payload["files"], parameters)


def _localize(text: str, paths: dict[str, str]) -> str:
    for local, client in paths.items():
        text = text.replace(local, client)
    return text


def cosim_job(payload: dict[str, Any]) -> dict[str, Any]:
    """One case-study co-simulation; returns how it ended and its run folder's files (zlib-compressed).

    The run folder is written in a temporary folder of the worker and sent back whole; the
    paths of the worker's file cache in ``manifest.json`` and ``summary.json`` are replaced
    by the client's paths (the SHA-256 in the manifest names the same bytes).
    """
    from orchestration.master.session import run_plan

    plan, paths = _plan(payload)
    with tempfile.TemporaryDirectory(prefix="mre-cosim-run-") as tmp:
        folder = Path(tmp) / "run"
        outcome = run_plan(plan, folder, plots=False, progress=False)
        files = {}
        for f in sorted(folder.iterdir()):
            if f.is_file():
                data = f.read_bytes()
                if f.suffix == ".json":
                    data = _localize(data.decode(), paths).encode()
                files[f.name] = zlib.compress(data, 1)
    s = outcome.summary
    return {"complete": outcome.result.complete, "status": outcome.result.status,
            "error": str(outcome.result.error) if outcome.result.error else None,
            "wall_time_s": s.get("wall_time_s"), "unit_warnings": s.get("unit_warnings", {}),
            "time_beyond_identified_range_s": s.get("time_beyond_identified_range_s"),
            "time_beyond_device_limit_s": s.get("time_beyond_device_limit_s"),
            "peak_base_displacement_m": s.get("peak_base_displacement_m"), "files": files}


def write_run_files(folder: Path, files: dict[str, bytes]) -> None:
    """Write a run folder sent back by :func:`cosim_job` (each file to a temporary name, then renamed)."""
    folder.mkdir(parents=True, exist_ok=True)
    for name, blob in files.items():
        fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=".tmp", dir=folder)
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(zlib.decompress(blob))
            os.chmod(tmp, 0o644)
            os.replace(tmp, folder / name)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise


def ida_job(payload: dict[str, Any]) -> dict[str, Any]:
    """One IDA run: the plan at ``payload["scale"]``; peaks and RMS values (units of peaks.csv), status, timing."""
    from orchestration.master.session import run_plan
    from orchestration.studies.analysis import run_metrics

    plan, _ = _plan(payload, {"ground": {"scale": float(payload["scale"])}})
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


def sweep_job(payload: dict[str, Any]) -> dict[str, Any]:
    """Constant-current sweep of one record (in-process physics): payload plan, files, currents, objective."""
    from orchestration.studies.config import ObjectiveSpec
    from orchestration.studies.tuning import sweep_currents

    plan, _ = _plan(payload)
    return sweep_currents(plan, list(payload["currents"]), ObjectiveSpec(**payload["objective"]))


def reference_job(payload: dict[str, Any]) -> dict[str, Any]:
    """Monolithic Radau reference at a constant current: peaks in the units of peaks.csv."""
    from components.physics.monolithic import simulate_radau
    from orchestration.studies.tuning import system_setup

    plan, _ = _plan(payload)
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

