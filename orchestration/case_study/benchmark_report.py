"""The controller benchmark's outputs (a study with a ``benchmark`` section): criteria.csv and report sections.

``criteria.csv``: record, strategy, J1...J9 (over the baseline, passive-off by default), mean_current_A,
joule_A2s, switching_rate_A_s; ``criteria_<second baseline>.csv``: the same normalised by the second
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
from orchestration.case_study.benchmark_criteria import CRITERIA, EFFORT, NAMES, effort, normalised, raw_criteria
from orchestration.case_study.case_metrics import pareto_front
from orchestration.case_study.case_records import CaseStudyRecord
from orchestration.case_study.case_rendering import TIE, Block, fmt

RANKED = ("J1", "J2", "J3", "J4", "J5", "J6", "J7", "J8")  # the ranking's mean: every lower-is-better criterion
Rows = list[dict[str, Any]]


def raw_table(study: CaseStudyRecord, series: dict[tuple[str, str], Any]) -> dict[tuple[str, str], dict[str, float]]:
    """(record, strategy) -> raw criteria and control effort of every successful run."""
    out = {}
    for (r, s), ser in series.items():
        values = raw_criteria(ser, study.records[r].masses_kg)
        values.update(effort(ser["time"], ser["controller.i"]))
        out[(r, s)] = values
    return out


def criteria_rows(study: CaseStudyRecord, raw: dict[tuple[str, str], dict[str, float]], baseline: str) -> Rows:
    """Rows of criteria.csv: J1...J9 over ``baseline``'s values on the same record, and the control effort."""
    rows = []
    for r in study.records:
        base = raw.get((r, baseline), {})
        for s in study.strategies:
            if (r, s) in raw:
                v = raw[(r, s)]
                rows.append({"record": r, "strategy": s, **normalised(v, base), **{k: v[k] for k in EFFORT}})
    return rows


def csv_text(rows: Rows) -> str:
    """CSV of the rows (columns record, strategy, J1...J9, effort)."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, ["record", "strategy", *CRITERIA, *EFFORT], lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue()


def ranking(rows: Rows, record: str) -> list[tuple[str, float]]:
    """Strategies on a record by the mean of J1...J8 (lower is better; NaN last)."""
    scores = [(row["strategy"], float(np.mean([row[k] for k in RANKED]))) for row in rows if row["record"] == record]
    return sorted(scores, key=lambda x: (not math.isfinite(x[1]), x[1]))


def verdicts(rows: Rows, best: str, records: list[str]) -> list[str]:
    """Every strategy against ``best`` in J5 (and J3), in words; the baseline cancels in these ratios."""
    by = {(row["record"], row["strategy"]): row for row in rows}
    out = []
    for s in dict.fromkeys(row["strategy"] for row in rows):
        if s == best:
            continue
        d5 = {r: by[(r, s)]["J5"] / by[(r, best)]["J5"] - 1 for r in records
              if (r, s) in by and (r, best) in by and math.isfinite(by[(r, s)]["J5"] / by[(r, best)]["J5"])}
        if not d5:
            out.append(f"**{s}**: no record with both runs")
            continue
        beats = sorted(-100 * d for d in d5.values() if d < -TIE)
        loses = sorted(100 * d for d in d5.values() if d > TIE)
        text = f"**{s}** beats the best constant current on {len(beats)} of {len(d5)} records"
        text += f", by {_span(beats)} in J5" if beats else " in J5"
        if loses:
            text += f"; loses on {len(loses)}, by {_span(loses)}"
        ties = len(d5) - len(beats) - len(loses)
        if ties:
            text += f"; ties (within {100 * TIE:g} %) on {ties}"
        d3 = [100 * (by[(r, s)]["J3"] / by[(r, best)]["J3"] - 1) for r in d5]
        text += f". Base displacement J3 against it: {min(d3):+.0f} to {max(d3):+.0f} %."
        out.append(text)
    return out


def _span(values: list[float]) -> str:
    return f"{values[0]:.1f} %" if len(values) == 1 or abs(values[-1] - values[0]) < 0.05 else \
        f"{values[0]:.1f}–{values[-1]:.1f} %"


def pareto_plot(rows: Rows, records: list[str], best: str, baseline: str, path: Path) -> Path:
    """J3 against J5 per record, every strategy a point (the baseline, at (1, 1), left out), the best constant
    current marked with a star, the non-dominated strategies joined by a line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(records)
    cols = min(n, 2)
    fig, axes = plt.subplots((n + cols - 1) // cols, cols, figsize=(6 * cols, 4.5 * ((n + cols - 1) // cols)),
                             squeeze=False)
    names = [s for s in dict.fromkeys(row["strategy"] for row in rows) if s != baseline]
    cmap = plt.get_cmap("tab10")
    markers = "osD^v<>phX"
    for ax, r in zip(axes.flat, records, strict=False):
        points = []
        for k, s in enumerate(names):
            row = next((x for x in rows if x["record"] == r and x["strategy"] == s), None)
            if row is None or not (math.isfinite(row["J3"]) and math.isfinite(row["J5"])):
                continue
            is_best = s == best
            points.append((row["J3"], row["J5"]))
            ax.scatter(row["J3"], row["J5"], s=260 if is_best else 50, marker="*" if is_best else markers[k % 10],
                       color="k" if is_best else cmap(k % 10), zorder=3, label=s)
        front = sorted(points[k] for k in pareto_front(points))
        if len(front) > 1:
            ax.plot(*zip(*front, strict=True), color="0.6", lw=1, zorder=1)
        ax.set_title(r)
        ax.set_xlabel("J3 peak base displacement / baseline's")
        ax.set_ylabel("J5 peak floor acceleration / baseline's")
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=7, loc="best")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp, dpi=100, bbox_inches="tight")
    plt.close(fig)
    tmp.replace(path)
    return path


def _table(rows: Rows, title: str) -> list[Block]:
    header = ["record", "strategy", *CRITERIA, "ī [A]", "∫i² [A²s]", "mean |di/dt| [A/s]"]
    body = [[row["record"], row["strategy"], *(fmt(row[k]) for k in CRITERIA), *(fmt(row[k]) for k in EFFORT)]
            for row in rows]
    return [Block("p", title), Block("table", header=header, rows=body)]


def benchmark_outputs(folder: Path, study: CaseStudyRecord, series: dict[tuple[str, str], Any]) -> list[Block]:
    """Write criteria.csv (and the second baseline's), the Pareto figure; the report's benchmark blocks."""
    spec = study.config.get("benchmark") or {}
    baseline, second = spec.get("baseline", "passive-off"), spec.get("second_baseline", "passive-on")
    best = spec.get("best_constant", "best-constant")
    records = list(study.records)
    raw = raw_table(study, series)
    rows = criteria_rows(study, raw, baseline)
    atomic_write_text(folder / "criteria.csv", csv_text(rows))
    blocks = [Block("h", "Controller benchmark (Narasimhan et al. 2006 criteria)"),
              Block("p", "J1…J9 are each strategy's value over the baseline's on the same record (lower is better; "
                         "J9, the share of the ground's input energy the isolators take, higher means more of it). "
                         + "; ".join(f"{k}: {v}" for k, v in NAMES.items()) + ". Definitions, in SI: "
                         "`orchestration/case_study/benchmark_criteria.py`, docs/controllers.md."),
              Block("h", "Ranking per record", level=3),
              Block("p", f"By the mean of J1…J8 over **{baseline}**, lower first (the mean weighs each criterion "
                         "by the baseline's value, so another baseline can reorder close strategies).")]
    for r in records:
        ranked = ranking(rows, r)
        blocks.append(Block("p", f"**{r}**: " + ", ".join(f"{k + 1}. {s} ({fmt(v)})"
                                                           for k, (s, v) in enumerate(ranked))))
    fig = pareto_plot(rows, records, best, baseline, folder / "figures" / "benchmark_pareto_J3_J5.png")
    blocks.append(Block("img", str(fig.relative_to(folder)), items=[
        f"J3 (peak base displacement) against J5 (peak floor acceleration), both over {baseline} (which sits "
        f"at (1, 1), not drawn); the star is the best constant current ({best}); the grey line joins the "
        "non-dominated strategies"]))
    blocks.append(Block("h", "Against the best constant current", level=3))
    blocks.append(Block("p", f"J5 of each strategy over {best}'s on the same record (this ratio does not depend on "
                             "the baseline); a difference within 1 % is a tie."))
    blocks.append(Block("ul", items=verdicts(rows, best, records)))
    blocks.append(Block("h", "Criteria tables", level=3))
    blocks += _table(rows, f"Baseline **{baseline}** (criteria.csv).")
    if second and any(s == second for _, s in raw):
        rows2 = criteria_rows(study, raw, second)
        atomic_write_text(folder / f"criteria_{second}.csv", csv_text(rows2))
        blocks += _table(rows2, f"Baseline **{second}** (criteria_{second}.csv): {baseline} drives the isolator "
                                "beyond its identified range on some records, which flatters ratios to it.")
    if study.config.get("robustness"):  # variants of the plant and sensors: robustness.csv and its section
        from orchestration.case_study.robustness_report import robustness_blocks

        blocks += robustness_blocks(folder, study, raw, baseline)
    return blocks
