"""The case study's report: its sections as blocks, and every output of a study folder, regenerated from data.

:func:`write_outputs` reads the study folder (``study.json``, the numbers each run computed from its every step and
the series its figures draw: :mod:`~orchestration.case_study.run_numbers`),
so ``python orchestration/study.py --report STUDY_DIR`` rebuilds everything at any time: the
numbers from :mod:`~orchestration.case_study.case_metrics`, the figures from
:mod:`~orchestration.case_study.case_figures`, the text rendered by
:mod:`~orchestration.case_study.case_rendering`. Each ``*_blocks`` function here is one
section of the report.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from orchestration.building_studies.run_metrics import INDEX_COLUMNS, INDEX_MEANING, PEAK_COLUMNS
from orchestration.case_study.case_figures import make_figures
from orchestration.case_study.case_metrics import (
    REFERENCE_KEYS,
    Metrics,
    Numbers,
    judged,
    load_metrics,
    write_tables,
)
from orchestration.case_study.case_records import CaseStudyRecord, RecordInfo
from orchestration.case_study.case_rendering import TIE, Block, compare, fmt, pct, to_html, to_markdown
from orchestration.case_study.claims import PINNED_SHARE, check_claims
from orchestration.master.figure_files import PNG_ONLY, FigureFiles
from orchestration.master.runfolder import write_json, write_text

CAPTIONS = {"fig15_current": "SOSM current per record, one column per gain set (cf. paper Fig. 15).",
            "pareto": "Peak top-floor acceleration against mean current over the sosm-fig15 tuning's "
                      "evaluations (colour: share of time at the limit), with the constant currents.",
            "fig16_top_acceleration": "Top-floor absolute acceleration, passive vs SOSM (cf. Fig. 16).",
            "fig17_profiles": "Peak drift per storey and peak acceleration per level (cf. Fig. 17); a line style and "
                              "marker per strategy, and the legend names strategies whose profiles coincide.",
            "sweep": "Objective J against the constant current.",
            "spectra": "Each record's 5 %-damped response spectrum as the runs play it (amplitude and time scale "
                       "applied), with the isolated first-mode period at 0 A and at the current limit (the "
                       "isolators' secant stiffness at 8 mm) from the runs' summary.json."}


def _order(key: str, study: CaseStudyRecord) -> tuple[int, int]:
    """Sort key of 'record[/strategy[/...]]' in the study's record and strategy order."""
    parts = key.split("/")
    records, strategies = list(study.records), study.strategies
    r = records.index(parts[0]) if parts[0] in records else len(records)
    s = strategies.index(parts[1]) if len(parts) > 1 and parts[1] in strategies else len(strategies)
    return r, s


def _controlled(study: CaseStudyRecord) -> list[str]:
    """The strategies that play the paper's controller (entries with ``paper_figures: controlled``)."""
    return study.paper("controlled")


def ground_reading(records: Mapping[str, RecordInfo]) -> str:
    """Which reading of the paper's "scaled down by 0.5" the study's records use."""
    scales = {(info.scale, info.time_scale) for info in records.values()}
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


def header_blocks(folder: Path, study: CaseStudyRecord) -> list[Block]:
    """Title and provenance."""
    prov = study.provenance
    kind = "Controller benchmark" if study.config.get("benchmark") is not None else "Case study"
    return [Block("h", f"{kind}: {study.name}", level=1),
            Block("p", f"Study folder `{folder.name}`, started {study.started or '?'}, finished "
                       f"{study.finished or '?'}; code commit `{prov.get('commit', '?')}`"
                       f"{' (working tree with uncommitted changes)' if prov.get('dirty') else ''}; coupling "
                       f"algorithm {', '.join(sorted(set(prov.get('algorithms', {}).values()))) or '?'}, "
                       f"step {prov.get('step_s', '?')} s. Overrides for every run: "
                       f"`{' '.join(study.run_overrides) or 'none'}`. Command: "
                       f"`{' '.join(prov.get('command', []))}`.")]


def failed_blocks(study: CaseStudyRecord) -> list[Block]:
    """The jobs that failed, if any."""
    failed = [(run.key, run.error) for run in study.runs if not run.ok]
    failed += [(f"{k} (sweep)", v.error) for k, v in study.sweep.items() if not v.ok]
    failed += [(f"{k} (reference)", v.error) for k, v in study.reference.items() if not v.ok]
    if not failed:
        return []
    return [Block("h", "Failed runs", level=2),
            Block("p", "These jobs failed; every other result below is complete."),
            Block("table", header=["run", "reason"],
                  rows=[[key, str(error or "?").replace("|", "/")] for key, error in failed])]


def invalid_blocks(study: CaseStudyRecord) -> list[Block]:
    """The runs that ended but are numerically invalid: listed with their reasons, not ranked or judged."""
    bad = [run for run in sorted([*study.runs, *study.variant_runs], key=lambda run: _order(run.key, study))
           if run.ok and run.valid is False]
    if not bad:
        return []
    return [Block("h", "Numerically invalid runs", level=2),
            Block("p", "These runs ended, but their numbers cannot be trusted (energy balance, coupling energy "
                       "error, non-finite values or step convergence: docs/running.md, \"Validity\"). Their peaks "
                       "are in the tables (peaks.csv, column valid); no ranking, claim or verdict uses them."),
            Block("table", header=["run", "reason"],
                  rows=[[run.key, "; ".join(run.invalid_reasons).replace("|", "/")] for run in bad])]


def gains_blocks(study: CaseStudyRecord) -> list[Block]:
    """The gains of each SOSM strategy, where they come from and how they were tuned."""
    blocks = []
    for strategy, g in study.gain_sets.items():
        if strategy not in study.strategies:
            continue
        gg, proc = g["gains"], g.get("procedure", {})
        obj = proc.get("objective", {})
        extra = ", ".join(f"{k} {v:g}" for k, v in obj.items()
                          if k.startswith("w_") and k not in ("w_acc", "w_drift") and v)
        tuned_on = proc.get("record", "?")
        tuned_on = " and ".join(map(str, tuned_on)) if isinstance(tuned_on, list) else tuned_on
        blocks.append(Block("p", f"**{strategy}** gains (from `{study.gains_files.get(strategy, '?')}`, tuned on "
                                 f"{tuned_on}"
                                 + (f" (first {proc['stop_time_s']:g} s)" if proc.get("stop_time_s") else "")
                                 + (f", objective with {extra}" if extra else "")
                                 + f", not per record): λ = {fmt(gg['lambda'], 4)} "
                                 f"1/s, ρ = {fmt(gg['rho'], 4)} A/s, ζ = {fmt(gg['zeta'], 4)} A·s^½/m^½, ϑ = "
                                 f"{fmt(gg['theta'], 4)} m^½/s^1.5, i_max = {fmt(gg['i_max'])} A"
                                 + (f", release band s_release = {fmt(gg['s_release'], 3)} m/s (a designer's "
                                    "extension, not in the paper: while |s| < s_release the current falls at ρ)"
                                    if gg.get("s_release") else "") + "."))
    return blocks


def claims_blocks(study: CaseStudyRecord, metrics: Metrics) -> tuple[list[Block], list[Block]]:
    """The paper's claims (section 4.3, Fig. 15-17) on our system: the ratios (with the results), and every claim
    checked (a long table, at the end)."""
    records, controlled, off = list(study.records), _controlled(study), study.uncontrolled
    lo, hi = study.config["paper_current_range"]
    rows = []
    for c in controlled:
        for r in records:
            s, o = metrics.get((r, c)), metrics.get((r, off))
            if s is None or o is None:
                rows.append([r, c, "–", "–", "–", "–", "–"])
                continue
            ra, rd = s["acc_3"] / o["acc_3"], s["drift_max_mm"] / o["drift_max_mm"]
            ok_i = s["current_min_A"] >= lo - 1e-12 and s["current_max_A"] <= hi + 1e-12
            rows.append([r, c, fmt(ra), "holds" if ra < 1 - TIE else "does not hold", fmt(rd),
                         "holds" if rd < 1 - TIE else "does not hold",
                         f"{fmt(s['current_min_A'])}-{fmt(s['current_max_A'])} A: {'yes' if ok_i else 'no'}"])
    checks = check_claims(metrics, records, study.strategies, controlled=controlled, uncontrolled=off, tie=TIE,
                          current_range=(lo, hi))
    judged = [c for c in checks if c.holds is not None]
    summary = [
        Block("h", "The paper's claims on our system", level=2),
        Block("p", "The paper (section 4.3, Fig. 16-17) reports that SOSM control reduces the top-floor "
                   "acceleration and the inter-storey drift against the passive structure, with the current "
                   f"varying within {lo:g}-{hi:g} A. Ratios are SOSM / {off} (below 1: SOSM lower). "
                   f"{sum(c.holds for c in judged)} of {len(judged)} checks of every claim hold (the table of "
                   "checks is at the end of the report)."),
        Block("table", header=["record", "strategy", "a_3 ratio", "acceleration claim", "drift ratio",
                               "drift claim", f"current within {lo:g}-{hi:g} A"], rows=rows),
    ]
    detail = [
        Block("h", "Every claim checked", level=2),
        Block("p", "Every claim of section 4.3, per record and strategy (the profile claims are made \"for all "
                   "the cases\"): floor peak accelerations from the base (level 0) to the top, drifts from "
                   f"storey 1 to the top; a {100 * TIE:g} % tie counts as holding. The current claim (Fig. 15) "
                   f"holds when the current stays within {lo:g}-{hi:g} A and sits at neither end for more than "
                   f"{100 * PINNED_SHARE:g} % of the run. "
                   f"{sum(c.holds for c in judged)} of {len(judged)} checks hold."),
        Block("table", header=["claim", "record", "strategy", "quantity", "holds"],
              rows=[[c.claim, c.record, c.strategy, c.quantity,
                     "–" if c.holds is None else ("holds" if c.holds else "FAILS")] for c in checks]),
    ]
    return summary, detail


def gain_set_blocks(study: CaseStudyRecord, metrics: Metrics) -> list[Block]:
    """Both SOSM gain sets against the uncontrolled and the passive strategy (``paper_figures: passive``), and the
    current statistics (Fig. 15)."""
    controlled, passive = _controlled(study), study.paper("passive")
    if not controlled:
        return []
    rows, cur = [], []
    for r in study.records:
        off = metrics.get((r, study.uncontrolled))
        on = metrics.get((r, passive[0])) if passive else None
        for c in controlled:
            m = metrics.get((r, c))
            if m is None:
                continue
            idx = study.indices.get(f"{r}/{c}", {})

            def vs(key: str, other: dict | None, m: dict = m) -> str:
                return pct(m[key], other[key]) if other else "–"

            rows.append([r, c, fmt(m["acc_3"]), vs("acc_3", off), vs("acc_3", on), fmt(m["drift_max_mm"]),
                         vs("drift_max_mm", off), vs("drift_max_mm", on), fmt(m["x_base_mm"]),
                         *(fmt(idx.get(k)) for k in ("J1", "J2", "J5", "J8"))])
            cur.append([r, c, fmt(m["current_min_A"]), fmt(m["current_max_A"]), fmt(m["current_mean_A"]),
                        fmt(m["current_limit_A"]), f"{100 * m['current_share_at_limit']:.1f} %",
                        f"{100 * m['current_share_at_zero']:.1f} %",
                        f"{fmt(m['time_current_outside_paper_range_s'])} s"])
    hi = study.config["paper_current_range"][1]
    return [
        Block("h", "SOSM gain sets against the passive settings", level=2),
        Block("p", "`sosm`: gains tuned for peak response only (i_max 3 A). `sosm-fig15`: the second gain set, "
                   "with a release band (not in the paper) and tuned with terms on the shares of time at its "
                   "2.5 A limit and at 0 A so that the current varies as in the paper's Fig. 15 "
                   "(docs/case_study.md). Percentages: this strategy's peak against "
                   f"{study.uncontrolled} ('vs off') and {passive[0] if passive else 'no passive strategy'} "
                   "('vs on'); negative is lower. Indices as below."),
        Block("table", header=["record", "strategy", "a_3 m/s²", "vs off", "vs on", "max drift mm", "vs off",
                               "vs on", "x_base mm", "J1", "J2", "J5", "J8"], rows=rows),
        Block("h", "Current statistics (Fig. 15)", level=3),
        Block("p", f"Over the whole run. 'at limit': share of the time at the strategy's own current limit; "
                   f"'at 0 A': share at 0 A; 'above {hi:g} A': time above the paper's range."),
        Block("table", header=["record", "strategy", "min A", "max A", "mean A", "limit A", "at limit", "at 0 A",
                               f"above {hi:g} A"], rows=cur),
    ]


def sosm_condition_blocks(study: CaseStudyRecord, numbers: Numbers) -> list[Block]:
    """Eq. (36)'s bounds tau, v_m, v_M along each SOSM run and the gain conditions after Eq. (39), as each run
    computed them from its every step."""
    rows = []
    for r in study.records:
        for strategy in study.strategies:
            c = (numbers.get((r, strategy)) or {}).get("sosm_conditions")
            if not c:
                continue
            rows.append([r, strategy, fmt(c["tau"]), fmt(c["v_m"]), fmt(c["v_M"]), fmt(c["reaching_margin"]),
                         "holds" if c["reaching_holds"] else "FAILS", f"{100 * c['share_pointwise']:.0f} %",
                         f"{100 * c['share_local']:.1f} %",
                         fmt(c["zeta_theta_over_rho"]), "holds" if c["zeta_theta_holds"] else "FAILS"])
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


def _comparisons(r: str, c: str, study: CaseStudyRecord, metrics: Metrics) -> list[str]:
    """SOSM strategy ``c`` against every other strategy of record ``r``, then its current."""
    sosm = metrics[(r, c)]
    items = []
    for s in study.strategies:
        if s in _controlled(study) or (r, s) not in metrics:
            continue
        o = metrics[(r, s)]
        label = s + (f" ({study.best_current.get(r, math.nan):g} A)" if study.flags(s).get("needs_sweep") else "")
        items.append(
            f"**{c}** vs **{label}**: {compare(sosm['acc_3'], o['acc_3'])} it on peak top-floor acceleration "
            f"({fmt(sosm['acc_3'])} vs {fmt(o['acc_3'])} m/s², {pct(sosm['acc_3'], o['acc_3'])}) and "
            f"{compare(sosm['drift_max_mm'], o['drift_max_mm'])} it on peak drift "
            f"({fmt(sosm['drift_max_mm'])} vs {fmt(o['drift_max_mm'])} mm, "
            f"{pct(sosm['drift_max_mm'], o['drift_max_mm'])}); "
            f"base displacement {fmt(sosm['x_base_mm'])} vs {fmt(o['x_base_mm'])} mm.")
    lo, hi = study.config["paper_current_range"]
    inside = sosm["current_min_A"] >= lo - 1e-12 and sosm["current_max_A"] <= hi + 1e-12
    items.append(f"**{c}** current: {fmt(sosm['current_min_A'])} to {fmt(sosm['current_max_A'])} A, mean "
                 f"{fmt(sosm['current_mean_A'])} A, at its {fmt(sosm['current_limit_A'])} A limit "
                 f"{100 * sosm['current_share_at_limit']:.0f} % of the time: "
                 f"{'within' if inside else 'NOT within'} the paper's "
                 f"{lo:g}-{hi:g} A" + ("." if inside else f" (above {hi:g} A for "
                                        f"{fmt(sosm['time_current_outside_paper_range_s'])} s of "
                                        f"{fmt(sosm['duration_s'])} s)."))
    return items


def _extrapolations(r: str, study: CaseStudyRecord, metrics: Metrics) -> list[str]:
    """The strategies of record ``r`` whose base left the identified range or the device limit."""
    cfg, items = study.config, []
    for s in study.strategies:
        m = metrics.get((r, s))
        if m is None:
            continue
        if m["time_beyond_15mm_s"] > 0:
            items.append(f"**{s}**: base displacement {fmt(m['x_base_mm'])} mm leaves the isolator's "
                         f"{1e3 * cfg['x_limit']:g} mm limit ({fmt(m['time_beyond_15mm_s'])} s beyond) and the "
                         f"±{1e3 * cfg['x_identified']:g} mm identified range ({fmt(m['time_beyond_8mm_s'])} s): "
                         "the isolator model is extrapolated.")
        elif m["time_beyond_8mm_s"] > 0:
            items.append(f"**{s}**: base displacement {fmt(m['x_base_mm'])} mm leaves the ±"
                         f"{1e3 * cfg['x_identified']:g} mm identified range ({fmt(m['time_beyond_8mm_s'])} s "
                         f"beyond; model extrapolated), within the {1e3 * cfg['x_limit']:g} mm limit.")
    return items


def verdict_blocks(study: CaseStudyRecord, metrics: Metrics) -> list[Block]:
    """A verdict per record: each SOSM strategy against the others, its current, extrapolations."""
    blocks = [Block("h", "Verdict per record", level=2),
              Block("p", f"Lower is better; a difference within {100 * TIE:g} % is called a tie. Peak drift is the "
                         "largest over the three storeys.")]
    for r in study.records:
        name = study.records[r].name
        blocks.append(Block("h", f"{r} ({name})" if name else r, level=3))  # the id, and the record's name
        if not _controlled(study):
            blocks.append(Block("p", "SOSM is not part of this study: no verdict."))
            continue
        items = []
        for c in _controlled(study):
            if (r, c) in metrics:
                items += _comparisons(r, c, study, metrics)
            else:
                items.append(f"No **{c}** result for this record (see failed runs): no verdict.")
        blocks.append(Block("ul", items=items + _extrapolations(r, study, metrics)))
    return blocks


def tables_blocks(study: CaseStudyRecord, metrics: Metrics) -> list[Block]:
    """The peaks and the evaluation indices of every run."""
    records, strategies = list(study.records), study.strategies
    hdr = ["record", "strategy", "x_base mm", "drift_1 mm", "drift_2 mm", "drift_3 mm", "acc_0", "acc_1", "acc_2",
           "acc_3 m/s²", "base shear N", "i max A", "i mean A"]
    return [
        Block("h", "Peaks", level=2),
        Block("p", "x_base: base (isolator) displacement; drift_j: storey j; acc_j: absolute acceleration of "
                   "level j (0 = base); base shear = |Σ m_j a_j| over all levels (= |F| with k_0 = c_0 = 0). "
                   "Also in `peaks.csv`."),
        Block("table", header=hdr, rows=[[r, s, *(fmt(metrics[(r, s)][c]) for c in PEAK_COLUMNS[2:])]
                                        for r in records for s in strategies if (r, s) in metrics]),
        Block("h", "Evaluation indices (Narasimhan et al. 2006)", level=2),
        Block("p", "Controlled / uncontrolled peak (or RMS), passive-off (0 A) as the uncontrolled case: "
                   + "; ".join(f"{k}: {v}" for k, v in INDEX_MEANING.items()) + ". Also in `indices.csv`."),
        Block("table", header=list(INDEX_COLUMNS),
              rows=[[r, s, *(fmt(study.indices[f"{r}/{s}"][c]) for c in INDEX_COLUMNS[2:])]
                    for r in records for s in strategies if f"{r}/{s}" in study.indices]),
    ]


def reference_blocks(study: CaseStudyRecord, metrics: Metrics) -> list[Block]:
    """The passive runs against the monolithic Radau reference (the coupling error)."""
    cfg = study.config
    not_computed = study.provenance.get("references_not_computed") or []
    note = [Block("p", f"Radau references of {len(not_computed)} passive run(s) not computed ("
                       + ", ".join(k.removesuffix("/reference") for k in not_computed)
                       + "): none cached for these inputs and this code. "
                       "`python orchestration/study.py --verify ...` computes them (and caches them for later "
                       "studies); `--resume DIR --verify` adds them to this folder.")] if not_computed else []
    if not study.reference:
        return [Block("h", "Passive runs against the monolithic reference", level=2), *note] if note else []
    rows = []
    for key, v in sorted(study.reference.items(), key=lambda kv: _order(kv[0], study)):
        r, s = key.split("/")
        m = metrics.get((r, s))
        if not v.ok or m is None:
            rows.append([r, s, "–", "–", "–", "–", "failed"])
            continue
        errs = {k: m[k] / v.value[k] - 1 for k in REFERENCE_KEYS if v.value.get(k)}
        worst = max(errs, key=lambda k: abs(errs[k]))
        rows.append([r, s, fmt(m["x_base_mm"]) + " / " + fmt(v.value["x_base_mm"]),
                     fmt(m["acc_3"]) + " / " + fmt(v.value["acc_3"]), f"{worst}: {100 * errs[worst]:+.1f} %",
                     f"{100 * np.mean([abs(e) for e in errs.values()]):.1f} %",
                     "within" if abs(errs[worst]) <= cfg["reference"]["tolerance"] else "OUTSIDE"])
    return [
        Block("h", "Passive runs against the monolithic reference", level=2),
        Block("p", "Radau (rtol " + fmt(cfg["reference"]["rtol"]) + ") of the same equations at the same "
                   "constant current (components.physics.monolithic.simulate_radau). The difference is the "
                   "coupling error of the co-simulation; accepted up to "
                   f"{100 * cfg['reference']['tolerance']:g} % "
                   "(README, Coupling error). Full table in `reference.csv`."),
        Block("table", header=["record", "strategy", "x_base mm co-sim / Radau", "acc_3 co-sim / Radau",
                               "largest error", "mean |error|", "tolerance"], rows=rows),
        *note,
    ]


def sweep_blocks(study: CaseStudyRecord) -> list[Block]:
    """The best constant current per record."""
    if not study.sweep:
        return []
    cfg = study.config
    o = cfg["objective"]
    return [
        Block("h", "Best constant current", level=2),
        Block("p", f"Swept {cfg['sweep_currents'][0]:g}-{cfg['sweep_currents'][-1]:g} A (the in-process "
                   "model on the paper's system, a co-simulation per current on any other plant); "
                   f"objective J = {o['w_acc']:g}·a_3/a_3,off + {o['w_drift']:g}·d/d_off + "
                   f"{o['penalty']:g}·max(0, x_0/{1e3 * o['x_limit']:g} mm − 1). The best current is chosen "
                   "per record in hindsight: an upper bound on what a passive setting can do."),
        Block("table", header=["record", "best current A", "J best", "J at i_max"],
              rows=[[r, fmt(sw.best_current_A), fmt(sw.best_J), fmt(sw.rows[-1]["J"]) if sw.rows else "–"]
                    for r, sw in sorted(study.sweep.items(), key=lambda kv: _order(kv[0], study))]),
    ]


def warning_blocks(study: CaseStudyRecord, metrics: Metrics) -> list[Block]:
    """The runs whose base left the range the isolator model was identified on."""
    x_id = 1e3 * study.config["x_identified"]
    runs = sorted(study.runs, key=lambda run: _order(run.key, study))
    warn = [f"{run.record} / {run.strategy}: {fmt(m['x_base_mm'])} mm, {fmt(m['time_beyond_8mm_s'])} s beyond "
            f"±{x_id:g} mm" for run in runs
            if run.ok and (m := metrics.get((run.record, run.strategy))) is not None and m["time_beyond_8mm_s"] > 0]
    if not warn:
        return []
    return [Block("h", "Warning: isolator model extrapolated", level=2),
            Block("p", f"The isolator law was identified on ±{x_id:g} mm; these runs go beyond it, where the sinh "
                       "term is an extrapolation:"),
            Block("ul", items=warn)]


def figure_blocks(folder: Path, figures: dict[str, Path], study: CaseStudyRecord) -> list[Block]:
    """Every figure with its caption (a hysteresis figure's caption names its record as the scenario does)."""
    from orchestration.case_study.case_figures import named

    def caption(name: str) -> str:
        record = name.removeprefix("hysteresis_")
        if name not in CAPTIONS and record in study.records:
            return f"Isolator force against base displacement, one panel per strategy: {named(study, record)}."
        return CAPTIONS.get(name, name)

    return [Block("h", "Figures", level=2)] + [Block("img", text=str(path.relative_to(folder)), items=[caption(name)])
                                               for name, path in figures.items()]


def build_report(folder: Path, study: CaseStudyRecord, metrics: Metrics, figures: dict[str, Path],
                 numbers: Numbers | None = None) -> list[Block]:
    """The report's blocks: provenance and failures, verdicts and tables (the results), the paper's claims, the
    gain sets, references, figures, then the long table of every claim checked."""
    valid = judged(study, metrics)  # ranked and judged: the numerically valid runs only
    claims, every_claim = claims_blocks(study, valid)
    return [*header_blocks(folder, study), *failed_blocks(study), *invalid_blocks(study),
            Block("p", ground_reading(study.records)),
            *gains_blocks(study), *verdict_blocks(study, valid), *tables_blocks(study, metrics), *claims,
            *gain_set_blocks(study, valid), *sosm_condition_blocks(study, numbers or {}),
            *reference_blocks(study, metrics), *sweep_blocks(study), *warning_blocks(study, metrics),
            *figure_blocks(folder, figures, study), *every_claim]


def write_outputs(folder: Path, study: CaseStudyRecord, files: FigureFiles = PNG_ONLY) -> CaseStudyRecord:
    """(Re)write peaks.csv, indices.csv, sweep.csv, reference.csv, figures (PNG, and each of ``files.formats``),
    report.md/html (which embed the PNGs) and study.json."""
    metrics, numbers, series = load_metrics(folder, study)
    write_tables(folder, study, metrics)
    figures = make_figures(folder, study, metrics, series, files)
    blocks = build_report(folder, study, metrics, figures, numbers)
    if study.config.get("benchmark") is not None:  # a controller benchmark: criteria.csv, its sections after the header
        from orchestration.case_study.benchmark_report import benchmark_outputs

        blocks = [*blocks[:2], *benchmark_outputs(folder, study, numbers, files), *blocks[2:]]
    write_text(folder / "report.md", to_markdown(blocks))
    write_text(folder / "report.html", to_html(blocks, folder))
    study.metrics = {f"{r}/{s}": m for (r, s), m in metrics.items()}
    write_json(folder / "study.json", study.to_json())
    return study


def read_study(folder: Path) -> CaseStudyRecord:
    """The study.json of a study folder."""
    return CaseStudyRecord.from_json(json.loads((folder / "study.json").read_text()))
