"""Recording chosen outputs at every communication point into preallocated arrays, and writing them as CSV.

Every type is recorded. Real (and FMI 3.0 Float64/Float32) columns are written as ``'%.12g'``;
integer, enumeration and Boolean columns are held in the same float64 arrays (exact up to
2^53, the algorithm refuses larger magnitudes) and written as plain integers (Booleans 0/1);
String columns are kept as Python strings and written quoted (RFC 4180: ``"a ""b"", c"``).
A run that records only Reals writes exactly the bytes it always did; a long one has them written by a forked
:class:`CsvProcess` while its units step (the same bytes).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mre_common.atomic_files import atomic_write
from mre_common.env_settings import env_megabytes, env_switch
from orchestration.master.algorithm import CouplingAlgorithm
from orchestration.master.child_process import Child, ChildStalled, exit_text, fork_safe
from orchestration.master.graph import Port
from orchestration.master.scenario import CSV_PROCESS_ENV
from orchestration.master.unit import Variable

SPILL_ENV = "MRE_COSIM_SPILL_MB"
DEFAULT_SPILL_MB = 256.0


def column_kind(var: Variable) -> str:
    """How a recorded variable's column is written: ``real``, ``integer`` (integers, enumerations, Booleans) or
    ``string``."""
    if var.fast_real or var.fmi_type in ("Real", "Float64", "Float32"):
        return "real"
    return "string" if var.fmi_type == "String" else "integer"


def spill_threshold() -> int:
    """Bytes of recorded results above which they live in a file, not in memory (``MRE_COSIM_SPILL_MB``)."""
    threshold = env_megabytes(SPILL_ENV, DEFAULT_SPILL_MB, zero_ok=True)  # 0: always spill; checked at resolve
    assert threshold is not None
    return threshold


class RowStorage:
    """The arrays a :class:`Recorder` fills: ``time`` (rows) and ``data`` (rows x columns), NaN until written.

    Larger than :func:`spill_threshold`: memory-mapped files in ``spill_dir``, unlinked as they
    are created. Otherwise, with ``shared``, anonymous shared memory: a process forked after
    the storage was made (the plot process) sees the rows the run writes later.
    """

    def __init__(self, rows: int, cols: int, spill_dir: Path | None = None, shared: bool = False) -> None:
        self.spilled = spill_dir is not None and rows * (cols + 1) * 8 > spill_threshold()
        self.time: np.ndarray
        self.data: np.ndarray
        if self.spilled:
            self.time = np.memmap(tempfile.TemporaryFile(dir=spill_dir), dtype=np.float64, mode="w+", shape=(rows,))
            self.data = np.memmap(tempfile.TemporaryFile(dir=spill_dir), dtype=np.float64, mode="w+",
                                  shape=(rows, max(cols, 1)))[:, :cols]
            step = ROWS_PER_CHUNK * 20
            for start in range(0, rows, step):  # NaN marks rows not written yet, a block at a time
                self.time[start : start + step] = np.nan
                self.data[start : start + step] = np.nan
        elif shared:
            import mmap

            buffer = mmap.mmap(-1, max(rows * (cols + 1) * 8, 8))  # MAP_SHARED | MAP_ANONYMOUS
            flat = np.frombuffer(buffer, dtype=np.float64, count=rows * (cols + 1))
            flat.fill(np.nan)
            self.time = flat[:rows]
            self.data = flat[rows:].reshape(rows, cols)
        else:
            self.time = np.full(rows, np.nan)
            self.data = np.full((rows, cols), np.nan)
        self.shared = self.spilled or shared


class Recorder:
    """Observer that copies the watched values after initialization and after every step.

    Results larger than :func:`spill_threshold` are kept in memory-mapped files in
    ``spill_dir`` (the run folder) instead of memory, so a long run's memory does not grow
    with its length (the operating system pages the rows out). The files are unlinked as
    they are created: they take disk space only while the recorder lives and can never be
    left behind, whatever ends the process.
    """

    def __init__(self, algorithm: CouplingAlgorithm, ports: Sequence[Port], n_steps: int,
                 spill_dir: Path | None = None, storage: RowStorage | None = None) -> None:
        self.ports = list(ports)
        self.names = [f"{u}.{v}" for u, v in self.ports]
        self._values = algorithm.values
        desc = algorithm.descriptions
        self.kinds = [column_kind(desc[u].variables[v]) for u, v in self.ports]
        numeric = [k for k, kind in enumerate(self.kinds) if kind != "string"]
        self._slots = np.asarray([algorithm.slot[self.ports[k]] for k in numeric], dtype=np.intp)
        self._numeric_columns = None if len(numeric) == len(self.ports) else np.asarray(numeric, dtype=np.intp)
        self._typed = algorithm.typed
        self._string_slots = [(k, algorithm.typed_slot[p]) for k, p in enumerate(self.ports)
                              if self.kinds[k] == "string"]
        self.strings: dict[int, list[str]] = {k: [] for k, _ in self._string_slots}  # column -> values by row
        if storage is None:
            storage = RowStorage(n_steps + 1, len(self.ports), spill_dir)
        elif storage.data.shape != (n_steps + 1, len(self.ports)):
            raise ValueError(f"row storage of shape {storage.data.shape} for {n_steps + 1} rows of "
                             f"{len(self.ports)} columns")
        self.spilled = storage.spilled
        self.time = storage.time
        self.data = storage.data
        self.count = 0  # rows written

    @classmethod
    def view(cls, ports: Sequence[Port], kinds: Sequence[str], storage: RowStorage, count: int) -> Recorder:
        """The first ``count`` rows of ``storage`` (numeric columns only) as a recorder to read, not to record
        with: what a process that shares the storage (the plot process) reads once the run has ended."""
        if any(kind == "string" for kind in kinds):
            raise ValueError("a recorder view holds numeric columns only")
        rec = cls.__new__(cls)
        rec.ports = list(ports)
        rec.names = [f"{u}.{v}" for u, v in rec.ports]
        rec.kinds = list(kinds)
        rec.strings = {}
        rec.spilled, rec.time, rec.data, rec.count = storage.spilled, storage.time, storage.data, count
        return rec

    def record(self, k: int, t: float) -> None:
        """Store row k at time t [s]."""
        self.time[k] = t
        if self._numeric_columns is None:
            self.data[k] = self._values[self._slots]
        else:
            self.data[k, self._numeric_columns] = self._values[self._slots]
            for column, slot in self._string_slots:
                values = self.strings[column]
                del values[k:]
                values.append(self._typed[slot])
        self.count = k + 1

    def rows_to_fill(self) -> tuple[list[Port], np.ndarray, np.ndarray]:
        """(ports, time, data) for an executor that copies the rows itself instead of calling
        :meth:`record` (the native one); it sets :attr:`count` after each range of steps."""
        return self.ports, self.time, self.data

    def column(self, name: str) -> np.ndarray:
        """Recorded values of one variable (``unit.var``), rows written so far (a String column as objects)."""
        k = self.names.index(name)
        if k in self.strings:
            return np.asarray(self.strings[k][: self.count], dtype=object)
        return self.data[: self.count, k]

    @property
    def times(self) -> np.ndarray:
        """Times of the rows written so far [s]."""
        return self.time[: self.count]

    def write_csv(self, path: Path) -> None:
        """The rows written so far as ``timeseries.csv`` (see :func:`write_timeseries`)."""
        write_timeseries(path, self.times, self.names, self.data[: self.count], self.kinds, self.strings)


ROWS_PER_CHUNK = 5000


def quote(text: str) -> str:
    """A String value as a CSV field: always quoted, inner quotes doubled (RFC 4180)."""
    return '"' + text.replace('"', '""') + '"'


def write_timeseries(path: Path, time: np.ndarray, names: Sequence[str], data: np.ndarray,
                     kinds: Sequence[str] | None = None, strings: Mapping[int, Sequence[str]] | None = None) -> None:
    """CSV with a ``time`` column first, then one column per variable, every number as ``'%.12g' % x``.

    With ``kinds`` (:func:`column_kind` per column) that are not all ``real``: ``integer``
    columns are written as whole numbers (``'%d'``) and ``string`` columns, whose values come
    from ``strings[column]``, as quoted text (:func:`quote`).

    Written atomically (temporary file, then rename). The same bytes as formatting row by row
    in Python, several times faster: blocks of rows go to the compiled formatter of the native
    kernel (:func:`orchestration.master.native_stepper.csv_formatter`, which formats exactly as
    Python does), or, without a C compiler, through one format string per block.
    """
    if kinds is not None and any(kind != "real" for kind in kinds):
        _write_typed(Path(path), time, names, data, kinds, strings or {})
        return
    rows = _RealRows(names)

    def write(f) -> None:  # bytes: the formatter's ASCII goes to the file as it is, not decoded and encoded again
        f.write(rows.header)
        rows.write(f, time, data, 0, len(time))

    atomic_write(Path(path), write, binary=True)


class _RealRows:
    """Rows of Real columns as ``timeseries.csv`` lines: ``'%.12g'`` by the kernel's compiled formatter
    (:func:`orchestration.master.native_stepper.csv_formatter`), or one Python format string per block without a C
    compiler. Each row's bytes do not depend on the blocks it is written in."""

    def __init__(self, names: Sequence[str]) -> None:
        from orchestration.master.native_stepper import csv_formatter

        self.header = (",".join(["time", *names]) + "\n").encode()
        self.n_cols = 1 + len(names)
        self.fast = csv_formatter()
        self.row = ",".join(["%.12g"] * self.n_cols) + "\n"
        self.part = np.empty((ROWS_PER_CHUNK, self.n_cols))

    def write(self, f: Any, time: np.ndarray, data: np.ndarray, first: int, last: int) -> None:
        """Rows ``first`` .. ``last - 1`` to the binary file ``f``, one block at a time (memory stays small)."""
        for start in range(first, last, ROWS_PER_CHUNK):
            stop = min(start + ROWS_PER_CHUNK, last)
            block = self.part[: stop - start]
            block[:, 0] = time[start:stop]
            block[:, 1:] = data[start:stop]
            if self.fast is not None:
                f.write(self.fast(block))
            else:
                f.write(((self.row * len(block)) % tuple(block.ravel().tolist())).encode("ascii"))


class CsvProcess:
    """``timeseries.csv`` of Real columns written by a forked process while the units step.

    :meth:`start` forks (:class:`~orchestration.master.child_process.Child`) before the run (before any thread and
    before the FMUs load) a child that shares the run's row storage (:class:`RowStorage` made ``shared``).
    :meth:`rows` tells it how many rows are final (the executor's progress ticks): it formats them on the
    machine's other CPU while this process steps. :meth:`finish` gives the final count and :meth:`wait` returns
    once the file is in place (written atomically, the same bytes as :func:`write_timeseries`), or raises
    :class:`OSError` naming what failed. The child ignores SIGINT and SIGTERM (the run decides when to stop) and,
    without a final count (:meth:`cancel`, or this process's death), removes its temporary file and exits.
    """

    MIN_ROWS = 20_000
    """Fewer rows take less than a fork's worth of time to write: they are written in the run's own process."""

    def __init__(self, child: Child, path: Path | None = None) -> None:
        self._child, self._path = child, path

    @property
    def _pid(self) -> int:
        """The child's process id (0 once reaped)."""
        return self._child.pid

    @staticmethod
    def wanted(rows: int, kinds: Sequence[str]) -> bool:
        """Whether a run of ``rows`` rows with columns of these kinds gains from a CSV process: many rows, Real columns
        only, another CPU, and a safe fork (:func:`~orchestration.master.child_process.fork_safe`);
        ``MRE_COSIM_CSV_PROCESS=0`` turns it off (to compare the two side by side: the file is the same)."""
        return (env_switch(CSV_PROCESS_ENV, True) and rows >= CsvProcess.MIN_ROWS
                and all(kind == "real" for kind in kinds) and (os.cpu_count() or 1) > 1 and fork_safe())

    @classmethod
    def start(cls, path: Path, names: Sequence[str], storage: RowStorage, close: Sequence[int] = ()) -> CsvProcess:
        """Fork the child that writes ``path`` from ``storage``; ``close``: file descriptors of this process the child
        must not hold (other children's pipe ends, so that they see this process close them)."""
        path = Path(path)
        child = Child.fork(lambda go: _csv_child(path, names, storage, go), "the CSV process failed", close)
        return cls(child, path)

    def rows(self, count: int) -> None:
        """The first ``count`` rows are recorded and will not change (a count that does not fit in the pipe is
        dropped: the next one says more)."""
        self._child.send(f"{count}\n")

    def finish(self, count: int) -> None:
        """The run recorded ``count`` rows in all: the child writes the rest and puts the file in place (the count
        is retried while the child runs, for at most :attr:`STALL_S`; a stopped child: :meth:`wait` says so)."""
        self._child.send(f"={count}\n", retry_s=self.STALL_S)
        self._child.close_go()

    STALL_S = 60.0
    """Longest the child may go without writing a byte once the run has ended [s]: then it is stopped."""
    INCOMPLETE_SUFFIX = ".incomplete"
    """The rows a child wrote before it died are kept as ``timeseries.csv.incomplete``."""

    def wait(self) -> None:
        """Once the file is in place; :class:`OSError` if the child could not write it, died, was stopped
        (SIGSTOP) or wrote nothing for :attr:`STALL_S` (bounded: it is killed then). Rows a dead child had
        written are kept under :attr:`INCOMPLETE_SUFFIX`, and the error names that file."""
        self._child.close_go()
        try:
            answer = self._child.answer(self._partial_size, self.STALL_S)
        except ChildStalled as stalled:
            raise OSError(f"the process writing it (pid {stalled.pid}) {stalled.why}{self._keep_partial()}") from None
        status = self._child.reap()
        if not isinstance(answer, dict):
            raise OSError(f"the process writing it ended without an answer ({exit_text(status, signal_number=True)})"
                          f"{self._keep_partial()}")
        if "error" in answer:
            raise OSError(answer["error"])

    def _partials(self) -> list[Path]:
        """The child's temporary file(s) (``.timeseries.csv.<random>.tmp``, as :func:`atomic_write` names it)."""
        if self._path is None:
            return []
        return sorted(self._path.parent.glob(f".{self._path.name}.*.tmp"))

    def _partial_size(self) -> int:
        try:
            return sum(p.stat().st_size for p in self._partials())
        except OSError:
            return -1

    def _keep_partial(self) -> str:
        """Keep the rows a dead child wrote as ``<name>.incomplete`` (whole rows only); the text naming it."""
        parts = self._partials()
        if not parts or self._path is None:
            return ""
        kept = self._path.with_name(self._path.name + self.INCOMPLETE_SUFFIX)
        try:
            data = parts[0].read_bytes()
            end = data.rfind(b"\n") + 1
            with open(parts[0], "r+b") as f:
                f.truncate(end)
            os.replace(parts[0], kept)
            for extra in parts[1:]:
                extra.unlink(missing_ok=True)
        except OSError:
            return ""
        rows = max(data[:end].count(b"\n") - 1, 0)
        return f"; the {rows} rows it wrote are kept in {kept.name} (the run is incomplete)"

    def cancel(self) -> None:
        """No file: the child removes its temporary file and exits."""
        self._child.cancel()

    def __del__(self) -> None:  # dropped without finish and wait (an exception in the run): the child exits
        try:
            self.cancel()
        except (OSError, AttributeError):
            pass


class _Cancelled(Exception):
    """The run ended without a final row count: no file."""


def _csv_child(path: Path, names: Sequence[str], storage: RowStorage, go: int) -> dict[str, Any] | None:
    """The CSV process: rows written as they are announced; answers ``{"ok": true}`` (an error is answered by
    :class:`~orchestration.master.child_process.Child`), nothing when cancelled."""

    def write(f: Any) -> None:
        rows = _RealRows(names)
        f.write(rows.header)
        done, final, pending = 0, None, b""
        while chunk := os.read(go, 4096):
            pending += chunk
            *lines, pending = pending.split(b"\n")
            available = done
            for line in lines:
                if line.startswith(b"="):
                    final = available = int(line[1:])
                elif line:
                    available = max(available, int(line))
            if available > done:
                rows.write(f, storage.time, storage.data, done, available)
                done = available
        if final is None:
            raise _Cancelled
        if final != done:
            raise ValueError(f"{final} rows announced after {done} were written")

    try:
        atomic_write(path, write, binary=True)
    except _Cancelled:
        return None
    return {"ok": True}


def _write_typed(path: Path, time: np.ndarray, names: Sequence[str], data: np.ndarray, kinds: Sequence[str],
                 strings: Mapping[int, Sequence[str]]) -> None:
    """:func:`write_timeseries` for columns of several kinds (row by row in Python)."""
    formats = {"real": "%.12g", "integer": "%d", "string": "%s"}
    row = ",".join(["%.12g", *(formats[kind] for kind in kinds)]) + "\n"

    def write(f) -> None:
        f.write(",".join(["time", *names]) + "\n")
        for start in range(0, len(time), ROWS_PER_CHUNK):
            stop = min(start + ROWS_PER_CHUNK, len(time))
            columns: list[list[Any]] = [np.asarray(time[start:stop], dtype=float).tolist()]
            for k, kind in enumerate(kinds):
                if kind == "string":
                    columns.append([quote(str(v)) for v in strings[k][start:stop]])
                else:
                    columns.append(np.asarray(data[start:stop, k], dtype=float).tolist())
            f.write("".join(row % values for values in zip(*columns, strict=True)))

    atomic_write(path, write)


def kept_rows(count: int, interval: int) -> slice | np.ndarray:
    """The rows a results file holds of ``count`` recorded ones: every ``interval``-th from the first, and the
    last (a slice when that is all of them or the last falls on the interval)."""
    if interval == 1 or count == 0 or (count - 1) % interval == 0:
        return slice(0, count, interval)
    return np.append(np.arange(0, count, interval), count - 1)


def write_results(folder: Path, recorder: Recorder, interval: int = 1, fmt: str = "csv") -> Path:
    """The recorded rows as the run's results file, ``timeseries.csv`` (:func:`write_timeseries`) or
    ``timeseries.parquet`` (:func:`write_parquet`), every ``interval``-th row and the last; its path."""
    rows = kept_rows(recorder.count, interval)
    time, data = recorder.time[: recorder.count][rows], recorder.data[: recorder.count][rows]
    index = np.arange(recorder.count)[rows] if recorder.strings else ()
    strings = {k: [values[i] for i in index] for k, values in recorder.strings.items()}
    path = Path(folder) / f"timeseries.{fmt}"
    if fmt == "parquet":
        write_parquet(path, time, recorder.names, data, recorder.kinds, strings)
    else:
        write_timeseries(path, time, recorder.names, data, recorder.kinds, strings)
    return path


def write_parquet(path: Path, time: np.ndarray, names: Sequence[str], data: np.ndarray, kinds: Sequence[str],
                  strings: Mapping[int, Sequence[str]]) -> None:
    """The rows as a Parquet table (pyarrow): ``time`` [s] first as float64, then one column per variable in SI:
    Reals as float32 (7 significant digits, relative error at most 6e-8: more than the 3-4 digits any table
    prints; timeseries.csv keeps 12), integers as int64, Strings as text. Byte-stream-split and zstd-compressed
    (about a third of the size as float64), written atomically. The units are the FMUs'
    (SI at every boundary, docs/fmu_variables.md); the summary's peaks come from every step in float64."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    columns = [pa.array(np.asarray(time, dtype=np.float64))]
    for k, kind in enumerate(kinds):
        if kind == "string":
            columns.append(pa.array([str(v) for v in strings[k]], type=pa.string()))
        elif kind == "integer":
            columns.append(pa.array(np.asarray(data[:, k]).astype(np.int64)))
        else:
            columns.append(pa.array(np.asarray(data[:, k], dtype=np.float32)))
    table = pa.table(columns, names=["time", *names])
    floats = [n for n, kind in zip(names, kinds, strict=True) if kind == "real"]
    atomic_write(Path(path), lambda f: pq.write_table(table, f, compression="zstd", use_dictionary=False,
                                                      use_byte_stream_split=floats or False), binary=True)
