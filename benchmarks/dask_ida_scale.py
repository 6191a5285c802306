"""The full IDA (not a test): wall time here, and a projection to larger clusters.

``python benchmarks/dask_ida_scale.py [--study scenarios/ida.yaml] [--set KEY=VALUE ...] [--per-job-ms D]``

Runs ``orchestration/ida.py`` on the study (default: the FEMA P695 far-field set, 44
components x 8 levels x 3 strategies = 1,056 runs) on the local cluster, notes the load
average before and after, and reads back from the study folder each run's cost on its
worker (the child process, from fork to result) and the wall time of the run phase.

Projection to N workers, from the measured numbers only::

    T(N) = T_fixed + (sum_i c_i + n d) / N  (+ up to c_max at the end: the last runs finish unevenly)

c_i: each run's measured cost on its worker; d: Dask's measured cost per job (from
``benchmarks/dask_engine.py``, ``--per-job-ms``); n: runs; T_fixed: planning, cluster start
and the report, measured here. The scheduler hands out tasks one at a time: its own cost
per task s (measured here as the run phase's wall minus the ideal sum(c)/workers, divided by
n, an upper bound) caps the rate at 1/s tasks per second whatever N is.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", type=Path, default=ROOT / "scenarios" / "ida.yaml")
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    parser.add_argument("--out", type=Path, help="study folder (default: a temporary one, kept)")
    parser.add_argument("--per-job-ms", type=float, default=0.0, help="Dask's cost per job d [ms], measured")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="ida-scale-")) / "study"
    load_before = os.getloadavg()
    cmd = [sys.executable, str(ROOT / "orchestration" / "ida.py"), str(args.study), "--out", str(out), "--quiet",
           *(x for kv in args.overrides for x in ("--set", kv))]
    start = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    total = time.perf_counter() - start
    load_after = os.getloadavg()
    print(proc.stdout.strip())
    if proc.returncode not in (0, 1):
        print(proc.stderr, file=sys.stderr)
        return proc.returncode
    info = json.loads((out / "ida.json").read_text())
    jobs = [json.loads(p.read_text()) for p in (out / "jobs").glob("*.json")]
    costs = [j["wall_time_s"] for j in jobs]
    n, workers, phase = len(costs), (info.get("batch") or info["engine"])["workers"], info["wall_time_s"]
    fixed = total - phase
    s = max(0.0, (phase - sum(costs) / workers) / n)
    d = args.per_job_ms / 1e3
    statuses: dict[str, int] = {}
    for j in jobs:
        key = j["value"]["status"] if j["ok"] else j["status"]
        statuses[key] = statuses.get(key, 0) + 1
    print(f"load average before {load_before[0]:.2f} / {load_before[1]:.2f} / {load_before[2]:.2f}, "
          f"after {load_after[0]:.2f} / {load_after[1]:.2f} / {load_after[2]:.2f}")
    print(f"runs {n} ({statuses}), workers {workers}; command wall {total:.0f} s = fixed {fixed:.0f} s "
          f"(planning {info['planning_s']:.0f} s, cluster start, report) + run phase {phase:.0f} s")
    print(f"per-run cost on the worker: median {statistics.median(costs):.2f} s, mean {statistics.mean(costs):.2f} s,"
          f" max {max(costs):.2f} s, sum {sum(costs):.0f} s; run phase / ideal (sum/{workers}) = "
          f"{phase / (sum(costs) / workers):.3f}; scheduler cost per task s <= {1e3 * s:.1f} ms")
    print()
    print("| workers | projected wall [s] | of which runs | run phase bound by the scheduler (n s) |")
    print("|---|---|---|---|")
    for w in (workers, 16, 64):
        runs = (sum(costs) + n * d) / w
        print(f"| {w} | {fixed + runs:.0f}-{fixed + runs + max(costs):.0f} | {runs:.0f}-{runs + max(costs):.0f} | "
              f"{n * s:.0f} |")
    print(json.dumps({"runs": n, "workers": workers, "total_s": total, "fixed_s": fixed, "phase_s": phase,
                      "sum_cost_s": sum(costs), "max_cost_s": max(costs), "median_cost_s": statistics.median(costs),
                      "sched_s": s, "load_before": load_before, "load_after": load_after, "statuses": statuses,
                      "folder": str(out)}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
