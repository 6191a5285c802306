"""What a case study needs of each co-simulation, computed in the run from every step: ``metrics.json``.

A study's tables, criteria and verdicts come from each run's numbers, computed by its job on the worker from the
recorder's every step in float64 (:func:`~orchestration.building_studies.run_metrics.recorded_series`), never from a
results file, which a study writes only when asked (``timeseries: true``) and which may keep every n-th step
(``simulation.output_interval``) or float32 (``output_format: parquet``). ``metrics.json`` holds:

* ``metrics``: the peaks, RMS values and shears of :func:`~orchestration.building_studies.run_metrics.run_metrics`
  (peaks.csv, indices.csv), the time outside the paper's current range and the shares of time at the current limit,
  at 0 A and at the range's top;
* ``criteria``: the raw J1...J9 of :func:`~orchestration.case_study.benchmark_criteria.raw_criteria` (J9 from the
  run's energy section) and the control effort (criteria.csv, robustness.csv);
* ``sosm_conditions``: Eq. (36)'s bounds along the run and the gain conditions after Eq. (39), for a strategy with
  an SOSM gain set (:func:`~components.physics.sosm_conditions.sosm_conditions`), else null.

The nominal runs also keep ``figure_series.parquet``: the few variables the study's figures draw (time, base
displacement, isolator force, top-floor acceleration, current, and the device current where a coil lag gives one)
at every k-th step, k the smallest that keeps at most :data:`FIGURE_ROWS` rows (every step of a record up to 40 s
at 1 ms; every 4th of Kobe's 150 s), float32. It draws figures; no number of a table comes from it.

Non-finite numbers are written as null and read back as NaN. A run folder written before runs kept their numbers
(it has ``timeseries.csv``) is read through the same functions from that file (:func:`read_numbers`).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

NUMBERS_FILE = "metrics.json"
FIGURE_SERIES_FILE = "figure_series.parquet"
FIGURE_ROWS = 40_000
"""Most rows of a run's figure series (every k-th step): enough for a figure several thousand pixels wide."""
MAX_NUMBERS_BYTES = 1 << 20
"""Largest ``metrics.json`` a report reads [bytes]: a run's is about 2 KB."""
TOP_FLOOR = "building.a_top"  # the figure series' name of the top floor's absolute acceleration [m/s^2]
DEVICE_CURRENT = "coil.i"  # a plant's coil lag output: the device current [A], drawn beside the command


@dataclass(frozen=True)
class NumberInputs:
    """What a run's numbers need besides its series: masses [kg] (base first), the controller's current limit [A],
    the paper's current range [A], an SOSM gain set (lambda, rho, zeta, theta, i_max; None: not an SOSM
    strategy) with the number of isolators, and whether the run keeps its figure series and its time series."""

    masses: list[float]
    current_limit: float
    paper_current_range: tuple[float, float]
    sosm_gains: dict[str, float] | None = None
    n_isolators: int = 2
    figure_series: bool = False
    timeseries: bool = False

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> NumberInputs:
        lo, hi = d["paper_current_range"]
        return cls(masses=[float(m) for m in d["masses"]], current_limit=float(d["current_limit"]),
                   paper_current_range=(float(lo), float(hi)), sosm_gains=d.get("sosm_gains"),
                   n_isolators=int(d.get("n_isolators") or 2), figure_series=bool(d.get("figure_series")),
                   timeseries=bool(d.get("timeseries")))


def current_shares(i: np.ndarray, limit: float, range_top: float) -> dict[str, float]:
    """Shares of the run's samples with the current at its limit, at 0 A and at or above ``range_top`` [A]
    (within 1e-6 A: the controller clips to its bounds exactly; the tolerance absorbs a results file's printing)."""
    if not len(i):
        return {"current_share_at_limit": math.nan, "current_share_at_zero": math.nan,
                "current_share_at_range_top": math.nan}
    return {"current_share_at_limit": float(np.mean(i >= limit - 1e-6)),
            "current_share_at_zero": float(np.mean(i <= 1e-6)),
            "current_share_at_range_top": float(np.mean(i >= range_top - 1e-6))}


def run_numbers(series: dict[str, np.ndarray], energy: dict[str, Any] | None, inputs: NumberInputs
                ) -> dict[str, Any]:
    """The numbers of one run (see the module) from its series at every step and its energy section."""
    from orchestration.building_studies.run_metrics import CURRENT, run_metrics
    from orchestration.case_study.benchmark_criteria import effort, raw_criteria

    t, i = series["time"], series[CURRENT]
    metrics = run_metrics(series, inputs.masses)
    lo, hi = inputs.paper_current_range
    dt = float(t[1] - t[0]) if len(t) > 1 else 0.0
    metrics["time_current_outside_paper_range_s"] = float(np.sum((i > hi + 1e-12) | (i < lo - 1e-12)) * dt)
    metrics["current_limit_A"] = inputs.current_limit
    metrics.update(current_shares(i, inputs.current_limit, hi))
    criteria = raw_criteria(series, inputs.masses, energy)
    criteria.update(effort(t, i))
    return {"rows": len(t), "metrics": metrics, "criteria": criteria,
            "sosm_conditions": _sosm_conditions(series, inputs)}


def _sosm_conditions(series: dict[str, np.ndarray], inputs: NumberInputs) -> dict[str, Any] | None:
    """Eq. (36)'s bounds and the gain conditions along the run, for an SOSM gain set; None without one."""
    if inputs.sosm_gains is None:
        return None
    from components.physics.sosm_conditions import sosm_conditions
    from components.physics.sosm_controller_core import IsolatorModel, SosmGains
    from orchestration.building_studies.run_metrics import CURRENT

    g = inputs.sosm_gains
    gains = SosmGains(lam=g["lambda"], rho=g["rho"], zeta=g["zeta"], theta=g["theta"], i_max=g["i_max"])
    # relative base acceleration: recorded, or absolute minus ground (both m/s^2)
    if "building.arel_0" in series:
        arel = series["building.arel_0"]
    elif "ground.ag" in series:
        arel = series["building.a_0"] - series["ground.ag"]
    else:
        return None
    c = sosm_conditions(series["time"], series["building.x_0"], series["building.v_0"], arel, series[CURRENT],
                        gains, IsolatorModel(), inputs.masses[0], inputs.n_isolators)
    return {k: (bool(v) if isinstance(v, bool | np.bool_) else float(v)) for k, v in asdict(c).items()}


def figure_rows(count: int) -> slice:
    """The rows of a run's figure series: every k-th of ``count``, k the smallest giving at most FIGURE_ROWS."""
    return slice(0, count, max(1, math.ceil(count / FIGURE_ROWS)))


def figure_columns(series: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The variables the study's figures draw, by the figure series' names, at every step of ``series``."""
    from orchestration.building_studies.run_metrics import CURRENT

    floors = sorted(int(k.rsplit("_", 1)[1]) for k in series
                    if k.startswith("building.a_") and k.rsplit("_", 1)[1].isdigit())
    out = {"time": series["time"], "building.x_0": series["building.x_0"], "isolator.F": series["isolator.F"],
           CURRENT: series[CURRENT]}
    if floors:
        out[TOP_FLOOR] = series[f"building.a_{floors[-1]}"]
    if DEVICE_CURRENT in series:
        out[DEVICE_CURRENT] = series[DEVICE_CURRENT]
    return out


def write_figure_series(path: Path, series: dict[str, np.ndarray]) -> None:
    """:func:`figure_columns` at :func:`figure_rows` as a Parquet table (time float64, the rest float32)."""
    from orchestration.master.recorder import write_parquet

    columns = figure_columns(series)
    rows = figure_rows(len(columns["time"]))
    names = [n for n in columns if n != "time"]
    data = np.column_stack([columns[n][rows] for n in names]) if names else np.zeros((0, 0))
    write_parquet(path, columns["time"][rows], names, data, ["real"] * len(names), {})


def _strict(value: Any) -> Any:
    """``value`` with every non-finite float as None (strict JSON)."""
    if isinstance(value, dict):
        return {k: _strict(v) for k, v in value.items()}
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    return value


def _floats(value: Any) -> Any:
    """``value`` as :func:`_strict` wrote it, with None back as NaN in the number tables."""
    if isinstance(value, dict):
        return {k: (math.nan if v is None else _floats(v)) for k, v in value.items()}
    return value


def numbers_json(numbers: dict[str, Any]) -> str:
    """``metrics.json``'s text: strict JSON, non-finite numbers as null."""
    doc = {"computed_from": "every step, in the run (orchestration/case_study/run_numbers.py)", **numbers}
    return json.dumps(_strict(doc), indent=1, allow_nan=False) + "\n"


class RunFileError(ValueError):
    """A run folder's file that is not what a study's run wrote (it names the file and what is wrong)."""


def _regular(path: Path) -> bool:
    """Whether ``path`` is there; RunFileError if it is, but is not a regular file (a folder, a device, a link to
    one)."""
    from orchestration.tool_files import input_problem

    if not (path.exists() or path.is_symlink()):
        return False
    problem = input_problem(path)
    if problem:
        raise RunFileError(f"{problem}: not a run's {path.name}")
    return True


def _required(part: str) -> tuple[str, ...]:
    """The names every run writes in a part of ``metrics.json`` (what the tables and the report read)."""
    from orchestration.building_studies.run_metrics import PEAK_COLUMNS
    from orchestration.case_study.benchmark_criteria import CRITERIA, EFFORT

    if part == "metrics":
        return (*PEAK_COLUMNS[2:], "current_min_A", "structure_shear_N", "rms_x_base_mm", "rms_acc_max",
                "drift_max_mm", "acc_max", "time_beyond_8mm_s", "time_beyond_15mm_s", "duration_s",
                "time_current_outside_paper_range_s", "current_limit_A", "current_share_at_limit",
                "current_share_at_zero", "current_share_at_range_top")
    return (*CRITERIA, *EFFORT) if part == "criteria" else ()


def _numbers_part(path: Path, doc: dict[str, Any], part: str, optional: bool = False) -> dict[str, Any] | None:
    """One part of ``metrics.json`` checked: a mapping of names to numbers (null for a non-finite one; Booleans in
    ``sosm_conditions``) with every name a run writes; None for an optional part that is null."""
    value = doc.get(part)
    if value is None and optional:
        return None
    if not isinstance(value, dict):
        raise RunFileError(f"{path}: '{part}' is not a mapping of numbers: not a run's {NUMBERS_FILE}")
    flags = part == "sosm_conditions"
    for k, v in value.items():
        if v is not None and not (isinstance(v, int | float) and (flags or not isinstance(v, bool))):
            raise RunFileError(f"{path}: {part}.{k} = {v!r} is not a number: not a run's {NUMBERS_FILE}")
    missing = [k for k in _required(part) if k not in value]
    if missing:
        raise RunFileError(f"{path}: {part} has no {', '.join(missing[:5])}: not a run's {NUMBERS_FILE}")
    return _floats(value)


def read_numbers(run_folder: Path, inputs: NumberInputs, energy: dict[str, Any] | None) -> dict[str, Any] | None:
    """A run's numbers: its ``metrics.json``, or (a folder written before runs kept them) computed from its
    ``timeseries.csv`` with ``inputs``; None if it has neither. RunFileError (naming the file) for a file that is
    not what a run wrote: not JSON, not numbers, larger than :data:`MAX_NUMBERS_BYTES`, not a regular file."""
    path = run_folder / NUMBERS_FILE
    if _regular(path):
        if path.stat().st_size > MAX_NUMBERS_BYTES:
            raise RunFileError(f"{path}: larger than {MAX_NUMBERS_BYTES >> 20} MiB: not a run's {NUMBERS_FILE}")
        try:
            doc = json.loads(path.read_text())
        except (ValueError, OSError) as exc:
            raise RunFileError(f"{path}: not JSON ({str(exc)[:120]}): not a run's {NUMBERS_FILE}") from None
        if not isinstance(doc, dict):
            raise RunFileError(f"{path}: a JSON {type(doc).__name__}, not an object: not a run's {NUMBERS_FILE}")
        return {"rows": doc.get("rows"), "metrics": _numbers_part(path, doc, "metrics"),
                "criteria": _numbers_part(path, doc, "criteria"),
                "sosm_conditions": _numbers_part(path, doc, "sosm_conditions", optional=True)}
    from orchestration.building_studies.run_metrics import read_timeseries

    csv_file = run_folder / "timeseries.csv"
    if not _regular(csv_file):
        return None
    return run_numbers(read_timeseries(csv_file), energy, inputs)


def read_figure_series(run_folder: Path) -> dict[str, np.ndarray] | None:
    """The series a run's figures draw (:func:`figure_columns`): its figure series, else its results file (every
    step it kept); None if it has none. RunFileError (naming the file) for one that is not a table of numbers with
    the columns the figures draw."""
    from orchestration.building_studies.run_metrics import CURRENT, read_timeseries

    for name in (FIGURE_SERIES_FILE, "timeseries.parquet", "timeseries.csv"):
        path = run_folder / name
        if _regular(path):
            try:
                series = read_timeseries(path)
                drawn = series if name == FIGURE_SERIES_FILE else figure_columns(series)
                missing = [c for c in ("time", "building.x_0", "isolator.F", CURRENT, TOP_FLOOR) if c not in drawn]
                if missing:
                    raise KeyError(f"no column {', '.join(missing)}")
                return drawn
            except Exception as exc:  # pyarrow's and numpy's errors for a file that is not what its name says
                raise RunFileError(f"{path}: not a run's {name} ({type(exc).__name__}: "
                                   f"{str(exc).splitlines()[0][:160] if str(exc) else ''})") from None
    return None
