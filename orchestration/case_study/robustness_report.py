"""The robustness outputs of a controller benchmark with variants: robustness.csv and the report's section.

``robustness.csv``: strategy, variant, record, J3, J4, J5, then J3_change_pct, J4_change_pct,
J5_change_pct and complete. J3 (peak base displacement), J4 (peak inter-storey drift) and J5
(peak absolute floor acceleration) are the criteria of :mod:`benchmark_criteria` (Narasimhan et al.
2006), each over the benchmark baseline's value (passive-off) on the NOMINAL plant and the same record,
as in criteria.csv, so a variant's row compares with the nominal rows directly. The change is the
strategy's degradation against its own nominal run, 100 (J_variant / J_nominal - 1) [%] (positive:
worse). The rows of variant ``nominal`` are the study's own runs. A variant run that did not finish
(diverged, failed) has no J and ``complete`` false; it counts as an unbounded degradation. A run an
interrupted study never started has no row.

The report's table gives, per strategy, the worst degradation of J3, J4 and J5 over the variants and
records, and a verdict computed from these numbers on the paper's claim that SOSM is "robust with
respect to any perturbations", against the other controllers (strategies whose current is not constant).
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any

from mre_common.atomic_files import atomic_write_text
from orchestration.case_study.case_records import CaseStudyRecord
from orchestration.case_study.case_rendering import Block, fmt

NOMINAL = "nominal"
JS = ("J3", "J4", "J5")
COLUMNS = ("strategy", "variant", "record", *JS, *(f"{j}_change_pct" for j in JS), "complete")
Rows = list[dict[str, Any]]


def declared_names(study: CaseStudyRecord) -> list[str]:
    """The variants the study file declares, in its order (not the sampled plants)."""
    return list((study.config.get("robustness") or {}).get("variants") or {})


def variant_names(study: CaseStudyRecord) -> list[str]:
    """Every variant of the study: the declared ones in the order of its file, then the sampled plants."""
    declared = declared_names(study)
    return declared + [v for v in dict.fromkeys(e.variant for e in study.variant_runs)
                       if v is not None and v not in declared]


def variant_raw(folder: Path, study: CaseStudyRecord) -> dict[tuple[str, str, str], dict[str, float] | None]:
    """Raw criteria of every variant run that was run, as it computed them from its every step, by (record,
    strategy, variant); None for one that failed."""
    from orchestration.case_study.case_metrics import run_numbers_of

    vraw: dict[tuple[str, str, str], dict[str, float] | None] = {}
    for e in study.variant_runs:
        if not e.ok and e.status is None:
            continue  # not run (an interrupted study): no row; --resume runs it
        found = run_numbers_of(folder, study, e) if e.ok else None
        vraw[(e.record, e.strategy, e.variant or "")] = None if found is None else found["criteria"]
    return vraw


def robustness_rows(folder: Path, study: CaseStudyRecord, raw: dict[tuple[str, str], dict[str, float]],
                    baseline: str, vraw: dict[tuple[str, str, str], dict[str, float] | None] | None = None) -> Rows:
    """Rows of robustness.csv (see the module): ``raw`` holds the nominal runs' raw criteria by (record, strategy),
    ``vraw`` the variant runs' (:func:`variant_raw`, read here when not given)."""
    if vraw is None:
        vraw = variant_raw(folder, study)
    rows = []
    for s in study.strategies:
        for v in [NOMINAL, *variant_names(study)]:
            for r in study.records:
                base, nom = raw.get((r, baseline), {}), raw.get((r, s))
                val = nom if v == NOMINAL else vraw.get((r, s, v))
                if v != NOMINAL and (r, s, v) not in vraw:
                    continue  # not planned (an older folder)
                row: dict[str, Any] = {"strategy": s, "variant": v, "record": r, "complete": val is not None}
                for j in JS:
                    b = base.get(j, math.nan)
                    row[j] = val[j] / b if val is not None and b and math.isfinite(b) else math.nan
                    n = nom[j] if nom is not None else math.nan
                    row[f"{j}_change_pct"] = (100.0 * (val[j] / n - 1.0) if val is not None and n and math.isfinite(n)
                                              else math.nan)
                rows.append(row)
    return rows


def csv_text(rows: Rows) -> str:
    """CSV of the rows, columns :data:`COLUMNS`."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, COLUMNS, lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue()


def worst(rows: Rows, strategy: str, j: str) -> tuple[float, str, str]:
    """The largest change [%] of criterion ``j`` over the strategy's variant rows, with its variant and record;
    an incomplete run is +inf."""
    best = (-math.inf, "", "")
    for row in rows:
        if row["strategy"] != strategy or row["variant"] == NOMINAL:
            continue
        c = math.inf if not row["complete"] else row[f"{j}_change_pct"]
        if math.isfinite(c) or c == math.inf:
            if c > best[0]:
                best = (c, row["variant"], row["record"])
    return best


def _pct(c: float) -> str:
    return "run failed" if c == math.inf else "–" if not math.isfinite(c) else f"{c:+.1f} %"


def controllers(study: CaseStudyRecord) -> list[str]:
    """Strategies whose current is not a constant (their nominal runs have no constant current)."""
    const = {e.strategy for e in study.runs if e.current_A is not None}
    return [s for s in study.strategies if s not in const]


def verdict(rows: Rows, study: CaseStudyRecord) -> list[str]:
    """The paper's robustness claim for SOSM against the other controllers, in words, from the rows."""
    ctrl = controllers(study)
    overall = {s: max((worst(rows, s, j) for j in JS), key=lambda w: w[0]) for s in ctrl}
    overall = {s: w for s, w in overall.items() if w[1]}
    paper = study.paper("controlled")  # the paper's controller: SOSM (entries with paper_figures: controlled)
    sosm = [s for s in paper if s in overall]
    others = [s for s in overall if s not in paper]
    if not sosm or not others:
        return ["The verdict needs an SOSM strategy and another controller, each with variant runs."]
    out = []
    order = sorted(overall, key=lambda s: overall[s][0])
    for s in sosm:
        c, v, r = overall[s]
        better = [o for o in others if overall[o][0] < c]
        rank = order.index(s) + 1
        text = (f"**{s}**: worst degradation {_pct(c)} ({v}, {r}; the largest change of J3, J4, J5 against its own "
                f"nominal run); rank {rank} of {len(order)} controllers (1: least degraded). ")
        per_var = []
        for var in dict.fromkeys(row["variant"] for row in rows if row["variant"] != NOMINAL):
            def w(x: str, var: str = var) -> float:
                vals = [math.inf if not row["complete"] else max(row[f"{j}_change_pct"] for j in JS)
                        for row in rows if row["strategy"] == x and row["variant"] == var]
                return max(vals) if vals else math.nan
            mine = w(s)
            if all(mine <= w(o) for o in others if math.isfinite(w(o)) or w(o) == math.inf):
                per_var.append(var)
        text += (f"It degrades least of all controllers under {len(per_var)} of "
                 f"{len({row['variant'] for row in rows}) - 1} variants" + (f" ({', '.join(per_var)})" if per_var
                                                                             else "") + ". ")
        if better:
            text += ("The paper's claim that SOSM is \"robust with respect to any perturbations\" does **not** hold "
                     "against the other controllers here: " + ", ".join(f"{o} ({_pct(overall[o][0])})" for o in better)
                     + " degrade less in the worst case.")
        else:
            nxt = ", ".join(f"{o} ({_pct(overall[o][0])})" for o in sorted(others, key=lambda o: overall[o][0])[:3])
            text += ("Against the other controllers the paper's claim holds in this sense: no other controller's worst "
                     f"degradation is smaller (next: {nxt}); it still changes by {_pct(c)}, so \"any perturbations\" "
                     "is not borne out absolutely.")
        out.append(text)
    return out


def robustness_blocks(folder: Path, study: CaseStudyRecord, raw: dict[tuple[str, str], dict[str, float]],
                      baseline: str) -> list[Block]:
    """Write robustness.csv; the report's robustness section."""
    vraw = variant_raw(folder, study)
    rows = robustness_rows(folder, study, raw, baseline, vraw)
    atomic_write_text(folder / "robustness.csv", csv_text(rows))
    names = declared_names(study)
    sampled = [v for v in variant_names(study) if v not in names]
    not_run = [e.key for e in study.variant_runs if not e.ok and e.status is None]
    labels = (study.config.get("robustness") or {}).get("variants") or {}
    blocks = [Block("h", "Robustness (designed on the nominal models, run on other plants)"),
              Block("p", "Variants: " + "; ".join(f"**{v}**" + (f" ({labels[v].get('label')})" if labels.get(v, {})
                                                                   .get("label") else "") for v in names)
                    + (f"{'; ' if names else ''}{len(sampled)} sampled plants (their section below)" if sampled else "")
                    + ". "
                    f"robustness.csv: J3, J4, J5 over **{baseline} on the nominal plant** (as criteria.csv), and the "
                    "change against the same strategy's nominal run in per cent (positive: worse)."),
              *([Block("p", f"**Incomplete**: {len(not_run)} of {len(study.variant_runs)} variant runs were not run "
                              "(the study was interrupted; `--resume` runs them). Every figure below covers only the "
                              "runs that ended.")] if not_run else []),
              Block("h", "Worst degradation per strategy", level=3),
              Block("p", "The largest change over every variant and record (where it happens); a run that did not "
                         "finish counts as failed.")]
    ctrl = set(controllers(study))
    body = []
    for s in study.strategies:
        cells = []
        for j in JS:
            c, v, r = worst(rows, s, j)
            cells.append(f"{_pct(c)} ({v}, {r})" if v else "–")
        failed = sum(1 for row in rows if row["strategy"] == s and not row["complete"])
        body.append([s + ("" if s in ctrl else " (constant)"), *cells, str(failed)])
    blocks.append(Block("table", header=["strategy", "worst J3 change", "worst J4 change", "worst J5 change",
                                         "runs failed"], rows=body))
    if names:
        blocks.append(Block("h", "Worst change of J3, J4, J5 per variant", level=3))
        body = []
        for s in study.strategies:
            cells = []
            for v in names:
                vals = [math.inf if not row["complete"] else max(row[f"{j}_change_pct"] for j in JS)
                        for row in rows if row["strategy"] == s and row["variant"] == v]
                cells.append(_pct(max(vals)) if vals else "–")
            body.append([s, *cells])
        blocks.append(Block("table", header=["strategy", *names], rows=body))
    blocks.append(Block("h", "The paper's robustness claim for SOSM", level=3))
    blocks.append(Block("ul", items=verdict(rows, study)))
    blocks.append(Block("p", "Nominal J5 for reference: " + "; ".join(
        f"{s} " + "/".join(fmt(row["J5"]) for row in rows if row["strategy"] == s and row["variant"] == NOMINAL)
        for s in study.strategies) + f" (records {', '.join(study.records)})."))
    if sampled and (folder / "plant_design.json").is_file():
        from orchestration.case_study.plant_uncertainty import uncertainty_blocks

        blocks += uncertainty_blocks(folder, study, vraw, raw, baseline)
    return blocks
