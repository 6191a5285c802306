"""The controller benchmark's cost: its wall time and parallel efficiency; not a test.

``python benchmarks/controller_benchmark_cost.py [--workers N] [--out DIR]`` runs
``orchestration/study.py scenarios/controller_benchmark.yaml`` into a new folder (under a temporary
folder unless ``--out``), timing the whole command; ``python benchmarks/controller_benchmark_cost.py
--folder DIR`` measures a finished study folder instead (its wall time from ``study.json``'s start and
end, to the second, or, for a folder without ``study.json``, from its ``.mre-cosim-run`` start to the
newest file written).

    parallel efficiency = sum of the runs' stepping times / (study wall time x workers)
    overhead            = study wall time / (sum of the runs' stepping times / workers) = 1 / efficiency

A run's stepping time is the master's own ``wall_time_s`` of the co-simulation (in its job's
``value``: the stepping loop, without starting the child process, loading the FMUs and writing the
run folder); a current sweep has none, and counts with its whole job time. The same ratios with
every job's whole time (``wall_time_s`` of ``jobs/*.json``: fork to result) are printed too. Results
reused from the cache (``reused_from``) are left out. Efficiency 1.0 would be workers never idle and
nothing but stepping done. Prints one line of text, then a JSON line.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from datetime import datetime
from pathlib import Path

PROJECT = Path(__file__).resolve().parents[1]
STUDY = ("orchestration/study.py", "scenarios/controller_benchmark.yaml")


def _seconds(stamp: str) -> float:
    return datetime.fromisoformat(stamp.replace("Z", "+00:00")).timestamp()


def _span_and_workers(folder: Path) -> tuple[float, int | None]:
    """(study wall time [s], workers or None) from ``study.json``, else from the folder's files."""
    record = folder / "study.json"
    if record.is_file():
        study = json.loads(record.read_text())
        pool = study.get("batch") or study.get("engine") or {}
        workers = pool.get("workers") or (study.get("config") or {}).get("workers")
        return _seconds(study["finished"]) - _seconds(study["started"]), (int(workers) if workers else None)
    started = _seconds(json.loads((folder / ".mre-cosim-run").read_text())["started"])
    newest = max(p.stat().st_mtime for p in folder.rglob("*") if p.is_file())
    return newest - started, None


def measure(folder: Path, workers: int | None = None, command_s: float | None = None) -> dict:
    """The efficiency of a finished controller-benchmark folder (``command_s``: the whole command [s])."""
    span, recorded = _span_and_workers(folder)
    workers = recorded or workers
    if not workers:
        raise SystemExit(f"{folder}: the number of workers is not recorded: give --workers")
    jobs = [json.loads(p.read_text()) for p in sorted((folder / "jobs").glob("*.json"))]
    computed = [j for j in jobs if not j.get("reused_from")]
    stepping = job_total = 0.0
    runs = sweeps = 0
    for job in computed:
        whole = float(job.get("wall_time_s") or 0.0)
        value = job.get("value") if isinstance(job.get("value"), dict) else {}
        inner = value.get("wall_time_s")
        job_total += whole
        if inner is None:  # a current sweep: its whole job
            sweeps += 1
            stepping += whole
        else:
            runs += 1
            stepping += float(inner)
    out = {"study": "controller_benchmark", "folder": str(folder), "runs": runs, "sweeps": sweeps,
           "reused": len(jobs) - len(computed), "failed": sum(1 for j in computed if not j.get("ok")),
           "workers": workers, "wall_s": round(span, 1), "stepping_sum_s": round(stepping, 1),
           "jobs_sum_s": round(job_total, 1),
           "efficiency": round(stepping / (span * workers), 3) if span > 0 else None,
           "overhead": round(span * workers / stepping, 3) if stepping > 0 else None,
           "efficiency_jobs": round(job_total / (span * workers), 3) if span > 0 else None}
    if command_s is not None:
        out["command_s"] = round(command_s, 1)
        out["efficiency_command"] = round(stepping / (command_s * workers), 3)
    return out


def run_study(out: Path, workers: int | None) -> float:
    """Run the benchmark into ``out``; returns the whole command's wall time [s]."""
    cmd = [sys.executable, *STUDY, "--out", str(out), "--quiet"]
    if workers:
        cmd += ["--workers", str(workers)]
    started = time.perf_counter()
    proc = subprocess.run(cmd, cwd=PROJECT)
    elapsed = time.perf_counter() - started
    if proc.returncode not in (0, 1):  # 1: some jobs failed; still measured (and counted as failed)
        raise SystemExit(f"{' '.join(cmd)} exited {proc.returncode}")
    return elapsed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folder", type=Path, help="measure this finished study folder instead of running")
    parser.add_argument("--workers", type=int, help="worker processes (default: the study's, else one per core)")
    parser.add_argument("--out", type=Path, help="study folder to create (default: under a temporary folder)")
    args = parser.parse_args(argv)
    if args.folder:
        result = measure(args.folder, args.workers)
    else:
        with tempfile.TemporaryDirectory(prefix="controller_benchmark_") as tmp:
            folder = args.out or Path(tmp) / "study"
            command_s = run_study(folder, args.workers)
            result = measure(folder, args.workers, command_s)
    print(f"controller benchmark: wall {result['wall_s']:.0f} s on {result['workers']} workers, "
          f"{result['runs']} runs + {result['sweeps']} sweeps ({result['failed']} failed), stepping sum "
          f"{result['stepping_sum_s']:.0f} s, efficiency {result['efficiency']} (overhead {result['overhead']}); "
          f"whole jobs {result['jobs_sum_s']:.0f} s, efficiency {result['efficiency_jobs']}")
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
