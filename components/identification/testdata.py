"""Shake-table test records: the CSV format, its validation, and a synthetic generator.

CSV format (one file per test run, UTF-8, comma separated)::

    # frequency_hz: 2
    # amplitude_mm: 4
    # current_a: 1
    # repeat: 1                      (optional, default 1)
    # synthetic: false               (optional; the generator writes true)
    time_s,displacement_mm,force_n[,velocity_mm_s][,force_clean_n]
    0.0,0.0,1.23
    ...

Metadata are ``# key: value`` lines before the header row; other comment lines are
ignored. Columns may come in any order; ``velocity_mm_s`` is optional (if absent, the
velocity is the second-order finite-difference derivative of the displacement,
``numpy.gradient(x, t, edge_order=2)``, as the paper does). ``force_clean_n`` appears
only in synthetic files (the force before noise); identification never reads it, the
report uses it to state the noise RMS. Time must be strictly increasing, every value
finite, and the file must hold at least two full cycles and ``MIN_SAMPLES`` samples.

Units are the paper's: mm, mm/s, N, s, Hz, A.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from components.identification.paper_tables import TABLE1, TEST_MATRIX, Condition
from components.physics.bouc_wen_core import BoucWenCurrentModel, bouc_wen_states
from components.physics.mre_isolator_core import HyperbolicParams
from mre_common.atomic_files import atomic_write_text

REQUIRED_COLUMNS = ("time_s", "displacement_mm", "force_n")
OPTIONAL_COLUMNS = ("velocity_mm_s", "force_clean_n")
REQUIRED_METADATA = ("frequency_hz", "amplitude_mm", "current_a")
MIN_SAMPLES = 32
SYNTHETIC_NOTE = "SYNTHETIC DATA: generated from the paper's Table 1 parameters, not measured"


class TestDataError(ValueError):
    """A test file (or record) is unusable; the message starts with the file name."""

    __test__ = False  # not a pytest test class


@dataclass(frozen=True, eq=False)
class ShakeRecord:
    """One shake-table test run, paper units: t [s], x [mm], v [mm/s], F [N]."""

    source: str
    frequency_hz: float
    amplitude_mm: float
    current_a: float
    repeat: int
    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    F: np.ndarray
    velocity_measured: bool = False
    synthetic: bool = False
    F_clean: np.ndarray | None = None
    meta: Mapping[str, str] = field(default_factory=dict)

    @property
    def condition(self) -> Condition:
        return (self.frequency_hz, self.amplitude_mm, self.current_a)

    def cycle_window(self, first_cycle: int, cycles: int) -> slice:
        """Samples of full cycles first_cycle .. first_cycle+cycles-1 (cycle 0 starts at t[0])."""
        period = 1.0 / self.frequency_hz
        eps = 1e-9 * period
        rel = self.t - self.t[0]
        available = math.floor((rel[-1] + eps) / period)
        if first_cycle + cycles > available:
            raise TestDataError(
                f"{self.source}: needs {first_cycle + cycles} full cycles of {self.frequency_hz:g} Hz "
                f"for the fit window, the record holds {available}"
            )
        start = np.searchsorted(rel, first_cycle * period - eps)
        stop = np.searchsorted(rel, (first_cycle + cycles) * period - eps)
        return slice(int(start), int(stop))


def _fail(source: str, message: str) -> TestDataError:
    return TestDataError(f"{source}: {message}")


def velocity_by_differences(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """dx/dt by second-order finite differences [mm/s] (x [mm], t [s])."""
    return np.gradient(x, t, edge_order=2)


def make_record(
    source: str,
    meta: Mapping[str, str],
    columns: Mapping[str, np.ndarray],
) -> ShakeRecord:
    """Validate metadata and columns and build a record; raises TestDataError naming ``source``."""
    missing_meta = [k for k in REQUIRED_METADATA if k not in meta]
    if missing_meta:
        raise _fail(source, f"missing metadata line(s) {', '.join('# ' + k + ': ...' for k in missing_meta)}")
    values = {}
    for key in (*REQUIRED_METADATA, "repeat"):
        raw = meta.get(key, "1")
        try:
            values[key] = float(raw)
        except ValueError:
            raise _fail(source, f"metadata {key} = {raw!r} is not a number") from None
        if not math.isfinite(values[key]):
            raise _fail(source, f"metadata {key} = {raw!r} is not finite")
    if values["frequency_hz"] <= 0 or values["amplitude_mm"] <= 0 or values["current_a"] < 0:
        raise _fail(source, "frequency_hz and amplitude_mm must be > 0 and current_a >= 0")
    missing = [c for c in REQUIRED_COLUMNS if c not in columns]
    if missing:
        raise _fail(
            source, f"missing column(s) {', '.join(missing)} (required: {', '.join(REQUIRED_COLUMNS)})"
        )
    for name, col in columns.items():
        bad = np.flatnonzero(~np.isfinite(col))
        if bad.size:
            raise _fail(
                source,
                f"column {name} has {bad.size} NaN/non-finite or non-numeric value(s), "
                f"first at data row {bad[0] + 1}",
            )
    t = np.asarray(columns["time_s"], dtype=float)
    n = t.size
    if n < MIN_SAMPLES:
        raise _fail(source, f"too few samples: {n} (at least {MIN_SAMPLES})")
    steps = np.diff(t)
    if np.any(steps <= 0):
        k = int(np.flatnonzero(steps <= 0)[0])
        raise _fail(
            source,
            f"time is not strictly increasing at data row {k + 2} (t = {t[k]:.9g} then {t[k + 1]:.9g})",
        )
    duration = t[-1] - t[0]
    if duration * values["frequency_hz"] < 2.0 - 1e-9:
        raise _fail(
            source,
            f"too few samples: {duration:.4g} s covers less than two cycles of {values['frequency_hz']:g} Hz",
        )
    x = np.asarray(columns["displacement_mm"], dtype=float)
    measured = "velocity_mm_s" in columns
    v = np.asarray(columns["velocity_mm_s"], dtype=float) if measured else velocity_by_differences(t, x)
    synthetic = str(meta.get("synthetic", "false")).strip().lower() in ("true", "yes", "1")
    clean = columns.get("force_clean_n")
    return ShakeRecord(
        source=source,
        frequency_hz=values["frequency_hz"],
        amplitude_mm=values["amplitude_mm"],
        current_a=values["current_a"],
        repeat=int(values["repeat"]),
        t=t,
        x=x,
        v=v,
        F=np.asarray(columns["force_n"], dtype=float),
        velocity_measured=measured,
        synthetic=synthetic,
        F_clean=None if clean is None else np.asarray(clean, dtype=float),
        meta=dict(meta),
    )


def read_csv(path: str | os.PathLike) -> ShakeRecord:
    """Read and validate one test file; every problem raises TestDataError naming the file."""
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise _fail(source, f"cannot read: {exc}") from None
    meta: dict[str, str] = {}
    body: list[str] = []
    for line in text.splitlines():
        stripped = line.strip()
        if stripped.startswith("#"):
            key, sep, value = stripped[1:].partition(":")
            if sep and not body:
                meta[key.strip()] = value.strip()
        elif stripped:
            body.append(stripped)
    if not body:
        raise _fail(source, "no header row and no data")
    reader = csv.reader(io.StringIO("\n".join(body)))
    header = [h.strip() for h in next(reader)]
    if len(set(header)) != len(header):
        raise _fail(source, f"duplicate column names in header {header}")
    known = set(REQUIRED_COLUMNS) | set(OPTIONAL_COLUMNS)
    unknown = [h for h in header if h not in known]
    if unknown:
        raise _fail(source, f"unknown column(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")
    rows = list(reader)
    data = np.full((len(rows), len(header)), np.nan)
    for r, row in enumerate(rows):
        if len(row) != len(header):
            raise _fail(source, f"data row {r + 1} has {len(row)} fields, the header has {len(header)}")
        for c, cell in enumerate(row):
            try:
                data[r, c] = float(cell)
            except ValueError:
                pass  # stays NaN, reported by make_record with its column
    columns = {h: data[:, c] for c, h in enumerate(header)}
    return make_record(source, meta, columns)


def read_folder(folder: str | os.PathLike) -> list[ShakeRecord]:
    """All ``*.csv`` test files of a folder, sorted by name."""
    paths = sorted(Path(folder).glob("*.csv"))
    if not paths:
        raise TestDataError(f"{folder}: no *.csv test files")
    return [read_csv(p) for p in paths]


def write_csv(record: ShakeRecord, path: str | os.PathLike) -> None:
    """Write a record in the documented CSV format (atomically)."""
    meta = {
        "frequency_hz": f"{record.frequency_hz:g}",
        "amplitude_mm": f"{record.amplitude_mm:g}",
        "current_a": f"{record.current_a:g}",
        "repeat": str(record.repeat),
        "synthetic": "true" if record.synthetic else "false",
        **{k: v for k, v in record.meta.items() if k not in (*REQUIRED_METADATA, "repeat", "synthetic")},
    }
    lines = [f"# {SYNTHETIC_NOTE}"] if record.synthetic else []
    lines += [f"# {k}: {v}" for k, v in meta.items()]
    cols = {"time_s": record.t, "displacement_mm": record.x, "force_n": record.F}
    if record.velocity_measured:
        cols["velocity_mm_s"] = record.v
    if record.F_clean is not None:
        cols["force_clean_n"] = record.F_clean
    lines.append(",".join(cols))
    table = np.column_stack(list(cols.values()))
    lines += [",".join(f"{val:.9g}" for val in row) for row in table]
    atomic_write_text(path, "\n".join(lines) + "\n")


# --------------------------------------------------------------------------- synthetic data


@dataclass(frozen=True)
class NoiseModel:
    """Additive, independent, zero-mean Gaussian measurement noise.

    Force noise std [N] = force_rel * RMS(clean force of the run) + force_abs_n.
    Displacement noise std [mm] = displacement_mm (default 0: the displacement is exact,
    so the finite-difference velocity has no noise amplification).
    """

    force_rel: float = 0.02
    force_abs_n: float = 0.0
    displacement_mm: float = 0.0

    def __post_init__(self) -> None:
        for name in ("force_rel", "force_abs_n", "displacement_mm"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"noise.{name} must be a finite number >= 0, got {value!r}")


def hyperbolic_force_mm(x, v, c0, k0, alpha, beta, F0=0.0):
    """Eq. (3)-(4) in paper units (x [mm], v [mm/s], k0 [N/mm], ...); broadcasts; force [N]."""
    return c0 * v + k0 * x + alpha * np.sinh(beta * x) + F0


@dataclass(frozen=True)
class SyntheticSettings:
    """How synthetic runs are made: their noise, the true model and the record's sampling.

    ``model="hyperbolic"``: Eq. (3)-(4) with the Table 1 parameters of the condition.
    ``model="bouc_wen"``: Eq. (1)-(2) with ``bouc_wen`` evaluated at the condition's current
    (model-form error test). ``fs_hz`` sampling rate, ``cycles`` of the sine, ``F0_n`` force
    offset [N]; the file carries velocity only if ``include_velocity``.
    """

    noise: NoiseModel
    model: str = "hyperbolic"
    fs_hz: float = 256.0
    cycles: int = 10
    F0_n: float = 0.0
    include_velocity: bool = False
    bouc_wen: BoucWenCurrentModel | None = None


def synthetic_record(condition: Condition, repeat: int, rng: np.random.Generator,
                     settings: SyntheticSettings) -> ShakeRecord:
    """One synthetic run: x = A sin(2 pi f t) from t = 0, force from the true model (``settings``) plus noise.

    The exact velocity drives the true force.
    """
    noise, model, fs_hz, cycles, F0_n = settings.noise, settings.model, settings.fs_hz, settings.cycles, settings.F0_n
    include_velocity, bouc_wen = settings.include_velocity, settings.bouc_wen
    f, a, i = condition
    if cycles < 2:
        raise ValueError("synthetic cycles must be >= 2")
    n = round(cycles * fs_hz / f) + 1
    t = np.arange(n) / fs_hz
    w = 2.0 * np.pi * f
    x = a * np.sin(w * t)
    v = a * w * np.cos(w * t)
    if model == "hyperbolic":
        p = TABLE1[condition]
        clean = hyperbolic_force_mm(x, v, p["c0"], p["k0"], p["alpha"], p["beta"], F0_n)
        truth = {**p, "F0": F0_n}
    elif model == "bouc_wen":
        if bouc_wen is None:
            raise ValueError("model='bouc_wen' needs the bouc_wen coefficients")
        bw = bouc_wen.at_current(i, F0_n).to_paper_units()
        y = bouc_wen_states(x, bw["beta"], bw["gamma"], bw["delta"], bw["n"], dx_max=0.02)
        clean = bw["k"] * x + bw["c"] * v + bw["alpha"] * y + F0_n
        truth = bw
    else:
        raise ValueError(f"unknown synthetic model {model!r} (hyperbolic or bouc_wen)")
    sigma_f = noise.force_rel * float(np.sqrt(np.mean(clean**2))) + noise.force_abs_n
    force = clean + sigma_f * rng.standard_normal(n)
    x_meas = x + noise.displacement_mm * rng.standard_normal(n) if noise.displacement_mm > 0 else x
    meta = {
        "synthetic": "true",
        "synthetic_model": model,
        "noise_force_std_n": f"{sigma_f:.6g}",
        "noise_displacement_std_mm": f"{noise.displacement_mm:g}",
        **{f"true_{k}": f"{val:.6g}" for k, val in truth.items()},
    }
    return ShakeRecord(
        source=f"synthetic:{model}:f{f:g}Hz_A{a:g}mm_I{i:g}A_r{repeat}",
        frequency_hz=f,
        amplitude_mm=a,
        current_a=i,
        repeat=repeat,
        t=t,
        x=x_meas,
        v=v if include_velocity else velocity_by_differences(t, x_meas),
        F=force,
        velocity_measured=include_velocity,
        synthetic=True,
        F_clean=clean,
        meta=meta,
    )


def generate_synthetic(
    seed: int,
    noise: NoiseModel,
    conditions: Iterable[Condition] = TEST_MATRIX,
    repeats: int = 5,
    **kwargs,
) -> list[ShakeRecord]:
    """Synthetic runs over ``conditions`` x ``repeats``; reproducible for a given seed.

    Each run draws from its own generator seeded by (seed, condition index, repeat), so
    a run does not change when other conditions are added or removed. ``kwargs``: the other
    fields of :class:`SyntheticSettings`.
    """
    settings = SyntheticSettings(noise, **kwargs)
    records = []
    for cond in conditions:
        index = TEST_MATRIX.index(cond)
        for r in range(1, repeats + 1):
            rng = np.random.default_rng([seed, index, r])
            records.append(synthetic_record(cond, r, rng, settings))
    return records


def true_hyperbolic(condition: Condition, F0: float = 0.0) -> HyperbolicParams:
    """The Table 1 parameters of a condition in SI (the truth of the synthetic data)."""
    return HyperbolicParams.from_paper_units(F0=F0, **TABLE1[condition])


__all__ = [
    "MIN_SAMPLES",
    "NoiseModel",
    "ShakeRecord",
    "TestDataError",
    "generate_synthetic",
    "hyperbolic_force_mm",
    "make_record",
    "read_csv",
    "read_folder",
    "synthetic_record",
    "velocity_by_differences",
    "write_csv",
]
