"""One job in a child process of the worker: how every co-simulation of a study runs.

pythonfmu units load into the interpreter that hosts them. Run in the worker itself, a
co-simulation would leave behind, for good: its FMUs' resource folders on ``sys.path``
(four entries per run), their Python modules in ``sys.modules`` (so a later FMU with the
same module name but other code would silently run the first one's code), and memory that
grows with every run. The native executor also holds the GIL for a whole run, which would starve the worker's event loop
(heartbeats) on long runs, and a crashing FMU would take the worker down, so Dask would
retry it elsewhere as if the machine had failed. A child process per run has none of
these problems and makes a crash the run's own failure, with its signal.

Children are forked from a *forkserver* (``multiprocessing``), started once per worker and
preloaded with :mod:`orchestration.batch.forkserver_preload` (numpy, scipy, fmpy,
pythonfmu, the master, the native kernel, the worker's main script), so a child costs a
fork, not an interpreter start, and a run in a child is as fast as in the worker. The child dies
with its forkserver (``PR_SET_PDEATHSIG``), so a worker that goes away takes its running
co-simulation with it.

A child hosts one run and exits, so its FMUs are loaded from extractions shared by every run of
the machine (``<temp>/mre-cosim-files-<uid>/extracted/<SHA-256 of the archive>/``, made once;
:func:`orchestration.master.fmu_loading.share_extractions`), not extracted afresh for each run.
Every run still instantiates its units fresh, in a fresh process.

This is the study's one way to fork, and it is not the engine's
(:mod:`orchestration.master.child_process`, which forks a run's CSV and plot writers from the run's
own process and shares its row storage with them). The two serve different purposes: here the
child is forked from a long-lived server preloaded with the modules a run imports (not from the
worker, which has threads, so a plain fork would be unsafe), runs arbitrary pickled work, sends a
pickled result back through a :mod:`multiprocessing` connection, and is bounded by a timeout and a
cancellation poll; there the child is forked from a single-threaded run, shares memory with it, is
fed row counts through a pipe and answers one JSON value.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import signal
import sys
import tempfile
import threading
import time
import traceback
from collections.abc import Callable
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

PRELOAD = "orchestration.batch.forkserver_preload"
MAIN_ENV = "MRE_COSIM_FORKSERVER_MAIN"  # the main script the forkserver imports (see _context)
MAX_OUTPUT = 200_000  # bytes of a child's output sent back (the end of it)
_LOCK = threading.Lock()
_CONTEXT: Any = None


def _context(preload: tuple[str, ...] = ()) -> Any:
    """The forkserver context, its server started with the preload modules importable (once per process;
    ``preload``: more modules to import in the server, the jobs' own, when this call starts it)."""
    global _CONTEXT
    with _LOCK:
        if _CONTEXT is None:
            # Dask starts its workers as daemonic processes, which multiprocessing forbids to have
            # children. Ours cannot outlive the worker (they die with its forkserver, which dies
            # with the worker), which is what that rule protects against.
            mp.current_process()._config["daemon"] = False  # type: ignore[attr-defined]
            ctx = mp.get_context("forkserver")
            ctx.set_forkserver_preload([*preload, PRELOAD])  # PRELOAD last: its gc.freeze() covers them all
            from multiprocessing import forkserver, spawn

            # Python 3.11's forkserver neither applies the parent's sys.path before its preload
            # imports nor imports the parent's main script (it looks for a key that its own
            # preparation data does not have), so every child would run the main script again
            # (importing the studies each time). Both go to the server through the
            # environment while it starts; the preload module imports the main script.
            main = spawn.get_preparation_data("forkserver").get("init_main_from_path")
            saved = {k: os.environ.get(k) for k in ("PYTHONPATH", MAIN_ENV)}
            os.environ["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if p)
            if main:
                os.environ[MAIN_ENV] = main
            try:
                forkserver.ensure_running()
            finally:
                for key, value in saved.items():
                    if value is None:
                        os.environ.pop(key, None)
                    else:
                        os.environ[key] = value
            _CONTEXT = ctx
    return _CONTEXT


def start_forkserver(preload: tuple[str, ...] = ()) -> bool:
    """Start this process's forkserver now (it takes seconds: preloads), not with the first job; False if it cannot.

    ``preload``: the job modules to import in it as well (see :class:`~orchestration.batch.pool.BatchPool`).
    """
    try:
        _context(tuple(preload))
    except Exception:  # the first job will say why
        return False
    return True


def _die_with_parent() -> None:
    """Linux: SIGKILL this process when its parent (the forkserver) exits."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG


def extraction_root() -> Path:
    """Where the children of this machine's workers keep each FMU extracted, by the archive's SHA-256."""
    from orchestration.batch.portable import cache_root

    return cache_root() / "extracted"


def _share_extractions() -> None:
    """This child hosts one run and exits: its FMUs are loaded from extractions shared by every run of the machine
    (:func:`orchestration.master.fmu_loading.share_extractions`; each instance is still created fresh)."""
    try:
        from orchestration.master.fmu_loading import share_extractions
    except ImportError:  # a forkserver that preloaded an older master (the code changed under a running study)
        return
    share_extractions(extraction_root())


def _child(func_bytes: bytes, payload: Any, conn: Connection, log: str | None) -> None:
    import cloudpickle  # type: ignore[import-untyped]

    _die_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the study decides about interruptions
    _share_extractions()
    if log is not None:
        stream = open(log, "a", buffering=1)  # lives as long as the process
        os.dup2(stream.fileno(), 1)
        os.dup2(stream.fileno(), 2)
        sys.stdout = sys.stderr = stream
    try:
        message = {"ok": True, "value": cloudpickle.loads(func_bytes)(payload)}
    except BaseException as exc:  # every failure goes back to the parent as text
        message = {"ok": False, "error": one_line(exc), "details": traceback.format_exc()}
        if log is not None:
            print(message["details"], file=sys.stderr)
    try:
        conn.send(message)
    except Exception as exc:  # an unpicklable value
        conn.send({"ok": False, "error": f"result could not be sent back: {one_line(exc)}",
                   "details": traceback.format_exc()})
    conn.close()


def one_line(exc: BaseException) -> str:
    """``Type: message`` on one line, at most 500 characters."""
    text = f"{type(exc).__name__}: {exc}".strip()
    return (text.splitlines() or [type(exc).__name__])[0][:500]


def exit_reason(code: int | None) -> str:
    """Why a child ended without sending a result."""
    if code is None:
        return "process did not exit"
    if code < 0:
        try:
            return f"process killed by signal {signal.Signals(-code).name}"
        except ValueError:
            return f"process killed by signal {-code}"
    return f"process exited with code {code} without a result"


def _remove_run_folders(pid: int) -> None:
    """Remove the temporary run folders a child ``pid`` that did not end by itself left (see jobs.run_folder)."""
    import shutil

    from orchestration.batch.jobs import run_folder_prefix

    for folder in Path(tempfile.gettempdir()).glob(run_folder_prefix(pid) + "*"):
        shutil.rmtree(folder, ignore_errors=True)


def call_in_child(
    func: Callable[[Any], Any],
    payload: Any,
    timeout_s: float | None = None,
    log: str | None = None,
    cancelled: Callable[[], bool] | None = None,
) -> dict[str, Any]:
    """``func(payload)`` in a forked child; ``{"ok", "value" | "error", "details", "wall_time_s"}``.

    The child is killed after ``timeout_s`` [s] or as soon as ``cancelled()`` says so (polled
    every 0.2 s). Without ``log`` (a file to append the child's output to) the end of the
    child's stdout and stderr comes back as ``"output"``. ``func`` travels with cloudpickle
    (a closure will do); ``payload`` must pickle.
    """
    import cloudpickle

    ctx = _context()
    start = time.perf_counter()
    captured = None
    if log is None:  # the child's output comes back as "output" (unit warnings, tracebacks)
        fd, captured = tempfile.mkstemp(prefix="mre-cosim-job-", suffix=".log")
        os.close(fd)
    reader, writer = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(cloudpickle.dumps(func), payload, writer, log or captured),
                       daemon=False)
    try:
        proc.start()
    except Exception as exc:  # the payload does not pickle, the forkserver is gone, ...
        reader.close()
        writer.close()
        if captured is not None:
            os.unlink(captured)
        return {"ok": False, "error": f"could not start the job's process: {one_line(exc)}",
                "details": traceback.format_exc(), "wall_time_s": time.perf_counter() - start}
    writer.close()
    message: dict[str, Any] | None = None
    reason: str | None = None
    try:
        while True:
            if reader.poll(0.2):
                try:
                    message = reader.recv()
                except (EOFError, OSError):
                    message = None
                break
            if not proc.is_alive() and not reader.poll(0):
                break
            if timeout_s is not None and time.perf_counter() - start > timeout_s:
                reason = f"timed out after {timeout_s:g} s (process killed)"
                break
            if cancelled is not None and cancelled():
                reason = "cancelled (process killed)"
                break
    finally:
        reader.close()
        if reason is not None or message is None:
            proc.join(timeout=0.5 if reason is None else 0)
            if proc.is_alive():
                proc.kill()
        proc.join()
        if message is None and proc.pid is not None:  # killed or crashed: its temporary run folder stays behind
            _remove_run_folders(proc.pid)
    wall = time.perf_counter() - start
    output = ""
    if captured is not None:
        with contextlib.suppress(OSError):
            with open(captured, "rb") as f:
                f.seek(max(0, os.path.getsize(captured) - MAX_OUTPUT))
                output = f.read().decode("utf-8", "replace")
            os.unlink(captured)
    if message is None:
        return {"ok": False, "error": reason or exit_reason(proc.exitcode), "details": "", "wall_time_s": wall,
                "output": output}
    return {"details": "", **message, "wall_time_s": wall, "output": output}
