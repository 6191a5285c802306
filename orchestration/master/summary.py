"""``summary.json``: a run's summary as a typed record (:class:`RunSummary`), and the engine's part of it.

The engine's part is generic: every recorded numeric variable's peak, minimum and maximum
(:func:`summarize`) and the run's numerical validity (:func:`~orchestration.master.report.report_summary`:
a non-finite recorded value is the engine's reason, the application's hook adds its own, such as an energy
balance that does not close). The application's other entries (peaks per role, the physical outcome, the
energy balance) are carried as the hook made them, in its order.

The file is strict JSON (RFC 8259): a non-finite number is written as null and named, with its reason,
under ``non_finite`` (:func:`~orchestration.master.runfolder.strict_json_data`). :meth:`RunSummary.to_json`
is the one serialiser; :meth:`RunSummary.from_dict` reads the same layout back, so that
``from_dict(d).to_dict() == d`` (same keys in the same order).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from mre_common.atomic_files import atomic_write_text
from orchestration.master.recorder import Recorder
from orchestration.master.runfolder import NON_FINITE_KEY, strict_json_data


def peak(x: np.ndarray) -> float | None:
    """Largest absolute value, or None for an empty series."""
    return float(np.max(np.abs(x))) if len(x) else None


def sample_interval(rec: Recorder) -> float:
    """The recorded time step [s] (0 with fewer than two samples)."""
    t = rec.times
    return float(t[1] - t[0]) if len(t) > 1 else 0.0


@dataclass(frozen=True)
class VariableRange:
    """One recorded variable's peak (largest absolute value), minimum and maximum over every step, SI units
    (None: nothing recorded, or not finite once read back from the file)."""

    max_abs: float | None
    min: float | None
    max: float | None


@dataclass(frozen=True)
class ResultsFile:
    """The run's results file: its name (None: the run was asked to write none, see
    :func:`~orchestration.master.session.run_plan`), the interval of the rows it keeps, how many it holds."""

    file: str | None
    every_nth_step: int
    rows: int


@dataclass
class RunSummary:
    """``summary.json``: how the run ended, its numerical validity, the application's entries, every variable.

    Written in this order: the run's status (``scenario`` .. ``results_file``; ``executor_note`` only when
    there is one), ``valid`` and ``invalid_reasons``, the application's entries (:attr:`report`), the
    ``variables`` table, then what was added after the run (``step_convergence`` by ``--verify-step``, any
    other key in :attr:`later`) and ``non_finite`` (the values written as null).
    """

    scenario: str
    caption: str
    complete: bool
    status: str
    error: str | None
    run_id: str
    end_time_s: float
    steps_done: int
    n_steps: int
    wall_time_s: float
    executor: str
    unit_warnings: dict[str, int]
    results_file: ResultsFile
    valid: bool
    invalid_reasons: list[str]
    variables: dict[str, VariableRange]
    executor_note: str = ""  # why the native executor was not used, if it was not
    report: dict[str, Any] = field(default_factory=dict)  # the application's entries (ReportHook.summarize)
    step_convergence: dict[str, Any] | None = None  # added by --verify-step (orchestration.step_check)
    later: dict[str, Any] = field(default_factory=dict)  # other keys after the variables table
    non_finite: dict[str, str] = field(default_factory=dict)  # "path" -> reason, of values written as null

    STATUS_KEYS: ClassVar[tuple[str, ...]] = ("scenario", "caption", "complete", "status", "error", "run_id",
                                              "end_time_s", "steps_done", "n_steps", "wall_time_s", "executor")

    def to_dict(self) -> dict[str, Any]:
        """The record as ``summary.json`` lays it out (numbers as they are: :meth:`to_json` makes them strict)."""
        out: dict[str, Any] = {key: getattr(self, key) for key in self.STATUS_KEYS}
        if self.executor_note:
            out["executor_note"] = self.executor_note
        out |= {"unit_warnings": self.unit_warnings, "results_file": asdict(self.results_file),
                "valid": self.valid, "invalid_reasons": self.invalid_reasons}
        out |= {k: v for k, v in self.report.items() if k not in out}
        out["variables"] = {name: asdict(r) for name, r in self.variables.items()}
        if self.step_convergence is not None:
            out["step_convergence"] = self.step_convergence
        out |= {k: v for k, v in self.later.items() if k not in out}
        if self.non_finite:
            out[NON_FINITE_KEY] = self.non_finite
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RunSummary:
        """The record of a summary laid out as :meth:`to_dict` lays it out (a run's, or ``summary.json`` read back);
        a key of the run's status or validity that is missing is a :class:`KeyError`."""
        engine = {*cls.STATUS_KEYS, "executor_note", "unit_warnings", "results_file", "valid", "invalid_reasons",
                  "variables", "step_convergence", NON_FINITE_KEY}
        report: dict[str, Any] = {}
        later: dict[str, Any] = {}
        after_variables = False
        for key, value in data.items():
            after_variables = after_variables or key == "variables"
            if key not in engine:
                (later if after_variables else report)[key] = value
        return cls(**{key: data[key] for key in cls.STATUS_KEYS},
                   executor_note=data.get("executor_note") or "",
                   unit_warnings=dict(data["unit_warnings"]),
                   results_file=ResultsFile(**data["results_file"]),
                   valid=bool(data["valid"]),
                   invalid_reasons=[str(r) for r in data["invalid_reasons"]],
                   report=report,
                   variables={name: VariableRange(**r) for name, r in data["variables"].items()},
                   step_convergence=data.get("step_convergence"),
                   later=later,
                   non_finite=dict(data.get(NON_FINITE_KEY) or {}))

    @classmethod
    def read(cls, path: Path) -> RunSummary:
        """A ``summary.json`` read back."""
        return cls.from_dict(json.loads(Path(path).read_text()))

    def to_json(self) -> str:
        """The file's text: strict JSON, indented, a non-finite number as null and named under ``non_finite``."""
        return json.dumps(strict_json_data(self.to_dict()), indent=2, default=str, allow_nan=False)

    def write(self, path: Path) -> None:
        """Write the file atomically (temporary file, then rename)."""
        atomic_write_text(path, self.to_json())


def write_summary(path: Path, summary: Mapping[str, Any]) -> None:
    """A run's summary (laid out as :meth:`RunSummary.to_dict` lays it out) written as ``summary.json``."""
    RunSummary.from_dict(summary).write(path)


def variable_ranges(rec: Recorder) -> dict[str, VariableRange]:
    """Every recorded numeric variable's peak, minimum and maximum (SI units), all columns at once."""
    numeric = [k for k, kind in enumerate(rec.kinds) if kind != "string"]
    if not rec.count or not numeric:
        return {rec.names[k]: VariableRange(None, None, None) for k in numeric}
    block = rec.data[: rec.count]
    if len(numeric) != block.shape[1]:
        block = block[:, numeric]
    top, low, high = np.max(np.abs(block), axis=0), np.min(block, axis=0), np.max(block, axis=0)
    return {rec.names[k]: VariableRange(float(top[j]), float(low[j]), float(high[j])) for j, k in enumerate(numeric)}


def summarize(rec: Recorder) -> dict[str, Any]:
    """The engine's own summary: ``{"variables": {name: {"max_abs", "min", "max"}}}`` (:func:`variable_ranges`)."""
    return {"variables": {name: asdict(r) for name, r in variable_ranges(rec).items()}}


def non_finite(rec: Recorder) -> list[str]:
    """One line per recorded numeric variable that took a non-finite value (NaN, +-inf), with when it first did."""
    numeric = [k for k, kind in enumerate(rec.kinds) if kind != "string"]
    if not rec.count or not numeric:
        return []
    block = rec.data[: rec.count]
    bad = ~np.isfinite(block[:, numeric] if len(numeric) != block.shape[1] else block)
    out = []
    for j in np.flatnonzero(bad.any(axis=0)):
        row, col = int(np.argmax(bad[:, j])), numeric[j]
        out.append(f"non-finite value: {rec.names[col]} = {block[row, col]} at t = {rec.times[row]:.6g} s")
    return out
