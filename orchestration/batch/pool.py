"""The batch pool: jobs fanned out with ``dask.distributed``, on this machine or on a cluster.

It knows no study: a job is a module-level function and a payload; the studies
(:mod:`orchestration.case_study`, :mod:`orchestration.ida_study`) and the identification
build their jobs on it.


* Default: an embedded local cluster, one process worker per core, one thread each.
* ``scheduler="tcp://HOST:8786"`` (or ``DASK_SCHEDULER_ADDRESS``): an existing cluster
  (``dask scheduler`` and ``dask worker`` started by hand, see the README). An unreachable
  scheduler, one without workers, or workers that cannot import this project, raise
  :class:`BatchUnavailable` before any job is sent.
* A job is ``fn(payload)`` with ``fn`` a module-level function. With ``isolate=True`` it
  runs in a child process of the worker (:mod:`orchestration.batch.child`): how every
  co-simulation of a study runs. A job that raises, times out or crashes its child is recorded
  (status ``failed``, with its reason) and never retried. A *worker* that dies mid-job
  (killed, out of memory, machine lost) makes the scheduler run the job again on another
  worker, at most ``max_worker_deaths`` times (the scheduler's ``allowed-failures``),
  after which it is recorded as ``lost``.
* Ctrl-C: jobs not finished are cancelled (a running co-simulation's child is killed) and
  ``KeyboardInterrupt`` propagates after ``on_done`` saw every finished job.
* Large inputs used by many jobs (FMU bytes, plans) are sent once with :meth:`BatchPool.share`:
  a worker fetches each once and keeps it for every job that names it.

For one-off maps (identification) :func:`map_jobs` and :func:`map_values` are the one-call forms.
"""

from __future__ import annotations

import logging
import os
import sys
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

SCHEDULER_ENV = "DASK_SCHEDULER_ADDRESS"


class BatchUnavailable(RuntimeError):
    """No usable Dask cluster: unreachable scheduler, no workers, or workers without this project."""


@dataclass
class JobResult:
    """How a job ended: ``value`` if ok, else ``error`` (one line) and ``details`` (traceback).

    ``status``: ``ok``; ``failed`` (the job itself raised, timed out or its process crashed:
    not retried); ``lost`` (the workers running it died ``max_worker_deaths`` + 1 times);
    ``cancelled`` (interrupted before it finished).
    """

    key: str
    ok: bool
    value: Any = None
    error: str | None = None
    details: str = ""
    wall_time_s: float = 0.0
    status: str = "ok"
    worker: str | None = None
    output: str = ""  # what an isolated job printed (the end of it)


def default_workers() -> int:
    """CPUs this process may use (one worker per core)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def scheduler_address(option: str | None) -> str | None:
    """The scheduler to use: the command-line option, else ``DASK_SCHEDULER_ADDRESS``, else None (local)."""
    return option or os.environ.get(SCHEDULER_ENV) or None


def scheduler_endpoint(address: str) -> tuple[str, int]:
    """The host and port of a scheduler address (``tcp://HOST:PORT`` or ``HOST:PORT``); BatchUnavailable if malformed.

    Only plain TCP is supported (what ``dask scheduler`` listens on by default): ``http://`` (the
    dashboard), ``tls://`` and other schemes are refused up front, never waited for.
    """
    text = address.strip()
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    if scheme != "tcp":
        raise BatchUnavailable(f"scheduler address {address!r}: only tcp://HOST:PORT is supported "
                               f"(not {scheme}://; the dashboard's http:// address is not the scheduler's)")
    host, colon, port_text = rest.rpartition(":")
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    if not colon or not host or not port_text.isdigit() or not 0 < int(port_text) < 65536 or "/" in rest:
        raise BatchUnavailable(f"scheduler address {address!r} is malformed: expected tcp://HOST:PORT "
                               "(port 1-65535), e.g. tcp://127.0.0.1:8786")
    return host, int(port_text)


def probe_scheduler(address: str, timeout_s: float) -> None:
    """Check within ``timeout_s`` (per step) that a Dask scheduler answers at ``address``; BatchUnavailable if not.

    A Dask scheduler speaks first: right after accepting a connection it sends its handshake
    (an 8-byte little-endian length, then msgpack frames). A listener that accepts and stays
    silent (an HTTP server, a stalled process) or sends something else is refused here, so no
    later wait of the Dask client can hang on it.
    """
    import socket

    host, port = scheduler_endpoint(address)
    try:
        sock = socket.create_connection((host, port), timeout=timeout_s)
    except TimeoutError:
        raise BatchUnavailable(f"cannot reach the Dask scheduler at {address}: no connection within "
                               f"{timeout_s:g} s") from None
    except OSError as exc:
        raise BatchUnavailable(f"cannot reach the Dask scheduler at {address}: {exc.strerror or exc}") from None
    try:
        sock.settimeout(timeout_s)
        head = b""
        deadline = time.monotonic() + timeout_s
        while len(head) < 8 and time.monotonic() < deadline:
            chunk = sock.recv(8 - len(head))
            if not chunk:
                break
            head += chunk
    except TimeoutError:
        raise BatchUnavailable(f"{address} accepted the connection but sent nothing within {timeout_s:g} s: "
                               "not a Dask scheduler (or a stalled one)") from None
    except OSError as exc:
        raise BatchUnavailable(f"cannot talk to the Dask scheduler at {address}: {exc.strerror or exc}") from None
    finally:
        sock.close()
    if len(head) < 8 or not 0 < int.from_bytes(head, "little") < 1 << 24:
        raise BatchUnavailable(f"{address} answered, but not as a Dask scheduler does")


def _cancelled_check() -> Callable[[], bool] | None:
    """In a Dask task: a function telling whether the client cancelled this task."""
    try:
        from distributed.worker import get_worker, thread_state

        worker, key = get_worker(), thread_state.key
    except (ImportError, ValueError, AttributeError):
        return None

    def cancelled() -> bool:
        ts = worker.state.tasks.get(key)
        return ts is None or ts.state in ("cancelled", "released", "forgotten")

    return cancelled


def run_task(fn: Callable[[Any], Any], payload: Any, isolate: bool, timeout_s: float | None) -> dict[str, Any]:
    """What runs on a worker: ``fn(payload)`` (in a child process if ``isolate``); never raises."""
    from orchestration.batch.child import call_in_child, one_line

    start = time.perf_counter()
    try:
        if isolate:
            out = call_in_child(fn, payload, timeout_s, cancelled=_cancelled_check())
        else:
            out = {"ok": True, "value": fn(payload)}
    except Exception as exc:
        out = {"ok": False, "error": one_line(exc), "details": traceback.format_exc()}
    out.setdefault("wall_time_s", time.perf_counter() - start)
    try:
        from distributed.worker import get_worker

        out["worker"] = get_worker().address
    except (ImportError, ValueError):
        out["worker"] = None
    return out


def hold(obj: Any) -> Any:
    """A task that returns its argument: how shared data lives on the cluster (see BatchPool.share)."""
    return obj


def worker_info(preload: tuple[str, ...] = ()) -> dict[str, Any]:
    """Run on every worker when connecting: Python and package versions; starts its forkserver (child.py),
    with the job modules ``preload`` imported in it."""
    from orchestration.batch.child import start_forkserver
    from orchestration.batch.portable import installed_version

    return {"python": sys.version.split()[0], "mre_cosim": installed_version(), "pid": os.getpid(),
            "forkserver": start_forkserver(preload)}


class ProgressBar:
    """One progress bar for a whole batch of jobs: jobs done / total, and how many failed."""

    def __init__(self, total: int, desc: str, initial: int = 0, enabled: bool = True) -> None:
        self.failures = 0
        self._bar = None
        if enabled:
            from tqdm import tqdm

            self._bar = tqdm(total=total, initial=initial, desc=desc, unit="job", file=sys.stderr, disable=None,
                             dynamic_ncols=True)

    def done(self, ok: bool) -> None:
        """One more job finished."""
        if not ok:
            self.failures += 1
        if self._bar is not None:
            if not ok:
                self._bar.set_postfix(failed=self.failures, refresh=False)
            self._bar.update(1)

    def write(self, text: str) -> None:
        """A message above the bar (stderr)."""
        if self._bar is not None:
            self._bar.write(text, file=sys.stderr)
        else:
            print(text, file=sys.stderr)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


class BatchPool:
    """A Dask client on a local cluster (default) or an existing scheduler; use as a context manager.

    ``preload``: modules of the jobs to come (e.g. ``"orchestration.case_study.case_jobs"``), imported
    once in each worker's forkserver so that an isolated job's child starts with them loaded.
    """

    def __init__(self, scheduler: str | None = None, workers: int | None = None, *, max_worker_deaths: int = 2,
                 connect_timeout_s: float = 10.0, preload: tuple[str, ...] = (), answer_timeout_s: float = 120.0
                 ) -> None:
        if workers is not None and workers < 1:
            raise ValueError("workers must be at least 1")
        if max_worker_deaths < 0:
            raise ValueError("max_worker_deaths must not be negative")
        self.scheduler = scheduler
        self.requested_workers = workers
        self.max_worker_deaths = max_worker_deaths
        self.connect_timeout_s = connect_timeout_s
        self.answer_timeout_s = answer_timeout_s  # bound of every other wait on the cluster (workers' set-up, copies)
        self.preload = tuple(preload)
        self.client: Any = None
        self.cluster: Any = None
        self.workers_info: dict[str, Any] = {}
        self._shared: dict[str, Any] = {}  # key -> handle of everything shared (see share)

    # -- lifecycle ------------------------------------------------------------------------------
    def __enter__(self) -> BatchPool:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def start(self) -> None:
        """Start the local cluster or connect to the scheduler; BatchUnavailable if that is not possible."""
        import dask
        from distributed import Client, LocalCluster

        if self.scheduler is None:
            n = self.requested_workers or default_workers()
            with dask.config.set({"distributed.scheduler.allowed-failures": self.max_worker_deaths}):
                self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                                            scheduler_port=0, dashboard_address=":0",
                                            silence_logs=logging.ERROR)
                self.client = Client(self.cluster, set_as_default=False)
            from orchestration.batch.worker_plugin import IgnoreInterrupt

            self.client.register_plugin(IgnoreInterrupt())  # our own workers: Ctrl-C is the client's business
        else:
            probe_scheduler(self.scheduler, self.connect_timeout_s)
            try:
                self.client = Client(self.scheduler, timeout=f"{self.connect_timeout_s}s", set_as_default=False)
            except (OSError, TimeoutError) as exc:
                raise BatchUnavailable(f"cannot reach the Dask scheduler at {self.scheduler}: {exc}") from None
            try:
                self.client.wait_for_workers(1, timeout=self.connect_timeout_s)
            except TimeoutError:
                self.close()
                raise BatchUnavailable(f"the Dask scheduler at {self.scheduler} has no workers "
                                        f"(waited {self.connect_timeout_s:g} s): start some with "
                                        f"'dask worker {self.scheduler}'") from None
        try:
            self.workers_info = self.client.run(worker_info, self.preload, callback_timeout=self.answer_timeout_s)
        except TimeoutError:  # a worker (or the scheduler) that never answers: every wait on the network is bounded
            where = self.scheduler or "the local cluster"
            self.close()
            raise BatchUnavailable(f"the Dask workers at {where} did not finish their set-up within "
                                    f"{self.answer_timeout_s:g} s (Python and package versions, job modules "
                                    "imported): is a worker stuck or overloaded?") from None
        except Exception as exc:  # a worker that cannot import the project
            self.close()
            raise BatchUnavailable(f"the Dask workers cannot run this project's jobs (is mre-cosim installed "
                                    f"on every worker?): {type(exc).__name__}: {exc}") from None

    def close(self) -> None:
        """Close the client (and the local cluster, with its workers)."""
        self._shared.clear()
        for thing in (self.client, self.cluster):
            if thing is not None:
                try:
                    thing.close()
                except Exception:  # already gone
                    pass
        self.client = self.cluster = None

    # -- facts ----------------------------------------------------------------------------------
    @property
    def address(self) -> str:
        return self.client.scheduler.address

    @property
    def n_workers(self) -> int:
        return len(self.workers_info)

    @property
    def dashboard(self) -> str | None:
        """The Dask dashboard's address, or None (no dashboard: the ``bokeh`` package is not installed)."""
        try:
            import bokeh  # noqa: F401
        except ImportError:
            return None
        try:
            return self.client.dashboard_link
        except Exception:
            return None

    def describe(self) -> str:
        """One line: where the jobs run."""
        where = "local cluster" if self.scheduler is None else f"scheduler {self.scheduler}"
        text = f"batch pool: {where}, {self.n_workers} workers"
        board = self.dashboard
        return f"{text}; Dask dashboard: {board}" if board else f"{text} (Dask dashboard: pip install bokeh)"

    # -- work -----------------------------------------------------------------------------------
    def share(self, obj: Any, dedupe: bool = True) -> Any:
        """Put ``obj`` on every worker once; put the returned handle in payloads (jobs get ``obj``).

        The object travels inside a task (``hold(obj)``) that the scheduler keeps: if every
        worker holding it dies, Dask runs that task again instead of failing the jobs that
        need it. It is copied to every worker up front (held by one worker only, it would
        pull the scheduler into running every job that names it there); a worker that joins
        later fetches it from a peer. Handles live as long as the pool. ``dedupe``: bytes
        with the same SHA-256 share one handle.
        """
        import hashlib
        import warnings

        key = "bytes-" + hashlib.sha256(obj).hexdigest() if dedupe and isinstance(obj, bytes | bytearray) else None
        if key is not None and key in self._shared:
            return self._shared[key]
        with warnings.catch_warnings():  # "large object in the task graph": on purpose (see above)
            warnings.simplefilter("ignore")
            handle = self.client.submit(hold, obj, pure=False, key=f"shared-{os.urandom(8).hex()}")
        try:
            self.client.replicate([handle], callback_timeout=self.answer_timeout_s)
        except Exception:  # best effort: without copies, jobs fetch it from a peer
            pass
        self._shared[key or handle.key] = handle
        return handle

    def map(
        self,
        fn: Callable[[Any], Any],
        payloads: Sequence[Any],
        keys: Sequence[str] | None = None,
        *,
        isolate: bool = False,
        timeout_s: float | None = None,
        on_done: Callable[[JobResult], None] | None = None,
        costs: Sequence[float] | None = None,
    ) -> list[JobResult]:
        """``fn(payload)`` for every payload, results in payload order; see the module docstring for faults.

        ``keys`` name the jobs (default ``job-<index>``); payloads may hold :meth:`share` handles
        inside dicts, lists and tuples. ``costs`` (any unit, e.g. steps) are the jobs' expected
        relative run times: the longest start first, so the last jobs to finish are short ones
        and the workers run out of work together (longest-processing-time-first). On Ctrl-C
        unfinished jobs are cancelled and KeyboardInterrupt propagates.
        """
        from distributed import as_completed
        from distributed.client import FutureCancelledError

        keys = list(keys) if keys is not None else [f"job-{k}" for k in range(len(payloads))]
        if len(keys) != len(payloads):
            raise ValueError("one key per payload")
        if costs is not None and len(costs) != len(payloads):
            raise ValueError("one cost per payload")
        order = sorted(range(len(payloads)), key=lambda k: -costs[k]) if costs is not None else range(len(payloads))
        index: dict[Any, int] = {}
        futures = []
        for rank, k in enumerate(order):
            # Dask runs a client's tasks by priority, then in submission order: both follow ``order``.
            fut = self.client.submit(run_task, fn, payloads[k], isolate, timeout_s, pure=False, retries=0,
                                     key=f"{keys[k]}-{os.urandom(6).hex()}", priority=len(payloads) - rank)
            index[fut.key] = k
            futures.append(fut)
        results: list[JobResult | None] = [None] * len(payloads)
        try:
            for fut in as_completed(futures, loop=self.client.loop):
                k = index[fut.key]
                try:
                    out = fut.result()
                    res = JobResult(keys[k], bool(out.get("ok")), out.get("value"), out.get("error"),
                                    out.get("details", ""), float(out.get("wall_time_s", 0.0)),
                                    "ok" if out.get("ok") else "failed", out.get("worker"), out.get("output", ""))
                except FutureCancelledError:
                    res = JobResult(keys[k], False, error="cancelled", status="cancelled")
                except Exception as exc:
                    from distributed.scheduler import KilledWorker

                    if isinstance(exc, KilledWorker):
                        res = JobResult(keys[k], False, status="lost", error=(
                            f"lost: the worker running it died {exc.allowed_failures + 1} times "
                            f"(limit {exc.allowed_failures} re-runs)"))
                    else:
                        res = JobResult(keys[k], False, error=f"{type(exc).__name__}: {exc}"[:500],
                                        details=traceback.format_exc(), status="failed")
                results[k] = res
                fut.release()
                if on_done is not None:
                    on_done(res)
        except KeyboardInterrupt:
            try:
                self.client.cancel([f for f in futures if not f.done()])
            except Exception:  # the cluster is going away too
                pass
            raise
        return [r for r in results if r is not None]


def map_jobs(  # noqa: PLR0913 - keyword-only options: those of BatchPool.map, and of the pool made here
    fn: Callable[[Any], Any],
    payloads: Sequence[Any],
    *,
    pool: BatchPool | None = None,
    scheduler: str | None = None,
    workers: int | None = None,
    isolate: bool = False,
    timeout_s: float | None = None,
    keys: Sequence[str] | None = None,
    on_done: Callable[[JobResult], None] | None = None,
) -> list[JobResult]:
    """``fn(payload)`` for each payload on ``pool`` (or a new one: local, or ``scheduler``); results in order.

    ``fn`` must be a module-level function; payloads and values must pickle. Never raises
    for a failing job: look at each result's ``ok``/``status``/``error``. Raises
    BatchUnavailable if no cluster can be had and KeyboardInterrupt on Ctrl-C.
    """
    if pool is not None:
        return pool.map(fn, payloads, keys, isolate=isolate, timeout_s=timeout_s, on_done=on_done)
    with BatchPool(scheduler_address(scheduler), workers) as own:
        return own.map(fn, payloads, keys, isolate=isolate, timeout_s=timeout_s, on_done=on_done)


def map_values(fn: Callable[[Any], Any], items: Sequence[Any], **options: Any) -> list[Any]:
    """``list(map(fn, items))`` on a batch pool (options as :func:`map_jobs`); RuntimeError naming the first failure."""
    results = map_jobs(fn, items, **options)
    for res in results:
        if not res.ok:
            raise RuntimeError(f"job {res.key} {res.status}: {res.error}\n{res.details}")
    return [res.value for res in results]
