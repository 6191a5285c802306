"""Study tables, figures and report (Markdown and self-contained HTML), regenerated from data.

Everything here reads the study folder (``study.json`` and the runs' ``timeseries.csv``),
so ``python orchestration/study.py --report STUDY_DIR`` rebuilds the report at any time.
"""

from __future__ import annotations

import base64
import html
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from components.physics.sosm_conditions import sosm_conditions
from components.physics.sosm_controller_core import IsolatorModel, SosmGains
from orchestration.master.runfolder import write_json, write_text
from orchestration.studies.analysis import (
    INDEX_COLUMNS,
    INDEX_MEANING,
    PEAK_COLUMNS,
    csv_text,
    indices,
    read_timeseries,
    run_metrics,
)
from orchestration.studies.claims import PINNED_SHARE, check_claims
from orchestration.studies.config import SOSM_STRATEGIES, UNCONTROLLED

TIE = 0.01  # relative difference below which two peaks are called a tie
COLORS = {"passive-off": "0.25", "passive-on": "tab:blue", "best-constant": "tab:green", "sosm": "tab:red",
          "sosm-fig15": "tab:orange", "on-off": "tab:purple"}
STYLES = {"passive-off": ":", "passive-on": "--", "best-constant": "-.", "sosm": "-", "sosm-fig15": "-",
          "on-off": "-"}
REFERENCE_KEYS = ("x_base_mm", "drift_1_mm", "drift_2_mm", "drift_3_mm", "acc_0", "acc_1", "acc_2", "acc_3",
                  "base_shear_N")


@dataclass
class Block:
    """One report element: heading, paragraph, table, image or bullet list."""

    kind: str
    text: str = ""
    level: int = 2
    header: list[str] = field(default_factory=list)
    rows: list[list[str]] = field(default_factory=list)
    items: list[str] = field(default_factory=list)


def _f(v: Any, digits: int = 3) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    if isinstance(v, float | np.floating):
        return f"{v:.{digits}g}" if abs(v) < 1e4 else f"{v:.0f}"
    return str(v)


def _pct(a: float, b: float) -> str:
    return f"{100 * (a / b - 1):+.1f} %"


def _compare(a: float, b: float) -> str:
    """'beats' if a is lower than b by more than TIE, 'loses' if higher, else 'ties' (lower is better)."""
    if not (math.isfinite(a) and math.isfinite(b)) or b == 0:
        return "n/a"
    r = a / b - 1
    return "beats" if r < -TIE else "loses to" if r > TIE else "ties with"


# ---------------------------------------------------------------- data


def load_metrics(folder: Path, study: dict[str, Any]) -> tuple[dict[tuple[str, str], dict[str, float]],
                                                                dict[tuple[str, str], dict[str, np.ndarray]]]:
    """Metrics and time series of every successful run of a study folder."""
    metrics: dict[tuple[str, str], dict[str, float]] = {}
    series: dict[tuple[str, str], dict[str, np.ndarray]] = {}
    for run in study["runs"]:
        if not run.get("ok"):
            continue
        path = folder / run["folder"] / "timeseries.csv"
        if not path.is_file():
            run["ok"] = False
            run["error"] = f"{path} is missing"
            continue
        key = (run["record"], run["strategy"])
        series[key] = read_timeseries(path)
        metrics[key] = m = run_metrics(series[key], study["records"][run["record"]]["masses_kg"])
        t, i = series[key]["time"], series[key]["controller.i"]
        lo, hi = study["config"]["paper_current_range"]
        dt = float(t[1] - t[0]) if len(t) > 1 else 0.0
        m["time_current_outside_paper_range_s"] = float(np.sum((i > hi + 1e-12) | (i < lo - 1e-12)) * dt)
        limit = current_limit(study, run["strategy"])
        m["current_limit_A"] = limit
        m.update(current_shares(i, limit, hi))
    return metrics, series


def current_limit(study: dict[str, Any], strategy: str) -> float:
    """The controller's current limit [A] of a strategy: the second gain set's own, else the study's i_max."""
    cfg = study["config"]
    if strategy == "sosm-fig15":
        return float((cfg.get("fig15") or {}).get("i_max", cfg["i_max"]))
    return float(cfg["i_max"])


def current_shares(i: np.ndarray, limit: float, range_top: float) -> dict[str, float]:
    """Shares of the run's samples with the current at its limit, at 0 A and at or above ``range_top`` [A]
    (within 1e-6 A: the controller clips to its bounds exactly, the tolerance only absorbs the CSV's printing)."""
    if not len(i):
        return {"current_share_at_limit": math.nan, "current_share_at_zero": math.nan,
                "current_share_at_range_top": math.nan}
    return {"current_share_at_limit": float(np.mean(i >= limit - 1e-6)),
            "current_share_at_zero": float(np.mean(i <= 1e-6)),
            "current_share_at_range_top": float(np.mean(i >= range_top - 1e-6))}


# ---------------------------------------------------------------- figures


def _save(fig: Any, path: Path) -> Path:
    import matplotlib.pyplot as plt

    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp, dpi=100, bbox_inches="tight")
    plt.close(fig)
    tmp.replace(path)
    return path


def pareto_front(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the points (x, y) no other point dominates (both lower is better), sorted by x."""
    order = sorted(range(len(points)), key=lambda k: (points[k][0], points[k][1]))
    front, best_y = [], math.inf
    for k in order:
        if points[k][1] < best_y:
            front.append(k)
            best_y = points[k][1]
    return front


def pareto_figure(study: dict[str, Any]) -> Any:
    """Peak top-floor acceleration against mean current over the second gain set's tuning evaluations, per tuning
    record, with the constant currents on the same window; None without evaluations."""
    from orchestration.studies.tuning import RECORD_COLUMNS, read_table

    doc = (study.get("gain_sets") or {}).get("sosm-fig15") or {}
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
    fig, axes = plt.subplots(1, len(records), figsize=(4.2 * len(records), 3.6), squeeze=False)
    for ax, r in zip(axes[0], records, strict=True):
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
        ax.set(xlabel="mean current [A]", ylabel="peak top-floor acceleration a_3 [m/s²]", yscale="log",
               title=f"{r}, first {window:g} s" if window else r)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=6)
    fig.colorbar(sc, ax=axes[0, -1], label=f"share of time at {chosen['i_max']:g} A")
    fig.suptitle(f"sosm-fig15 tuning: {len(sosm)} evaluations (objective weights: "
                 + ", ".join(f"{k} {v:g}" for k, v in proc.get("objective", {}).items() if k.startswith("w_"))
                 + ")", fontsize=9)
    fig.tight_layout()
    return fig


def make_figures(folder: Path, study: dict[str, Any], metrics: dict, series: dict) -> dict[str, Path]:
    """The paper-like figures (Fig. 15-17), hysteresis loops per record and the current sweep."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figdir = folder / "figures"
    figdir.mkdir(exist_ok=True)
    records = list(study["records"])
    strategies = study["strategies"]
    i_max = study["config"]["i_max"]
    hi = study["config"]["paper_current_range"][1]
    x_id, x_lim = 1e3 * study["config"]["x_identified"], 1e3 * study["config"]["x_limit"]
    made: dict[str, Path] = {}
    n = len(records)

    def masses_of(r: str) -> list[float]:
        return study["records"][r]["masses_kg"]

    def named(r: str) -> str:
        """A record's name with its amplitude scale (``kobe ×0.5``)."""
        scale = study["records"][r].get("scale")
        return f"{r} ×{scale:g}" if isinstance(scale, int | float) else r

    controlled = [s for s in strategies if s in SOSM_STRATEGIES]
    if controlled:
        fig, axes = plt.subplots(n, len(controlled), figsize=(8 * len(controlled) ** 0.5, 1.9 * n), squeeze=False,
                                 sharey=True)
        for col, s in enumerate(controlled):
            limit = current_limit(study, s)
            for ax, r in zip(axes[:, col], records, strict=True):
                ts = series.get((r, s))
                if ts is not None:
                    ax.plot(ts["time"], ts["controller.i"], color=COLORS[s], lw=0.6)
                ax.axhline(hi, color="0.5", ls="--", lw=0.8)
                ax.axhline(limit, color="0.5", ls=":", lw=0.8)
                ax.set(ylabel="i [A]", ylim=(-0.1, i_max * 1.08))
                ax.set_title(f"{named(r)}: {s} current (dashed {hi:g} A as in the paper, dotted its limit "
                             f"{limit:g} A)", fontsize=9)
                ax.grid(alpha=0.3)
            axes[-1, col].set_xlabel("time [s]")
        fig.tight_layout()
        made["fig15_current"] = _save(fig, figdir / "fig15_current.png")
    pareto = pareto_figure(study)
    if pareto is not None:
        made["pareto"] = _save(pareto, figdir / "pareto.png")

    fig, axes = plt.subplots(n, 1, figsize=(8, 1.9 * n), squeeze=False)
    for ax, r in zip(axes[:, 0], records, strict=True):
        for s in (UNCONTROLLED, "passive-on", *SOSM_STRATEGIES):
            ts = series.get((r, s))
            if ts is not None and s in strategies:
                ax.plot(ts["time"], ts["building.a_3"], color=COLORS[s], ls="-",
                        lw=0.6 if s in SOSM_STRATEGIES else 0.5, alpha=0.8 if s != "passive-on" else 0.6, label=s)
        ref_ts = series.get((r, UNCONTROLLED))
        if ref_ts is not None and len(ref_ts["time"]) > 1:
            a = np.abs(ref_ts["building.a_3"])
            strong = ref_ts["time"][a > 0.05 * a.max()]
            if len(strong):
                ax.set_xlim(0.0, min(ref_ts["time"][-1], strong[-1] + 5.0))
        ax.set(ylabel="a_3 [m/s²]")
        ax.set_title(f"{named(r)}: top-floor (3rd floor) absolute acceleration, strong-motion window", fontsize=9)
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7, loc="upper right")
    axes[-1, 0].set_xlabel("time [s]")
    fig.tight_layout()
    made["fig16_top_acceleration"] = _save(fig, figdir / "fig16_top_acceleration.png")

    fig, axes = plt.subplots(n, 2, figsize=(8, 2.4 * n), squeeze=False)
    for row, r in enumerate(records):
        for s in strategies:
            m = metrics.get((r, s))
            if m is None:
                continue
            nd = len([k for k in m if re.fullmatch(r"drift_\d+_mm", k)])
            axes[row, 0].plot([m[f"drift_{j}_mm"] for j in range(1, nd + 1)], range(1, nd + 1), marker="o",
                              color=COLORS[s], ls=STYLES[s], label=s)
            axes[row, 1].plot([m[f"acc_{j}"] for j in range(nd + 1)], range(nd + 1), marker="o", color=COLORS[s],
                              ls=STYLES[s], label=s)
        axes[row, 0].set(ylabel=f"{named(r)}\nstorey", xlabel="peak drift [mm]", yticks=range(1, len(masses_of(r))))
        axes[row, 1].set(ylabel="level (0 = base)", xlabel="peak abs. acceleration [m/s²]",
                         yticks=range(len(masses_of(r))))
        for ax in axes[row]:
            ax.grid(alpha=0.3)
    if axes[0, 1].get_legend_handles_labels()[0]:
        axes[0, 1].legend(fontsize=7)
    fig.tight_layout()
    made["fig17_profiles"] = _save(fig, figdir / "fig17_profiles.png")

    for r in records:
        present = [s for s in strategies if (r, s) in series]
        if not present:
            continue
        fig, axes = plt.subplots(1, len(present), figsize=(3.2 * len(present), 3.0), squeeze=False, sharey=True)
        for ax, s in zip(axes[0], present, strict=True):
            ts = series[(r, s)]
            ax.plot(1e3 * ts["building.x_0"], ts["isolator.F"], color=COLORS[s], lw=0.4)
            for edge, style in ((x_id, "--"), (x_lim, ":")):
                ax.axvline(edge, color="0.5", ls=style, lw=0.8)
                ax.axvline(-edge, color="0.5", ls=style, lw=0.8)
            ax.set(title=s, xlabel="x_0 [mm]")
            ax.grid(alpha=0.3)
        n_iso = study["records"][r].get("n_isolators")
        axes[0, 0].set_ylabel(f"force of the {n_iso} isolators together [N]" if n_iso else "isolator force F [N]")
        fig.suptitle(f"{named(r)}: isolator hysteresis per strategy "
                     f"(dashed ±{x_id:g} mm identified, dotted ±{x_lim:g} mm limit)",
                     fontsize=9)
        fig.tight_layout()
        made[f"hysteresis_{r}"] = _save(fig, figdir / f"hysteresis_{r}.png")

    sweeps = study.get("sweep") or {}
    if sweeps:
        fig, ax = plt.subplots(figsize=(6, 3.2))
        for r, sw in sweeps.items():
            if not sw.get("ok"):
                continue
            rows = sw["rows"]
            line = ax.plot([q["current_A"] for q in rows], [q["J"] for q in rows], marker=".", label=r)[0]
            ax.plot([sw["best_current_A"]], [sw["best_J"]], marker="o", ms=8, mfc="none", color=line.get_color())
        ax.set(xlabel="constant current [A]", ylabel="objective J", yscale="log",
               title="constant-current sweep (in-process); circle = best")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
        made["sweep"] = _save(fig, figdir / "sweep.png")
    return made


# ---------------------------------------------------------------- report


def _order(key: str, study: dict[str, Any]) -> tuple[int, int]:
    """Sort key of 'record[/strategy[/...]]' in the study's record and strategy order."""
    parts = key.split("/")
    records, strategies = list(study["records"]), study["strategies"]
    r = records.index(parts[0]) if parts[0] in records else len(records)
    s = strategies.index(parts[1]) if len(parts) > 1 and parts[1] in strategies else len(strategies)
    return r, s


def _verdict(r: str, study: dict[str, Any], metrics: dict) -> list[Block]:
    cfg = study["config"]
    blocks = [Block("h", r, level=3)]
    controlled = [s for s in study["strategies"] if s in SOSM_STRATEGIES]
    if not controlled:
        blocks.append(Block("p", "SOSM is not part of this study: no verdict."))
        return blocks
    items = []
    for c in controlled:
        sosm = metrics.get((r, c))
        if sosm is None:
            items.append(f"No **{c}** result for this record (see failed runs): no verdict.")
            continue
        for s in study["strategies"]:
            if s in SOSM_STRATEGIES or (r, s) not in metrics:
                continue
            o = metrics[(r, s)]
            label = s + (f" ({study['best_current'].get(r, math.nan):g} A)" if s == "best-constant" else "")
            items.append(
                f"**{c}** vs **{label}**: {_compare(sosm['acc_3'], o['acc_3'])} it on peak top-floor acceleration "
                f"({_f(sosm['acc_3'])} vs {_f(o['acc_3'])} m/s², {_pct(sosm['acc_3'], o['acc_3'])}) and "
                f"{_compare(sosm['drift_max_mm'], o['drift_max_mm'])} it on peak drift "
                f"({_f(sosm['drift_max_mm'])} vs {_f(o['drift_max_mm'])} mm, "
                f"{_pct(sosm['drift_max_mm'], o['drift_max_mm'])}); "
                f"base displacement {_f(sosm['x_base_mm'])} vs {_f(o['x_base_mm'])} mm.")
        lo, hi = cfg["paper_current_range"]
        inside = sosm["current_min_A"] >= lo - 1e-12 and sosm["current_max_A"] <= hi + 1e-12
        items.append(f"**{c}** current: {_f(sosm['current_min_A'])} to {_f(sosm['current_max_A'])} A, mean "
                     f"{_f(sosm['current_mean_A'])} A, at its {_f(sosm['current_limit_A'])} A limit "
                     f"{100 * sosm['current_share_at_limit']:.0f} % of the time: "
                     f"{'within' if inside else 'NOT within'} the paper's "
                     f"{lo:g}-{hi:g} A" + ("." if inside else f" (above {hi:g} A for "
                                            f"{_f(sosm['time_current_outside_paper_range_s'])} s of "
                                            f"{_f(sosm['duration_s'])} s)."))
    for s in study["strategies"]:
        m = metrics.get((r, s))
        if m is None:
            continue
        if m["time_beyond_15mm_s"] > 0:
            items.append(f"**{s}**: base displacement {_f(m['x_base_mm'])} mm leaves the isolator's "
                         f"{1e3 * cfg['x_limit']:g} mm limit ({_f(m['time_beyond_15mm_s'])} s beyond) and the "
                         f"±{1e3 * cfg['x_identified']:g} mm identified range ({_f(m['time_beyond_8mm_s'])} s): "
                         "the isolator model is extrapolated.")
        elif m["time_beyond_8mm_s"] > 0:
            items.append(f"**{s}**: base displacement {_f(m['x_base_mm'])} mm leaves the ±"
                         f"{1e3 * cfg['x_identified']:g} mm identified range ({_f(m['time_beyond_8mm_s'])} s "
                         f"beyond; model extrapolated), within the {1e3 * cfg['x_limit']:g} mm limit.")
    blocks.append(Block("ul", items=items))
    return blocks


def _sosm_condition_blocks(study: dict[str, Any], records: list[str], series: dict) -> list[Block]:
    """Eq. (36)'s bounds tau, v_m, v_M along each SOSM run and the gain conditions after Eq. (39)."""
    sets = dict(study.get("gain_sets") or {})
    if not sets and study.get("gains"):
        sets = {"sosm": study["gains"]}  # a study folder written before the second gain set
    rows = []
    for strategy, doc in sets.items():
        gg = doc["gains"]
        gains = SosmGains(lam=gg["lambda"], rho=gg["rho"], zeta=gg["zeta"], theta=gg["theta"], i_max=gg["i_max"])
        for r in records:
            ts = series.get((r, strategy))
            if ts is None:
                continue
            info = study["records"][r]
            # relative base acceleration: recorded, or absolute minus ground (both m/s²)
            arel = ts["building.arel_0"] if "building.arel_0" in ts else ts["building.a_0"] - ts["ground.ag"]
            c = sosm_conditions(ts["time"], ts["building.x_0"], ts["building.v_0"], arel,
                                ts["controller.i"], gains, IsolatorModel(), info["masses_kg"][0],
                                int(info.get("n_isolators") or 2))
            rows.append([r, strategy, _f(c.tau), _f(c.v_m), _f(c.v_M), _f(c.reaching_margin),
                         "holds" if c.reaching_holds else "FAILS", f"{100 * c.share_pointwise:.0f} %",
                         f"{100 * c.share_local:.1f} %",
                         _f(c.zeta_theta_over_rho), "holds" if c.zeta_theta_holds else "FAILS"])
    if not rows:
        return []
    return [
        Block("h", "The SOSM convergence conditions (Eq. 36-39)", level=2),
        Block("p", "The paper's finite-time convergence needs |Φ| ≤ τ and 0 < v_m ≤ Ψ ≤ v_M for all t (Eq. 36) "
                   "with ρ v_m − τ > ϑ²/2 and ζ ϑ > ρ. Measured along each SOSM run (Φ = s̈ − Ψ u from the recorded "
                   "base acceleration and current, Ψ of Eq. 34 with the controller's isolator model; "
                   "`components/physics/sosm_conditions.py`). Ψ changes sign with the motion and vanishes at "
                   "rest, so v_m = 0 and the first condition cannot hold: the paper's convergence argument does "
                   "not apply globally; the controller applies sign(Ψ) u. 'pointwise' is the share of the run "
                   "where ρ |Ψ(t)| − τ > ϑ²/2, 'local' where ρ |Ψ(t)| − |Φ(t)| > ϑ²/2. Units: τ in m/s³, v in "
                   "m/(s² A)."),
        Block("table", header=["record", "strategy", "τ", "v_m", "v_M", "ρ v_m − τ − ϑ²/2", "reaching condition",
                               "pointwise",
                               "local", "ζ ϑ / ρ", "ζ ϑ > ρ"], rows=rows),
    ]


def ground_reading(study: dict[str, Any]) -> str:
    """Which reading of the paper's "scaled down by 0.5" the study's records use."""
    scales = {(info.get("scale"), info.get("time_scale", 1.0)) for info in study["records"].values()}
    parts = []
    for amp, ts in sorted(scales, key=str):
        amp = 1.0 if amp is None else float(amp)
        ts = 1.0 if ts is None else float(ts)
        if ts != 1.0 and amp == 1.0:
            what = (f"**time-scaled reading**: the records play {1 / ts:g} times faster (time ×{ts:g}, every "
                    "frequency ×" f"{1 / ts:g}) at their full amplitude")
        elif ts == 1.0:
            what = f"**amplitude reading**: the records ×{amp:g} in amplitude, at their own speed"
        else:
            what = f"amplitude ×{amp:g} and time ×{ts:g}"
        parts.append(what)
    return ("Ground motion: " + "; ".join(parts) + ". The paper scales the records \"down by 0.5\" \"to make sure "
            "the fundamental frequency of smart structure with the main seismic frequency spectrum\", which fits "
            "either reading (README, Assumptions).")


def _gain_set_blocks(study: dict[str, Any], records: list[str], metrics: dict) -> list[Block]:
    """Both SOSM gain sets against passive-off and passive-on, and the current statistics (Fig. 15)."""
    controlled = [s for s in study["strategies"] if s in SOSM_STRATEGIES]
    if not controlled:
        return []
    rows, cur = [], []
    for r in records:
        off, on = metrics.get((r, UNCONTROLLED)), metrics.get((r, "passive-on"))
        for c in controlled:
            m = metrics.get((r, c))
            if m is None:
                continue
            idx = (study.get("indices") or {}).get(f"{r}/{c}", {})

            def vs(key: str, other: dict | None, m: dict = m) -> str:
                return _pct(m[key], other[key]) if other else "–"

            rows.append([r, c, _f(m["acc_3"]), vs("acc_3", off), vs("acc_3", on), _f(m["drift_max_mm"]),
                         vs("drift_max_mm", off), vs("drift_max_mm", on), _f(m["x_base_mm"]),
                         *(_f(idx.get(k)) for k in ("J1", "J2", "J5", "J8"))])
            cur.append([r, c, _f(m["current_min_A"]), _f(m["current_max_A"]), _f(m["current_mean_A"]),
                        _f(m["current_limit_A"]), f"{100 * m['current_share_at_limit']:.1f} %",
                        f"{100 * m['current_share_at_zero']:.1f} %",
                        f"{_f(m['time_current_outside_paper_range_s'])} s"])
    hi = study["config"]["paper_current_range"][1]
    return [
        Block("h", "SOSM gain sets against the passive settings", level=2),
        Block("p", "`sosm`: gains tuned for peak response only (i_max 3 A). `sosm-fig15`: the second gain set, "
                   "with a release band (not in the paper) and tuned with terms on the shares of time at its "
                   "2.5 A limit and at 0 A so that the current varies as in the paper's Fig. 15 "
                   "(docs/case_study.md). Percentages: this strategy's peak against "
                   "passive-off (0 A) and passive-on (3 A); negative is lower. Indices as below."),
        Block("table", header=["record", "strategy", "a_3 m/s²", "vs off", "vs on", "max drift mm", "vs off",
                               "vs on", "x_base mm", "J1", "J2", "J5", "J8"], rows=rows),
        Block("h", "Current statistics (Fig. 15)", level=3),
        Block("p", f"Over the whole run. 'at limit': share of the time at the strategy's own current limit; "
                   f"'at 0 A': share at 0 A; 'above {hi:g} A': time above the paper's range."),
        Block("table", header=["record", "strategy", "min A", "max A", "mean A", "limit A", "at limit", "at 0 A",
                               f"above {hi:g} A"], rows=cur),
    ]


def build_report(folder: Path, study: dict[str, Any], metrics: dict, figures: dict[str, Path],
                 series: dict | None = None) -> list[Block]:
    """The report's blocks: provenance, claims check, verdicts, tables, figures, failures."""
    cfg = study["config"]
    records = list(study["records"])
    strategies = study["strategies"]
    b: list[Block] = [Block("h", f"Case study: {study['name']}", level=1)]
    prov = study.get("provenance", {})
    b.append(Block("p", f"Study folder `{folder.name}`, started {study.get('started', '?')}, finished "
                        f"{study.get('finished', '?')}; code commit `{prov.get('commit', '?')}`"
                        f"{' (working tree with uncommitted changes)' if prov.get('dirty') else ''}; coupling "
                        f"algorithm {', '.join(sorted(set(prov.get('algorithms', {}).values()))) or '?'}, "
                        f"step {prov.get('step_s', '?')} s. Overrides for every run: "
                        f"`{' '.join(study.get('run_overrides', [])) or 'none'}`. Command: "
                        f"`{' '.join(prov.get('command', []))}`."))
    failed = [run for run in study["runs"] if not run.get("ok")] + [
        {"key": f"{k} (sweep)", "error": v.get("error")} for k, v in (study.get("sweep") or {}).items()
        if not v.get("ok")] + [{"key": f"{k} (reference)", "error": v.get("error")}
                               for k, v in (study.get("reference") or {}).items() if not v.get("ok")]
    if failed:
        b.append(Block("h", "Failed runs", level=2))
        b.append(Block("p", "These jobs failed; every other result below is complete."))
        b.append(Block("table", header=["run", "reason"],
                       rows=[[f["key"], str(f.get("error") or "?").replace("|", "/")] for f in failed]))
    b.append(Block("p", ground_reading(study)))
    sets = study.get("gain_sets") or ({"sosm": study["gains"]} if study.get("gains") else {})
    for strategy, g in sets.items():
        if strategy not in strategies:
            continue
        gg, proc = g["gains"], g.get("procedure", {})
        files = study.get("gains_files") or {"sosm": study.get("gains_file", "?")}
        obj = proc.get("objective", {})
        extra = ", ".join(f"{k} {v:g}" for k, v in obj.items()
                          if k.startswith("w_") and k not in ("w_acc", "w_drift") and v)
        b.append(Block("p", f"**{strategy}** gains (from `{files.get(strategy, '?')}`, tuned on "
                            f"{proc.get('record', '?')}"
                            + (f" (first {proc['stop_time_s']:g} s)" if proc.get("stop_time_s") else "")
                            + (f", objective with {extra}" if extra else "")
                            + f", not per record): λ = {_f(gg['lambda'], 4)} "
                            f"1/s, ρ = {_f(gg['rho'], 4)} A/s, ζ = {_f(gg['zeta'], 4)} A·s^½/m^½, ϑ = "
                            f"{_f(gg['theta'], 4)} m^½/s^1.5, i_max = {_f(gg['i_max'])} A"
                            + (f", release band s_release = {_f(gg['s_release'], 3)} m/s (a designer's extension, "
                               "not in the paper: while |s| < s_release the current falls at ρ)"
                               if gg.get("s_release") else "") + "."))

    controlled = [s for s in strategies if s in SOSM_STRATEGIES]
    b.append(Block("h", "The paper's claims on our system", level=2))
    b.append(Block("p", "The paper (section 4.3, Fig. 16-17) reports that SOSM control reduces the top-floor "
                        "acceleration and the inter-storey drift against the passive structure, with the current "
                        f"varying within {cfg['paper_current_range'][0]:g}-{cfg['paper_current_range'][1]:g} A. "
                        "Ratios are SOSM / passive-off (below 1: SOSM lower)."))
    rows = []
    lo, hi = cfg["paper_current_range"]
    for c in controlled:
        for r in records:
            s, o = metrics.get((r, c)), metrics.get((r, UNCONTROLLED))
            if s is None or o is None:
                rows.append([r, c, "–", "–", "–", "–", "–"])
                continue
            ra, rd = s["acc_3"] / o["acc_3"], s["drift_max_mm"] / o["drift_max_mm"]
            ok_i = s["current_min_A"] >= lo - 1e-12 and s["current_max_A"] <= hi + 1e-12
            rows.append([r, c, _f(ra), "holds" if ra < 1 - TIE else "does not hold", _f(rd),
                         "holds" if rd < 1 - TIE else "does not hold",
                         f"{_f(s['current_min_A'])}-{_f(s['current_max_A'])} A: {'yes' if ok_i else 'no'}"])
    b.append(Block("table", header=["record", "strategy", "a_3 ratio", "acceleration claim", "drift ratio",
                                    "drift claim", f"current within {lo:g}-{hi:g} A"], rows=rows))
    checks = check_claims(metrics, records, strategies, controlled=controlled or "sosm", tie=TIE,
                          current_range=(lo, hi))
    judged = [c for c in checks if c.holds is not None]
    b.append(Block("p", "Every claim of section 4.3, per record and strategy (the profile claims are made \"for all "
                        "the cases\"): floor peak accelerations from the base (level 0) to the top, drifts from "
                        f"storey 1 to the top; a {100 * TIE:g} % tie counts as holding. The current claim (Fig. 15) "
                        f"holds when the current stays within {lo:g}-{hi:g} A and sits at neither end for more than "
                        f"{100 * PINNED_SHARE:g} % of the run. "
                        f"{sum(c.holds for c in judged)} of {len(judged)} checks hold."))
    b.append(Block("table", header=["claim", "record", "strategy", "quantity", "holds"],
                   rows=[[c.claim, c.record, c.strategy, c.quantity,
                          "–" if c.holds is None else ("holds" if c.holds else "FAILS")] for c in checks]))
    b.extend(_gain_set_blocks(study, records, metrics))

    b.extend(_sosm_condition_blocks(study, records, series or {}))

    b.append(Block("h", "Verdict per record", level=2))
    b.append(Block("p", f"Lower is better; a difference within {100 * TIE:g} % is called a tie. Peak drift is the "
                        "largest over the three storeys."))
    for r in records:
        b.extend(_verdict(r, study, metrics))

    b.append(Block("h", "Peaks", level=2))
    b.append(Block("p", "x_base: base (isolator) displacement; drift_j: storey j; acc_j: absolute acceleration of "
                        "level j (0 = base); base shear = |Σ m_j a_j| over all levels (= |F| with k_0 = c_0 = 0). "
                        "Also in `peaks.csv`."))
    hdr = ["record", "strategy", "x_base mm", "drift_1 mm", "drift_2 mm", "drift_3 mm", "acc_0", "acc_1", "acc_2",
           "acc_3 m/s²", "base shear N", "i max A", "i mean A"]
    b.append(Block("table", header=hdr, rows=[[r, s, *(_f(metrics[(r, s)][c]) for c in PEAK_COLUMNS[2:])]
                                             for r in records for s in strategies if (r, s) in metrics]))
    b.append(Block("h", "Evaluation indices (Narasimhan et al. 2006)", level=2))
    b.append(Block("p", "Controlled / uncontrolled peak (or RMS), passive-off (0 A) as the uncontrolled case: "
                        + "; ".join(f"{k}: {v}" for k, v in INDEX_MEANING.items()) + ". Also in `indices.csv`."))
    b.append(Block("table", header=list(INDEX_COLUMNS),
                   rows=[[r, s, *(_f(study["indices"][f"{r}/{s}"][c]) for c in INDEX_COLUMNS[2:])]
                         for r in records for s in strategies if f"{r}/{s}" in study["indices"]]))

    ref = study.get("reference") or {}
    if ref:
        b.append(Block("h", "Passive runs against the monolithic reference", level=2))
        b.append(Block("p", "Radau (rtol " + _f(cfg["reference"]["rtol"]) + ") of the same equations at the same "
                       "constant current (components.physics.monolithic.simulate_radau). The difference is the "
                       "coupling error of the co-simulation; accepted up to "
                       f"{100 * cfg['reference']['tolerance']:g} % "
                       "(README, Coupling error). Full table in `reference.csv`."))
        rows = []
        for key, v in sorted(ref.items(), key=lambda kv: _order(kv[0], study)):
            r, s = key.split("/")
            m = metrics.get((r, s))
            if not v.get("ok") or m is None:
                rows.append([r, s, "–", "–", "–", "–", "failed"])
                continue
            errs = {k: m[k] / v["value"][k] - 1 for k in REFERENCE_KEYS if v["value"].get(k)}
            worst = max(errs, key=lambda k: abs(errs[k]))
            rows.append([r, s, _f(m["x_base_mm"]) + " / " + _f(v["value"]["x_base_mm"]),
                         _f(m["acc_3"]) + " / " + _f(v["value"]["acc_3"]), f"{worst}: {100 * errs[worst]:+.1f} %",
                         f"{100 * np.mean([abs(e) for e in errs.values()]):.1f} %",
                         "within" if abs(errs[worst]) <= cfg["reference"]["tolerance"] else "OUTSIDE"])
        b.append(Block("table", header=["record", "strategy", "x_base mm co-sim / Radau", "acc_3 co-sim / Radau",
                                        "largest error", "mean |error|", "tolerance"], rows=rows))

    sweeps = study.get("sweep") or {}
    if sweeps:
        b.append(Block("h", "Best constant current", level=2))
        o = cfg["objective"]
        b.append(Block("p", f"Swept {cfg['sweep_currents'][0]:g}-{cfg['sweep_currents'][-1]:g} A in the in-process "
                            f"model; objective J = {o['w_acc']:g}·a_3/a_3,off + {o['w_drift']:g}·d/d_off + "
                            f"{o['penalty']:g}·max(0, x_0/{1e3 * o['x_limit']:g} mm − 1). The best current is chosen "
                            "per record in hindsight: an upper bound on what a passive setting can do."))
        b.append(Block("table", header=["record", "best current A", "J best", "J at i_max"],
                       rows=[[r, _f(sw.get("best_current_A")), _f(sw.get("best_J")),
                              _f(sw["rows"][-1]["J"]) if sw.get("rows") else "–"]
                             for r, sw in sorted(sweeps.items(), key=lambda kv: _order(kv[0], study))]))
    runs = sorted(study["runs"], key=lambda run: _order(run["key"], study))
    warn = [f"{run['record']} / {run['strategy']}: {_f(metrics[(run['record'], run['strategy'])]['x_base_mm'])} mm, "
            f"{_f(metrics[(run['record'], run['strategy'])]['time_beyond_8mm_s'])} s beyond "
            f"±{1e3 * cfg['x_identified']:g} mm" for run in runs
            if run.get("ok") and (run["record"], run["strategy"]) in metrics
            and metrics[(run["record"], run["strategy"])]["time_beyond_8mm_s"] > 0]
    if warn:
        b.append(Block("h", "Warning: isolator model extrapolated", level=2))
        b.append(Block("p", f"The isolator law was identified on ±{1e3 * cfg['x_identified']:g} mm; these runs go "
                            "beyond it, where the sinh term is an extrapolation:"))
        b.append(Block("ul", items=warn))
    b.append(Block("h", "Figures", level=2))
    captions = {"fig15_current": "SOSM current per record, one column per gain set (cf. paper Fig. 15).",
                "pareto": "Peak top-floor acceleration against mean current over the sosm-fig15 tuning's "
                          "evaluations (colour: share of time at the limit), with the constant currents.",
                "fig16_top_acceleration": "Top-floor absolute acceleration, passive vs SOSM (cf. Fig. 16).",
                "fig17_profiles": "Peak drift per storey and peak acceleration per level (cf. Fig. 17).",
                "sweep": "Objective J against the constant current."}
    for name, path in figures.items():
        b.append(Block("img", text=str(path.relative_to(folder)),
                       items=[captions.get(name, f"Isolator force against displacement, {name.split('_', 1)[-1]}.")]))
    return b


def to_markdown(blocks: list[Block]) -> str:
    """Markdown text of the report blocks."""
    out: list[str] = []
    for bl in blocks:
        if bl.kind == "h":
            out.append("#" * bl.level + " " + bl.text)
        elif bl.kind == "p":
            out.append(bl.text)
        elif bl.kind == "ul":
            out.append("\n".join(f"* {it}" for it in bl.items))
        elif bl.kind == "table":
            out.append("\n".join(["| " + " | ".join(bl.header) + " |", "|" + "---|" * len(bl.header),
                                  *("| " + " | ".join(row) + " |" for row in bl.rows)]))
        elif bl.kind == "img":
            out.append(f"![{bl.items[0]}]({bl.text})\n\n*{bl.items[0]}*")
    return "\n\n".join(out) + "\n"


def _html_inline(text: str) -> str:
    t = html.escape(text)
    t = re.sub(r"\*\*(.+?)\*\*", r"<b>\1</b>", t)
    return re.sub(r"`(.+?)`", r"<code>\1</code>", t)


def to_html(blocks: list[Block], folder: Path) -> str:
    """Self-contained HTML (figures inline as base64 PNG)."""
    parts = ["<!DOCTYPE html><html><head><meta charset='utf-8'><title>case study</title><style>"
             "body{font-family:sans-serif;max-width:1100px;margin:2em auto;line-height:1.4}"
             "table{border-collapse:collapse;font-size:0.85em;margin:1em 0}td,th{border:1px solid #bbb;"
             "padding:2px 6px;text-align:right}td:first-child,td:nth-child(2){text-align:left}"
             "img{max-width:100%}figcaption{font-style:italic}</style></head><body>"]
    for bl in blocks:
        if bl.kind == "h":
            parts.append(f"<h{bl.level}>{_html_inline(bl.text)}</h{bl.level}>")
        elif bl.kind == "p":
            parts.append(f"<p>{_html_inline(bl.text)}</p>")
        elif bl.kind == "ul":
            parts.append("<ul>" + "".join(f"<li>{_html_inline(it)}</li>" for it in bl.items) + "</ul>")
        elif bl.kind == "table":
            head = "".join(f"<th>{_html_inline(h)}</th>" for h in bl.header)
            body = "".join("<tr>" + "".join(f"<td>{_html_inline(c)}</td>" for c in row) + "</tr>" for row in bl.rows)
            parts.append(f"<table><tr>{head}</tr>{body}</table>")
        elif bl.kind == "img":
            data = base64.b64encode((folder / bl.text).read_bytes()).decode()
            parts.append(f"<figure><img src='data:image/png;base64,{data}'><figcaption>"
                         f"{_html_inline(bl.items[0])}</figcaption></figure>")
    parts.append("</body></html>\n")
    return "\n".join(parts)


def write_outputs(folder: Path, study: dict[str, Any]) -> dict[str, Any]:
    """(Re)write peaks.csv, indices.csv, sweep.csv, reference.csv, figures, report.md/html and study.json."""
    metrics, series = load_metrics(folder, study)
    records, strategies = list(study["records"]), study["strategies"]
    peak_rows, index_rows, study["indices"] = [], [], {}
    for r in records:
        off = metrics.get((r, UNCONTROLLED))
        for s in strategies:
            m = metrics.get((r, s))
            if m is None:
                continue
            peak_rows.append({"record": r, "strategy": s, **m})
            if off is not None:
                idx = indices(m, off)
                study["indices"][f"{r}/{s}"] = idx
                index_rows.append({"record": r, "strategy": s, **idx})
    write_text(folder / "peaks.csv", csv_text(PEAK_COLUMNS, peak_rows))
    write_text(folder / "indices.csv", csv_text(INDEX_COLUMNS, index_rows))
    sweeps = study.get("sweep") or {}
    if sweeps:
        rows = [{"record": r, **q, "best": q["current_A"] == sw["best_current_A"]}
                for r, sw in sweeps.items() if sw.get("ok") for q in sw["rows"]]
        write_text(folder / "sweep.csv", csv_text(("record", "current_A", "x0", "d", "a3", "J", "best"), rows))
    ref = study.get("reference") or {}
    if ref:
        rows = []
        for key, v in ref.items():
            r, s = key.split("/")
            m = metrics.get((r, s))
            if v.get("ok") and m is not None:
                for k in REFERENCE_KEYS:
                    rows.append({"record": r, "strategy": s, "peak": k, "cosim": m[k], "radau": v["value"][k],
                                 "rel_error": m[k] / v["value"][k] - 1 if v["value"][k] else math.nan})
        write_text(folder / "reference.csv", csv_text(("record", "strategy", "peak", "cosim", "radau", "rel_error"),
                                                      rows))
    figures = make_figures(folder, study, metrics, series)
    blocks = build_report(folder, study, metrics, figures, series)
    write_text(folder / "report.md", to_markdown(blocks))
    write_text(folder / "report.html", to_html(blocks, folder))
    study["metrics"] = {f"{r}/{s}": m for (r, s), m in metrics.items()}
    write_json(folder / "study.json", study)
    return study


def read_study(folder: Path) -> dict[str, Any]:
    """The study.json of a study folder."""
    return json.loads((folder / "study.json").read_text())
