"""Run summary and plots, from the recorded time series and the scenario's ``report`` roles.

The master knows no physics; the scenario says which recorded variable plays which role
(base displacement, drifts, floor accelerations, current, isolator force) and this
module turns them into the peaks engineers read, plus a generic peak table of every
recorded variable.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from orchestration.master.recorder import Recorder
from orchestration.master.scenario import ReportSpec

# The isolator model was identified on +-8 mm; the device allows 15 mm (paper, section 2).
IDENTIFIED_RANGE_M = 0.008
DEVICE_LIMIT_M = 0.015


def _peak(x: np.ndarray) -> float | None:
    return float(np.max(np.abs(x))) if len(x) else None


def summarize(rec: Recorder, spec: ReportSpec) -> dict[str, Any]:
    """Peaks per role and per recorded variable (SI units)."""
    out: dict[str, Any] = {}
    if spec.base_displacement is not None:
        x = rec.column(str(spec.base_displacement))
        out["peak_base_displacement_m"] = _peak(x)
        out["time_beyond_identified_range_s"] = float(np.sum(np.abs(x) > IDENTIFIED_RANGE_M) * _dt(rec))
        out["time_beyond_device_limit_s"] = float(np.sum(np.abs(x) > DEVICE_LIMIT_M) * _dt(rec))
    if spec.drifts:
        out["peak_drift_m"] = {str(r): _peak(rec.column(str(r))) for r in spec.drifts}
    if spec.floor_accelerations:
        out["peak_abs_acceleration_m_s2"] = {str(r): _peak(rec.column(str(r))) for r in spec.floor_accelerations}
    if spec.current is not None:
        i = rec.column(str(spec.current))
        out["peak_current_A"] = float(np.max(i)) if len(i) else None
        out["mean_current_A"] = float(np.mean(i)) if len(i) else None
    if spec.isolator_force is not None:
        out["peak_isolator_force_N"] = _peak(rec.column(str(spec.isolator_force)))
    out["variables"] = {
        name: {"max_abs": _peak(rec.data[: rec.count, k]),
               "min": float(np.min(rec.data[: rec.count, k])) if rec.count else None,
               "max": float(np.max(rec.data[: rec.count, k])) if rec.count else None}
        for k, name in enumerate(rec.names)
    }
    return out


def _dt(rec: Recorder) -> float:
    t = rec.times
    return float(t[1] - t[0]) if len(t) > 1 else 0.0


def plot(rec: Recorder, spec: ReportSpec, folder: Path, title: str) -> list[Path]:
    """PNG plots for the roles present: top-floor acceleration, drifts, current, hysteresis loop."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = rec.times
    made: list[Path] = []

    def save(fig, name: str) -> None:
        path = folder / name
        tmp = folder / f".{name}.tmp.png"
        fig.savefig(tmp, dpi=110, bbox_inches="tight")
        plt.close(fig)
        tmp.replace(path)
        made.append(path)

    if spec.floor_accelerations:
        top = str(spec.floor_accelerations[-1])
        fig, ax = plt.subplots(figsize=(8, 3))
        ax.plot(t, rec.column(top), lw=0.7)
        ax.set(xlabel="time [s]", ylabel="absolute acceleration [m/s²]", title=f"{title}: {top}")
        ax.grid(alpha=0.3)
        save(fig, "top_floor_acceleration.png")
    if spec.drifts:
        fig, ax = plt.subplots(figsize=(8, 3))
        for r in spec.drifts:
            ax.plot(t, 1e3 * rec.column(str(r)), lw=0.7, label=str(r))
        ax.set(xlabel="time [s]", ylabel="inter-storey drift [mm]", title=f"{title}: drifts")
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
        save(fig, "drifts.png")
    if spec.current is not None:
        fig, ax = plt.subplots(figsize=(8, 3))
        ax.plot(t, rec.column(str(spec.current)), lw=0.8)
        ax.set(xlabel="time [s]", ylabel="current [A]", title=f"{title}: {spec.current}")
        ax.grid(alpha=0.3)
        save(fig, "current.png")
    if spec.isolator_force is not None and spec.base_displacement is not None:
        fig, ax = plt.subplots(figsize=(5, 4))
        ax.plot(1e3 * rec.column(str(spec.base_displacement)), rec.column(str(spec.isolator_force)), lw=0.5)
        for edge in (IDENTIFIED_RANGE_M, -IDENTIFIED_RANGE_M):
            ax.axvline(1e3 * edge, color="0.6", ls="--", lw=0.8)
        ax.set(xlabel="isolator displacement [mm]", ylabel="isolator force [N]",
               title=f"{title}: hysteresis (dashed: identified ±8 mm)")
        ax.grid(alpha=0.3)
        save(fig, "isolator_hysteresis.png")
    return made
