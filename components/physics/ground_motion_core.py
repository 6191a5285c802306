"""Ground-motion records: reading and playback.

Formats:

* two-column text or CSV, ``time_s,accel_g`` (comma, semicolon, tab or blank separated),
  ``#`` starts a comment, an optional non-numeric header line is allowed;
* PEER NGA ``.AT2``: four header lines, the fourth giving ``NPTS`` and ``DT``, then the
  accelerations in g, several per line.

Accelerations are in g (g = 9.80665 m/s^2). Playback interpolates linearly between
samples and gives zero outside the record.

Numbers are plain decimals (``-0.25``, ``1.5e-3``); Python-only spellings (``1_0``,
``inf``, ``nan``) are refused, as are non-finite times, files that are not regular files
and files larger than :data:`MAX_RECORD_BYTES`.
"""

from __future__ import annotations

import bisect
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

G = 9.80665  # m/s^2
MAX_RECORD_BYTES = 256 * 1024 * 1024
"""Largest record file read (a million samples take about 20 MB)."""
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")


class RecordError(ValueError):
    """A record file that cannot be used; the message names the file and line."""

    def __init__(self, path: Path | str, message: str, line: int | None = None) -> None:
        where = f"{path}:{line}" if line is not None else f"{path}"
        super().__init__(f"{where}: {message}")
        self.path = str(path)
        self.line = line


@dataclass(frozen=True)
class Record:
    """A ground-motion record: times [s] (strictly increasing) and accelerations [g]."""

    time: np.ndarray
    accel_g: np.ndarray
    source: str = ""

    @property
    def duration(self) -> float:
        """Time of the last sample [s]."""
        return float(self.time[-1])


def _split(line: str) -> list[str]:
    return [p for p in re.split(r"[,;\s]+", line.strip()) if p]


class _NonFinite(ValueError):
    """``inf``, ``nan`` and their spellings."""


def _number(text: str) -> float:
    """A plain decimal number; ValueError for anything else (``1_0``, ``0x10``, ...), _NonFinite for ``inf``/``nan``."""
    if not _NUMBER.fullmatch(text):
        if text.lower().lstrip("+-") in ("inf", "infinity", "nan"):
            raise _NonFinite(text)
        raise ValueError(text)
    return float(text)


def read_two_column(path: Path) -> Record:
    """Read a ``time_s,accel_g`` text/CSV record."""
    times: list[float] = []
    accels: list[float] = []
    lines: list[int] = []
    header_allowed = True
    for lineno, raw in enumerate(path.read_text(errors="replace").splitlines(), start=1):
        text = raw.split("#", 1)[0].strip()
        if not text:
            continue
        parts = _split(text)
        try:
            values = [_number(p) for p in parts]
        except _NonFinite:
            raise RecordError(path, f"non-finite value in {text!r}", lineno) from None
        except ValueError:
            if header_allowed and not any(_is_number(p) for p in parts):
                header_allowed = False
                continue
            raise RecordError(path, f"not a number in {text!r}", lineno) from None
        header_allowed = False
        if len(values) != 2:
            raise RecordError(path, f"expected 2 columns (time_s, accel_g), found {len(values)}", lineno)
        if not all(math.isfinite(v) for v in values):
            raise RecordError(path, f"non-finite value in {text!r}", lineno)
        if times and values[0] <= times[-1]:
            raise RecordError(
                path, f"time {values[0]:g} s does not increase (previous {times[-1]:g} s, line {lines[-1]})", lineno
            )
        times.append(values[0])
        accels.append(values[1])
        lines.append(lineno)
    if len(times) < 2:
        raise RecordError(path, f"needs at least 2 samples, found {len(times)}")
    return Record(np.array(times), np.array(accels), str(path))


def _is_number(text: str) -> bool:
    return _NUMBER.fullmatch(text) is not None


def read_at2(path: Path) -> Record:
    """Read a PEER NGA ``.AT2`` record (accelerations in g at a constant DT)."""
    lines = path.read_text(errors="replace").splitlines()
    if len(lines) < 5:
        raise RecordError(path, "an AT2 file needs 4 header lines and data")
    header = lines[3]
    m_npts = re.search(r"NPTS\s*=?\s*(\d+)", header, re.I)
    m_dt = re.search(r"DT\s*=?\s*([0-9.Ee+-]+)", header, re.I)
    if not (m_npts and m_dt):
        raise RecordError(path, f"header line must give NPTS and DT, got {header.strip()!r}", 4)
    npts = int(m_npts.group(1)[:18])
    try:
        dt = _number(m_dt.group(1))
    except ValueError:
        raise RecordError(path, f"DT is not a number: {m_dt.group(1)!r}", 4) from None
    if not (dt > 0 and math.isfinite(dt)):
        raise RecordError(path, f"DT must be positive, got {dt}", 4)
    values: list[float] = []
    for lineno, raw in enumerate(lines[4:], start=5):
        for part in _split(raw):
            try:
                value = _number(part)
            except _NonFinite:
                raise RecordError(path, f"non-finite value {part!r}", lineno) from None
            except ValueError:
                raise RecordError(path, f"not a number: {part!r}", lineno) from None
            if not math.isfinite(value):
                raise RecordError(path, f"non-finite value {part!r}", lineno)
            values.append(value)
    if len(values) != npts:
        raise RecordError(path, f"header says NPTS = {npts}, found {len(values)} values")
    if npts < 2:
        raise RecordError(path, f"needs at least 2 samples, found {npts}")
    with np.errstate(over="ignore"):
        times = np.arange(npts) * dt
    if not np.isfinite(times[-1]) or not np.all(np.diff(times) > 0):
        raise RecordError(path, f"DT = {dt:g} s gives times that are not finite and increasing "
                                f"(last sample at {times[-1]:g} s)", 4)
    return Record(times, np.array(values), str(path))


def read_record(path: Path | str) -> Record:
    """Read a record; ``.at2`` files as PEER NGA, everything else as two-column text."""
    path = Path(path)
    if not path.exists():
        raise RecordError(path, "no such file")
    if not path.is_file():
        raise RecordError(path, "not a regular file (a folder, FIFO or device)")
    size = path.stat().st_size
    if size == 0:
        raise RecordError(path, "the file is empty")
    if size > MAX_RECORD_BYTES:
        raise RecordError(path, f"{size:,} bytes, more than the {MAX_RECORD_BYTES:,} a record may have")
    if path.suffix.lower() == ".at2":
        return read_at2(path)
    return read_two_column(path)


class GroundMotion:
    """Plays a record: ag(t) [m/s^2] = scale * g * a(t / time_scale), zero outside the record.

    ``time_scale`` stretches the record in time: a sample at record time tau plays at
    simulation time time_scale * tau.
    """

    def __init__(self, record: Record, scale: float = 1.0, time_scale: float = 1.0) -> None:
        if not (math.isfinite(scale) and math.isfinite(time_scale) and time_scale > 0):
            raise ValueError(f"scale must be finite and time_scale positive, got {scale}, {time_scale}")
        self.record = record
        self.scale = scale
        self.time_scale = time_scale
        self._t = record.time.tolist()
        self._a = (record.accel_g * (G * scale)).tolist()

    @property
    def duration(self) -> float:
        """Simulation time at which the record ends [s]."""
        return self.record.duration * self.time_scale

    def acceleration(self, t: float) -> float:
        """Ground acceleration [m/s^2] at simulation time t [s]."""
        tau = t / self.time_scale
        times = self._t
        if tau < times[0] or tau > times[-1]:
            return 0.0
        k = bisect.bisect_right(times, tau)
        if k >= len(times):
            return self._a[-1]
        t0, t1 = times[k - 1], times[k]
        a0, a1 = self._a[k - 1], self._a[k]
        return a0 + (a1 - a0) * (tau - t0) / (t1 - t0)
