"""The Dask study pool (orchestration/batch/pool.py): results, isolation, faults.

Co-simulations run in a child process of the worker (orchestration/batch/child.py), never
in the worker itself: these tests check that many runs through the workers equal a run in
a fresh process bit for bit, that no FMU module ever lands in a worker, that a job failing
by itself is recorded once and not retried, and that a worker killed mid-job costs a re-run
elsewhere, a bounded number of times.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path

import pytest

from orchestration.batch.pool import BatchPool, BatchUnavailable, map_jobs, map_values
from orchestration.batch.portable import FileCorrupted, FileRef, file_bytes, local_copy, portable
from orchestration.case_study.case_jobs import OUTPUTS_OVERRIDE
from orchestration.engine_hooks import plan_scenario
from orchestration.ida_study.ida_jobs import ida_job

from ..conftest import PROJECT


@pytest.fixture(scope="module")
def pool():
    with BatchPool(workers=2, max_worker_deaths=1) as e:
        yield e


def _square(x: int) -> int:
    return x * x


def _tally(path: str) -> int:
    with open(path, "a") as f:
        f.write("x")
    return len(Path(path).read_text())


def _raises(payload: dict) -> None:
    _tally(payload["counter"])
    raise RuntimeError("broken model")


def _segfaults(payload: dict) -> None:
    _tally(payload["counter"])
    os.kill(os.getpid(), signal.SIGSEGV)


def _sleeps(payload: dict) -> None:
    time.sleep(payload["s"])


def _kills_its_worker_once(payload: dict) -> str:
    """Runs in the worker itself (isolate=False): the first attempt kills the worker process."""
    attempt = _tally(payload["counter"])
    if attempt == 1:
        os.kill(os.getpid(), signal.SIGKILL)
    return f"attempt {attempt}"


def _kills_its_worker_always(payload: dict) -> None:
    _tally(payload["counter"])
    os.kill(os.getpid(), signal.SIGKILL)


def _length(payload: dict) -> int:
    return len(payload["data"])


def _fmu_traces() -> dict:
    """What a worker's interpreter holds of FMUs: pythonfmu slave modules, resource folders on sys.path."""
    return {"modules": sorted(m for m in sys.modules if m.endswith("_fmu")),
            "resources": [p for p in sys.path if p.endswith("resources")]}


def _ida_payload(stop_time: float = 2.0) -> dict:
    plan = plan_scenario(PROJECT / "scenarios" / "kobe.yaml",
                         (f"simulation.stop_time={stop_time}", "controller.mode=sosm", OUTPUTS_OVERRIDE))
    pp = portable(plan)
    return {"plan": pp, "files": {sha: p.read_bytes() for sha, p in file_bytes([pp]).items()}, "scale": 0.8,
            "masses": [98.3] * 4}


@pytest.mark.slow
def test_values_come_back_in_order(pool):
    assert map_values(_square, list(range(7)), pool=pool) == [k * k for k in range(7)]
    assert [r.value for r in map_jobs(_square, [3, 4], pool=pool, isolate=True)] == [9, 16]


@pytest.mark.slow
def test_cosimulations_through_the_workers_equal_a_fresh_process_and_leave_no_trace(pool):
    """Six runs on two workers (each in its own child process) equal the same run in this process, exactly."""
    payload = _ida_payload()
    fresh = ida_job(payload)
    assert fresh["status"] == "ok" and fresh["metrics"]["x_base_mm"] > 0
    shared = {**payload, "files": {sha: pool.share(data) for sha, data in payload["files"].items()},
              "plan": pool.share(payload["plan"], dedupe=False)}
    before = pool.client.run(_fmu_traces)  # (a worker inherits sys.path from the process that started it)
    results = pool.map(ida_job, [shared] * 6, isolate=True)
    assert all(r.ok for r in results)
    for r in results:
        assert r.value["metrics"] == fresh["metrics"]
    assert len({r.worker for r in results}) == 2
    after = pool.client.run(_fmu_traces)
    assert after == before and all(traces["modules"] == [] for traces in after.values())


@pytest.mark.slow
def test_a_job_that_fails_by_itself_is_recorded_once_and_not_retried(pool, tmp_path):
    counters = [str(tmp_path / f"c{k}") for k in range(2)]
    workers = set(pool.client.scheduler_info()["workers"])
    results = pool.map(_raises, [{"counter": counters[0]}], isolate=False)
    assert results[0].status == "failed" and results[0].error == "RuntimeError: broken model"
    assert "Traceback" in results[0].details
    results = pool.map(_segfaults, [{"counter": counters[1]}], isolate=True)
    assert results[0].status == "failed" and results[0].error == "process killed by signal SIGSEGV"
    # Dask re-runs a task only when its worker is lost: once the scheduler is idle with the same workers,
    # nothing can run the jobs again (polled, at most 30 s, instead of a fixed wait).
    deadline = time.monotonic() + 30
    while any(pool.client.processing().values()) and time.monotonic() < deadline:
        time.sleep(0.02)
    assert not any(pool.client.processing().values()), "the scheduler still runs tasks after 30 s"
    assert set(pool.client.scheduler_info()["workers"]) == workers, "a worker was lost"
    assert [Path(c).read_text() for c in counters] == ["x", "x"]


@pytest.mark.slow
def test_a_job_over_its_time_is_killed(pool):
    start = time.perf_counter()
    res = pool.map(_sleeps, [{"s": 60}], isolate=True, timeout_s=1.0)[0]
    assert res.status == "failed" and res.error.startswith("timed out after 1 s")
    assert time.perf_counter() - start < 20


@pytest.mark.slow
def test_a_killed_worker_costs_a_rerun_elsewhere_a_bounded_number_of_times(pool, tmp_path):
    once, always = str(tmp_path / "once"), str(tmp_path / "always")
    shared = pool.share(b"x" * 1000)  # on every worker; the kills below take both original workers
    results = pool.map(_kills_its_worker_once, [{"counter": once}], isolate=False)
    assert results[0].ok and results[0].value == "attempt 2"
    results = pool.map(_kills_its_worker_always, [{"counter": always}], isolate=False)
    assert results[0].status == "lost" and "died 2 times" in results[0].error
    assert Path(always).read_text() == "xx"  # the first run and one re-run (max_worker_deaths = 1)
    assert map_values(_square, [5], pool=pool) == [25]  # the cluster is still usable
    assert map_values(_length, [{"data": shared}], pool=pool) == [1000]  # and the shared data is back


def test_files_travel_by_content(tmp_path, monkeypatch):
    monkeypatch.setattr("orchestration.batch.portable.cache_root", lambda: tmp_path / "cache")
    data = b"time_s,accel_g\n0,0\n1,0.1\n"
    import hashlib

    ref = FileRef(hashlib.sha256(data).hexdigest(), "r.csv")
    path = local_copy(ref, data)
    assert path.read_bytes() == data and path.name == "r.csv"
    assert local_copy(ref, b"ignored: already there") == path
    with pytest.raises(FileCorrupted):
        local_copy(FileRef("0" * 64, "r.csv"), data)


def test_job_keys_change_with_content_and_code(monkeypatch):
    from orchestration.batch import portable as mod

    pp = portable(plan_scenario(PROJECT / "scenarios" / "kobe.yaml", ("simulation.stop_time=1",)))
    same = portable(plan_scenario(PROJECT / "scenarios" / "kobe.yaml", ("simulation.stop_time=1",)))
    other = portable(plan_scenario(PROJECT / "scenarios" / "kobe.yaml", ("simulation.stop_time=1", "ground.scale=0.6")))
    key = mod.job_key("ida", {"plan": mod.plan_content(pp)})
    assert key == mod.job_key("ida", {"plan": mod.plan_content(same)})
    assert key != mod.job_key("ida", {"plan": mod.plan_content(other)})
    assert key != mod.job_key("ida", {"plan": mod.plan_content(pp), "scale": 2.0})
    monkeypatch.setattr(mod, "code_version", lambda sources=(): "another code version")
    assert key != mod.job_key("ida", {"plan": mod.plan_content(pp)})
    monkeypatch.undo()
    monkeypatch.delenv(mod.CODE_VERSION_ENV, raising=False)  # a study's own sources count in its keys
    mod.code_version.cache_clear()
    plain = mod.job_key("ida", {"plan": mod.plan_content(pp)})
    assert plain != mod.job_key("ida", {"plan": mod.plan_content(pp)}, ("orchestration/ida_study/ida_jobs.py",))


@pytest.mark.slow
def test_an_unreachable_scheduler_is_refused_quickly():
    start = time.perf_counter()
    with pytest.raises(BatchUnavailable, match="cannot reach"):
        BatchPool("tcp://127.0.0.1:9", connect_timeout_s=2).start()
    assert time.perf_counter() - start < 30


@pytest.mark.slow
def test_tuning_fanned_out_on_the_engine_equals_tuning_in_process(pool):
    from orchestration.building_studies.run_settings import run_overrides
    from orchestration.case_study.case_config import ObjectiveSpec, TuningSpec, load_study
    from orchestration.case_study.tuning import pool_evaluate, tune

    study = load_study(PROJECT / "scenarios" / "case_study.yaml")
    plan = plan_scenario(study.scenario_path("elcentro"), run_overrides(study.spec))
    spec = TuningSpec(stop_time=2.0, n_samples=3, max_evals=4, seed=7)
    here = tune(plan, spec, ObjectiveSpec(), 3.0)
    there = tune(plan, spec, ObjectiveSpec(), 3.0, evaluate=pool_evaluate(pool, plan))
    assert there["gains"] == here["gains"] and there["history"] == here["history"]


def _started_at(payload: float) -> float:
    started = time.monotonic()  # system-wide clock: comparable between the jobs of one machine
    time.sleep(0.02)
    return started


@pytest.mark.slow
def test_jobs_with_costs_start_longest_first():
    # One worker runs one job at a time, so the order the jobs start in is the order the
    # scheduler gave them: longest expected first (LPT), whatever order they were listed in.
    costs = [3.0, 9.0, 1.0, 7.0, 5.0, 8.0, 2.0]
    with BatchPool(workers=1) as one:
        results = one.map(_started_at, costs, costs=costs)
    assert all(r.ok for r in results)
    started = [r.value for r in results]
    by_start = [c for _, c in sorted(zip(started, costs, strict=True))]
    assert by_start == sorted(costs, reverse=True)
