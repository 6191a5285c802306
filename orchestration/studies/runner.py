"""Parallel execution of a study: every job in its own process ('spawn'), failures isolated.

A job is a module-level function and a picklable payload. Each job runs in a fresh
process started with the 'spawn' context (pythonfmu FMUs load into the host interpreter,
so co-simulations never share one). The child sends back ``{"ok": True, "value": ...}``
or the exception text; a child that dies without answering (crash, signal, timeout) is
reported with its exit code. One job failing never affects the others.
"""

from __future__ import annotations

import multiprocessing as mp
import signal
import sys
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any


@dataclass(frozen=True)
class Job:
    """One unit of work: ``func(payload)`` in its own process; output goes to ``log`` (a file)."""

    key: str
    func: Callable[[dict[str, Any]], Any]
    payload: dict[str, Any] = field(default_factory=dict)
    log: Path | None = None


@dataclass
class JobResult:
    """How a job ended: ``value`` if ok, else ``error`` (one line) and ``details`` (traceback)."""

    key: str
    ok: bool
    value: Any = None
    error: str | None = None
    details: str = ""
    wall_time_s: float = 0.0


def _child(func: Callable[[dict[str, Any]], Any], payload: dict[str, Any], conn: Connection, log: str | None) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides about interruptions
    if log is not None:
        stream = open(log, "a", buffering=1)  # lives as long as the process
        sys.stdout = sys.stderr = stream
    try:
        message = {"ok": True, "value": func(payload)}
    except BaseException as exc:  # every failure goes back to the parent as text
        message = {"ok": False, "error": f"{type(exc).__name__}: {exc}".splitlines()[0][:500],
                   "details": traceback.format_exc()}
        print(message["details"], file=sys.stderr)
    conn.send(message)
    conn.close()


def _exit_reason(code: int | None) -> str:
    if code is None:
        return "process did not exit"
    if code < 0:
        try:
            return f"process killed by signal {signal.Signals(-code).name}"
        except ValueError:
            return f"process killed by signal {-code}"
    return f"process exited with code {code} without a result"


def run_jobs(
    jobs: list[Job],
    workers: int,
    on_done: Callable[[JobResult], None] | None = None,
    timeout_s: float | None = None,
) -> dict[str, JobResult]:
    """Run jobs, at most ``workers`` at a time, each in its own spawned process.

    On KeyboardInterrupt the running children are terminated, jobs not started are
    reported as not run, and the exception propagates after ``on_done`` saw every job.
    """
    ctx = mp.get_context("spawn")
    pending = list(jobs)
    running: dict[str, tuple[Any, Connection, float, Job]] = {}
    results: dict[str, JobResult] = {}

    def finish(res: JobResult) -> None:
        results[res.key] = res
        if on_done is not None:
            on_done(res)

    def reap(key: str, message: dict[str, Any] | None, reason: str | None = None) -> None:
        proc, conn, start, _ = running.pop(key)
        conn.close()
        proc.join(timeout=10)
        if proc.is_alive():
            proc.kill()
            proc.join()
        wall = time.time() - start
        if message is None:
            finish(JobResult(key, False, error=reason or _exit_reason(proc.exitcode), wall_time_s=wall))
        else:
            finish(JobResult(key, bool(message.get("ok")), message.get("value"), message.get("error"),
                             message.get("details", ""), wall))

    try:
        while pending or running:
            while pending and len(running) < workers:
                job = pending.pop(0)
                reader, writer = ctx.Pipe(duplex=False)
                log = str(job.log) if job.log else None
                proc = ctx.Process(target=_child, args=(job.func, job.payload, writer, log), name=f"study-{job.key}",
                                   daemon=False)
                proc.start()
                writer.close()
                running[job.key] = (proc, reader, time.time(), job)
            conns = {entry[1]: key for key, entry in running.items()}
            sentinels = {entry[0].sentinel: key for key, entry in running.items()}
            ready = wait(list(conns) + list(sentinels), timeout=1.0)
            for obj in ready:
                key = conns.get(obj, sentinels.get(obj))
                if key not in running:
                    continue
                proc, conn, _, _ = running[key]
                if obj is conn or conn.poll():
                    try:
                        reap(key, conn.recv())
                    except (EOFError, OSError):
                        reap(key, None)
                elif not proc.is_alive():
                    reap(key, None)
            if timeout_s is not None:
                now = time.time()
                for key, (proc, _, start, _) in list(running.items()):
                    if now - start > timeout_s:
                        proc.kill()
                        reap(key, None, f"timed out after {timeout_s:g} s (process killed)")
    except KeyboardInterrupt:
        for key, (proc, _, _, _) in list(running.items()):
            proc.terminate()
            reap(key, None, "interrupted (process terminated)")
        for job in pending:
            finish(JobResult(job.key, False, error="interrupted before it started"))
        raise
    return results
