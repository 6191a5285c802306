"""The suite benchmark's cost: wall time per phase, parallel efficiency, tuning runs per strategy; not a test.

``python benchmarks/suite_benchmark_cost.py [--out DIR] [--set KEY=VALUE ...]`` runs
``orchestration/study.py scenarios/controller_suite_benchmark.yaml`` into a new folder (under a temporary folder
unless ``--out``), timing the whole command; ``--folder DIR`` reads a finished one instead. From the folder's
``benchmark.json`` (written by the command, :mod:`orchestration.suite_benchmark.benchmark_run`):

    parallel efficiency = sum of the jobs' wall times / (phase wall time x workers)      (idle workers)
    run efficiency      = sum of the runs' own times (run_plan) / (phase wall time x workers)
    command / stepping  = whole command / (sum of the runs' own times / workers)

A job's wall time runs from forking its child process to its result; a run's own time is the master's
``run_plan`` (loading the FMUs and stepping). Prints a table, then a JSON line.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PROJECT = Path(__file__).resolve().parents[1]
STUDY = ("orchestration/study.py", "scenarios/controller_suite_benchmark.yaml")


def measure(folder: Path, command_s: float | None = None) -> dict:
    """The cost figures of a finished suite benchmark folder (``command_s``: the whole command [s], if timed)."""
    info = json.loads((folder / "benchmark.json").read_text())
    if not info.get("complete") or "cost" not in info:
        raise SystemExit(f"{folder}: not a complete suite benchmark (benchmark.json says complete: "
                         f"{info.get('complete')})")
    cost = dict(info["cost"])
    runs = [float((json.loads(p.read_text()).get("value") or {}).get("run_wall_time_s") or 0.0)
            for p in sorted((folder / "score" / "jobs").glob("*.json"))]
    w = cost["workers"]
    cost["scoring_run_efficiency"] = sum(runs) / (cost["scoring_s"] * w)
    total = command_s if command_s is not None else cost["total_s"]
    stepping = sum(runs) + cost.get("tuning_run_efficiency", float("nan")) * cost["tuning_s"] * w
    cost.update(command_s=total, command_over_stepping=total / (stepping / w))
    return cost


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folder", type=Path, help="a finished suite benchmark folder")
    parser.add_argument("--out", type=Path, help="folder for a new run (default: a temporary one)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args()
    command_s = None
    if args.folder is None:
        out = args.out or Path(tempfile.mkdtemp(prefix="suite-benchmark-cost-")) / "run"
        command = [sys.executable, *STUDY, "--out", str(out), "--quiet",
                   *(a for o in args.overrides for a in ("--set", o))]
        t0 = time.perf_counter()
        code = subprocess.run(command, cwd=PROJECT, check=False).returncode
        command_s = time.perf_counter() - t0
        if code != 0:
            raise SystemExit(f"the suite benchmark exited {code}")
        args.folder = out
    c = measure(args.folder, command_s)
    rows = [("workers", c["workers"]), ("tuning wall time [s]", f"{c['tuning_s']:.0f}"),
            ("tuning runs (per strategy)", f"{c['tuning_runs']} ({c.get('tuning_runs_per_strategy', '?')})"),
            ("tuning efficiency, jobs / runs", f"{c['tuning_efficiency']:.2f} / "
                                               f"{c.get('tuning_run_efficiency', float('nan')):.2f}"),
            ("scoring wall time [s]", f"{c['scoring_s']:.0f}"), ("scoring runs", c["scoring_runs"]),
            ("scoring efficiency, jobs / runs", f"{c['scoring_efficiency']:.2f} / {c['scoring_run_efficiency']:.2f}"),
            ("whole command [s]", f"{c['command_s']:.0f}"),
            ("whole command / its runs' own time per worker", f"{c['command_over_stepping']:.2f}")]
    for name, value in rows:
        print(f"{name:48s} {value}")
    print(json.dumps(c))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
