"""The case study's jobs, as they run on a Dask worker (:mod:`orchestration.batch`).

Co-simulations run in a child process of the worker (``isolate=True``) and send their run
folder back; the in-process physics (current sweep, Radau reference) runs in the worker.
Payloads and values are plain data (they cross into other processes and into ``jobs/``), each
read and written through its record: :class:`SweepInputs`, :class:`ReferenceInputs`,
:class:`CosimResult`. Every co-simulation records the building studies' variables
(:data:`orchestration.building_studies.run_settings.RECORDED`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from orchestration.batch.jobs import job_plan, run_folder
from orchestration.building_studies.run_settings import RECORDED
from orchestration.case_study.benchmark_criteria import FORCE_OFF as FORCE_OFF_OUTPUT

OUTPUTS_OVERRIDE = "outputs=[" + ", ".join(RECORDED) + "]"
# A controller benchmark records the floors' velocities too (the input energy of its criterion J9).
# And the isolator's force at 0 A along the same motion (J6), where the isolator FMU gives it (case_plan.plan_cosim).
BENCHMARK_OUTPUTS_OVERRIDE = ("outputs=[" + ", ".join((*RECORDED, "building.v_1", "building.v_2", "building.v_3",
                                                       "ground.ag", FORCE_OFF_OUTPUT)) + "]")
# The code that decides these jobs' numbers, besides the engine's (orchestration.batch.portable.job_key): every
# project module this one imports, directly or through others, also inside the job functions (code_sources).
CODE_SOURCES = ("module:orchestration.case_study.case_jobs",)


@dataclass(frozen=True)
class SweepInputs:
    """The inputs of a sweep job besides its plan: the constant currents [A] and the objective's settings."""

    currents: list[float]
    objective: dict[str, Any]  # an ObjectiveSpec dump

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> SweepInputs:
        return cls(currents=list(d["currents"]), objective=dict(d["objective"]))


@dataclass(frozen=True)
class ReferenceInputs:
    """The inputs of a Radau reference job besides its plan: the constant current [A] and the relative tolerance."""

    current: float
    rtol: float

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> ReferenceInputs:
        return cls(current=float(d["current"]), rtol=float(d["rtol"]))


@dataclass(frozen=True)
class CosimResult:
    """How one case-study co-simulation ended, as its job returns it and ``jobs/`` stores it (without ``files``,
    which the client writes into the run folder)."""

    complete: bool
    status: str
    error: str | None
    wall_time_s: float | None
    unit_warnings: dict[str, Any]
    time_beyond_identified_range_s: float | None
    time_beyond_device_limit_s: float | None
    peak_base_displacement_m: float | None
    files: dict[str, bytes] | None = None  # the run folder's files (zlib-compressed), by name; None once written

    def to_json(self) -> dict[str, Any]:
        out = asdict(self)
        if self.files is None:
            del out["files"]
        return out

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> CosimResult:
        return cls(complete=bool(d["complete"]), status=d["status"], error=d["error"], wall_time_s=d["wall_time_s"],
                   unit_warnings=d["unit_warnings"], time_beyond_identified_range_s=d["time_beyond_identified_range_s"],
                   time_beyond_device_limit_s=d["time_beyond_device_limit_s"],
                   peak_base_displacement_m=d["peak_base_displacement_m"], files=d.get("files"))

    @staticmethod
    def describes(value: Any) -> bool:
        """Whether a job's value is a co-simulation's (not a sweep's or a reference's)."""
        return isinstance(value, dict) and "complete" in value and "time_beyond_identified_range_s" in value


def cosim_job(payload: dict[str, Any]) -> dict[str, Any]:
    """One case-study co-simulation; returns how it ended and its run folder's files (:class:`CosimResult`): its
    numbers (``metrics.json``, from the recorder's every step), its figure series where asked, and its time series
    only where the study asks for them (:mod:`orchestration.case_study.run_numbers`)."""
    from orchestration.case_study.run_numbers import NumberInputs

    inputs = NumberInputs.from_json(payload["numbers"])
    outcome, files = run_folder(payload, results_file=inputs.timeseries,
                                add_files=lambda plan, outcome, folder: write_numbers(plan, outcome, folder, inputs))
    s = outcome.summary
    return CosimResult(
        complete=outcome.result.complete, status=outcome.result.status,
        error=str(outcome.result.error) if outcome.result.error else None, wall_time_s=s.get("wall_time_s"),
        unit_warnings=s.get("unit_warnings", {}),
        time_beyond_identified_range_s=s.get("time_beyond_identified_range_s"),
        time_beyond_device_limit_s=s.get("time_beyond_device_limit_s"),
        peak_base_displacement_m=s.get("peak_base_displacement_m"), files=files).to_json()


def write_numbers(plan: Any, outcome: Any, folder: Any, inputs: Any) -> None:
    """A run's ``metrics.json`` (and its figure series where ``inputs`` asks), from the recorder's every step; none
    for a run that recorded fewer than two steps. A variable the numbers need that the run did not record (a unit
    from another tool without it) fails the job, naming it."""
    from mre_common.atomic_files import atomic_write_text
    from orchestration.building_studies.run_metrics import recorded_series
    from orchestration.case_study.run_numbers import (
        FIGURE_SERIES_FILE,
        NUMBERS_FILE,
        numbers_json,
        run_numbers,
        write_figure_series,
    )

    if outcome.recorder.count < 2:
        return
    current = getattr(plan.report, "current", None)
    series = recorded_series(outcome.recorder, None if current is None else str(current))
    try:
        numbers = run_numbers(series, outcome.summary.get("energy"), inputs)
    except KeyError as exc:
        raise RuntimeError(f"the study's numbers need the variable {exc}, which this run did not record") from None
    atomic_write_text(folder / NUMBERS_FILE, numbers_json(numbers))
    if inputs.figure_series:
        write_figure_series(folder / FIGURE_SERIES_FILE, series)


def sweep_job(payload: dict[str, Any]) -> dict[str, Any]:
    """Constant-current sweep of one record (in-process physics): payload plan, files and :class:`SweepInputs`."""
    from orchestration.case_study.case_config import ObjectiveSpec
    from orchestration.case_study.current_sweep import sweep_currents

    plan, _ = job_plan(payload)
    inputs = SweepInputs.from_json(payload)
    return sweep_currents(plan, inputs.currents, ObjectiveSpec(**inputs.objective))


def reference_job(payload: dict[str, Any]) -> dict[str, Any]:
    """Monolithic Radau reference at a constant current (:class:`ReferenceInputs`): peaks in the units of peaks.csv."""
    from components.physics.monolithic import simulate_radau
    from orchestration.building_studies.in_process_model import system_setup

    plan, _ = job_plan(payload)
    inputs = ReferenceInputs.from_json(payload)
    sim = plan.loaded.scenario.simulation
    setup = system_setup(plan, inputs.current)
    n = sim.n_steps
    t_eval = sim.start_time + np.arange(n + 1) * sim.step
    t_eval[-1] = sim.stop_time
    if sim.start_time != 0.0:
        raise ValueError("the Radau reference starts at t = 0")
    tr = simulate_radau(setup, sim.stop_time, t_eval, rtol=inputs.rtol)
    p = tr.peaks()
    out = {"x_base_mm": 1e3 * p["x_0"]}
    out.update({f"drift_{j}_mm": 1e3 * p[f"drift_{j}"] for j in range(1, tr.x.shape[1])})
    out.update({f"acc_{j}": p[f"a_{j}"] for j in range(tr.x.shape[1])})
    out["base_shear_N"] = float(np.max(np.abs(tr.F)))
    return out
