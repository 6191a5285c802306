"""Figures and report of an IDA study (Markdown and self-contained HTML), regenerated from its data.

* ``figures/ida_curves.png``: one panel per strategy; for every record component the peak
  isolator displacement [mm] against the intensity, the median over components in bold,
  the identified 8 mm and the 15 mm device limit marked.
* ``figures/fragility.png``: one panel per limit state, the strategies side by side: the
  fitted lognormal, its confidence band, and the observed fraction at each level.
* ``report.md`` / ``report.html``: the settings, a verdict per limit state, the fits, the
  runs that failed.

Verdict: the strategy with the highest median capacity (the intensity at which half the
runs exceed the limit state) is the best for that limit state; it is "clearly" better
when its median's confidence interval does not overlap the runner-up's.
"""

from __future__ import annotations

import base64
import html
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from orchestration.master.runfolder import write_text
from orchestration.studies.fragility import Fit
from orchestration.studies.ida_config import QUANTITIES, IdaSpec

COLORS = ("0.25", "tab:blue", "tab:red", "tab:purple", "tab:green", "tab:orange", "tab:brown", "tab:cyan")
STYLES = {"passive-off": ":", "passive-on": "--"}


def _im_label(info: dict[str, Any]) -> str:
    if info["measure"] == "sa":
        return f"Sa(T1 = {info['period_s']:.3g} s, {100 * info['config']['intensity']['damping']:g} %) [g]"
    return "PGA [g]"


def _threshold_text(quantity: str, threshold: float) -> str:
    _, _, unit = QUANTITIES[quantity]
    return f"{1e3 * threshold:g} mm" if unit == "m" else f"{threshold:g} {unit}"


def ida_figure(path: Path, info: dict[str, Any], rows: list[dict[str, Any]], strategies: list[str]) -> None:
    """IDA curves, one panel per strategy."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    levels = sorted({r["intensity"] for r in rows})
    fig, axes = plt.subplots(1, len(strategies), figsize=(4.2 * len(strategies), 4.2), sharey=True, squeeze=False)
    for ax, s in zip(axes[0], strategies, strict=True):
        mine = [r for r in rows if r["strategy"] == s]
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
        ax.set_xscale("log")
        ax.set_title(s)
        ax.set_xlabel("peak isolator displacement [mm]")
        ax.grid(alpha=0.3, which="both")
    axes[0][0].set_ylabel(_im_label(info))
    axes[0][0].legend(fontsize=7, loc="lower right")
    fig.suptitle(f"{info['name']}: IDA curves ({len({r['record_id'] for r in rows})} components)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def fragility_figure(path: Path, info: dict[str, Any], spec: IdaSpec, fits: dict[str, dict[str, Fit]]) -> None:
    """Fragility curves per limit state, strategies side by side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    levels = np.asarray(spec.intensity.levels, dtype=float)
    x = np.geomspace(levels[0] / 2, levels[-1] * 1.5, 200)
    names = list(fits)
    fig, axes = plt.subplots(1, len(names), figsize=(4.4 * len(names), 4.0), sharey=True, squeeze=False)
    for ax, name in zip(axes[0], names, strict=True):
        ls = spec.limit_states[name]
        for k, (s, fit) in enumerate(fits[name].items()):
            color = COLORS[k % len(COLORS)]
            frac = [(st.level, st.k / st.n) for st in fit.stripes if st.n]
            ax.plot([f[0] for f in frac], [f[1] for f in frac], "o", color=color, ms=4, alpha=0.8)
            if fit.ok:
                lo, hi = fit.band(x)
                ax.fill_between(x, lo, hi, color=color, alpha=0.12, lw=0)
                ax.plot(x, fit.probability(x), color=color, ls=STYLES.get(s, "-"),
                        label=f"{s}: θ={fit.theta:.3g} g, β={fit.beta:.2f}")
            else:
                ax.plot([], [], "o", color=color, label=f"{s}: {fit.kind}")
        ax.set_xscale("log")
        ax.set_ylim(-0.02, 1.02)
        ax.set_title(f"{ls.label or name}\n({ls.quantity.replace('_', ' ')} > "
                     f"{_threshold_text(ls.quantity, ls.threshold)})", fontsize=9)
        ax.set_xlabel(_im_label(info))
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7, loc="upper left")
    axes[0][0].set_ylabel("P(exceed)")
    fig.suptitle(f"{info['name']}: fragility, lognormal MLE with {100 * spec.confidence:g} % band", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def verdict(name: str, spec: IdaSpec, by_strategy: dict[str, Fit], unit: str = "g") -> str:
    """One line: which strategy needs the highest intensity to reach this limit state, and how clearly."""
    ls = spec.limit_states[name]
    head = f"**{ls.label or name}** ({ls.quantity.replace('_', ' ')} > {_threshold_text(ls.quantity, ls.threshold)})"
    top = spec.intensity.levels[-1]

    def capacity(fit: Fit) -> float:  # for ranking
        return {"fit": fit.theta, "none-exceed": math.inf, "all-exceed": 0.0}.get(
            fit.kind, math.sqrt(fit.bounds[0] * fit.bounds[1]) if fit.kind == "separated" else math.nan)

    ranked = sorted(by_strategy.items(), key=lambda kv: -capacity(kv[1]))
    if len(ranked) == 1:
        s, fit = ranked[0]
        return f"{head}: {s} only: {describe(fit, unit)}."
    (s1, f1), (s2, f2) = ranked[0], ranked[1]
    if f1.kind == "none-exceed" and f2.kind == "none-exceed":
        tied = [s for s, f in ranked if f.kind == "none-exceed"]
        return f"{head}: not reached up to {top:g} {unit} by {', '.join(tied)}: the ladder does not tell them apart."
    if f1.kind == "none-exceed":
        return (f"{head}: **{s1}** best: never exceeded up to {top:g} {unit}, while {s2} reaches it "
                f"({describe(f2, unit)}).")
    if f1.kind == "all-exceed":
        return f"{head}: every strategy exceeds it from the lowest level on: lower the ladder."
    c1, c2 = capacity(f1), capacity(f2)
    ratio = f", ×{c1 / c2:.2f} the next" if c2 > 0 and math.isfinite(c1 / c2) else ""
    if f1.ok and f2.ok:
        lo1, _ = f1.theta_interval()
        _, hi2 = f2.theta_interval()
        strength = "clearly better (the intervals of the medians do not overlap)" if lo1 > hi2 else \
            "not distinguishable at this sample size (the intervals of the medians overlap)"
    else:
        strength = "(no finite fit for one of them: see the table)"
    return (f"{head}: **{s1}** needs the highest intensity ({describe(f1, unit)}){ratio}, "
            f"{s2} ({describe(f2, unit)}): {strength}.")


def describe(fit: Fit, unit: str = "g") -> str:
    """A fit in words."""
    if fit.ok:
        lo, hi = fit.theta_interval()
        return (f"median {fit.theta:.3g} {unit}, {100 * fit.confidence:g} % interval {lo:.3g}-{hi:.3g} {unit}, "
                f"β = {fit.beta:.2f}" + (f"; {fit.note}" if fit.note else ""))
    if fit.kind == "separated":
        return f"median between {fit.bounds[0]:g} and {fit.bounds[1]:g} {unit}"
    return fit.note


def _table(header: list[str], rows: list[list[Any]]) -> str:
    def cell(v: Any) -> str:
        if v is None or (isinstance(v, float) and math.isnan(v)):
            return ""
        return f"{v:.4g}" if isinstance(v, float) else str(v).replace("|", "/")

    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell(v) for v in r) + " |" for r in rows]
    return "\n".join(lines)


def report_markdown(info: dict[str, Any], spec: IdaSpec, rows: list[dict[str, Any]],
                    fits: dict[str, dict[str, Fit]]) -> str:
    """The report's Markdown (figures referenced as files)."""
    comps = info["components"]
    statuses: dict[str, int] = {}
    for r in rows:
        statuses[r["status"]] = statuses.get(r["status"], 0) + 1
    walls = [r["wall_time_s"] for r in rows if r["wall_time_s"] is not None]
    lines = [f"# {info['name']}: incremental dynamic analysis and fragility", ""]
    if info.get("description"):
        lines += [info["description"], ""]
    suite = spec.suite if isinstance(spec.suite, str) else f"folder {spec.suite.folder}"
    durations = [c["window_s"][1] - c["window_s"][0] for c in comps]
    window = ("strong motion (Arias 5-95 %, widened by D/4 before and D/2 after)" if spec.window.strong_motion
              else "whole record")
    lines += [
        "## Settings", "",
        f"* Suite: {suite}, {len(comps)} components; window: {window}, {min(durations):.1f}-{max(durations):.1f} s "
        f"of record time, then {spec.window.tail_s:g} s of free vibration.",
        f"* Time scale {spec.time_scale:g} (a record sample at τ plays at {spec.time_scale:g}·τ).",
        f"* Intensity: {info['measure_label']}"
        + (f", T1 = {info['period_s']:.4g} s (isolators' secant stiffness at "
           f"{1e3 * spec.intensity.period_displacement_m:g} mm, {spec.intensity.period_current_A:g} A, or as set)"
           if info["measure"] == "sa" else "")
        + f"; levels {', '.join(f'{v:g}' for v in spec.intensity.levels)} g.",
        f"* Strategies: {', '.join(info['strategies'])}.",
        f"* Runs: {len(rows)} ({', '.join(f'{n} {s}' for s, n in sorted(statuses.items()))}); "
        + (f"wall time per run {min(walls):.2f}-{max(walls):.2f} s (median {float(np.median(walls)):.2f} s); "
           if walls else "")
        + f"study wall time {info.get('wall_time_s', 0):.0f} s on {info['engine']['workers']} workers.",
        "* A run stopped by the scenario's divergence limit (`limits.max_abs`) counts as exceeding every limit "
        "state; failed runs are left out of the stripes.", "",
        "## Verdict per limit state", "",
    ]
    lines += [f"* {verdict(name, spec, fits[name])}" for name in fits]
    lines += ["", "## Fragility fits", "",
              f"Lognormal, maximum likelihood on the stripes; {100 * spec.confidence:g} % interval of the median "
              "from the expected Fisher information.", ""]
    table = []
    for name, by_s in fits.items():
        for s, fit in by_s.items():
            lo, hi = fit.theta_interval() if fit.ok else (None, None)
            table.append([name, s, fit.kind, fit.theta if fit.ok else None, lo, hi, fit.beta if fit.ok else None,
                          " ".join(f"{st.k}/{st.n}" for st in fit.stripes)])
    lines += [_table(["limit state", "strategy", "fit", "median [g]", "low", "high", "β",
                      "exceeded / runs per level"], table), ""]
    lines += ["## Figures", "", "![IDA curves](figures/ida_curves.png)", "",
              "![fragility curves](figures/fragility.png)", ""]
    bad = [r for r in rows if r["status"] not in ("ok", "diverged")]
    if bad:
        lines += ["## Failed runs", "", _table(["run", "status", "reason"],
                                               [[r["key"], r["status"], (r["error"] or "")[:200]] for r in bad]), ""]
    lines += ["## Records", "", _table(["id", "source", "window [s]", "IM at scale 1 [g]"],
                                       [[c["id"], c["source"], f"{c['window_s'][0]:.2f}-{c['window_s'][1]:.2f}",
                                         c["im"]] for c in comps]), ""]
    prov = info.get("provenance", {})
    lines += ["## Provenance", "", f"commit {prov.get('commit')} (uncommitted changes: {prov.get('dirty')}), "
              f"version {prov.get('version')}; started {info.get('started')}, finished {info.get('finished')}"
              + (", interrupted" if info.get("interrupted") else "") + ".", ""]
    return "\n".join(lines)


def _inline(text: str) -> str:
    text = html.escape(text)
    text = re.sub(r"\*\*(.+?)\*\*", r"<b>\1</b>", text)
    return re.sub(r"`(.+?)`", r"<code>\1</code>", text)


def report_html(markdown: str, folder: Path) -> str:
    """Self-contained HTML of the report's Markdown (figures inline)."""
    out = ["<!DOCTYPE html><html><head><meta charset='utf-8'><title>IDA report</title><style>"
           "body{font-family:sans-serif;max-width:1200px;margin:2em auto;line-height:1.4}"
           "table{border-collapse:collapse;font-size:0.85em}td,th{border:1px solid #bbb;padding:2px 6px}"
           "img{max-width:100%}</style></head><body>"]
    in_list = False
    table: list[str] = []

    def flush_table() -> None:
        if table:
            cells = [[c.strip() for c in row.strip("|").split("|")] for row in table if not row.startswith("|---")]
            out.append("<table>" + "".join(
                "<tr>" + "".join(f"<{'th' if k == 0 else 'td'}>{_inline(c)}</{'th' if k == 0 else 'td'}>"
                                 for c in row) + "</tr>" for k, row in enumerate(cells)) + "</table>")
            table.clear()

    for line in markdown.splitlines():
        if line.startswith("|"):
            table.append(line)
            continue
        flush_table()
        if not line.startswith("* ") and in_list:
            out.append("</ul>")
            in_list = False
        if line.startswith("#"):
            level = len(line) - len(line.lstrip("#"))
            out.append(f"<h{level}>{_inline(line.lstrip('#').strip())}</h{level}>")
        elif line.startswith("* "):
            if not in_list:
                out.append("<ul>")
                in_list = True
            out.append(f"<li>{_inline(line[2:])}</li>")
        elif m := re.fullmatch(r"!\[(.*)\]\((.*)\)", line):
            data = base64.b64encode((folder / m.group(2)).read_bytes()).decode()
            out.append(f"<p><img alt='{html.escape(m.group(1))}' src='data:image/png;base64,{data}'></p>")
        elif line.strip():
            out.append(f"<p>{_inline(line)}</p>")
    flush_table()
    if in_list:
        out.append("</ul>")
    out.append("</body></html>")
    return "\n".join(out)


def write_report(folder: Path, info: dict[str, Any], spec: IdaSpec, rows: list[dict[str, Any]],
                 fits: dict[str, dict[str, Fit]]) -> None:
    """Figures, report.md and report.html of a study folder."""
    (folder / "figures").mkdir(exist_ok=True)
    strategies = list(info["strategies"])
    ida_figure(folder / "figures" / "ida_curves.png", info, rows, strategies)
    fragility_figure(folder / "figures" / "fragility.png", info, spec, fits)
    markdown = report_markdown(info, spec, rows, fits)
    write_text(folder / "report.md", markdown)
    write_text(folder / "report.html", report_html(markdown, folder))
