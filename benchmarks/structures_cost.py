"""What yielding storeys cost: ``python benchmarks/structures_cost.py [--rounds N] [--opensees]``.

Options also: ``--bouc-wen``, ``--write FILE``.

Each variant is the whole command ``python orchestration/run.py SCENARIO [--set ...] --out DIR --no-plots
--quiet`` on Kobe 1995 x 0.5 (150 s at 1 ms, 150 000 steps), in a fresh process and a fresh output folder.
Every round runs every variant once, in turn (the order reversed every other round), and each ratio is
taken within a round, variant against its linear reference measured beside it, so a drift of the shared
machine's speed cancels; the tables quote the median of the rounds' ratios with their min and max.

Variants (A against its reference B):

- ``kobe_yielding.yaml`` (bilinear Steel01 storeys, SOSM: the storeys stay elastic, the exact elastic path)
  against ``kobe.yaml`` (linear storeys, exact ZOH);
- the same two at 0 A (``controller.mode=passive``, ``controller.i_passive=0``): the storeys yield
  (storey 1 to a ductility of 2.4), so the Newmark-Newton path runs;
- ``--opensees``: the OpenSees building unit with ``scenarios/structures/dyke_linear.py`` against
  ``kobe.yaml``, and with a copy of ``dyke_steel01.py`` carrying ``kobe_yielding.yaml``'s yield shears (the
  same model as the bilinear ShearBuilding) at 0 A, against the linear and the bilinear ShearBuilding at 0 A;
- ``--bouc-wen``: ``kobe_yielding.yaml`` with ``hysteresis=bouc-wen`` at 0 A (about 6x: slow).

Figures per run: CPU time of the command (user + system of the child and its children, from rusage), its
wall time, and the stepping loop alone (``wall_time_s`` of summary.json). Prints a markdown report;
``--write FILE`` also writes it there. Needs openseespy for ``--opensees``.
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import statistics
import sys
import tempfile
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from opensees_cost import measure_command

PROJECT = Path(__file__).resolve().parent.parent
RUN_PY = PROJECT / "orchestration" / "run.py"
SCENARIOS = PROJECT / "scenarios"
OPENSEES_FMU = PROJECT / "fmus" / "OpenSeesBuilding.fmu"
STRUCTURES = SCENARIOS / "structures"
PASSIVE_OFF = ["controller.mode=passive", "controller.i_passive=0"]
TARGET = 1.5  # the target: bilinear storeys at most 1.5x the linear building's whole Kobe command
FIGURES = ("cpu", "wall", "loop")


@dataclass
class Variant:
    """One whole command: a scenario and its ``--set`` overrides."""

    label: str
    scenario: str
    overrides: list[str] = field(default_factory=list)

    def argv(self, out: Path) -> list[str]:
        argv = [sys.executable, str(RUN_PY), str(SCENARIOS / self.scenario), "--out", str(out), "--no-plots",
                "--quiet"]
        for item in self.overrides:
            argv += ["--set", item]
        return argv

    def command(self) -> str:
        """The command as the report shows it: project paths relative, the benchmark's own script by name."""
        sets = "".join(f" --set {_shown(item)}" for item in self.overrides)
        return f"python orchestration/run.py scenarios/{self.scenario}{sets} --out DIR --no-plots --quiet"


def _shown(item: str) -> str:
    name, _, value = item.partition("=")
    path = Path(value)
    if path.is_absolute():
        value = str(path.relative_to(PROJECT)) if path.is_relative_to(PROJECT) else f"TMP/{path.name}"
    return f"{name}={value}"


def kobe_yielding_storeys() -> tuple[list[float], list[float]]:
    """(fy_j [N], b_j [1]) of scenarios/kobe_yielding.yaml."""
    params = yaml.safe_load((SCENARIOS / "kobe_yielding.yaml").read_text())["units"]["building"]["parameters"]
    n = sum(1 for name in params if name.startswith("fy_"))
    return [float(params[f"fy_{j}"]) for j in range(1, n + 1)], [float(params[f"b_{j}"]) for j in range(1, n + 1)]


def steel01_script_like_kobe_yielding(folder: Path) -> Path:
    """A copy of dyke_steel01.py with kobe_yielding.yaml's yield shears and hardening ratios."""
    fy, b = kobe_yielding_storeys()
    text = (STRUCTURES / "dyke_steel01.py").read_text()
    for name, values in (("YIELD_SHEARS", fy), ("HARDENING", b)):
        text, count = re.subn(rf"^{name} = .*$", f"{name} = {tuple(values)!r}", text, count=1, flags=re.M)
        if count != 1:
            raise SystemExit(f"dyke_steel01.py has no line '{name} = ...' to replace")
    path = folder / "dyke_steel01_kobe_yielding.py"
    path.write_text(text)
    return path


def variants(opensees: bool, bouc_wen: bool, folder: Path) -> tuple[list[Variant], list[tuple[str, str]]]:
    """The variants, and the (A, B) label pairs whose ratio A/B is reported."""
    lin, bil = Variant("linear, SOSM", "kobe.yaml"), Variant("bilinear, SOSM", "kobe_yielding.yaml")
    lin0 = Variant("linear, 0 A", "kobe.yaml", PASSIVE_OFF)
    bil0 = Variant("bilinear, 0 A", "kobe_yielding.yaml", PASSIVE_OFF)
    chosen = [lin, bil, lin0, bil0]
    pairs = [(bil.label, lin.label), (bil0.label, lin0.label)]
    if opensees:
        fmu = f"units.building.fmu={OPENSEES_FMU}"
        steel01 = steel01_script_like_kobe_yielding(folder)
        linear_script = f"building.script={STRUCTURES / 'dyke_linear.py'}"
        os_lin = Variant("OpenSees linear, SOSM", "kobe.yaml", [fmu, linear_script])
        os_st = Variant("OpenSees Steel01, 0 A", "kobe.yaml", [fmu, f"building.script={steel01}", *PASSIVE_OFF])
        chosen += [os_lin, os_st]
        pairs += [(os_lin.label, lin.label), (os_st.label, lin0.label), (os_st.label, bil0.label)]
    if bouc_wen:
        bw = Variant("Bouc-Wen, 0 A", "kobe_yielding.yaml", ["building.hysteresis=bouc-wen", *PASSIVE_OFF])
        chosen.append(bw)
        pairs.append((bw.label, lin0.label))
    return chosen, pairs


def measure(variant: Variant, out: Path) -> dict[str, float]:
    """One whole command: CPU [s] (user + system of the child), wall [s], stepping loop [s]."""
    return measure_command(variant.argv(out), out)


def load() -> str:
    return " / ".join(f"{v:.2f}" for v in os.getloadavg())


def report(rounds: list[dict[str, dict[str, float]]], chosen: list[Variant], pairs: list[tuple[str, str]],
           argv: list[str], load_start: str, load_end: str) -> str:
    """The markdown report of the rounds."""
    n = len(rounds)
    med = {v.label: {f: statistics.median(r[v.label][f] for r in rounds) for f in FIGURES} for v in chosen}
    lines = [
        "# Structures: what a nonlinear storey step costs",
        "",
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, {platform.platform()}. Load average (1/5/15 min) at the start {load_start}, "
        f"at the end {load_end}; the machine is shared, so absolute times vary with its load, ratios much less: "
        f"each is taken within a round, against the reference measured beside it. Command: "
        f"`python benchmarks/structures_cost.py {' '.join(argv)}`; generated "
        f"{datetime.now(UTC).strftime('%Y-%m-%d %H:%M:%S')} UTC. Kobe 1995 x 0.5, 150 s at 1 ms (150 000 steps).",
        "",
        f"## Ratios (median of {n} rounds, min-max in brackets)",
        "",
        "| A / B | CPU time | wall time | stepping loop | target |",
        "|---|---|---|---|---|",
    ]
    for a, b in pairs:
        cells = []
        for f in FIGURES:
            ratios = [r[a][f] / r[b][f] for r in rounds]
            cells.append(f"**{statistics.median(ratios):.2f}x** ({min(ratios):.2f}-{max(ratios):.2f})"
                         if f == "cpu" else f"{statistics.median(ratios):.2f}x ({min(ratios):.2f}-{max(ratios):.2f})")
        target = ""
        if a.startswith("bilinear") and b.startswith("linear"):
            ratio = statistics.median(r[a]["cpu"] / r[b]["cpu"] for r in rounds)
            target = f"<= {TARGET}x (CPU): {'met' if ratio <= TARGET else 'missed'}"
        lines.append(f"| {a} / {b} | {' | '.join(cells)} | {target} |")
    lines += ["", "## Variants (medians)", "", "| variant | command | CPU [s] | wall [s] | stepping loop [s] |",
              "|---|---|---|---|---|"]
    for v in chosen:
        m = med[v.label]
        lines.append(f"| {v.label} | `{v.command()}` | {m['cpu']:.2f} | {m['wall']:.2f} | {m['loop']:.2f} |")
    if any("TMP/" in v.command() for v in chosen):
        lines += ["", "TMP/dyke_steel01_kobe_yielding.py: a copy of scenarios/structures/dyke_steel01.py with "
                  "kobe_yielding.yaml's fy_j and b_j (the same storeys as the bilinear ShearBuilding), written by "
                  "the benchmark into its temporary folder."]
    lines += ["", "## Rounds", "", "| round | " + " | ".join(f"{v.label}: CPU / wall [s]" for v in chosen) + " |",
              "|---|" + "---|" * len(chosen)]
    for i, r in enumerate(rounds, 1):
        lines.append(f"| {i} | " + " | ".join(f"{r[v.label]['cpu']:.2f} / {r[v.label]['wall']:.2f}" for v in chosen)
                     + " |")
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5, help="rounds; each runs every variant once (default 5)")
    parser.add_argument("--opensees", action="store_true", help="also the OpenSees building unit (needs openseespy)")
    parser.add_argument("--bouc-wen", action="store_true", help="also Bouc-Wen storeys at 0 A (slow)")
    parser.add_argument("--write", type=Path, help="also write the markdown report to this file")
    args = parser.parse_args()
    if args.opensees and not OPENSEES_FMU.is_file():
        raise SystemExit(f"{OPENSEES_FMU} is missing: build it with python -m components.build")
    load_start = load()
    rounds: list[dict[str, dict[str, float]]] = []
    with tempfile.TemporaryDirectory(prefix="structures-cost-") as tmp:
        chosen, pairs = variants(args.opensees, args.bouc_wen, Path(tmp))
        for r in range(args.rounds):
            order = chosen if r % 2 == 0 else chosen[::-1]
            results = {}
            for i, v in enumerate(order):
                results[v.label] = measure(v, Path(tmp) / f"round{r}-{i}")
                print(f"round {r + 1} {v.label}: " + ", ".join(f"{f} {results[v.label][f]:.2f} s" for f in FIGURES),
                      file=sys.stderr, flush=True)
            rounds.append(results)
    text = report(rounds, chosen, pairs, sys.argv[1:], load_start, load())
    print(text)
    if args.write:
        args.write.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
