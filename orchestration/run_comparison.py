"""Runs side by side: the peaks of their report roles in one table, and overlays of their time histories.

A run folder (``run.py``'s) holds ``summary.json`` (every variable's peak, computed from every step during
the run), ``manifest.json`` (the scenario, with its report roles) and ``timeseries.csv``. The comparison
takes the variables of the first run's roles (base displacement, drifts, floor accelerations, current,
isolator force, ground acceleration) that every run recorded; the others are named, not compared.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from orchestration.master.figure_files import FigureFiles, save_figure

ROLES = (  # report role, what it is, SI unit, display unit, factor SI -> display
    ("base_displacement", "base displacement", "m", "mm", 1e3),
    ("drifts", "storey drift", "m", "mm", 1e3),
    ("floor_accelerations", "absolute floor acceleration", "m/s2", "m/s²", 1.0),
    ("current", "current command", "A", "A", 1.0),
    ("device_current", "device current", "A", "A", 1.0),
    ("isolator_force", "isolator force", "N", "kN", 1e-3),
    ("ground_acceleration", "ground acceleration", "m/s2", "m/s²", 1.0),
)


class ComparisonError(ValueError):
    """A folder that is not a run, or runs with nothing in common; the message names the folder."""


@dataclass
class Run:
    """One run folder: its label, its report roles (role -> variables), its peaks and its time series."""

    folder: Path
    label: str
    roles: dict[str, list[str]]
    peaks: dict[str, float]  # variable -> peak |value| over every step [SI]
    valid: bool | None
    names: dict[str, str] = field(default_factory=dict)  # variable -> the report's label for it
    _series: dict[str, np.ndarray] | None = field(default=None, repr=False)

    def series(self) -> dict[str, np.ndarray]:
        """The recorded columns by name (read on first use); ComparisonError naming the file if it is not a
        results file of numbers with a ``time`` column."""
        if self._series is None:
            parquet = self.folder / "timeseries.parquet"
            path = parquet if parquet.is_file() else self.folder / "timeseries.csv"
            try:
                self._series = _read_parquet(path) if path == parquet else _read_csv(path)
            except Exception as exc:  # pyarrow's and numpy's errors for a file that is not what its name says
                raise ComparisonError(f"{path}: not a results file ({type(exc).__name__}: "
                                      f"{str(exc).splitlines()[0][:200] if str(exc) else ''})") from None
            if "time" not in self._series:
                raise ComparisonError(f"{path}: no time column")
        return self._series


def _read_parquet(path: Path) -> dict[str, np.ndarray]:
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    return {name: table.column(name).to_numpy().astype(float) for name in table.column_names}


def _read_csv(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="") as f:
        header = next(csv.reader(f), [])
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    if data.size and data.shape[1] != len(header):
        raise ValueError(f"{data.shape[1]} columns of numbers under {len(header)} names")
    return {name: data[:, k] for k, name in enumerate(header)}


MAX_JSON_BYTES = 64 << 20
"""Largest summary.json or manifest.json read (a run writes a few kB)."""


def _mapping(value: object) -> dict:
    return value if isinstance(value, dict) else {}


def _number_or_nan(value: object) -> float:
    """A JSON number as a float (nan for anything else, or for an integer too large for one)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return math.nan
    try:
        return float(value)
    except OverflowError:
        return math.nan


def read_run(folder: Path) -> Run:
    """A run folder; ComparisonError naming the folder and the file if it is none (or not a complete run)."""
    folder = Path(folder)
    texts = {}
    for name in ("summary.json", "manifest.json"):
        try:
            if (folder / name).stat().st_size > MAX_JSON_BYTES:
                raise ComparisonError(f"{folder}/{name}: larger than {MAX_JSON_BYTES >> 20} MiB, not a run's")
            texts[name] = json.loads((folder / name).read_text())
        except FileNotFoundError:
            raise ComparisonError(f"{folder}: no {name} (not a run folder of run.py)") from None
        except (OSError, ValueError) as exc:
            raise ComparisonError(f"{folder}/{name}: unreadable ({exc})") from None
        if not isinstance(texts[name], dict):
            raise ComparisonError(f"{folder}/{name}: not a run's {name} (a JSON {type(texts[name]).__name__})")
    summary, manifest = texts["summary.json"], texts["manifest.json"]
    if not any((folder / f"timeseries.{ext}").is_file() for ext in ("csv", "parquet")):
        kept = _mapping(summary.get("results_file"))
        why = (" (the run kept no time series: a study keeps its runs' only with `timeseries: true`; its numbers "
               "are in the run's metrics.json)" if "file" in kept and kept["file"] is None else "")
        raise ComparisonError(f"{folder}: no timeseries.csv or timeseries.parquet{why}")
    report = _mapping(_mapping(manifest.get("scenario")).get("report"))
    roles = {}
    for role, *_ in ROLES:
        value = report.get(role)
        names = [value] if isinstance(value, str) else [v for v in value if isinstance(v, str)] \
            if isinstance(value, list) else []
        if names:
            roles[role] = names
    peaks = {k: _number_or_nan(v.get("max_abs")) for k, v in _mapping(summary.get("variables")).items()
             if isinstance(v, dict) and "max_abs" in v}
    label = str(summary.get("caption") or folder.name)
    names = {k: v for k, v in _mapping(report.get("labels")).items() if isinstance(v, str) and "=" not in k}
    return Run(folder, label, roles, peaks, summary.get("valid") if isinstance(summary.get("valid"), bool) else None,
               names)


def labelled(runs: list[Run]) -> list[Run]:
    """The runs, each labelled by its caption, or by its folder name where captions repeat."""
    captions = [r.label for r in runs]
    for r in runs:
        if captions.count(r.label) > 1:
            r.label = r.folder.name
    return runs


@dataclass(frozen=True)
class Row:
    """One compared variable: its role, name, display unit and each run's peak in that unit."""

    role: str
    what: str
    variable: str
    unit: str
    peaks: tuple[float, ...]


def compared(runs: list[Run]) -> tuple[list[Row], list[str]]:
    """The rows (the first run's role variables that every run has a peak of) and a note per variable left out."""
    rows, notes = [], []
    for role, what, _si, unit, factor in ROLES:
        for variable in runs[0].roles.get(role, []):
            missing = [r.folder.name for r in runs if variable not in r.peaks]
            if missing:
                notes.append(f"{variable} ({what}): not in {', '.join(missing)}")
                continue
            rows.append(Row(role, what, variable, unit, tuple(factor * r.peaks[variable] for r in runs)))
    others = sorted({v for r in runs[1:] for vs in r.roles.values() for v in vs} - {row.variable for row in rows}
                    - {n.split(" ")[0] for n in notes})
    notes += [f"{v}: a role of a later run, not of {runs[0].folder.name}" for v in others]
    return rows, notes


def _number(x: float) -> str:
    return "nan" if not math.isfinite(x) else f"{x:.4g}"


def table(runs: list[Run], rows: list[Row]) -> str:
    """The peaks as a plain-text table: a column per run, and each later run's change against the first."""
    head = ["variable", "unit", *(f"[{k + 1}]" for k in range(len(runs))),
            *(f"[{k + 1}] vs [1]" for k in range(1, len(runs)))]
    body = []
    for row in rows:
        first = row.peaks[0]
        changes = [f"{100 * (p / first - 1):+.1f} %" if first else "-" for p in row.peaks[1:]]
        body.append([row.variable, row.unit, *(_number(p) for p in row.peaks), *changes])
    widths = [max(len(str(c)) for c in col) for col in zip(head, *body, strict=True)]
    lines = ["  ".join(str(c).ljust(w) for c, w in zip(line, widths, strict=True)).rstrip()
             for line in (head, *body)]
    legend = [f"[{k + 1}] {r.label} ({r.folder}){'' if r.valid is not False else ', NOT numerically valid'}"
              for k, r in enumerate(runs)]
    return "\n".join([*legend, "peaks (largest |value| over every step, summary.json):", *lines])


def write_csv(runs: list[Run], rows: list[Row], path: Path) -> None:
    """peaks.csv: variable, unit, then each run's peak (columns named by run folder)."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["role", "variable", "unit", *(r.folder.name for r in runs)])
        for row in rows:
            w.writerow([row.role, row.variable, row.unit, *(repr(p) for p in row.peaks)])


COMPARE_DPI = 150
"""The overlays' PNG resolution unless one is asked for [dots per inch]."""
STYLES = ({"ls": "-"}, {"ls": "--"}, {"ls": ":"}, {"ls": "-."})


def figures(runs: list[Run], rows: list[Row], out: Path, files: FigureFiles, made: list[Path]) -> list[Path]:
    """One overlay per role (its variables in a grid of panels, a line style per run) as PNG and each of
    ``files.formats``; each file is appended to ``made`` as soon as it is written (so a failure can remove them)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from orchestration.master.report import decimate

    factor = {role: f for role, *_, f in ROLES}
    for role, what, *_ in ROLES:
        mine = [row for row in rows if row.role == role]
        if not mine:
            continue
        cols = 1 if len(mine) == 1 else 2
        n_rows = math.ceil(len(mine) / cols)
        fig, axes = plt.subplots(n_rows, cols, figsize=(9 if cols == 2 else 8, 2.6 * n_rows + 0.6), squeeze=False,
                                 sharex=True)
        for ax, row in zip(axes.flat, mine, strict=False):
            for k, r in enumerate(runs):
                ts = r.series()
                if row.variable not in ts:
                    continue
                t, y = decimate(ts["time"], factor[role] * ts[row.variable])
                ax.plot(t, y, lw=0.8, label=f"[{k + 1}] {r.label}", color=f"C{k % 10}", **STYLES[k % len(STYLES)])
            name = runs[0].names.get(row.variable, "")
            ax.set_title(f"{row.variable}" + (f": {name}" if name and "{" not in name else ""), fontsize=9,
                         loc="left")
            ax.set_ylabel(f"{what} [{row.unit}]", fontsize=8)
            ax.grid(alpha=0.3)
        for ax in list(axes.flat)[len(mine):]:
            ax.set_visible(False)
        for ax in axes[-1]:
            ax.set_xlabel("time [s]")
        handles, labels = axes.flat[0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="upper center", ncol=1, fontsize=8, frameon=False)
        fig.tight_layout(rect=(0, 0, 1, 1 - 0.07 * len(runs) / n_rows))
        try:
            save_figure(fig, out / f"{role}.png", files, COMPARE_DPI, tight=False, made=made)
        finally:
            plt.close(fig)
    return made
