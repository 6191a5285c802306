"""Benchmarks of the Dask study pool (not tests): parallel efficiency and Dask's cost per job.

``python benchmarks/dask_engine.py [--jobs N] [--rounds R]`` prints Markdown and a JSON line.

Workload: IDA runs of ``scenarios/ida_shipped.yaml`` (the four shipped records, strong-motion
windows played at 0.2x, 2 s tail), at the first three intensity levels, passive-off and SOSM:
24 co-simulations of 4-10 simulated seconds, each in a child process of a worker, as the
studies run them. Measured alternately, round after round, so the machine's load (other
work on it) spreads over both sides of each ratio; medians over rounds.

1. Parallel efficiency: the same jobs on a local cluster of 1 worker and of 2 workers;
   efficiency = T(1) / (2 T(2)) (1.0 is ideal). It is the product of two factors, reported
   apart because other work on the machine moves the second one: how busy Dask keeps the
   workers (sum of the jobs' times over workers x wall, 2 workers against 1), and how much
   slower each job runs when two run at once (both cores taken: other processes on the
   machine then compete for them). Jobs start longest first (``BatchPool.map(costs=...)``).
2. Dask's cost per job: the same jobs one after the other (a) called here in a child process
   exactly as a worker calls them (``child.call_in_child``), (b) through Dask on one worker
   (submit, schedule, ship the shared plan and file handles, run, send back). Cost = (b) / (a) - 1.
   Also (c): the same runs in this process without a child (what isolation costs), and
   Dask's own cost per task: no-op jobs on one worker, in the worker and in a child.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from orchestration.batch.child import call_in_child
from orchestration.batch.pool import BatchPool
from orchestration.batch.portable import file_bytes
from orchestration.ida_study.ida_config import load_ida
from orchestration.ida_study.ida_jobs import ida_job
from orchestration.ida_study.ida_plan import prepare_ida

STUDY = Path(__file__).resolve().parents[1] / "scenarios" / "ida_shipped.yaml"


def workload(n_levels: int = 3, strategies: tuple[str, ...] = ("passive-off", "sosm")):
    """(prepared study, [(plan key, scale)]) for the benchmark's jobs."""
    prepared = prepare_ida(STUDY, *load_ida(STUDY))
    levels = prepared.study.spec.intensity.levels[:n_levels]
    jobs = [((c.rec.id, s), level / c.im) for c in prepared.components for level in levels for s in strategies]
    return prepared, jobs


def payloads_local(prepared, jobs) -> list[dict]:
    files = {sha: p.read_bytes() for sha, p in file_bytes(list(prepared.plans.values())).items()}
    return [{"plan": prepared.plans[key], "files": {sha: files[sha] for sha in prepared.plans[key].shas},
             "scale": scale, "masses": prepared.masses} for key, scale in jobs]


def payloads_shared(pool: BatchPool, prepared, jobs) -> list[dict]:
    files = {sha: pool.share(p.read_bytes()) for sha, p in file_bytes(list(prepared.plans.values())).items()}
    plans = {key: pool.share(pp, dedupe=False) for key, pp in prepared.plans.items()}
    return [{"plan": plans[key], "files": {sha: files[sha] for sha in prepared.plans[key].shas},
             "scale": scale, "masses": prepared.masses} for key, scale in jobs]


def on_cluster(workers: int, prepared, jobs) -> tuple[float, list[float]]:
    """Wall time of the jobs on a fresh local cluster of ``workers`` (cluster start excluded), job times."""
    with BatchPool(workers=workers) as pool:
        payloads = payloads_shared(pool, prepared, jobs)
        pool.map(ida_job, payloads[:workers], isolate=True)  # warm: each worker has the files and plans
        start = time.perf_counter()
        costs = [prepared.plans[key].plan.loaded.scenario.simulation.n_steps for key, _ in jobs]
        results = pool.map(ida_job, payloads, isolate=True, costs=costs)
        wall = time.perf_counter() - start
    assert all(r.ok for r in results), [r.error for r in results if not r.ok]
    return wall, [r.wall_time_s for r in results]


def _noop(x: int) -> int:
    return x


def per_task_cost(n: int = 200) -> tuple[float, float]:
    """Dask's own cost per task on one worker [s]: a no-op in the worker, and a no-op in a child of it."""
    with BatchPool(workers=1) as pool:
        pool.map(_noop, [0, 1], isolate=True)
        start = time.perf_counter()
        pool.map(_noop, list(range(n)))
        plain = (time.perf_counter() - start) / n
        start = time.perf_counter()
        pool.map(_noop, list(range(n // 4)), isolate=True)
        isolated = (time.perf_counter() - start) / (n // 4)
    return plain, isolated


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--levels", type=int, default=3)
    args = parser.parse_args()
    load_start = os.getloadavg()
    prepared, jobs = workload(args.levels)
    n = len(jobs)
    local = payloads_local(prepared, jobs)
    t1, t2, t_child, t_dask, t_direct, u1, u2, slow = [], [], [], [], [], [], [], []
    for _ in range(args.rounds):
        wall1, jobs1 = on_cluster(1, prepared, jobs)
        wall2, jobs2 = on_cluster(2, prepared, jobs)
        t1.append(wall1)
        t2.append(wall2)
        u1.append(sum(jobs1) / wall1)  # busy fraction of the worker(s): Dask's part of the efficiency
        u2.append(sum(jobs2) / (2 * wall2))
        slow.append(sum(jobs2) / sum(jobs1))  # how much slower each job ran two at a time: the machine's part
        start = time.perf_counter()
        for p in local:
            assert call_in_child(ida_job, p)["ok"]
        t_child.append((time.perf_counter() - start) / n)
        t_dask.append(t1[-1] / n)
        start = time.perf_counter()
        for p in local:
            ida_job(p)
        t_direct.append((time.perf_counter() - start) / n)
    prepared.cleanup()
    noop, noop_child = per_task_cost()
    m = {k: statistics.median(v) for k, v in
         {"t1": t1, "t2": t2, "child": t_child, "dask": t_dask, "direct": t_direct, "u1": u1, "u2": u2,
          "slow": slow}.items()}
    eff = m["t1"] / (2 * m["t2"])
    per_round = [a / (2 * b) for a, b in zip(t1, t2, strict=True)]
    cost = m["dask"] / m["child"] - 1
    isolation = m["child"] / m["direct"] - 1
    print(f"load average at start {load_start[0]:.2f}, at end {os.getloadavg()[0]:.2f}; {n} jobs, {args.rounds} rounds")
    print()
    print("| measure | value |")
    print("|---|---|")
    print(f"| wall, 1 worker (median of {args.rounds}) | {m['t1']:.2f} s ({', '.join(f'{v:.2f}' for v in t1)}) |")
    print(f"| wall, 2 workers | {m['t2']:.2f} s ({', '.join(f'{v:.2f}' for v in t2)}) |")
    print(f"| **parallel efficiency** T(1) / (2 T(2)) | **{eff:.3f}** (rounds: "
          f"{', '.join(f'{a / (2 * b):.2f}' for a, b in zip(t1, t2, strict=True))}) |")
    print(f"| parallel efficiency, median of the rounds' own | {statistics.median(per_round):.3f} |")
    print(f"| the machine's factor: 1 / (job time two at a time / one at a time) | {1 / m['slow']:.3f} |")
    print(f"| workers busy (sum of job times / workers x wall): 1 worker, 2 workers | {m['u1']:.3f}, {m['u2']:.3f} |")
    print(f"| job time two at a time / one at a time (CPU shared with the rest of the machine) | {m['slow']:.3f} |")
    print(f"| per job, child process called directly | {m['child']:.3f} s |")
    print(f"| per job, through Dask (1 worker) | {m['dask']:.3f} s |")
    print(f"| **Dask's cost per job** | **{100 * cost:+.1f} %** ({1e3 * (m['dask'] - m['child']):+.0f} ms) |")
    print(f"| Dask's own cost per task: a no-op job / a no-op job in a child | {1e3 * noop:.1f} ms / "
          f"{1e3 * noop_child:.1f} ms |")
    print(f"| per job, in this process (no child) | {m['direct']:.3f} s |")
    print(f"| isolation's cost per job (child vs in-process) | {100 * isolation:+.1f} % "
          f"({1e3 * (m['child'] - m['direct']):+.0f} ms) |")
    print(json.dumps({"jobs": n, "rounds": args.rounds, "load_start": load_start, "load_end": os.getloadavg(),
                      "t1": t1, "t2": t2, "child": t_child, "dask": t_dask, "direct": t_direct,
                      "efficiency": eff, "efficiency_rounds": per_round, "dask_cost": cost, "isolation_cost": isolation,
                      "noop_task_s": noop, "noop_child_task_s": noop_child,
                      "busy_1": u1, "busy_2": u2, "slowdown": slow}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
