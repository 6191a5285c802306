"""The case study's figures (``figures/``): the paper's Fig. 15-17, the isolator hysteresis per record,
the constant-current sweep and the second gain set's tuning front. Each function draws one figure; each
strategy has its own line style and marker, and a legend says where two strategies' curves coincide."""

from __future__ import annotations

import re
import textwrap
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from components.physics.ground_motion_core import G as STANDARD_GRAVITY
from orchestration.case_study.case_metrics import Metrics, Series, pareto_front
from orchestration.case_study.case_records import CaseStudyRecord
from orchestration.case_study.run_numbers import TOP_FLOOR
from orchestration.figure_axes import (
    coincidence_note,
    coincident,
    few_ticks,
    legend_below,
    plain_log_axis,
    strategy_style,
)
from orchestration.master.figure_files import PNG_ONLY, FigureFiles, save_figure

STUDY_DPI = 100
"""The studies' PNG resolution unless one is asked for (``--dpi``) [dots per inch]."""


def style(study: CaseStudyRecord, s: str) -> dict[str, Any]:
    """The line style, marker and colour of strategy ``s`` (its entry's ``style``, else by its place)."""
    return strategy_style(s, study.strategies, study.flags(s).get("style"))


def save(fig: Any, path: Path, files: FigureFiles = PNG_ONLY) -> Path:
    """Write ``fig`` as ``path`` (PNG, and each of ``files.formats`` beside it) and close it; the PNG."""
    import matplotlib.pyplot as plt

    try:
        save_figure(fig, path, files, STUDY_DPI)
    finally:
        plt.close(fig)
    return path


def _where(records: dict[str, list[str]], names: list[str]) -> list[str]:
    """Legend notes: each coincidence with the records (and panel, where only one) it holds on, or "every
    record"."""
    return [f"{note} ({'every record' if on == names else ', '.join(on)})" for note, on in records.items()]


def named(study: CaseStudyRecord, r: str) -> str:
    """A record's readable name with its amplitude scale (``Kobe 1995 JMA N-S ×0.5``; the id where the scenario
    names none)."""
    info = study.records[r]
    name = getattr(info, "name", None) or r
    return f"{name} ×{info.scale:g}" if isinstance(info.scale, int | float) else name


def pareto_figure(study: CaseStudyRecord) -> Any:
    """Peak top-floor acceleration against mean current over the second gain set's tuning evaluations, per tuning
    record, with the constant currents on the same window; None without evaluations."""
    from orchestration.case_study.tuning import RECORD_COLUMNS, read_table

    doc = study.gain_sets.get("sosm-fig15") or {}
    ev = doc.get("evaluations")
    if not ev:
        return None
    import matplotlib.pyplot as plt

    sosm, passive = read_table(ev["sosm"]), read_table(ev["passive"])
    records = list(dict.fromkeys(c.split(".")[0] for c in ev["sosm"]["columns"] if "." in c
                                 and c.split(".")[1] in RECORD_COLUMNS))
    chosen = doc["gains"]
    proc = doc.get("procedure", {})
    window = proc.get("stop_time_s")
    cols = min(2, len(records))  # a grid, not a strip
    n_rows = -(-len(records) // cols)
    fig, axes = plt.subplots(n_rows, cols, figsize=(5.2 * cols, 3.8 * n_rows), squeeze=False)
    for ax in list(axes.flat)[len(records):]:
        ax.set_visible(False)
    for ax, r in zip(axes.flat, records, strict=False):
        pts = [(row[f"{r}.i_mean"], row[f"{r}.a3"]) for row in sosm]
        sat = [row[f"{r}.s_bound"] for row in sosm]
        sc = ax.scatter(*zip(*pts, strict=True), c=sat, cmap="viridis", vmin=0, vmax=1, s=14, label="SOSM evaluations")
        front = pareto_front(pts)
        ax.plot([pts[k][0] for k in front], [pts[k][1] for k in front], color="tab:red", lw=1,
                label="non-dominated")
        ax.plot([row[f"{r}.i_mean"] for row in passive], [row[f"{r}.a3"] for row in passive], color="0.3",
                ls="--", marker="s", ms=3, lw=0.8, label="constant current")
        best = [k for k, row in enumerate(sosm) if row["lambda"] == chosen["lambda"] and row["rho"] == chosen["rho"]]
        if best:
            ax.plot(*pts[best[0]], marker="*", ms=14, mfc="none", color="k", label="chosen (sosm-fig15)")
        ax.set(xlabel="mean current [A]", ylabel="peak top-floor acceleration [m/s²]",
               title=f"{r}, first {window:g} s" if window else r)
        plain_log_axis(ax.yaxis)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=6)
    fig.colorbar(sc, ax=axes[0, -1], label=f"share of time at {chosen['i_max']:g} A")
    fig.suptitle(f"sosm-fig15 tuning: {len(sosm)} evaluations (objective weights: "
                 + ", ".join(f"{k} {v:g}" for k, v in proc.get("objective", {}).items() if k.startswith("w_"))
                 + ")", fontsize=9)
    fig.tight_layout()
    return fig


def current_figure(study: CaseStudyRecord, series: Series, metrics: Metrics) -> Any:
    """Fig. 15: the SOSM current per record, one column per gain set (the dotted line its run's current limit);
    None without an SOSM strategy."""
    import matplotlib.pyplot as plt

    controlled = study.paper("controlled")
    if not controlled:
        return None
    records = list(study.records)
    i_max, hi = study.config["i_max"], study.config["paper_current_range"][1]
    fig, axes = plt.subplots(len(records), len(controlled), figsize=(8 * len(controlled) ** 0.5, 1.9 * len(records)),
                             squeeze=False, sharey=True)
    device = False
    for col, s in enumerate(controlled):
        for ax, r in zip(axes[:, col], records, strict=True):
            ts = series.get((r, s))
            limit = (metrics.get((r, s)) or {}).get("current_limit_A", i_max)
            if ts is not None:
                ax.plot(ts["time"], ts["controller.i"], color=style(study, s)["color"], lw=0.6)
                if "coil.i" in ts:  # a plant with a coil lag: the device current, dashed, beside the command
                    ax.plot(ts["time"], ts["coil.i"], color="0.2", lw=0.5, ls="--")
                    device = True
            ax.axhline(hi, color="0.5", ls="--", lw=0.8)
            ax.axhline(limit, color="0.5", ls=":", lw=0.8)
            ax.set(ylabel="current [A]", ylim=(-0.1, i_max * 1.08))
            ax.set_title(f"{named(study, r)}: {s} (limit {limit:g} A)", fontsize=9)  # short: columns sit side by side
            ax.grid(alpha=0.3)
        axes[-1, col].set_xlabel("time [s]")
    fig.suptitle(f"SOSM current command; dashed grey: {hi:g} A, the top of the paper's range; dotted grey: the "
                 "controller's limit" + ("; dark dashed: the device current behind the coil" if device else ""),
                 fontsize=9)
    fig.tight_layout()
    return fig


def _units(study: CaseStudyRecord) -> dict[str, Any]:
    """The study's ``figure_units`` (older study.json files: m/s2 and mm)."""
    return {"acceleration": "m/s2", "drift": "mm", "storey_heights": None, **(study.config.get("figure_units") or {})}


def acceleration_axis(values: Any, unit: str) -> tuple[Any, str]:
    """Accelerations [m/s^2] on the figure's axis (``unit`` m/s2 or g, standard gravity) and the axis' unit."""
    return (np.asarray(values, dtype=float) / STANDARD_GRAVITY, "g") if unit == "g" else (values, "m/s²")


def drift_axis(values_mm: list[float], units: dict[str, Any]) -> tuple[list[float], str]:
    """Peak drifts of storeys 1..n [mm] on the figure's axis (mm, or drift ratio in % of ``storey_heights``)."""
    if units["drift"] == "ratio":
        heights = units["storey_heights"][: len(values_mm)]  # none given: the axis' label only
        return [0.1 * d / h for d, h in zip(values_mm, heights, strict=True)], "drift ratio [%]"
    return values_mm, "peak drift [mm]"


def top_acceleration_figure(study: CaseStudyRecord, series: Series) -> Any:
    """Fig. 16: the top-floor absolute acceleration per record, passive against SOSM, strong-motion window."""
    import matplotlib.pyplot as plt

    records = list(study.records)
    unit = _units(study)["acceleration"]
    fig, axes = plt.subplots(len(records), 1, figsize=(8, 1.9 * len(records)), squeeze=False)
    where: dict[str, list[str]] = {}
    for ax, r in zip(axes[:, 0], records, strict=True):
        drawn = {}
        passive, controlled = study.paper("passive"), study.paper("controlled")
        for s in (study.uncontrolled, *passive, *controlled):
            ts = series.get((r, s))
            if ts is not None and s in study.strategies:
                drawn[s] = acceleration_axis(ts[TOP_FLOOR], unit)[0]
                ax.plot(ts["time"], drawn[s], **style(study, s), markevery=max(1, len(ts["time"]) // 12), ms=3,
                        mfc="none", lw=0.6 if s in controlled else 0.5, alpha=0.6 if s in passive else 0.8, label=s)
        ref_ts = series.get((r, study.uncontrolled))
        if ref_ts is not None and len(ref_ts["time"]) > 1:
            a = np.abs(ref_ts[TOP_FLOOR])
            strong = ref_ts["time"][a > 0.05 * a.max()]
            if len(strong):
                ax.set_xlim(0.0, min(ref_ts["time"][-1], strong[-1] + 5.0))
        ax.set(ylabel=f"acceleration [{acceleration_axis([], unit)[1]}]")
        ax.set_title(f"{named(study, r)}: top-floor absolute acceleration, strong-motion window", fontsize=9)
        ax.grid(alpha=0.3)
        low, high = ax.get_ylim()
        for pair in coincident(drawn, high - low):
            where.setdefault(coincidence_note(*pair), []).append(named(study, r))
    axes[-1, 0].set_xlabel("time [s]")
    fig.tight_layout()
    legend_below(fig, _where(where, [named(study, r) for r in records]), ncol=4)  # a legend in a panel hid motion
    return fig


def profiles_figure(study: CaseStudyRecord, metrics: Metrics) -> Any:
    """Fig. 17: peak drift per storey and peak acceleration per level, per record and strategy."""
    import matplotlib.pyplot as plt

    records = list(study.records)
    units = _units(study)
    fig, axes = plt.subplots(len(records), 2, figsize=(10, 2.4 * len(records)), squeeze=False)
    where: dict[str, list[str]] = {}
    drift_label, acc_unit = drift_axis([], units)[1], acceleration_axis([], units["acceleration"])[1]
    for row, r in enumerate(records):
        drawn: tuple[dict[str, list[float]], dict[str, list[float]]] = ({}, {})
        for s in study.strategies:
            m = metrics.get((r, s))
            if m is None:
                continue
            nd = len([k for k in m if re.fullmatch(r"drift_\d+_mm", k)])
            drawn[0][s] = drift_axis([m[f"drift_{j}_mm"] for j in range(1, nd + 1)], units)[0]
            drawn[1][s] = list(acceleration_axis([m[f"acc_{j}"] for j in range(nd + 1)], units["acceleration"])[0])
            look = style(study, s) | {"mfc": "none", "label": s}
            axes[row, 0].plot(drawn[0][s], range(1, nd + 1), **look)
            axes[row, 1].plot(drawn[1][s], range(nd + 1), **look)
        pairs = [coincident(curves, ax.get_xlim()[1] - ax.get_xlim()[0])
                 for ax, curves in zip(axes[row], drawn, strict=True)]
        for pair in dict.fromkeys([*pairs[0], *pairs[1]]):
            panel = "" if pair in pairs[0] and pair in pairs[1] else " drift" if pair in pairs[0] else " acceleration"
            where.setdefault(coincidence_note(*pair), []).append(named(study, r) + panel)
        n_levels = len(study.records[r].masses_kg)
        axes[row, 0].set(ylabel=f"{textwrap.fill(named(study, r), 22)}\nstorey", xlabel=drift_label,
                         yticks=range(1, n_levels))
        axes[row, 1].set(ylabel="level (0 = base)", xlabel=f"peak abs. acceleration [{acc_unit}]",
                         yticks=range(n_levels))
        for ax in axes[row]:
            ax.grid(alpha=0.3)
            few_ticks(ax.xaxis)
    fig.tight_layout()
    legend_below(fig, _where(where, [named(study, r) for r in records]))  # under the grid: it hides no profile
    return fig


def hysteresis_figure(study: CaseStudyRecord, series: Series, r: str) -> Any:
    """The isolator force against its displacement, one panel per strategy of record ``r``; None without runs."""
    import matplotlib.pyplot as plt

    present = [s for s in study.strategies if (r, s) in series]
    if not present:
        return None
    x_id, x_lim = 1e3 * study.config["x_identified"], 1e3 * study.config["x_limit"]
    cols = min(3, len(present))  # a grid, not a strip: the panels stay readable in report.html
    n_rows = -(-len(present) // cols)
    fig, axes = plt.subplots(n_rows, cols, figsize=(3.6 * cols, 3.1 * n_rows + 0.4), squeeze=False, sharey=True)
    for ax in list(axes.flat)[len(present):]:
        ax.set_visible(False)
    for ax, s in zip(axes.flat, present, strict=False):
        ts = series[(r, s)]
        ax.plot(1e3 * ts["building.x_0"], ts["isolator.F"], color=style(study, s)["color"], lw=0.4)
        for edge, ls in ((x_id, "--"), (x_lim, ":")):
            ax.axvline(edge, color="0.5", ls=ls, lw=0.8)
            ax.axvline(-edge, color="0.5", ls=ls, lw=0.8)
        ax.set(title=s, xlabel="base displacement [mm]")
        ax.grid(alpha=0.3)
    n_iso = study.records[r].n_isolators
    for row in axes:
        row[0].set_ylabel(f"force of the {n_iso} isolators [N]" if n_iso else "isolator force [N]")
    fig.suptitle(f"{named(study, r)}: isolator hysteresis per strategy "
                 f"(dashed ±{x_id:g} mm identified, dotted ±{x_lim:g} mm limit)",
                 fontsize=9)
    fig.tight_layout()
    return fig


def sweep_figure(study: CaseStudyRecord) -> Any:
    """The objective J against the constant current per record, the best circled; None without sweeps."""
    import matplotlib.pyplot as plt

    if not study.sweep:
        return None
    fig, ax = plt.subplots(figsize=(6, 3.2))
    for r, sw in study.sweep.items():
        if not sw.ok:
            continue
        line = ax.plot([q["current_A"] for q in sw.rows], [q["J"] for q in sw.rows], marker=".",
                       label=named(study, r))[0]
        ax.plot([sw.best_current_A], [sw.best_J], marker="o", ms=8, mfc="none", color=line.get_color())
    ax.set(xlabel="constant current [A]", ylabel="objective J",
           title="constant-current sweep (in-process); circle = best")
    plain_log_axis(ax.yaxis)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    return fig


def run_periods(folder: Path, study: CaseStudyRecord) -> dict[str, float]:
    """The isolated periods of the study's first run that reports them (its summary.json's ``periods``), by
    label: T1 at 0 A and at the current limit [s]; empty when no run does (a swapped unit, an older folder)."""
    import json

    for run in study.runs:
        try:
            periods = json.loads((folder / run.folder / "summary.json").read_text()).get("periods") or {}
        except (OSError, ValueError, AttributeError):
            continue
        if "isolated_0A_s" in periods:
            marks = {"T1 at 0 A": float(periods["isolated_0A_s"])}
            if periods.get("isolated_i_max_s"):
                marks[f"T1 at {periods.get('i_max_A', 0):g} A"] = float(periods["isolated_i_max_s"])
            return marks
    return {}


def spectra_figure(folder: Path, study: CaseStudyRecord) -> Any:
    """Each record's response spectrum as the runs play it (amplitude and time scale applied), the isolated
    periods marked (:func:`run_periods`); None when a record's file is not on this machine."""
    from components.physics.ground_motion_core import RecordError, read_record
    from orchestration.spectrum_figure import spectrum, spectrum_figure

    curves = {}
    for r, info in study.records.items():
        try:
            rec = read_record(Path(info.record_file))
        except (OSError, RecordError, ValueError):
            return None
        curves[named(study, r)] = spectrum(rec.time, rec.accel_g, info.scale if info.scale is not None else 1.0,
                                          info.time_scale)
    return spectrum_figure(curves, run_periods(folder, study), "the records as the runs play them")


def make_figures(folder: Path, study: CaseStudyRecord, metrics: Metrics, series: Series,
                 files: FigureFiles = PNG_ONLY) -> dict[str, Path]:
    """Every figure into ``folder/figures`` (PNG, and each of ``files.formats`` beside it); name -> PNG, in the
    report's order."""
    import matplotlib

    matplotlib.use("Agg")
    figdir = folder / "figures"
    figdir.mkdir(exist_ok=True)
    draw: list[tuple[str, Callable[[], Any]]] = [
        ("fig15_current", lambda: current_figure(study, series, metrics)), ("pareto", lambda: pareto_figure(study)),
        ("fig16_top_acceleration", lambda: top_acceleration_figure(study, series)),
        ("fig17_profiles", lambda: profiles_figure(study, metrics))]
    draw += [(f"hysteresis_{r}", lambda r=r: hysteresis_figure(study, series, r)) for r in study.records]
    draw.append(("sweep", lambda: sweep_figure(study)))
    draw.append(("spectra", lambda: spectra_figure(folder, study)))
    made: dict[str, Path] = {}
    for name, figure in draw:  # one figure open at a time
        fig = figure()
        if fig is not None:
            made[name] = save(fig, figdir / f"{name}.png", files)
    return made
