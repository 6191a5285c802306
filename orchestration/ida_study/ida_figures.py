"""The figures of an IDA study.

* ``figures/ida_curves.png``: one panel per strategy; for every record component the peak
  isolator displacement [mm] against the intensity, the median over components in bold,
  the identified 8 mm and the 15 mm device limit marked (failed runs left out, as in the stripes).
* ``figures/fragility.png``: one panel per limit state, a curve per strategy (controller) on
  each: the fitted lognormal, its confidence band, and the observed fraction at each level; each strategy
  its own line style and marker, and the legend says where two strategies' fitted curves coincide.
* ``figures/spectra.png``: every component's response spectrum as the runs play it at the first level, their
  median and T1 marked (:mod:`orchestration.spectrum_figure`).

Each is a PNG at :data:`IDA_DPI` (or ``--dpi``), with the vector formats asked for beside it (``--format``).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from orchestration.figure_axes import add_legend_notes, coincidence_note, coincident, plain_log_axis, strategy_style
from orchestration.ida_study.fragility import Fit
from orchestration.ida_study.ida_config import QUANTITIES, IdaSpec
from orchestration.ida_study.ida_metrics import ENDED
from orchestration.ida_study.ida_records import IdaInfo
from orchestration.master.figure_files import PNG_ONLY, FigureFiles, save_figure

MAX_COLUMNS = 4  # panels per row of the IDA curves
IDA_DPI = 110
"""The IDA figures' PNG resolution unless one is asked for (``--dpi``) [dots per inch]."""


def _save(fig: Any, path: Path, files: FigureFiles) -> None:
    import matplotlib.pyplot as plt

    try:
        save_figure(fig, path, files, IDA_DPI, tight=False)
    finally:
        plt.close(fig)



def im_label(info: IdaInfo) -> str:
    """The intensity axis' label."""
    if info.measure == "sa":
        return f"Sa(T1 = {info.period_s:.3g} s, {100 * info.config['intensity']['damping']:g} %) [g]"
    return "PGA [g]"


def threshold_text(quantity: str, threshold: float) -> str:
    """A limit state's threshold in its unit (mm for displacements)."""
    _, _, unit = QUANTITIES[quantity]
    if unit == "1":  # a drift ratio
        return f"{100 * threshold:g} % of the storey height"
    return f"{1e3 * threshold:g} mm" if unit == "m" else f"{threshold:g} {unit}"


def ida_figure(path: Path, info: IdaInfo, rows: list[dict[str, Any]], strategies: list[str],
               files: FigureFiles = PNG_ONLY) -> None:
    """IDA curves, one panel per strategy."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    levels = sorted({r["intensity"] for r in rows})
    n_rows = math.ceil(len(strategies) / MAX_COLUMNS)  # more than MAX_COLUMNS strategies: wrapped into rows
    n_cols = math.ceil(len(strategies) / n_rows)
    fig, axes = plt.subplots(n_rows, n_cols, figsize=(4.2 * n_cols, 4.2 * n_rows), sharey=True, squeeze=False)
    for ax in axes.flat[len(strategies):]:
        ax.set_visible(False)
    for ax, s in zip(axes.flat, strategies, strict=False):
        mine = [r for r in rows if r["strategy"] == s and r["status"] in ENDED]  # a failed run's last values: no
        medians = []
        for comp in sorted({r["record_id"] for r in mine}):
            pts = sorted((r["intensity"], r["x_base_mm"]) for r in mine
                         if r["record_id"] == comp and r["x_base_mm"] is not None)
            if pts:
                ax.plot([p[1] for p in pts], [p[0] for p in pts], color="0.6", lw=0.6, alpha=0.7)
        for level in levels:
            vals = [r["x_base_mm"] for r in mine if r["intensity"] == level and r["x_base_mm"] is not None]
            medians.append(float(np.median(vals)) if vals else math.nan)
        ax.plot(medians, levels, color="k", lw=2.2, marker="o", ms=3, label="median")
        for x, name in ((8.0, "identified 8 mm"), (15.0, "device limit 15 mm")):
            ax.axvline(x, color="tab:orange" if x == 8.0 else "tab:red", ls="--", lw=1, label=name)
        plain_log_axis(ax.xaxis)
        ax.set_title(s)
        ax.set_xlabel("peak isolator displacement [mm]")
        ax.grid(alpha=0.3, which="both")
    for row in axes:
        row[0].set_ylabel(im_label(info))
    axes[0][0].legend(fontsize=7, loc="lower right")
    fig.suptitle(f"{info.name}: IDA curves ({len({r['record_id'] for r in rows})} components)", fontsize=10)
    fig.tight_layout()
    _save(fig, path, files)


def fragility_figure(path: Path, info: IdaInfo, spec: IdaSpec, fits: dict[str, dict[str, Fit]],
                     files: FigureFiles = PNG_ONLY) -> None:
    """Fragility curves per limit state, strategies side by side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    levels = np.asarray(spec.intensity.levels, dtype=float)
    x = np.geomspace(levels[0] / 2, levels[-1] * 1.5, 200)
    names = list(fits)
    cols = min(2, len(names))  # a grid, not a strip: each panel about half the report's width
    n_rows = math.ceil(len(names) / cols)
    fig, axes = plt.subplots(n_rows, cols, figsize=(6.4 * cols, 4.6 * n_rows), sharey=True, squeeze=False)
    for ax in list(axes.flat)[len(names):]:
        ax.set_visible(False)
    for ax, name in zip(axes.flat, names, strict=False):
        ls = spec.limit_states[name]
        strategies = list(fits[name])
        curves = {}
        for s, fit in fits[name].items():
            style = strategy_style(s, strategies, info.flags(s).get("style"))
            color = style["color"]
            frac = [(st.level, st.k / st.n) for st in fit.stripes if st.n]
            ax.plot([f[0] for f in frac], [f[1] for f in frac], ls="none", marker=style["marker"], color=color,
                    ms=4, alpha=0.8, mfc="none")
            if fit.ok:
                lo, hi = fit.band(x)
                ax.fill_between(x, lo, hi, color=color, alpha=0.12, lw=0)
                curves[s] = fit.probability(x)
                ax.plot(x, curves[s], color=color, ls=style["ls"], label=f"{s}: θ={fit.theta:.3g} g, β={fit.beta:.2f}")
            else:
                ax.plot([], [], ls="none", marker=style["marker"], color=color, label=f"{s}: {fit.kind}")
        plain_log_axis(ax.xaxis)
        ax.set_ylim(-0.02, 1.02)
        ax.set_title(f"{ls.label or name}\n({ls.quantity.replace('_', ' ')} > "
                     f"{threshold_text(ls.quantity, ls.threshold)})", fontsize=9)
        ax.set_xlabel(im_label(info))
        ax.grid(alpha=0.3, which="both")
        add_legend_notes(ax, [coincidence_note(*p) for p in coincident(curves, 1.04)], fontsize=7, loc="upper left")
    for row in axes:
        row[0].set_ylabel("probability of exceedance")
    fig.suptitle(f"{info.name}: fragility, lognormal MLE with {100 * spec.confidence:g} % band", fontsize=10)
    fig.tight_layout()
    _save(fig, path, files)


def spectra_figure(path: Path, info: IdaInfo, records: Path, files: FigureFiles = PNG_ONLY) -> bool:
    """``figures/spectra.png``: every component's response spectrum as the runs play it at the first intensity
    level (windowed, time-scaled, scaled to the level), their median, and T1 marked; False (nothing drawn) when a
    component's file in ``records`` is missing or unreadable (a folder copied without its records)."""
    from components.physics.ground_motion_core import RecordError, read_record
    from orchestration.spectrum_figure import spectrum, spectrum_figure

    level = float(info.config["intensity"]["levels"][0])
    time_scale = float(info.config.get("time_scale", 1.0))
    curves = {}
    for c in info.components:
        try:
            rec = read_record(records / f"{c.id}.csv")
        except (OSError, RecordError):
            return False
        curves[c.id] = spectrum(rec.time, rec.accel_g, level / c.im, time_scale)
    marks = {"T1 (isolated)": info.period_s} if info.period_s else {}
    measure = im_label(info).removesuffix(" [g]")
    fig = spectrum_figure(curves, marks, f"{len(curves)} components scaled to {measure} = {level:g} g, as played",
                          median=len(curves) > 4)
    _save(fig, path, files)
    return True
