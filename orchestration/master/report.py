"""Run summary and plots, from the recorded time series and the scenario's ``report`` roles.

The master knows no physics; the scenario says which recorded variable plays which role
(base displacement, drifts, floor accelerations, current, isolator force, ground
acceleration), how to name variables for a reader (``labels``) and what the run is
(``caption``, filled from the run's parameter values), and this module turns them into
the peaks engineers read, a generic peak table of every recorded variable, and figures
that say what was run.
"""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from orchestration.master.recorder import Recorder
from orchestration.master.scenario import ReportSpec
from orchestration.master.yaml_source import DataFile

# Defaults when the scenario names no displacement limits: the isolator model was
# identified on +-8 mm and the device allows 15 mm (paper, section 2).
IDENTIFIED_RANGE_M = 0.008
DEVICE_LIMIT_M = 0.015

PLACEHOLDER = re.compile(r"\{([A-Za-z_][A-Za-z0-9_]*)\.([A-Za-z_][A-Za-z0-9_.\[\]]*)\}")
_MAX_POINTS = 4000  # per plotted line: a figure is ~1000 px wide; min/max pairs keep every peak


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
    if spec.ground_acceleration is not None:
        ag = rec.column(str(spec.ground_acceleration))
        out["peak_ground_acceleration_m_s2"] = _peak(ag)
        window = strong_motion_window(rec.times, ag)
        if window is not None:
            out["strong_motion_window_s"] = list(window)
    out["variables"] = {
        name: {"max_abs": _peak(rec.data[: rec.count, k]),
               "min": float(np.min(rec.data[: rec.count, k])) if rec.count else None,
               "max": float(np.max(rec.data[: rec.count, k])) if rec.count else None}
        for k, name in enumerate(rec.names) if rec.kinds[k] != "string"
    }
    return out


def _dt(rec: Recorder) -> float:
    t = rec.times
    return float(t[1] - t[0]) if len(t) > 1 else 0.0


def strong_motion_window(t: np.ndarray, ag: np.ndarray) -> tuple[float, float] | None:
    """Time window [s] holding the strong motion and the response right after it.

    The significant duration D5-95 (from 5 % to 95 % of the Arias intensity, the
    cumulative integral of ag²), widened by a quarter of D before and half of D after
    (the structure keeps moving after the ground calms down). None without motion.
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


@dataclass(frozen=True)
class RunDescription:
    """What a reader needs to name a run: parameter values (set or declared) and readable labels."""

    values: dict[str, dict[str, Any]]  # unit -> parameter -> value used in the run
    model_names: dict[str, str]  # unit -> the FMU's model name
    labels: dict[str, str] = field(default_factory=dict)

    def value(self, unit: str, name: str) -> Any:
        """A parameter's value as the run used it, or None if the unit has no such parameter."""
        return self.values.get(unit, {}).get(name)

    def render(self, template: str, depth: int = 0) -> str:
        """Fill ``{unit.param}`` with the run's values; a value with a label ``unit.param=value`` shows the label.

        A placeholder naming a parameter the unit does not have (a unit swapped for another
        FMU) shows that unit's model name, so a caption stays true for any swap.
        """

        def fill(m: re.Match[str]) -> str:
            unit, name = m.group(1), m.group(2)
            value = self.value(unit, name)
            if value is None:
                return self.model_names.get(unit, f"{unit}.{name}")
            text = _plain(value)
            label = self.labels.get(f"{unit}.{name}={text}")
            if label is not None and depth < 2:
                return self.render(label, depth + 1)
            return text

        return PLACEHOLDER.sub(fill, template)

    def label(self, ref: str) -> str:
        """A variable's readable name (``labels`` in the scenario), or ``unit.variable``."""
        text = self.labels.get(ref)
        return self.render(text) if text is not None else ref


def _plain(value: Any) -> str:
    if isinstance(value, DataFile):
        return Path(str(value)).name
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:g}"
    return Path(value).name if isinstance(value, str) and "/" in value else str(value)


def caption(spec: ReportSpec, run: RunDescription, name: str) -> str:
    """One line saying what was run (record, scale, strategy, ...), or the scenario's name."""
    return run.render(spec.caption) if spec.caption else name


def displacement_limits(spec: ReportSpec, run: RunDescription) -> dict[str, float]:
    """Named displacement limits [m] for the hysteresis plot (values or ``unit.param`` references)."""
    if not spec.displacement_limits:
        return {"identified range": IDENTIFIED_RANGE_M, "device limit": DEVICE_LIMIT_M}
    out = {}
    for label, ref in spec.displacement_limits.items():
        value = ref if isinstance(ref, int | float) else run.value(*str(ref).split(".", 1))
        if isinstance(value, int | float) and not isinstance(value, bool) and value > 0:
            out[label] = float(value)
    return out


def decimate(t: np.ndarray, y: np.ndarray, max_points: int = _MAX_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """At most ``max_points`` points that keep every bucket's minimum and maximum (so every peak shows)."""
    n = len(t)
    if n <= max_points:
        return t, y
    buckets = max_points // 2
    edges = np.linspace(0, n, buckets + 1).astype(np.intp)
    keep = []
    for lo, hi in itertools.pairwise(edges):
        if hi > lo:
            seg = y[lo:hi]
            a, b = lo + int(np.argmin(seg)), lo + int(np.argmax(seg))
            keep.extend((a, b) if a <= b else (b, a))
    idx = np.unique(np.asarray(keep, dtype=np.intp))
    return t[idx], y[idx]


def plot(rec: Recorder, spec: ReportSpec, folder: Path, name: str, run: RunDescription) -> list[Path]:
    """PNG figures for the roles present: top-floor acceleration with the ground, drifts, current, hysteresis.

    Each figure is titled with the run's caption. Time histories show the strong-motion
    window large and the whole record below it (window shaded) when the scenario names the
    ground acceleration; displacements and drifts are drawn in mm, as engineers read them.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = rec.times
    made: list[Path] = []
    head = caption(spec, run, name)
    window = None
    if spec.ground_acceleration is not None:
        window = strong_motion_window(t, rec.column(str(spec.ground_acceleration)))
        if window is not None and window[1] - window[0] > 0.8 * (t[-1] - t[0]):
            window = None  # the record is nearly all strong motion: one panel

    def save(fig, file: str) -> None:
        path = folder / file
        tmp = folder / f".{file}.tmp.png"
        fig.savefig(tmp, dpi=110, bbox_inches="tight")
        plt.close(fig)
        tmp.replace(path)
        made.append(path)

    def time_figure(title: str, ylabel: str, lines: list[tuple[np.ndarray, str, dict[str, Any]]]):
        if window is None:
            fig, ax = plt.subplots(figsize=(9, 3.4))
            axes = [ax]
        else:
            fig, axes = plt.subplots(2, 1, figsize=(9, 4.6), gridspec_kw={"height_ratios": [3, 1]})
        for k, ax in enumerate(axes):
            mask = slice(None)
            if window is not None and k == 0:
                mask = (t >= window[0]) & (t <= window[1])
            for y, label, style in lines:
                ax.plot(*decimate(t[mask], y[mask]), label=label, **({"lw": 0.7} | style))
            ax.grid(alpha=0.3)
        axes[0].set(ylabel=ylabel, title=f"{head}\n{title}")
        axes[-1].set(xlabel="time [s]")
        if window is not None:
            axes[0].set_xlim(*window)
            axes[0].text(0.995, 0.02, f"strong motion {window[0]:.1f}-{window[1]:.1f} s (Arias 5-95 %, widened)",
                         transform=axes[0].transAxes, ha="right", va="bottom", fontsize=7, color="0.35")
            axes[1].axvspan(*window, color="0.85", zorder=0)
            axes[1].set_xlim(t[0], t[-1])
            axes[1].set_title("whole record (shaded: window above)", fontsize=8, loc="left")
        if len(lines) > 1:
            axes[0].legend(fontsize=7, loc="upper right")
        fig.tight_layout()
        return fig

    if spec.floor_accelerations:
        top = str(spec.floor_accelerations[-1])
        lines = []
        if spec.ground_acceleration is not None:
            ground = str(spec.ground_acceleration)
            lines.append((rec.column(ground), f"{run.label(ground)}", {"color": "0.6", "lw": 0.6}))
        lines.append((rec.column(top), run.label(top), {"color": "C0"}))
        save(time_figure(f"absolute acceleration: {run.label(top)}", "acceleration [m/s²]", lines),
             "top_floor_acceleration.png")
    if spec.drifts:
        lines = [(1e3 * rec.column(str(r)), run.label(str(r)), {}) for r in spec.drifts]
        save(time_figure("inter-storey drifts", "drift [mm]", lines), "drifts.png")
    if spec.current is not None:
        ref = str(spec.current)
        save(time_figure(f"command: {run.label(ref)}", "current [A]", [(rec.column(ref), run.label(ref), {})]),
             "current.png")
    if spec.isolator_force is not None and spec.base_displacement is not None:
        fig, ax = plt.subplots(figsize=(6, 4.6))
        x_ref, f_ref = str(spec.base_displacement), str(spec.isolator_force)
        ax.plot(1e3 * rec.column(x_ref), rec.column(f_ref), lw=0.4)
        styles = iter([("0.5", "--"), ("C3", ":"), ("C2", "-.")])
        for label, edge in displacement_limits(spec, run).items():
            color, ls = next(styles, ("0.3", ":"))
            for sign in (1, -1):
                ax.axvline(sign * 1e3 * edge, color=color, ls=ls, lw=0.9, label=f"{label} ±{1e3 * edge:g} mm"
                           if sign == 1 else None)
        ax.set(xlabel=f"{run.label(x_ref)} [mm]", ylabel=f"{run.label(f_ref)} [N]", title=f"{head}\nhysteresis")
        ax.legend(fontsize=7, loc="upper left")
        ax.grid(alpha=0.3)
        save(fig, "isolator_hysteresis.png")
    return made
