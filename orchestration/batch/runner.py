"""The former process pool's interface, now on the Dask batch pool (:mod:`orchestration.batch.pool`).

``run_jobs(jobs, workers)`` runs each :class:`Job` in a child process of a worker of a
local Dask cluster (``isolate=True``), so a job that raises or crashes is recorded and the
others go on, exactly as before. New code should call
:func:`orchestration.batch.pool.map_jobs` (or an :class:`~orchestration.batch.pool.BatchPool`)
directly; this module stays for callers written against the old pool.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from orchestration.batch.pool import BatchPool, JobResult

__all__ = ["Job", "JobResult", "run_jobs"]


@dataclass(frozen=True)
class Job:
    """One unit of work: ``func(payload)`` in a child process; a failure's traceback goes to ``log`` (a file)."""

    key: str
    func: Callable[[Any], Any]
    payload: Any = field(default_factory=dict)
    log: Path | None = None


def run_jobs(
    jobs: list[Job],
    workers: int,
    on_done: Callable[[JobResult], None] | None = None,
    timeout_s: float | None = None,
) -> dict[str, JobResult]:
    """Run jobs on a local Dask cluster of ``workers`` processes; results by job key.

    On KeyboardInterrupt unfinished jobs are cancelled and the exception propagates after
    ``on_done`` saw every finished job.
    """
    if not jobs:
        return {}
    by_key = {job.key: job for job in jobs}
    results: dict[str, JobResult] = {}

    def done(res: JobResult) -> None:
        job = by_key[res.key]
        if not res.ok and job.log is not None:
            with open(job.log, "a") as f:
                f.write(f"{res.error}\n{res.details}\n")
        results[res.key] = res
        if on_done is not None:
            on_done(res)

    with BatchPool(workers=max(1, min(workers, len(jobs)))) as pool:
        pool.map(_call, [(job.func, job.payload) for job in jobs], [job.key for job in jobs], isolate=True,
                   timeout_s=timeout_s, on_done=done)
    return results


def _call(item: tuple[Callable[[Any], Any], Any]) -> Any:
    func, payload = item
    return func(payload)
