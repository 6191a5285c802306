"""In-process stepping: the engine's coupling algorithm over in-process units / the former hand-written copy.

``python benchmarks/inprocess_bench.py [--rounds N] [--stop S] [--executors]``

Prints the ratio first: ``orchestration.inprocess.simulate_coupled`` (in-process units stepped by
:class:`~orchestration.master.algorithm.CouplingAlgorithm`'s program, scalar executor) against
``tests/monolithic_oracle.simulate_coupled`` (the hand-written copy of the algorithm that tuning and
base sensitivity used before), on the same record, system and scheme, side by side in this one process:
rounds alternate which goes first, the ratio is the median of the per-round ratios (wall and CPU time),
so the machine's load cancels as far as it can. Target: <= 1.0. Both give the same numbers, bit for
bit (checked here on every round). ``--executors`` adds the engine's numpy executor
(``CouplingAlgorithm.step``) as a third column, for information.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

PROJECT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(PROJECT))

from components.physics.ground_motion_core import GroundMotion, read_record  # noqa: E402
from components.physics.monolithic import SystemSetup, Trajectory  # noqa: E402
from orchestration.inprocess import simulate_coupled  # noqa: E402
from tests.support.monolithic_oracle import simulate_coupled as oracle  # noqa: E402

RECORD = PROJECT / "scenarios" / "records" / "kobe_1995_jma_ns.csv"
H = 1e-3


def _timed(fn, *args, **kwargs) -> tuple[Trajectory, float, float]:
    wall, cpu = time.perf_counter(), time.process_time()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - wall, time.process_time() - cpu


def _identical(a: Trajectory, b: Trajectory) -> bool:
    return all(np.array_equal(getattr(a, f), getattr(b, f)) for f in ("t", "x", "v", "a", "arel", "F", "i", "ag"))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5, help="alternating rounds (default 5)")
    parser.add_argument("--stop", type=float, default=150.0, help="simulated seconds of Kobe (default 150)")
    parser.add_argument("--executors", action="store_true", help="also time CouplingAlgorithm.step (numpy)")
    args = parser.parse_args(argv)
    setup = SystemSetup(GroundMotion(read_record(RECORD), scale=0.5), passive_current=None)  # SOSM, default gains
    n = round(args.stop / H)
    contenders = {"inprocess": lambda: simulate_coupled(setup, H, n),
                  "oracle": lambda: oracle(setup, H, n)}
    if args.executors:
        contenders["engine step()"] = lambda: simulate_coupled(setup, H, n, executor="python")
    times: dict[str, list[tuple[float, float]]] = {k: [] for k in contenders}
    rows = []
    for r in range(args.rounds):
        names = list(contenders) if r % 2 == 0 else list(reversed(contenders))
        results = {}
        for name in names:
            results[name], wall, cpu = _timed(contenders[name])
            times[name].append((wall, cpu))
        same = all(_identical(results["inprocess"], t) for t in results.values())
        if not same:
            print("error: the in-process path and the oracle differ", file=sys.stderr)
            return 1
        rows.append(f"round {r + 1}: " + ", ".join(f"{k} {times[k][-1][0]:.2f} s (CPU {times[k][-1][1]:.2f} s)"
                                                   for k in contenders) + f"; load {os.getloadavg()[0]:.2f}")
    ratio = statistics.median(a[0] / b[0] for a, b in zip(times["inprocess"], times["oracle"], strict=True))
    ratio_cpu = statistics.median(a[1] / b[1] for a, b in zip(times["inprocess"], times["oracle"], strict=True))
    med = {k: statistics.median(w for w, _ in v) for k, v in times.items()}
    print(f"ratio in-process units + CouplingAlgorithm / hand-written copy: {ratio:.3f} (wall, median of "
          f"{args.rounds} rounds), {ratio_cpu:.3f} (CPU); target <= 1.0: {'met' if ratio <= 1.0 else 'MISSED'}")
    print(f"Kobe x0.5, {args.stop:g} s at {H * 1e3:g} ms ({n} steps), SOSM, gauss-seidel, step-mean; results "
          "identical bit for bit on every round")
    print("medians: " + ", ".join(f"{k} {v:.2f} s ({v / n * 1e6:.1f} us/step)" for k, v in med.items()))
    for line in rows:
        print("  " + line)
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}, numpy {np.__version__}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
