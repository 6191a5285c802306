"""Peaks and the normalised evaluation indices of a study, from the runs' time series.

Definitions (SI; level 0 = base floor, levels 1..n = storeys):

* base shear V0(t) = |sum_j m_j a_j(t)| over all levels 0..n, a_j absolute acceleration
  [N]: the force the isolation level transmits. With the default base floor (k_0 = c_0 = 0)
  it equals the isolator force |F| (sum_j m_j a_j = -F).
* structure shear Vs(t) = |shear_1(t)| [N]: the shear of the first storey above the base
  (k_1 drift_1 + c_1 (v_1 - v_0)), i.e. the base shear of the superstructure.
* indices (Narasimhan et al. 2006, smart base-isolated benchmark), controlled / uncontrolled
  with passive-off (0 A) as the uncontrolled case, same record:
  J1 peak V0; J2 peak Vs; J3 peak base displacement; J4 peak inter-storey drift over
  storeys; J5 peak absolute acceleration over levels 0..n; J7 RMS base displacement;
  J8 largest RMS absolute acceleration over levels 0..n. RMS over the whole run.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

PEAK_COLUMNS = ("record", "strategy", "x_base_mm", "drift_1_mm", "drift_2_mm", "drift_3_mm", "acc_0", "acc_1",
                "acc_2", "acc_3", "base_shear_N", "current_max_A", "current_mean_A")
INDEX_COLUMNS = ("record", "strategy", "J1", "J2", "J3", "J4", "J5", "J7", "J8")
INDEX_MEANING = {
    "J1": "peak base shear",
    "J2": "peak structure shear (storey 1)",
    "J3": "peak base displacement",
    "J4": "peak inter-storey drift",
    "J5": "peak absolute floor acceleration",
    "J7": "RMS base displacement",
    "J8": "RMS absolute floor acceleration",
}


CURRENT = "controller.i"
"""The studies' name for a run's current command [A]: the report's ``current`` role. A controller whose output has
another name (a strategy entry's ``current: u``) is read under this name too (:func:`read_timeseries`)."""


def _current_role(folder: Path) -> str | None:
    """The variable the run's report named its current command (its ``manifest.json``), if it has one."""
    try:
        role = json.loads((folder / "manifest.json").read_text())["scenario"]["report"]["current"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return role if isinstance(role, str) else None


def read_timeseries(path: Path) -> dict[str, np.ndarray]:
    """Columns of a run's results file by name (``time`` first): ``timeseries.csv``, or a Parquet table (a
    ``.parquet`` path, as float64); the current command also as :data:`CURRENT` when the run's controller calls it
    otherwise."""
    path = Path(path)
    if path.suffix == ".parquet":
        import pyarrow.parquet as pq

        table = pq.read_table(path)
        columns = {name: table.column(name).to_numpy().astype(np.float64) for name in table.column_names}
    else:
        with open(path) as f:
            header = next(csv.reader(f))
        if not header:
            raise ValueError(f"{path}: empty header")
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        if data.shape[0] == 0:
            data = np.zeros((0, len(header)))
        columns = {name: data[:, k] for k, name in enumerate(header)}
    return with_current(columns, _current_role(path.parent))


def with_current(columns: dict[str, np.ndarray], role: str | None) -> dict[str, np.ndarray]:
    """``columns`` with the current command also under :data:`CURRENT` where the run's report names it ``role``."""
    if CURRENT not in columns and role in columns:
        columns[CURRENT] = columns[role]
    return columns


def recorded_series(recorder: Any, current: str | None = None) -> dict[str, np.ndarray]:
    """Every step a run recorded, by name (``time`` first), from its recorder in memory (not its results file,
    which may keep every n-th step or none); the current command also as :data:`CURRENT` where the run's report
    names it ``current`` (a controller from another tool). Numeric columns only; copies."""
    n = recorder.count
    columns = {"time": np.array(recorder.time[:n], dtype=np.float64)}
    for k, name in enumerate(recorder.names):
        if k not in recorder.strings:
            columns[name] = np.array(recorder.data[:n, k], dtype=np.float64)
    return with_current(columns, current)


def _peak(x: np.ndarray) -> float:
    return float(np.max(np.abs(x))) if len(x) else math.nan


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if len(x) else math.nan


def run_metrics(ts: dict[str, np.ndarray], masses: Sequence[float]) -> dict[str, float]:
    """Peaks (units of peaks.csv) and the RMS values and shears the indices need."""
    n = len(masses) - 1
    acc = np.column_stack([ts[f"building.a_{j}"] for j in range(n + 1)])
    out: dict[str, float] = {"x_base_mm": 1e3 * _peak(ts["building.x_0"])}
    for j in range(1, n + 1):
        out[f"drift_{j}_mm"] = 1e3 * _peak(ts[f"building.drift_{j}"])
    for j in range(n + 1):
        out[f"acc_{j}"] = _peak(acc[:, j])
    out["base_shear_N"] = _peak(acc @ np.asarray(masses, dtype=float))
    i = ts["controller.i"]
    out["current_max_A"] = float(np.max(i)) if len(i) else math.nan
    out["current_min_A"] = float(np.min(i)) if len(i) else math.nan
    out["current_mean_A"] = float(np.mean(i)) if len(i) else math.nan
    out["structure_shear_N"] = _peak(ts["building.shear_1"])
    out["isolator_force_N"] = _peak(ts["isolator.F"])
    out["rms_x_base_mm"] = 1e3 * _rms(ts["building.x_0"])
    out["rms_acc_max"] = max(_rms(acc[:, j]) for j in range(n + 1))
    out["drift_max_mm"] = max(out[f"drift_{j}_mm"] for j in range(1, n + 1))
    out["acc_max"] = max(out[f"acc_{j}"] for j in range(n + 1))
    dt = float(ts["time"][1] - ts["time"][0]) if len(ts["time"]) > 1 else 0.0
    x = np.abs(ts["building.x_0"])
    out["time_beyond_8mm_s"] = float(np.sum(x > 0.008) * dt)
    out["time_beyond_15mm_s"] = float(np.sum(x > 0.015) * dt)
    out["duration_s"] = float(ts["time"][-1] - ts["time"][0]) if len(ts["time"]) else 0.0
    return out


def indices(m: dict[str, float], off: dict[str, float]) -> dict[str, float]:
    """J1-J5, J7, J8 of a run against the passive-off run of the same record."""

    def ratio(key: str) -> float:
        return m[key] / off[key] if off.get(key) else math.nan

    return {"J1": ratio("base_shear_N"), "J2": ratio("structure_shear_N"), "J3": ratio("x_base_mm"),
            "J4": ratio("drift_max_mm"), "J5": ratio("acc_max"), "J7": ratio("rms_x_base_mm"),
            "J8": ratio("rms_acc_max")}


def csv_text(columns: Sequence[str], rows: list[dict[str, Any]]) -> str:
    """CSV text with the given columns (floats at full precision, missing as empty; text quoted where needed)."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")  # quotes a cell only where it holds a comma or a quote
    writer.writerow(columns)
    for row in rows:
        cells = []
        for c in columns:
            v = row.get(c)
            cells.append("" if v is None or (isinstance(v, float) and math.isnan(v)) else
                         (repr(float(v)) if isinstance(v, float | np.floating) else str(v)))
        writer.writerow(cells)
    return buf.getvalue()
