"""The text of an IDA study's report: Markdown and self-contained HTML.

``report.md`` / ``report.html``: the settings, a verdict per limit state, the fits, the
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

from orchestration.ida_study.fragility import Fit, stroke_capacity, stroke_limit_state
from orchestration.ida_study.ida_config import IdaSpec
from orchestration.ida_study.ida_figures import threshold_text
from orchestration.ida_study.ida_metrics import ENDED, collapse_margins
from orchestration.ida_study.ida_records import IdaInfo


def verdict(name: str, spec: IdaSpec, by_strategy: dict[str, Fit], unit: str = "g") -> str:
    """One line: which strategy needs the highest intensity to reach this limit state, and how clearly."""
    ls = spec.limit_states[name]
    head = f"**{ls.label or name}** ({ls.quantity.replace('_', ' ')} > {threshold_text(ls.quantity, ls.threshold)})"
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


def not_counted(strategies: list[str], rows: list[dict[str, Any]]) -> str:
    """What a limit state's stripes leave out: each strategy's complete runs that are numerically invalid
    (:func:`~orchestration.ida_study.ida_metrics.exceeded` counts them for no limit state)."""
    counts = {s: sum(1 for r in rows if r["strategy"] == s and r["status"] == "ok" and r.get("valid") is False)
              for s in strategies}
    if not any(counts.values()):
        return ""
    return (" Not counted, numerically invalid: " + ", ".join(f"{n} run{'s' if n != 1 else ''} of {s}"
                                                             for s, n in counts.items() if n) + ".")


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


def _settings(info: IdaInfo, spec: IdaSpec, rows: list[dict[str, Any]]) -> list[str]:
    """The report's title and settings section."""
    comps = info.components
    statuses: dict[str, int] = {}
    for r in rows:
        statuses[r["status"]] = statuses.get(r["status"], 0) + 1
    walls = [r["wall_time_s"] for r in rows if r["wall_time_s"] is not None]
    lines = [f"# {info.name}: incremental dynamic analysis and fragility", ""]
    if info.description:
        lines += [info.description, ""]
    suite = spec.suite if isinstance(spec.suite, str) else f"folder {spec.suite.folder}"
    durations = [c.window_s[1] - c.window_s[0] for c in comps]
    window = ("strong motion (Arias 5-95 %, widened by D/4 before and D/2 after)" if spec.window.strong_motion
              else "whole record")
    return [
        *lines, "## Settings", "",
        f"* Suite: {suite}, {len(comps)} components; window: {window}, {min(durations):.1f}-{max(durations):.1f} s "
        f"of record time, then {spec.window.tail_s:g} s of free vibration.",
        f"* Time scale {spec.time_scale:g} (a record sample at τ plays at {spec.time_scale:g}·τ).",
        f"* Intensity: {info.measure_label}"
        + (f", T1 = {info.period_s:.4g} s (isolators' secant stiffness at "
           f"{1e3 * spec.intensity.period_displacement_m:g} mm, {spec.intensity.period_current_A:g} A, or as set)"
           if info.measure == "sa" else "")
        + f"; levels {', '.join(f'{v:g}' for v in spec.intensity.levels)} g.",
        f"* Strategies: {', '.join(info.strategies)}.",
        f"* Runs: {len(rows)} ({', '.join(f'{n} {s}' for s, n in sorted(statuses.items()))}); "
        + (f"wall time per run {min(walls):.2f}-{max(walls):.2f} s (median {float(np.median(walls)):.2f} s); "
           if walls else "")
        + f"study wall time {info.wall_time_s or 0:.0f} s on {info.batch['workers']} workers.",
        "* A run stopped by the scenario's divergence limit (`limits.max_abs`), or that collapsed (the OpenSees "
        "unit did not converge), counts as exceeding every limit state; failed runs are left out of the stripes, "
        "and so are complete runs that are numerically invalid (energy books, non-finite values: column `valid`); "
        "a physical exceedance (beyond the device limit) is a result and counts.",
        "",
    ]


def _fits(spec: IdaSpec, fits: dict[str, dict[str, Fit]], rows: list[dict[str, Any]]) -> list[str]:
    """The verdicts and the table of the fits."""
    lines = ["## Verdict per limit state", ""]
    lines += [f"* {verdict(name, spec, fits[name])}{not_counted(list(fits[name]), rows)}" for name in fits]
    lines += ["", "## Fragility fits", "",
              f"Lognormal, maximum likelihood on the stripes; {100 * spec.confidence:g} % interval of the median "
              "from the expected Fisher information.", ""]
    table = []
    for name, by_s in fits.items():
        for s, fit in by_s.items():
            lo, hi = fit.theta_interval() if fit.ok else (None, None)
            table.append([name, s, fit.kind, fit.theta if fit.ok else None, lo, hi, fit.beta if fit.ok else None,
                          " ".join(f"{st.k}/{st.n}" for st in fit.stripes)])
    return [*lines, _table(["limit state", "strategy", "fit", "median [g]", "low", "high", "β",
                            "exceeded / runs per level"], table), ""]


def _stroke(spec: IdaSpec, fits: dict[str, dict[str, Fit]]) -> list[str]:
    """Per strategy, the intensity up to which the device stays within its stroke (fragility.stroke_capacity)."""
    name = stroke_limit_state({k: (v.quantity, v.threshold) for k, v in spec.limit_states.items() if k in fits})
    if name is None:
        return []
    ls = spec.limit_states[name]
    rows = [[s, stroke_capacity(f).text("g", spec.confidence)] for s, f in fits[name].items()]
    return ["## Stroke", "", f"The intensity up to which the device stays within its stroke: the median of the "
            f"fragility '{name}' (isolator beyond {1e3 * ls.threshold:g} mm), with its {100 * spec.confidence:g} % "
            "interval.", "", _table(["strategy", "within its stroke up to"], rows), ""]


def _collapse(spec: IdaSpec, rows: list[dict[str, Any]], fits: dict[str, dict[str, Fit]]) -> list[str]:
    """The collapse fragilities and their margin (FEMA P695's CMR when S_MT is given), if a limit state is one."""
    margins = collapse_margins(fits, spec, rows)
    if not margins:
        return []
    collapsed = sum(1 for r in rows if r["status"] == "collapsed")
    lines = ["## Collapse", "",
             f"A run collapses when a storey's peak drift ratio passes the limit state's threshold, or when the "
             f"OpenSees building unit does not converge ({collapsed} runs here; they count as collapses at their "
             "intensity, not as failures). S_CT is the median of the collapse fragility (maximum likelihood).",
             "", f"* Margin: {margins[0]['margin_kind']}; reference {margins[0]['reference']:.4g} g "
             f"({margins[0]['reference_source']}).", ""]
    table = [[m["limit_state"], m["strategy"], m["fit"], m["s_ct"], m["s_ct_low"], m["s_ct_high"], m["beta"],
              m["margin"]] for m in margins]
    return [*lines, _table(["limit state", "strategy", "fit", "S_CT [g]", "low", "high", "β", "margin"], table), ""]


def _runs_and_provenance(info: IdaInfo, rows: list[dict[str, Any]], spectra: bool = False) -> list[str]:
    """Figures (with the response spectra when ``spectra``), failed runs, the records and the provenance."""
    lines = ["## Figures", "", "![IDA curves](figures/ida_curves.png)", "",
             "![fragility curves](figures/fragility.png)", ""]
    if spectra:
        lines += ["![response spectra](figures/spectra.png)", ""]
    bad = [r for r in rows if r["status"] not in ENDED]
    if bad:
        lines += ["## Failed runs", "", _table(["run", "status", "reason"],
                                               [[r["key"], r["status"], (r["error"] or "")[:200]] for r in bad]), ""]
    invalid = [r for r in rows if r["status"] == "ok" and r.get("valid") is False]
    if invalid:
        lines += ["## Numerically invalid runs (not counted)", "",
                  _table(["run", "reason"], [[r["key"], (r.get("invalid_reasons") or "")[:300]] for r in invalid]), ""]
    lines += ["## Records", "", _table(["id", "source", "window [s]", "IM at scale 1 [g]"],
                                       [[c.id, c.source, f"{c.window_s[0]:.2f}-{c.window_s[1]:.2f}", c.im]
                                        for c in info.components]), ""]
    prov = info.provenance
    return [*lines, "## Provenance", "", f"commit {prov.get('commit')} (uncommitted changes: {prov.get('dirty')}), "
            f"version {prov.get('version')}; started {info.started}, finished {info.finished}"
            + (", interrupted" if info.interrupted else "") + ".", ""]


def report_markdown(info: IdaInfo, spec: IdaSpec, rows: list[dict[str, Any]], fits: dict[str, dict[str, Fit]],
                    spectra: bool = False) -> str:
    """The report's Markdown (figures referenced as files; ``spectra``: the response spectra figure was drawn)."""
    return "\n".join([*_settings(info, spec, rows), *_fits(spec, fits, rows), *_stroke(spec, fits),
                      *_collapse(spec, rows, fits), *_runs_and_provenance(info, rows, spectra)])


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
