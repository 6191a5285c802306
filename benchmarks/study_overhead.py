"""What a study costs beyond its runs: the batch layer's overhead ratio, not a test.

``python benchmarks/study_overhead.py`` runs ``orchestration/study.py scenarios/case_study.yaml`` and
``orchestration/ida.py scenarios/ida_shipped.yaml`` (each into a new folder under a temporary folder),
timing each whole command; ``python benchmarks/study_overhead.py DIR ...`` measures study folders
that exist (their wall time from ``study.json``'s (IDA: ``ida.json``'s) start and end, to the second).

overhead = wall time / (sum of the jobs' compute times / workers)

The jobs' compute times are their ``wall_time_s`` in ``jobs/*.json`` (each measured where it ran:
a co-simulation from the fork of its child process to its result), results reused from the
cache across studies (``reused_from``) left out. 1.0 would be workers never idle and nothing
else done. The whole command also pays the cluster's start, the checks of every scenario
before anything runs, and the report (tables, figures); ``study.json``'s span leaves out the
first two. Prints one line per study, ratio first, then a JSON line.

``--job-cost`` instead measures the fixed cost of one short run (El Centro, 0.5 s simulated, the
size of an IDA window's start) in a child process as a worker runs it, with the FMUs extracted
afresh for the run (as before) and from the machine's shared extractions (now), alternately.
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
STUDIES = {"case_study": ("orchestration/study.py", "scenarios/case_study.yaml"),
           "ida_shipped": ("orchestration/ida.py", "scenarios/ida_shipped.yaml")}


def _seconds(stamp: str) -> float:
    return datetime.fromisoformat(stamp.replace("Z", "+00:00")).timestamp()


def measure(folder: Path, command_s: float | None = None) -> dict:
    """The overhead ratios of a finished study folder (``command_s``: the whole command's wall time [s])."""
    record = folder / "study.json" if (folder / "study.json").is_file() else folder / "ida.json"  # IDA: ida.json
    study = json.loads(record.read_text())
    jobs = [json.loads(p.read_text()) for p in sorted((folder / "jobs").glob("*.json"))]
    computed = [j for j in jobs if not j.get("reused_from")]
    compute = sum(float(j.get("wall_time_s") or 0.0) for j in computed)
    pool = study.get("batch") or study.get("engine") or {}  # "engine": folders written before the batch layer
    workers = int(pool.get("workers") or (study.get("config") or {}).get("workers") or 1)
    span = _seconds(study["finished"]) - _seconds(study["started"])
    ideal = compute / workers
    out = {"study": study["name"], "folder": str(folder), "jobs": len(computed), "reused": len(jobs) - len(computed),
           "workers": workers, "jobs_compute_s": round(compute, 1), "ideal_s": round(ideal, 1),
           "study_span_s": round(span, 1), "overhead_span": round(span / ideal, 3) if ideal else None}
    if command_s is not None:
        out["command_s"] = round(command_s, 1)
        out["overhead_command"] = round(command_s / ideal, 3) if ideal else None
    return out


def run(name: str, root: Path, extra: list[str]) -> dict:
    """Run one study's command into ``root/name``; its measurement."""
    tool, study = STUDIES[name]
    out = root / name
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, str(PROJECT / tool), str(PROJECT / study), "--out", str(out), "--quiet",
                           *extra], cwd=PROJECT, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        sys.exit(f"{name}: exit {proc.returncode}\n{proc.stderr[-2000:]}")
    return measure(out, wall)


def _short_run(shared: bool) -> float:
    """One short run as a study's child runs it; its wall time [s] (without the fork)."""
    from orchestration.engine_hooks import plan_scenario
    from orchestration.master import fmu_loading
    from orchestration.master.session import run_plan

    if not shared:
        fmu_loading.share_extractions(None)
    start = time.perf_counter()
    plan = plan_scenario(PROJECT / "scenarios" / "elcentro.yaml", ("simulation.stop_time=0.5",))
    with tempfile.TemporaryDirectory() as tmp:
        run_plan(plan, Path(tmp) / "run", plots=False, progress=False)
    return time.perf_counter() - start


def job_cost(rounds: int) -> dict:
    """Median wall time of a short run in a child: FMUs extracted afresh against shared extractions."""
    import statistics

    from orchestration.batch.child import call_in_child

    times: dict[str, list[float]] = {"fresh": [], "shared": []}
    call_in_child(_short_run, True)  # the forkserver started, the extractions made
    for _ in range(rounds):
        for name in times:
            res = call_in_child(_short_run, name == "shared")
            if not res["ok"]:
                sys.exit(res["error"])
            times[name].append(res["wall_time_s"])
    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"job cost: shared extractions {med['shared']:.3f} s, fresh {med['fresh']:.3f} s per short run "
          f"(saves {med['fresh'] - med['shared']:.3f} s; medians of {rounds}, child fork included)")
    return {"job_cost_s": med, "rounds": rounds}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="*", type=Path, help="finished study folders to measure (default: run both)")
    parser.add_argument("--only", choices=sorted(STUDIES), action="append", help="run only this study (repeatable)")
    parser.add_argument("--verify", action="store_true", help="case study: compute the Radau references too")
    parser.add_argument("--job-cost", type=int, metavar="ROUNDS", help="measure a short run's fixed cost instead")
    args = parser.parse_args(argv)
    if args.job_cost:
        print(json.dumps(job_cost(args.job_cost)))
        return 0
    with open("/proc/loadavg") as f:
        load_before = f.read().split()[:3]
    if args.folders:
        results = [measure(f) for f in args.folders]
    else:
        root = Path(tempfile.mkdtemp(prefix="mre-cosim-overhead-"))
        results = [run(name, root, ["--verify"] if args.verify and name == "case_study" else [])
                   for name in (args.only or list(STUDIES))]
    with open("/proc/loadavg") as f:
        load_after = f.read().split()[:3]
    for r in results:
        ratio = r.get("overhead_command", r["overhead_span"])
        print(f"overhead {ratio} {r['study']}: " + (f"command {r['command_s']} s, " if "command_s" in r else "")
              + f"record span {r['study_span_s']} s (ratio {r['overhead_span']}), jobs {r['jobs_compute_s']} s "
              f"over {r['workers']} workers = {r['ideal_s']} s ({r['jobs']} jobs, {r['reused']} reused)")
    print(f"load average before {' '.join(load_before)}, after {' '.join(load_after)}")
    print(json.dumps({"results": results, "load_before": load_before, "load_after": load_after}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
