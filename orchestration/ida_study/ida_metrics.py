"""The numbers of an IDA study: a row per run (results.parquet/.csv) and the fragility fits (fragility.csv).

Rows are plain column -> value dicts in the order of :data:`COLUMNS` (the table files'
columns); indices are against the uncontrolled strategy (passive-off, shipped) at the same component and level.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from mre_common.atomic_files import atomic_write
from orchestration.building_studies.run_metrics import INDEX_COLUMNS, csv_text, indices
from orchestration.ida_study.ida_config import QUANTITIES, RATIO_QUANTITIES, IdaSpec
from orchestration.ida_study.ida_jobs import COLLAPSED_STATUS
from orchestration.ida_study.ida_records import ComponentInfo, RunOutcome
from orchestration.master.runfolder import write_text

if TYPE_CHECKING:
    from orchestration.ida_study.fragility import Fit

PEAKS = ("x_base_mm", "drift_1_mm", "drift_2_mm", "drift_3_mm", "drift_max_mm", "acc_0", "acc_1", "acc_2", "acc_3",
         "acc_max", "base_shear_N", "structure_shear_N", "isolator_force_N", "current_max_A", "current_mean_A",
         "rms_x_base_mm", "rms_acc_max", "time_beyond_8mm_s", "time_beyond_15mm_s", "residual_drift_1_mm",
         "residual_drift_2_mm", "residual_drift_3_mm", "residual_drift_max_mm")
COLUMNS = ("record", "component", "record_id", "intensity_measure", "intensity", "im_unscaled", "scale",
           "strategy", *PEAKS, *INDEX_COLUMNS[2:], "status", "error", "wall_time_s", "end_time_s", "key", "valid",
           "invalid_reasons")
TEXT_COLUMNS = ("record", "component", "record_id", "intensity_measure", "strategy", "status", "error", "key",
                "invalid_reasons")
ENDED = ("ok", "diverged", COLLAPSED_STATUS)  # runs that count in the fragility stripes


def run_label(component_id: str, level: float, strategy: str) -> str:
    """A run's label: ``record_id/level/strategy``."""
    return f"{component_id}/{level:g}/{strategy}"


def _no_none(metrics: dict[str, Any]) -> dict[str, float]:
    return {k: (math.nan if x is None else x) for k, x in metrics.items()}


def result_row(comp: ComponentInfo, measure: str, level: float, strategy: str, res: RunOutcome | None,
               off_metrics: dict[str, Any] | None) -> dict[str, Any]:
    """The row (COLUMNS) of one run; ``off_metrics``: the uncontrolled strategy's at the same component and level."""
    label = run_label(comp.id, level, strategy)
    row: dict[str, Any] = {"record": comp.record, "component": comp.component, "record_id": comp.id,
                           "intensity_measure": measure, "intensity": level, "im_unscaled": comp.im,
                           "scale": level / comp.im, "strategy": strategy, "key": label}
    if res is None:
        row.update(status="not run", error="not run (interrupted)")
    elif not res.ok:
        row.update(status=res.status, error=res.error, wall_time_s=res.wall_time_s)
    else:
        v = res.result
        if v is None:  # ok without a value: a result the job did not write
            raise ValueError(f"{label}: a finished run without its job's value")
        m = v.metrics
        row.update({k: m.get(k) for k in PEAKS})
        row.update(status=v.status, error=v.error, wall_time_s=res.wall_time_s, end_time_s=v.end_time_s)
        if v.valid is not None:  # numerical validity (results stored before runs said so: unknown)
            row.update(valid=bool(v.valid), invalid_reasons="; ".join(v.invalid_reasons))
        if off_metrics and v.status == "ok" and m:
            row.update(indices(_no_none(m), _no_none(off_metrics)))
    return {c: row.get(c) for c in COLUMNS}


def result_rows(components: list[ComponentInfo], measure: str, results: dict[str, RunOutcome], levels: list[float],
                strategies: list[str], uncontrolled: str | None) -> list[dict[str, Any]]:
    """One row per run (COLUMNS), component by component, level by level, strategy by strategy; the indices over
    the ``uncontrolled`` strategy's run at the same component and level (none without one)."""
    rows = []
    for comp in components:
        for level in levels:
            off = results.get(run_label(comp.id, level, uncontrolled)) if uncontrolled is not None else None
            done = off.result if off is not None else None
            off_metrics = done.metrics if done is not None and done.status == "ok" else None
            rows += [result_row(comp, measure, level, s, results.get(run_label(comp.id, level, s)), off_metrics)
                     for s in strategies]
    return rows


def drift_ratio(row: dict[str, Any], heights: list[float] | None) -> float | None:
    """The largest peak drift ratio of a run: max over storeys of drift_j / h_j [1] (None without heights)."""
    if not heights:
        return None
    ratios = [row.get(f"drift_{j}_mm") for j in range(1, len(heights) + 1)]
    if any(r is None for r in ratios):
        return None
    return max(1e-3 * r / h for r, h in zip(ratios, heights, strict=True))


def exceeded(row: dict[str, Any], quantity: str, threshold: float, heights: list[float] | None = None) -> bool | None:
    """Did a run exceed a limit state? None if the run does not count (failed, not run, numerically invalid).

    A run stopped by the divergence limit, or that collapsed (the OpenSees unit did not converge),
    exceeds every limit state; drift ratios use the storey heights ``heights`` [m]. A complete run that is
    numerically invalid (``valid`` false: its energy books or its values cannot be trusted) is not counted;
    a physical exceedance (beyond the device limit, say) is a result and counts.
    """
    if row["status"] in ("diverged", COLLAPSED_STATUS):
        return True
    if row["status"] != "ok" or row.get("valid") is False:
        return None
    if quantity in RATIO_QUANTITIES:
        value = drift_ratio(row, heights)
        return None if value is None else bool(value > threshold)
    column, factor, _ = QUANTITIES[quantity]
    value = row.get(column)
    return None if value is None else bool(value * factor > threshold)


def collapse_margins(fits: dict[str, dict[str, Fit]], spec: IdaSpec, rows: list[dict[str, Any]]
                     ) -> list[dict[str, Any]]:
    """Per collapse limit state and strategy: the median collapse intensity S_CT and its margin.

    With ``collapse_margin.s_mt``: FEMA P695's collapse margin ratio CMR = S_CT / S_MT (FEMA P695,
    2009, Eq. 6-1; not adjusted by the spectral shape factor). Without it, S_MT cannot be computed
    (it is read from a design spectrum): the ratio of S_CT to the median intensity of the study's
    records at scale 1 instead (``margin_kind`` says which).
    """
    unscaled = sorted({r["record_id"]: r["im_unscaled"] for r in rows if r.get("im_unscaled")}.values())
    records_median = float(np.median(unscaled)) if unscaled else math.nan
    out = []
    for name, by_strategy in fits.items():
        if spec.limit_states[name].quantity != "collapse":
            continue
        for s, fit in by_strategy.items():
            s_ct = fit.theta if fit.ok else math.nan
            lo, hi = fit.theta_interval() if fit.ok else (math.nan, math.nan)
            if spec.collapse_margin is not None:
                kind, ref, source = "CMR (FEMA P695)", spec.collapse_margin.s_mt, spec.collapse_margin.source
            else:
                kind, ref = "S_CT / median IM of the records at scale 1 (not FEMA P695's CMR)", records_median
                source = "no design spectrum given: S_MT cannot be computed"
            out.append({"limit_state": name, "strategy": s, "fit": fit.kind, "s_ct": s_ct, "s_ct_low": lo,
                        "s_ct_high": hi, "beta": fit.beta if fit.ok else math.nan, "reference": ref,
                        "margin": s_ct / ref if ref else math.nan, "margin_kind": kind, "reference_source": source,
                        "note": fit.note})
    return out


def fragilities(rows: list[dict[str, Any]], spec: IdaSpec) -> dict[str, dict[str, Fit]]:
    """Limit state -> strategy -> fitted fragility."""
    from orchestration.ida_study.fragility import Stripe, fit_fragility  # scipy.stats: only when needed

    out: dict[str, dict[str, Fit]] = {}
    for name, ls in spec.limit_states.items():
        out[name] = {}
        for s in spec.strategy_names:
            stripes = []
            for level in spec.intensity.levels:
                marks = [exceeded(r, ls.quantity, ls.threshold, spec.storey_heights) for r in rows
                         if r["strategy"] == s and r["intensity"] == level]
                counted = [m for m in marks if m is not None]
                stripes.append(Stripe(level, len(counted), sum(counted)))
            out[name][s] = fit_fragility(stripes, spec.confidence)
    return out


def fragility_rows(fits: dict[str, dict[str, Fit]], spec: IdaSpec) -> list[dict[str, Any]]:
    """The table of fragility.csv: one row per limit state and strategy."""
    rows = []
    for name, by_strategy in fits.items():
        ls = spec.limit_states[name]
        for s, fit in by_strategy.items():
            lo, hi = fit.theta_interval() if fit.ok else (math.nan, math.nan)
            rows.append({"limit_state": name, "quantity": ls.quantity, "threshold": ls.threshold, "strategy": s,
                         "fit": fit.kind, "median": fit.theta if fit.ok else None, "beta": fit.beta if fit.ok else None,
                         "median_low": lo, "median_high": hi, "confidence": fit.confidence,
                         "between_low": fit.bounds[0] if fit.kind == "separated" else None,
                         "between_high": fit.bounds[1] if fit.kind == "separated" else None,
                         "stripes": " ".join(f"{st.level:g}:{st.k}/{st.n}" for st in fit.stripes), "note": fit.note})
    return rows


def table_csv(columns: tuple[str, ...] | list[str], rows: list[dict[str, Any]]) -> str:
    """CSV text (quoted where needed; floats at full precision, missing as empty)."""
    return csv_text(columns, rows)


def write_tables(folder: Path, rows: list[dict[str, Any]]) -> None:
    """results.parquet (pyarrow) and results.csv, each written to a temporary name and renamed."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    schema = pa.schema([(c, pa.string() if c in TEXT_COLUMNS else pa.bool_() if c == "valid" else pa.float64())
                        for c in COLUMNS])
    table = pa.Table.from_pylist([{c: (float(r.get(c)) if r.get(c) is not None and schema.field(c).type == pa.float64()
                                       else r.get(c)) for c in COLUMNS} for r in rows], schema=schema)
    atomic_write(folder / "results.parquet", lambda f: pq.write_table(table, f), binary=True)
    write_text(folder / "results.csv", table_csv(COLUMNS, rows))


def read_rows(folder: Path) -> list[dict[str, Any]]:
    """The runs of a study folder (results.parquet)."""
    import pyarrow.parquet as pq

    rows = pq.read_table(folder / "results.parquet").to_pylist()
    for r in rows:
        for k, v in r.items():
            if isinstance(v, float) and math.isnan(v):
                r[k] = None
    return rows
