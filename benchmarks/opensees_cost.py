"""What the OpenSees building unit costs: ``python benchmarks/opensees_cost.py [--rounds N] [--yielding]``.

Runs the whole command ``python orchestration/run.py SCENARIO --out DIR --no-plots --quiet`` for
El Centro with the ShearBuilding unit (``scenarios/elcentro.yaml``) and with the OpenSees unit
(``scenarios/elcentro_opensees.yaml``), alternating, ``--rounds`` times each, and prints the
medians and the ratio OpenSees / ShearBuilding of: wall time, CPU time of the command (user +
system, from the child's rusage) and the stepping loop alone (``wall_time_s`` of summary.json).
``--yielding`` adds the yielding pair: ShearBuilding ``hysteresis=bilinear`` against the OpenSees
unit with ``scenarios/structures/dyke_steel01.py`` (same fy_j, b_j). Needs openseespy.
"""

from __future__ import annotations

import argparse
import ast
import json
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PROJECT = Path(__file__).resolve().parent.parent
RUN_PY = PROJECT / "orchestration" / "run.py"
SCENARIOS = PROJECT / "scenarios"
STEEL01 = SCENARIOS / "structures" / "dyke_steel01.py"


def steel01_overrides() -> list[str]:
    """``--set`` values giving ShearBuilding the storeys of the Steel01 script (read without running it)."""
    values = {}
    for node in ast.parse(STEEL01.read_text()).body:
        if isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Name):
            if node.targets[0].id in ("YIELD_SHEARS", "HARDENING"):
                values[node.targets[0].id] = ast.literal_eval(node.value)
    out = ["building.hysteresis=bilinear"]
    out += [f"building.fy_{j}={v}" for j, v in enumerate(values["YIELD_SHEARS"], 1)]
    out += [f"building.b_{j}={v}" for j, v in enumerate(values["HARDENING"], 1)]
    return out


def variants(yielding: bool) -> dict[str, tuple[str, list[str]]]:
    out = {"ShearBuilding": ("elcentro.yaml", []), "OpenSees": ("elcentro_opensees.yaml", [])}
    if yielding:
        out["ShearBuilding bilinear"] = ("elcentro.yaml", steel01_overrides())
        out["OpenSees Steel01"] = ("elcentro_opensees.yaml", [f"building.script={STEEL01}"])
    return out


def measure(scenario: str, overrides: list[str], folder: Path) -> dict[str, float]:
    """One whole command: wall [s], CPU [s] (user + system of the child) and the stepping loop [s]."""
    argv = [sys.executable, str(RUN_PY), str(SCENARIOS / scenario), "--out", str(folder), "--no-plots", "--quiet"]
    for item in overrides:
        argv += ["--set", item]
    return measure_command(argv, folder)


def measure_command(argv: list[str], folder: Path) -> dict[str, float]:
    """``argv`` (a run writing ``folder``) as a whole command: wall [s], CPU [s] (user + system of the child) and
    the stepping loop [s] (its ``summary.json``)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(argv, cwd=PROJECT, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({done.returncode}):\n{done.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    loop = json.loads((folder / "summary.json").read_text())["wall_time_s"]
    return {"wall": wall, "cpu": cpu, "loop": loop}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3, help="runs of each variant, alternating (default 3)")
    parser.add_argument("--yielding", action="store_true", help="also the bilinear / Steel01 pair")
    args = parser.parse_args()
    chosen = variants(args.yielding)
    times: dict[str, list[dict[str, float]]] = {name: [] for name in chosen}
    with tempfile.TemporaryDirectory(prefix="opensees-cost-") as tmp:
        for r in range(args.rounds):
            for name, (scenario, overrides) in chosen.items():
                times[name].append(measure(scenario, overrides, Path(tmp) / f"{name.replace(' ', '_')}-{r}"))
                print(f"round {r + 1} {name}: " + ", ".join(f"{k} {v:.2f} s" for k, v in times[name][-1].items()),
                      flush=True)
    median = {name: {k: statistics.median(t[k] for t in ts) for k in ("wall", "cpu", "loop")}
              for name, ts in times.items()}
    print(f"\nEl Centro (53.76 s at 1 ms), medians of {args.rounds} alternating runs:")
    for name, m in median.items():
        print(f"  {name:24s} command {m['wall']:6.2f} s wall, {m['cpu']:6.2f} s CPU; stepping loop {m['loop']:6.2f} s")
    pairs = [("OpenSees", "ShearBuilding")] + ([("OpenSees Steel01", "ShearBuilding bilinear"),
                                                ("ShearBuilding bilinear", "ShearBuilding")] if args.yielding else [])
    for a, b in pairs:
        ratios = ", ".join(f"{k} {median[a][k] / median[b][k]:.2f}x" for k in ("wall", "cpu", "loop"))
        print(f"  {a} / {b}: {ratios}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
