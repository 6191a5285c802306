"""The controller benchmark's outputs (a study with a ``benchmark`` section): criteria.csv and report sections.

``criteria.csv``: record, strategy, J1...J9 (over the baseline, passive-off by default; J6 over passive-on's),
mean_current_A, joule_A2s, switching_rate_A_s; ``criteria_<second baseline>.csv``: the same normalised by the second
baseline (passive-on: passive-off drives the isolator beyond its identified ±8 mm range, so ratios
to it flatter every controller). Criteria: :mod:`orchestration.case_study.benchmark_criteria`
(Narasimhan et al. 2006). The report gets a ranking per record, a Pareto plot of J3 against J5 with
the best constant current marked, and every strategy against the best constant current in words.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any

import numpy as np

from mre_common.atomic_files import atomic_write_text
from orchestration.case_study.benchmark_criteria import (
    CRITERIA,
    EFFORT,
    NAMES,
    j6_reference,
    normalised,
)
from orchestration.case_study.case_figures import save
from orchestration.case_study.case_metrics import pareto_front
from orchestration.case_study.case_records import CaseStudyRecord
from orchestration.case_study.case_rendering import TIE, Block, fmt
from orchestration.master.figure_files import PNG_ONLY, FigureFiles

# the ranking's mean: every lower-is-better criterion but J6, shown apart (it measures the control a strategy uses,
# not the response: passive-off's is 0 and would win it)
RANKED = ("J1", "J2", "J3", "J4", "J5", "J7", "J8")
EXTRA = ("J9_raw", "energy_error")  # J9's raw share E_d / E_in; the coupling's energy error, a fraction of E_in
Rows = list[dict[str, Any]]


def _entries(study: CaseStudyRecord) -> dict[tuple[str, str], Any]:
    return {(e.record, e.strategy): e for e in study.runs}


def raw_table(study: CaseStudyRecord, numbers: dict[tuple[str, str], Any]) -> dict[tuple[str, str], dict[str, float]]:
    """(record, strategy) -> raw criteria and control effort of every successful run, as the run computed them from
    its every step (J9 from its energy section), with J9's raw share ``J9_raw`` and the coupling energy error
    ``energy_error``, a fraction of the input."""
    out = {}
    entries = _entries(study)
    for (r, s), found in numbers.items():
        entry = entries.get((r, s))
        energy = entry.energy if entry is not None else None
        values = dict(found["criteria"])
        values["J9_raw"] = values["J9"]
        error = (energy or {}).get("max_coupling_error_fraction")
        values["energy_error"] = float(error) if isinstance(error, int | float) else math.nan
        out[(r, s)] = values
    return out


def criteria_rows(study: CaseStudyRecord, raw: dict[tuple[str, str], dict[str, float]], baseline: str) -> Rows:
    """Rows of criteria.csv: J1...J9 over ``baseline``'s values on the same record, the control effort, J9's raw
    share and the coupling energy error, and the run's own numerical validity (an invalid baseline is said in the
    ranking: its values weigh the criteria there, while the verdicts against the best constant current do not
    depend on it)."""
    rows = []
    entries = _entries(study)
    for r in study.records:
        base, j6_base = raw.get((r, baseline), {}), raw.get((r, j6_reference(study.config)), {})
        for s in study.strategies:
            if (r, s) in raw:
                v = raw[(r, s)]
                entry = entries.get((r, s))
                valid = None if entry is None else entry.valid
                reasons = list(entry.invalid_reasons) if entry is not None else []
                rows.append({"record": r, "strategy": s, **normalised(v, base, j6_base),
                             **{k: v[k] for k in EFFORT}, **{k: v[k] for k in EXTRA}, "valid": valid,
                             "invalid_reasons": "; ".join(reasons) if valid is not None else None})
    return rows


def csv_text(rows: Rows) -> str:
    """CSV of the rows (columns record, strategy, J1...J9, effort, J9_raw, energy_error, valid, invalid_reasons)."""
    buf = io.StringIO()
    columns = ["record", "strategy", *CRITERIA, *EFFORT, *EXTRA, "valid", "invalid_reasons"]
    if any("step_change" in row for row in rows):
        columns.append("step_change")
    w = csv.DictWriter(buf, columns, lineterminator="\n", extrasaction="ignore")
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue()


def ranked_rows(rows: Rows) -> Rows:
    """The rows a ranking or a verdict may use: every row not known to be numerically invalid."""
    return [row for row in rows if row.get("valid") is not False]


def ranking(rows: Rows, record: str) -> list[tuple[str, float]]:
    """Valid strategies on a record by the mean of J1...J5, J7, J8 (lower is better; NaN last); invalid rows are
    left out."""
    scores = [(row["strategy"], float(np.mean([row[k] for k in RANKED]))) for row in ranked_rows(rows)
              if row["record"] == record]
    return sorted(scores, key=lambda x: (not math.isfinite(x[1]), x[1]))


def verdicts(rows: Rows, best: str, records: list[str]) -> list[str]:
    """Every strategy against ``best`` in J5 (and J3), in words; the baseline cancels in these ratios."""
    by = {(row["record"], row["strategy"]): row for row in ranked_rows(rows)}
    out = []
    for s in dict.fromkeys(row["strategy"] for row in rows):
        if s == best:
            continue
        d5 = {r: by[(r, s)]["J5"] / by[(r, best)]["J5"] - 1 for r in records
              if (r, s) in by and (r, best) in by and math.isfinite(by[(r, s)]["J5"] / by[(r, best)]["J5"])}
        invalid = [r for r in records if (r, s) not in by and any(row["record"] == r and row["strategy"] == s
                                                                   for row in rows)]
        if not d5:
            out.append(f"**{s}**: no record with both runs valid" + (f" (invalid on {', '.join(invalid)})"
                                                                     if invalid else ""))
            continue
        tie = {r: tie_margin(by[(r, s)], by[(r, best)], "J5") for r in d5}
        beats = sorted(-100 * d for r, d in d5.items() if d < -tie[r])
        loses = sorted(100 * d for r, d in d5.items() if d > tie[r])
        text = f"**{s}** beats the best constant current on {len(beats)} of {len(d5)} records"
        text += f", by {_span(beats)} in J5" if beats else " in J5"
        if loses:
            text += f"; loses on {len(loses)}, by {_span(loses)}"
        ties = len(d5) - len(beats) - len(loses)
        if ties:
            widest = max(tie.values())
            text += f"; ties (within {100 * TIE:g} %" + (f", or the step's change, up to {100 * widest:.2g} %"
                                                       if widest > TIE else "") + f") on {ties}"
        d3 = [100 * (by[(r, s)]["J3"] / by[(r, best)]["J3"] - 1) for r in d5]
        text += f". Base displacement J3 against it: {_signed(min(d3))} to {_signed(max(d3))} %."
        if invalid:
            text += f" Not judged on {', '.join(invalid)}: numerically invalid."
        out.append(text)
    return out


def step_criteria_changes(folder: Path, study: CaseStudyRecord, raw: dict[tuple[str, str], dict[str, float]]
                          ) -> dict[tuple[str, str], dict[str, float]]:
    """``--verify-step``: (record, strategy) -> each raw criterion's relative change in the run at half the plant's
    step (the same for every baseline: the baseline's own change shows in its row)."""
    from orchestration.case_study.case_metrics import run_numbers_of

    out = {}
    for half in study.half_step_runs:
        key = (half.record, half.strategy)
        if not half.ok or key not in raw:
            continue
        found = run_numbers_of(folder, study, half)
        if found is None:
            continue
        fine = found["criteria"]
        out[key] = {k: (fine[k] / raw[key][k] - 1 if raw[key][k] else math.nan) for k in CRITERIA}
        entry = next((e for e in study.runs if (e.record, e.strategy) == key), None)
        if entry is not None:
            entry.step_change = out[key]
    return out


def with_step_changes(rows: Rows, changes: dict[tuple[str, str], dict[str, float]]) -> Rows:
    """Rows with each run's criteria changes at half the step (``step_changes``) and the largest over the ranked
    criteria (``step_change``, a column of criteria.csv), where the step was verified."""
    if not changes:
        return rows
    for row in rows:
        change = changes.get((row["record"], row["strategy"]))
        finite = [abs(change[k]) for k in RANKED if change is not None and math.isfinite(change[k])]
        row["step_changes"] = change or {}
        row["step_change"] = max(finite) if finite else math.nan
    return rows


def tie_margin(a: dict[str, Any], b: dict[str, Any], criterion: str) -> float:
    """The relative difference below which two rows tie on ``criterion``: the 1 % tie, or, where the step was
    verified (``--verify-step``), the sum of both rows' changes of it with the plant's step halved, if larger."""
    changes = [abs(row.get("step_changes", {}).get(criterion, 0.0)) for row in (a, b)]
    step = sum(c for c in changes if math.isfinite(c))
    return max(TIE, step)


def _signed(value: float) -> str:
    """A change in per cent, signed and whole (``+3``, ``-26``; ``0``, never ``-0``)."""
    whole = round(value)
    return f"{whole:+d}" if whole else "0"


def _span(values: list[float]) -> str:
    return f"{values[0]:.1f} %" if len(values) == 1 or abs(values[-1] - values[0]) < 0.05 else \
        f"{values[0]:.1f}–{values[-1]:.1f} %"


def pareto_figure(rows: Rows, records: list[str], best: str, baseline: str,
                  styles: dict[str, Any] | None = None) -> Any:
    """J3 against J5 per record, every strategy a point with its own marker (the baseline, at (1, 1), left out),
    the best constant current a hollow star, the non-dominated strategies joined by a line; the legend says which
    strategies' points coincide (within 0.5 % of each axis' span). ``styles``: each strategy's entry ``style``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from orchestration.figure_axes import coincidence_note, coincident, legend_below, strategy_style

    n = len(records)
    cols = min(n, 2)
    fig, axes = plt.subplots((n + cols - 1) // cols, cols, figsize=(6 * cols, 4.5 * ((n + cols - 1) // cols)),
                             squeeze=False)
    names = [s for s in dict.fromkeys(row["strategy"] for row in rows) if s != baseline]
    where: dict[str, list[str]] = {}
    for ax, r in zip(axes.flat, records, strict=False):
        points: dict[str, tuple[float, float]] = {}
        for s in names:
            row = next((x for x in rows if x["record"] == r and x["strategy"] == s), None)
            if row is None or not (math.isfinite(row["J3"]) and math.isfinite(row["J5"])):
                continue
            is_best = s == best
            points[s] = (row["J3"], row["J5"])
            look = strategy_style(s, names, (styles or {}).get(s))
            ax.scatter(row["J3"], row["J5"], s=260 if is_best else 50, marker="*" if is_best else look["marker"],
                       facecolors="none" if is_best else look["color"], edgecolors="k" if is_best else "face",
                       zorder=4 if is_best else 3, label=s)
        front = sorted(list(points.values())[k] for k in pareto_front(list(points.values())))
        if len(front) > 1:
            ax.plot(*zip(*front, strict=True), color="0.6", lw=1, zorder=1)
        ax.set_title(r)
        ax.set_xlabel("J3: peak base displacement / the baseline's")
        ax.set_ylabel("J5: peak floor acceleration / the baseline's")
        ax.grid(alpha=0.3)
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        for pair in coincident({s: [p] for s, p in points.items()}, (x1 - x0, y1 - y0)):
            where.setdefault(coincidence_note(*pair), []).append(r)
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    notes = [f"{note} ({'every record' if on == records else ', '.join(on)})" for note, on in where.items()]
    fig.tight_layout()
    legend_below(fig, notes, ncol=4)  # under the panels: inside one it hid points
    return fig


def pareto_plot(rows: Rows, records: list[str], best: str, baseline: str, path: Path,
                files: FigureFiles = PNG_ONLY, styles: dict[str, Any] | None = None) -> Path:
    """:func:`pareto_figure` written as ``path`` (PNG, and each of ``files.formats`` beside it); the PNG."""
    path.parent.mkdir(parents=True, exist_ok=True)
    return save(pareto_figure(rows, records, best, baseline, styles), path, files)


def _table(rows: Rows, title: str) -> list[Block]:
    header = ["record", "strategy", *CRITERIA, "ī [A]", "∫i² [A²s]", "mean |di/dt| [A/s]", "energy error",
              "valid"]
    if any("step_change" in row for row in rows):
        header.append("step change")
    body = [[row["record"], row["strategy"], *(fmt(row[k]) for k in CRITERIA), *(fmt(row[k]) for k in EFFORT),
             f"{100 * row['energy_error']:.2g} %" if math.isfinite(row["energy_error"]) else "not checked",
             {True: "yes", False: "NO", None: "?"}[row.get("valid")],
             *([f"{100 * row['step_change']:.2g} %" if math.isfinite(row.get("step_change", math.nan)) else "–"]
               if "step change" in header else [])]
            for row in rows]
    return [Block("p", title), Block("table", header=header, rows=body)]


def benchmark_outputs(folder: Path, study: CaseStudyRecord, numbers: dict[tuple[str, str], Any],
                      files: FigureFiles = PNG_ONLY) -> list[Block]:
    """Write criteria.csv (and the second baseline's), the Pareto figure (PNG, and ``files.formats``); the report's
    benchmark blocks."""
    spec = study.config.get("benchmark") or {}
    baseline, second = spec.get("baseline", "passive-off"), spec.get("second_baseline", "passive-on")
    best = spec.get("best_constant", "best-constant")
    records = list(study.records)
    raw = raw_table(study, numbers)
    changes = step_criteria_changes(folder, study, raw)
    rows = with_step_changes(criteria_rows(study, raw, baseline), changes)
    atomic_write_text(folder / "criteria.csv", csv_text(rows))
    blocks = [Block("h", "Controller benchmark (Narasimhan et al. 2006 criteria)"),
              Block("p", "J1…J9 are each strategy's value over the baseline's on the same record, J6 (the peak "
                         f"force the current controls, F − F at 0 A) over {j6_reference(study.config)}'s (lower is "
                         "better; "
                         "J9, the share of the ground's input energy the isolators take, higher means more of it; "
                         "from each run's energy balance, summary.json `energy`: J9_raw is the share itself, "
                         "energy_error the coupling's energy error as a fraction of the input energy). "
                         + "; ".join(f"{k}: {v}" for k, v in NAMES.items()) + ". Definitions, in SI: "
                         "`orchestration/case_study/benchmark_criteria.py`, docs/controllers.md."),
              Block("h", "Ranking per record", level=3),
              Block("p", f"By the mean of J1…J5, J7 and J8 over **{baseline}**, lower first (the mean weighs each "
                         "criterion by the baseline's value, so another baseline can reorder close strategies; J6, "
                         "the control force used, is shown apart: passive-off's is zero).")]
    for r in records:
        ranked = ranking(rows, r)
        left_out = [row for row in rows if row["record"] == r and row.get("valid") is False]
        text = f"**{r}**: " + (", ".join(f"{k + 1}. {s} ({fmt(v)})" for k, (s, v) in enumerate(ranked))
                               or "no valid run")
        if left_out:
            text += "; not ranked (numerically invalid): " + ", ".join(row["strategy"] for row in left_out)
            if any(row["strategy"] == baseline for row in left_out):
                text += (f" (the baseline {baseline} among them: its values weigh the criteria of this mean; "
                         f"criteria_{second}.csv gives the ratios to {second})" if second else "")
        blocks.append(Block("p", text + "."))
    fig = pareto_plot(ranked_rows(rows), records, best, baseline, folder / "figures" / "benchmark_pareto_J3_J5.png",
                      files, {s: study.flags(s).get("style") for s in study.strategies})
    blocks.append(Block("img", str(fig.relative_to(folder)), items=[
        f"J3 (peak base displacement) against J5 (peak floor acceleration), both over {baseline} (which sits "
        f"at (1, 1), not drawn); the hollow star is the best constant current ({best}); the grey line joins the "
        "non-dominated strategies; the legend names strategies whose points coincide; numerically invalid runs are "
        "not drawn"]))
    blocks.append(Block("h", "Against the best constant current", level=3))
    blocks.append(Block("p", f"J5 of each strategy over {best}'s on the same record (this ratio does not depend on "
                             "the baseline); a difference within 1 % is a tie, and so is one within the two runs' "
                             "changes of J5 when the plant's step is halved (study.py --verify-step, column "
                             "step_change). Numerically invalid runs are neither ranked nor judged (column valid)."))
    blocks.append(Block("ul", items=verdicts(rows, best, records)))
    blocks.append(Block("h", "Criteria tables", level=3))
    blocks += _table(rows, f"Baseline **{baseline}** (criteria.csv).")
    if second and any(s == second for _, s in raw):
        rows2 = with_step_changes(criteria_rows(study, raw, second), changes)
        atomic_write_text(folder / f"criteria_{second}.csv", csv_text(rows2))
        blocks += _table(rows2, f"Baseline **{second}** (criteria_{second}.csv): {baseline} drives the isolator "
                                "beyond its identified range on some records, which flatters ratios to it.")
    if study.config.get("robustness"):  # variants of the plant and sensors: robustness.csv and its section
        from orchestration.case_study.robustness_report import robustness_blocks

        blocks += robustness_blocks(folder, study, raw, baseline)
    return blocks
