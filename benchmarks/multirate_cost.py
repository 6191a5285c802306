"""The cost of multi-rate stepping: Kobe with the plant at 0.25 ms and the controller at 1 ms, against 1 ms; not a test.

``python benchmarks/multirate_cost.py [--stop S] [--rounds N] [--out DIR]`` runs ``scenarios/kobe.yaml``
(the FMUs, the native executor when it is available, as a scenario run) side by side, round after round:

* ``base``: ``simulation.step = 0.001`` (the shipped run);
* ``multirate``: ``simulation.step = 0.00025`` with ``units.controller.step = 0.001``;
* ``single-rate``: ``simulation.step = 0.00025`` for every unit (for comparison: the controller steps 4x as often).

A run's stepping time is the master's own ``wall_time_s`` (``summary.json``: initialization, the stepping
loop with recording and checks, teardown; not loading the FMUs or writing the run folder). The ratio is
the median over the rounds of multirate / base (goal <= 3: the plant steps 4 times as often, the
controller as often); ``single-rate`` / base is printed beside it. Every run is recorded at every base
step, as a run records. Prints one line per round, a summary line, then a JSON line.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
from pathlib import Path

PROJECT = Path(__file__).resolve().parents[1]
KOBE = PROJECT / "scenarios" / "kobe.yaml"
CASES = {
    "base": ("simulation.step=0.001",),
    "multirate": ("simulation.step=0.00025", "units.controller.step=0.001"),
    "single-rate": ("simulation.step=0.00025",),
}


def stepping_time(case: str, stop: float, out: Path) -> tuple[float, str]:
    """(the master's wall time [s], executor) of one Kobe run of ``case``, cut at ``stop`` [s]."""
    from orchestration.engine_hooks import plan_scenario
    from orchestration.master.session import run_plan

    plan = plan_scenario(KOBE, (*CASES[case], f"simulation.stop_time={stop:g}"))
    run = run_plan(plan, out=out, plots=False)
    if not run.result.complete:
        raise SystemExit(f"{case}: the run did not complete: {run.result.error}")
    return run.result.wall_time, run.result.executor


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stop", type=float, default=150.0, help="stop time [s] (default: the whole record, 150)")
    parser.add_argument("--rounds", type=int, default=3, help="rounds of the three runs (default 3)")
    parser.add_argument("--out", type=Path, default=None, help="folder for the run folders (default: temporary)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="multirate-cost-") as tmp:
        root = args.out or Path(tmp)
        times: dict[str, list[float]] = {case: [] for case in CASES}
        executors = set()
        for r in range(args.rounds):
            for case in CASES:
                seconds, executor = stepping_time(case, args.stop, root / f"{case}-{r}")
                times[case].append(seconds)
                executors.add(executor)
            print(f"round {r + 1}: " + ", ".join(f"{c} {times[c][-1]:.2f} s" for c in CASES), flush=True)
    ratio = statistics.median(m / b for m, b in zip(times["multirate"], times["base"], strict=True))
    single = statistics.median(s / b for s, b in zip(times["single-rate"], times["base"], strict=True))
    print(f"Kobe {args.stop:g} s, executor {'/'.join(sorted(executors))}: plant 0.25 ms with the controller at "
          f"1 ms takes {ratio:.2f}x the stepping time of the 1 ms run (goal <= 3); all units at 0.25 ms: "
          f"{single:.2f}x (median of {args.rounds} rounds)")
    print(json.dumps({"stop_time_s": args.stop, "rounds": args.rounds, "executor": sorted(executors),
                      "wall_time_s": times, "ratio_multirate": ratio, "ratio_single_rate": single}))


if __name__ == "__main__":
    main()
