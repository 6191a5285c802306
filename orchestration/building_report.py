"""The isolated building's report: its roles in a scenario's ``report:`` section, its limits, its summary and figures.

The engine (:mod:`orchestration.master.report`) knows recorded variables only; this module
is the application's :class:`~orchestration.master.report.ReportHook` (:data:`REPORT`, given
to the engine by :mod:`orchestration.engine_hooks`). A scenario names which recorded variable
plays which role (base displacement, inter-storey drifts, floor accelerations, isolator
current and force, ground acceleration) and may name the displacement limits drawn on the
hysteresis plot; from them come the peaks engineers read (``summary.json``) and four figures:
top-floor acceleration with the ground, drifts, current and the isolator's hysteresis.
Time histories show the strong-motion window large and the whole record below it;
displacements and drifts are drawn in mm, as engineers read them.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import ConfigDict, Field, field_validator

from components.physics.mre_isolator_core import DEVICE_LIMIT_M, IDENTIFIED_RANGE_M
from orchestration.master.recorder import Recorder
from orchestration.master.report import Figures, ReportHook, RunDescription, peak, sample_interval
from orchestration.master.scenario import Number, ReportSpec, VariableRef, variable_refs

__all__ = ["DEVICE_LIMIT_M", "IDENTIFIED_RANGE_M", "REPORT", "BuildingReport", "displacement_limits", "plot",
           "strong_motion_window", "summarize"]
# IDENTIFIED_RANGE_M, DEVICE_LIMIT_M: the limits drawn when a scenario names none: the isolator
# model was identified on +-8 mm and the device allows 15 mm (paper, section 2).


class BuildingReport(ReportSpec):
    """Roles of recorded variables of the isolated building (all optional), besides the caption and labels.

    Declared in the order the variables are added to a run's recording when ``outputs`` lists
    fewer (base displacement, current, isolator force, ground acceleration, drifts, floors).
    """

    model_config = ConfigDict(extra="forbid")

    base_displacement: VariableRef | None = None
    current: VariableRef | None = None
    isolator_force: VariableRef | None = None
    ground_acceleration: VariableRef | None = None
    drifts: list[VariableRef] = Field(default_factory=list)
    floor_accelerations: list[VariableRef] = Field(default_factory=list)
    displacement_limits: dict[str, Number | str] = Field(
        default_factory=dict, description="named limits [m] drawn on the hysteresis plot: a value or 'unit.param'")

    @field_validator("displacement_limits")
    @classmethod
    def _limit_refs(cls, value: dict[str, Number | str]) -> dict[str, Number | str]:
        for label, ref in value.items():
            if isinstance(ref, str):
                VariableRef.parse(ref)
            elif not ref > 0:
                raise ValueError(f"displacement limit {label!r} must be positive, got {ref}")
        return value

    @field_validator("base_displacement", "current", "isolator_force", "ground_acceleration", "drifts",
                     "floor_accelerations", mode="before")
    @classmethod
    def _refs(cls, value: Any) -> Any:
        return variable_refs(value)

    def templates(self) -> list[tuple[tuple[str, ...], str]]:
        """The caption and labels, and each displacement limit given as ``unit.param``."""
        return super().templates() + [(("displacement_limits", label), "{" + ref + "}")
                                      for label, ref in self.displacement_limits.items() if isinstance(ref, str)]


def summarize(spec: BuildingReport, rec: Recorder, run: RunDescription) -> dict[str, Any]:
    """Peaks per role (SI units), time beyond the isolator's identified range and device limit, strong motion."""
    out: dict[str, Any] = {}
    if spec.base_displacement is not None:
        x = rec.column(str(spec.base_displacement))
        out["peak_base_displacement_m"] = peak(x)
        out["time_beyond_identified_range_s"] = float(np.sum(np.abs(x) > IDENTIFIED_RANGE_M) * sample_interval(rec))
        out["time_beyond_device_limit_s"] = float(np.sum(np.abs(x) > DEVICE_LIMIT_M) * sample_interval(rec))
    if spec.drifts:
        out["peak_drift_m"] = {str(r): peak(rec.column(str(r))) for r in spec.drifts}
    if spec.floor_accelerations:
        out["peak_abs_acceleration_m_s2"] = {str(r): peak(rec.column(str(r))) for r in spec.floor_accelerations}
    if spec.current is not None:
        i = rec.column(str(spec.current))
        out["peak_current_A"] = float(np.max(i)) if len(i) else None
        out["mean_current_A"] = float(np.mean(i)) if len(i) else None
    if spec.isolator_force is not None:
        out["peak_isolator_force_N"] = peak(rec.column(str(spec.isolator_force)))
    if spec.ground_acceleration is not None:
        ag = rec.column(str(spec.ground_acceleration))
        out["peak_ground_acceleration_m_s2"] = peak(ag)
        window = strong_motion_window(rec.times, ag)
        if window is not None:
            out["strong_motion_window_s"] = list(window)
    return out


def strong_motion_window(t: np.ndarray, ag: np.ndarray) -> tuple[float, float] | None:
    """Time window [s] holding the strong motion and the response right after it.

    The significant duration D5-95 (Trifunac & Brady 1975: from 5 % to 95 % of the Arias
    intensity, the cumulative integral of ag²), widened by a quarter of D before and half of D
    after (the structure keeps moving after the ground calms down). None without motion.
    """
    if len(t) < 3:
        return None
    energy = np.cumsum(np.asarray(ag, dtype=float) ** 2)
    if not np.isfinite(energy[-1]) or energy[-1] <= 0:
        return None
    energy /= energy[-1]
    t5 = float(t[np.searchsorted(energy, 0.05)])
    t95 = float(t[min(np.searchsorted(energy, 0.95), len(t) - 1)])
    d = max(t95 - t5, float(t[1] - t[0]))
    return max(float(t[0]), t5 - 0.25 * d), min(float(t[-1]), t95 + 0.5 * d)


def displacement_limits(spec: BuildingReport, run: RunDescription) -> dict[str, float]:
    """Named displacement limits [m] for the hysteresis plot (values or ``unit.param`` references)."""
    if not spec.displacement_limits:
        return {"identified range": IDENTIFIED_RANGE_M, "device limit": DEVICE_LIMIT_M}
    out = {}
    for label, ref in spec.displacement_limits.items():
        value = ref if isinstance(ref, int | float) else run.value(*str(ref).split(".", 1))
        if isinstance(value, int | float) and not isinstance(value, bool) and value > 0:
            out[label] = float(value)
    return out


def plot(spec: BuildingReport, rec: Recorder, run: RunDescription, figures: Figures) -> None:
    """PNG figures for the roles present: top-floor acceleration with the ground, drifts, current, hysteresis.

    With the ground acceleration named, time histories show its strong-motion window
    (:func:`strong_motion_window`) large, unless the window covers nearly the whole record.
    """
    t = rec.times
    window, note = None, ""
    if spec.ground_acceleration is not None:
        window = strong_motion_window(t, rec.column(str(spec.ground_acceleration)))
        if window is not None and window[1] - window[0] > 0.8 * (t[-1] - t[0]):
            window = None  # the record is nearly all strong motion: one panel
        if window is not None:
            note = f"strong motion {window[0]:.1f}-{window[1]:.1f} s (Arias 5-95 %, widened)"

    def time_figure(title: str, ylabel: str, lines: list[tuple[np.ndarray, str, dict[str, Any]]]) -> Any:
        return figures.time_figure(t, title, ylabel, lines, window, note)

    if spec.floor_accelerations:
        top = str(spec.floor_accelerations[-1])
        lines = []
        if spec.ground_acceleration is not None:
            ground = str(spec.ground_acceleration)
            lines.append((rec.column(ground), f"{run.label(ground)}", {"color": "0.6", "lw": 0.6}))
        lines.append((rec.column(top), run.label(top), {"color": "C0"}))
        figures.save(time_figure(f"absolute acceleration: {run.label(top)}", "acceleration [m/s²]", lines),
                     "top_floor_acceleration.png")
    if spec.drifts:
        lines = [(1e3 * rec.column(str(r)), run.label(str(r)), {}) for r in spec.drifts]
        figures.save(time_figure("inter-storey drifts", "drift [mm]", lines), "drifts.png")
    if spec.current is not None:
        ref = str(spec.current)
        figures.save(time_figure(f"command: {run.label(ref)}", "current [A]", [(rec.column(ref), run.label(ref), {})]),
                     "current.png")
    if spec.isolator_force is not None and spec.base_displacement is not None:
        fig, ax = figures.plt.subplots(figsize=(6, 4.6))
        x_ref, f_ref = str(spec.base_displacement), str(spec.isolator_force)
        ax.plot(1e3 * rec.column(x_ref), rec.column(f_ref), lw=0.4)
        styles = iter([("0.5", "--"), ("C3", ":"), ("C2", "-.")])
        for label, edge in displacement_limits(spec, run).items():
            color, ls = next(styles, ("0.3", ":"))
            for sign in (1, -1):
                ax.axvline(sign * 1e3 * edge, color=color, ls=ls, lw=0.9, label=f"{label} ±{1e3 * edge:g} mm"
                           if sign == 1 else None)
        ax.set(xlabel=f"{run.label(x_ref)} [mm]", ylabel=f"{run.label(f_ref)} [N]",
               title=f"{figures.head}\nhysteresis")
        ax.legend(fontsize=7, loc="upper left")
        ax.grid(alpha=0.3)
        figures.save(fig, "isolator_hysteresis.png")


REPORT = ReportHook(BuildingReport, summarize, plot)
"""The isolated building's report hook (see the module docstring)."""
