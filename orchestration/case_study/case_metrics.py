"""The numbers of a case study: every run's metrics, and the tables peaks.csv, indices.csv, sweep.csv,
reference.csv, all from the study folder (``study.json`` and the numbers each run computed from its every step,
``metrics.json``: :mod:`orchestration.case_study.run_numbers`)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from orchestration.building_studies.run_metrics import INDEX_COLUMNS, PEAK_COLUMNS, csv_text, indices
from orchestration.case_study.case_records import CaseStudyRecord, RunEntry
from orchestration.case_study.run_numbers import NUMBERS_FILE, NumberInputs, read_figure_series, read_numbers
from orchestration.master.runfolder import write_text

REFERENCE_KEYS = ("x_base_mm", "drift_1_mm", "drift_2_mm", "drift_3_mm", "acc_0", "acc_1", "acc_2", "acc_3",
                  "base_shear_N")
SWEEP_COLUMNS = ("record", "current_A", "x0", "d", "a3", "J", "best")
REFERENCE_COLUMNS = ("record", "strategy", "peak", "cosim", "radau", "rel_error")
PEAK_TABLE_COLUMNS = (*PEAK_COLUMNS, "valid", "invalid_reasons")  # peaks.csv: the peaks, then numerical validity

Metrics = dict[tuple[str, str], dict[str, float]]  # (record, strategy) -> metric -> value
Numbers = dict[tuple[str, str], dict[str, Any]]  # (record, strategy) -> the run's numbers (run_numbers.py)
Series = dict[tuple[str, str], dict[str, np.ndarray]]  # (record, strategy) -> column -> samples (figure series)


def current_limit(study: CaseStudyRecord, strategy: str) -> float:
    """The controller's current limit [A] of a strategy in a study folder written before runs kept their numbers
    (their ``metrics.json`` says it): the second gain set's own, else the study's i_max."""
    cfg = study.config
    if strategy == "sosm-fig15":
        return float((cfg.get("fig15") or {}).get("i_max", cfg["i_max"]))
    return float(cfg["i_max"])


def legacy_inputs(study: CaseStudyRecord, run: RunEntry) -> NumberInputs:
    """The inputs of a run's numbers for a folder written before runs computed them: from ``study.json``."""
    doc = study.gain_sets.get(run.strategy) or {}
    info = study.records[run.record]
    return NumberInputs(masses=list(info.masses_kg), current_limit=current_limit(study, run.strategy),
                        paper_current_range=tuple(study.config["paper_current_range"]), sosm_gains=doc.get("gains"),
                        n_isolators=int(info.n_isolators or 2))


def run_numbers_of(folder: Path, study: CaseStudyRecord, run: RunEntry) -> dict[str, Any] | None:
    """A finished run's numbers (:func:`~orchestration.case_study.run_numbers.read_numbers`), its validity and energy
    read into its entry first; None (and the entry marked failed, saying why) for a run folder that has none."""
    read_validity(folder / run.folder, run)
    numbers = read_numbers(folder / run.folder, legacy_inputs(study, run), run.energy)
    if numbers is None:
        run.ok = False
        run.error = f"{folder / run.folder} has neither {NUMBERS_FILE} nor timeseries.csv"
    return numbers


def load_metrics(folder: Path, study: CaseStudyRecord) -> tuple[Metrics, Numbers, Series]:
    """Metrics, numbers and figure series of every successful run of a study folder: the metrics and numbers as the
    runs computed them from every step (``metrics.json``), the series the figures draw (``figure_series.parquet``,
    or a run's results file); a run without numbers is marked failed in ``study``."""
    metrics: Metrics = {}
    numbers: Numbers = {}
    series: Series = {}
    for run in study.runs:
        if not run.ok:
            continue
        found = run_numbers_of(folder, study, run)
        if found is None:
            continue
        key = (run.record, run.strategy)
        numbers[key], metrics[key] = found, found["metrics"]
        drawn = read_figure_series(folder / run.folder)
        if drawn is not None:
            series[key] = drawn
    apply_step_check(folder, study)
    return metrics, numbers, series


def read_validity(run_folder: Path, run: RunEntry) -> None:
    """A run's numerical validity and energy section from its summary.json, into its entry (a run folder written
    before runs said so, or without a readable summary: validity unknown, None)."""
    try:
        summary = json.loads((run_folder / "summary.json").read_text())
    except (OSError, ValueError):
        return
    if not isinstance(summary, dict) or "valid" not in summary:
        return
    run.valid = bool(summary["valid"])
    run.invalid_reasons = [str(r) for r in summary.get("invalid_reasons") or []]
    run.energy = summary.get("energy")


def _summary(run_folder: Path) -> dict[str, Any] | None:
    try:
        summary = json.loads((run_folder / "summary.json").read_text())
    except (OSError, ValueError):
        return None
    return summary if isinstance(summary, dict) else None


def apply_step_check(folder: Path, study: CaseStudyRecord) -> None:
    """``--verify-step``: each run's peaks against its run at half the plant's step; a run whose largest change is
    above the tolerance (1 %, :data:`~orchestration.building_report.DEFAULT_STEP_TOLERANCE`) is not converged in
    the step: numerically invalid, with that reason. A half-step run that did not end: the step is not checked."""
    from orchestration.building_report import DEFAULT_STEP_TOLERANCE
    from orchestration.step_check import step_section

    for half in study.half_step_runs:
        base = next((e for e in study.runs if e.key == half.key.removesuffix("/half-step")), None)
        if base is None or not base.ok:
            continue
        coarse, fine = _summary(folder / base.folder), _summary(folder / half.folder)
        if coarse is None or fine is None:
            continue
        _, reasons = step_section(coarse, fine, {}, DEFAULT_STEP_TOLERANCE, half.folder)
        if reasons and base.valid is not None and not any(r.startswith("step not converged")
                                                           for r in base.invalid_reasons):
            base.valid = False
            base.invalid_reasons = [*base.invalid_reasons, *reasons]


def validity_columns(run: RunEntry | None) -> dict[str, Any]:
    """The ``valid`` and ``invalid_reasons`` cells of a run's rows (empty where validity is unknown)."""
    if run is None or run.valid is None:
        return {"valid": None, "invalid_reasons": None}
    return {"valid": run.valid, "invalid_reasons": "; ".join(run.invalid_reasons)}


def judged(study: CaseStudyRecord, metrics: Metrics) -> Metrics:
    """The metrics of the runs a report may rank and judge: every run not known to be numerically invalid."""
    invalid = {(run.record, run.strategy) for run in study.runs if run.valid is False}
    return {k: m for k, m in metrics.items() if k not in invalid}


def pareto_front(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the points (x, y) no other point dominates (both lower is better), sorted by x."""
    order = sorted(range(len(points)), key=lambda k: (points[k][0], points[k][1]))
    front, best_y = [], math.inf
    for k in order:
        if points[k][1] < best_y:
            front.append(k)
            best_y = points[k][1]
    return front


def peak_and_index_rows(study: CaseStudyRecord, metrics: Metrics) -> tuple[list[dict], list[dict]]:
    """Rows of peaks.csv and indices.csv; the indices also go into ``study.indices`` (record/strategy)."""
    peak_rows, index_rows = [], []
    study.indices = {}
    for r in study.records:
        off = metrics.get((r, study.uncontrolled))
        for s in study.strategies:
            m = metrics.get((r, s))
            if m is None:
                continue
            peak_rows.append({"record": r, "strategy": s, **m, **validity_columns(_run(study, r, s))})
            if off is not None:
                idx = indices(m, off)
                study.indices[f"{r}/{s}"] = idx
                index_rows.append({"record": r, "strategy": s, **idx})
    return peak_rows, index_rows


def _run(study: CaseStudyRecord, record: str, strategy: str) -> RunEntry | None:
    return next((e for e in study.runs if e.record == record and e.strategy == strategy), None)


def sweep_rows(study: CaseStudyRecord) -> list[dict[str, Any]]:
    """Rows of sweep.csv: every swept current of every record, the best marked."""
    return [{"record": r, **q, "best": q["current_A"] == sw.best_current_A}
            for r, sw in study.sweep.items() if sw.ok for q in sw.rows]


def reference_rows(study: CaseStudyRecord, metrics: Metrics) -> list[dict[str, Any]]:
    """Rows of reference.csv: each passive run's peaks against the Radau reference's."""
    rows = []
    for key, v in study.reference.items():
        r, s = key.split("/")
        m = metrics.get((r, s))
        if v.ok and m is not None:
            for k in REFERENCE_KEYS:
                rows.append({"record": r, "strategy": s, "peak": k, "cosim": m[k], "radau": v.value[k],
                             "rel_error": m[k] / v.value[k] - 1 if v.value[k] else math.nan})
    return rows


def write_tables(folder: Path, study: CaseStudyRecord, metrics: Metrics) -> None:
    """peaks.csv, indices.csv, and sweep.csv and reference.csv if the study has them."""
    peak_rows, index_rows = peak_and_index_rows(study, metrics)
    write_text(folder / "peaks.csv", csv_text(PEAK_TABLE_COLUMNS, peak_rows))
    write_text(folder / "indices.csv", csv_text(INDEX_COLUMNS, index_rows))
    if study.sweep:
        write_text(folder / "sweep.csv", csv_text(SWEEP_COLUMNS, sweep_rows(study)))
    if study.reference:
        write_text(folder / "reference.csv", csv_text(REFERENCE_COLUMNS, reference_rows(study, metrics)))
