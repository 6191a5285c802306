"""A run's helper processes, forked from the run's own process: the one way the engine forks.

A run hands work that needs no units to forked children (:class:`~orchestration.master.recorder.CsvProcess`
writes ``timeseries.csv`` while the units step, :class:`~orchestration.master.report.PlotProcess` draws the
figures). Each child shares what it needs with the run by the fork itself (row storage in shared memory), and
talks to it through two pipes: the run writes short text messages to the child (``go``: a row count, ...), and the
child answers once, with one JSON value (``result``), then exits. This module holds what every such child needs:

- :meth:`Child.fork` flushes the standard streams (nothing buffered is written twice), makes the pipes, forks,
  and in the child closes the descriptors it must not hold, ignores SIGINT and SIGTERM (the run decides when to
  stop), runs the body and writes its answer. An exception the body lets through becomes an answer
  ``{"error": text}`` (an :class:`OSError` as its ``strerror``), so the run reports it and keeps its other results.
- :meth:`Child.send` never blocks the run on a child (the ``go`` pipe is non-blocking).
- :meth:`Child.answer` reads the JSON answer, optionally bounded: a child that is stopped (SIGSTOP) or makes no
  progress for a time is killed and :class:`ChildStalled` raised.
- :meth:`Child.reap` waits for the child's exit; :func:`exit_text` says how it ended.
- :meth:`Child.cancel` closes the ``go`` pipe without a message (the child exits) and reaps it.

A child is forked only where :func:`fork_safe`: on Linux with one thread (a fork copies no other thread, nor the
locks it may hold). The study's per-run processes are another purpose, with their own machinery
(:mod:`orchestration.batch.child`: a forkserver preloaded with the modules a run imports).
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from typing import Any

POLL_S = 0.5
"""How often a bounded :meth:`Child.answer` looks at the child while it says nothing [s]."""


def fork_safe() -> bool:
    """Forking is safe here: Linux and one thread (a fork copies no other thread, nor locks it might hold)."""
    return sys.platform.startswith("linux") and threading.active_count() == 1


def spare_processes(at_most: int) -> int:
    """How many children to give work that divides: the CPUs, at most ``at_most``, at least 1."""
    return max(1, min(at_most, os.cpu_count() or 1))


def exit_text(status: int, signal_number: bool = False) -> str:
    """How a child ended, from its wait status: ``killed by SIGKILL`` (``killed by signal 9`` with
    ``signal_number``) or ``exit code 1``."""
    if os.WIFSIGNALED(status):
        number = os.WTERMSIG(status)
        return f"killed by signal {number}" if signal_number else f"killed by {signal.Signals(number).name}"
    return f"exit code {os.WEXITSTATUS(status)}"


class ChildStalled(Exception):
    """A child that could not finish (stopped, or no progress for too long) was killed and reaped."""

    def __init__(self, pid: int, why: str) -> None:
        super().__init__(why)
        self.pid = pid  # the child's process id (it is reaped: the number may be reused)
        self.why = why


Body = Callable[[int], dict[str, Any] | None]
"""A child's work: gets the read end of the ``go`` pipe, returns its answer (None: no answer, e.g. cancelled)."""


class Child:
    """One forked child: its pid and the run's ends of its two pipes (``go`` to write, ``result`` to read; -1 once
    closed, and pid 0 once reaped)."""

    def __init__(self, pid: int, go: int, result: int) -> None:
        self.pid, self.go, self.result = pid, go, result

    @classmethod
    def fork(cls, body: Body, failure: str, close: Sequence[int] = ()) -> Child:
        """Fork a child that runs ``body(go)`` and answers what it returns; ``failure``: the words an unexpected
        exception's answer starts with (``"{failure} (ZeroDivisionError: ...)"``); ``close``: descriptors of
        this process the child must not hold (other children's pipe ends, so that those see the run close
        them)."""
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()  # nothing buffered before the fork is written twice
            except (AttributeError, OSError, ValueError):
                pass
        go_read, go_write = os.pipe()
        result_read, result_write = os.pipe()
        pid = os.fork()
        if pid == 0:  # the child: never returns into the caller's code
            code = 1
            try:
                for fd in (*close, go_write, result_read):
                    with contextlib.suppress(OSError):
                        os.close(fd)
                code = _child_main(body, failure, go_read, result_write)
            finally:
                os._exit(code)
        os.close(go_read)
        os.close(result_write)
        os.set_blocking(go_write, False)  # a stopped child must not block the run (send)
        return cls(pid, go_write, result_read)

    def send(self, text: str, retry_s: float = 0.0) -> bool:
        """Write ``text`` to the child without blocking the run: a full pipe drops it (False), unless ``retry_s``
        [s]: then it is retried while the child runs (not stopped), for at most that long. False also when the
        child has closed its end (it ended early: :meth:`answer` says why)."""
        deadline = time.monotonic() + retry_s
        while self.go >= 0:
            try:
                os.write(self.go, text.encode())
                return True
            except BlockingIOError:
                if retry_s <= 0 or self.stopped() or time.monotonic() > deadline:
                    return False
                select.select([], [self.go], [], POLL_S)
            except OSError:
                return False
        return False

    def close_go(self) -> None:
        """No more messages: the child reads the end of its input."""
        if self.go >= 0:
            os.close(self.go)
            self.go = -1

    def answer(self, progress: Callable[[], object] | None = None, stall_s: float | None = None) -> Any:
        """The child's answer (a JSON value; None without one: it died or was cancelled), once it has closed its
        end. With ``stall_s``: bounded; a child that is stopped (SIGSTOP, a debugger) or whose ``progress()`` (any
        value, e.g. the size of the file it writes) stays the same for ``stall_s`` [s] is killed and reaped, and
        :class:`ChildStalled` raised."""
        chunks = []
        last, quiet_since = object(), time.monotonic()
        while self.result >= 0:
            if stall_s is not None and not select.select([self.result], [], [], POLL_S)[0]:
                if self.stopped():
                    self._abandon("was stopped (SIGSTOP, or a debugger holds it)")
                now = progress() if progress is not None else None
                if now != last:
                    last, quiet_since = now, time.monotonic()
                elif time.monotonic() - quiet_since > stall_s:
                    self._abandon(f"wrote nothing for {stall_s:g} s")
                continue
            chunk = os.read(self.result, 65536)
            if not chunk:
                break
            chunks.append(chunk)
        try:
            return json.loads(b"".join(chunks) or b"null")
        except ValueError:
            return None

    def stopped(self) -> bool:
        """Whether the child is stopped (state T or t in /proc/<pid>/stat)."""
        try:
            with open(f"/proc/{self.pid}/stat", "rb") as f:
                state = f.read().rpartition(b")")[2].split()[0]
        except (OSError, IndexError):
            return False
        return state in (b"T", b"t")

    def reap(self) -> int:
        """Close the run's ends of the pipes and wait for the child's exit; its wait status (0 once reaped)."""
        self.close_go()
        if self.result >= 0:
            os.close(self.result)
            self.result = -1
        status = 0
        if self.pid > 0:
            status = os.waitpid(self.pid, 0)[1]
            self.pid = 0
        return status

    def cancel(self) -> None:
        """No answer wanted: the child sees its input end without a message, exits, and is reaped."""
        self.reap()

    def _abandon(self, why: str) -> None:
        pid = self.pid
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGKILL)
        self.reap()
        raise ChildStalled(pid, why)


def read_all(fd: int) -> bytes:
    """Everything written to ``fd`` until the writer closes it (a child's whole input)."""
    chunks = []
    while chunk := os.read(fd, 4096):
        chunks.append(chunk)
    return b"".join(chunks)


def _child_main(body: Body, failure: str, go: int, result: int) -> int:
    """In the child: run ``body``, write its answer (or the error it raised) as JSON; the exit code."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    answer: dict[str, Any] | None
    try:
        answer = body(go)
    except OSError as exc:
        answer = {"error": exc.strerror or str(exc)}
    except BaseException as exc:  # a bug: reported to the run, which keeps its other results
        last = traceback.format_exception_only(exc)[-1].strip()
        answer = {"error": f"{failure} ({last})", "traceback": traceback.format_exc()}
    if answer is None:
        return 0
    data = json.dumps(answer).encode()
    while data:
        data = data[os.write(result, data):]
    return 0
