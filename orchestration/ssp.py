"""SSP 1.0 packages from the command line.

``python orchestration/ssp.py export scenarios/kobe.yaml kobe.ssp [--set K=V] [--data-dir D] [--force]``
writes a scenario as a package; ``python orchestration/ssp.py check kobe.ssp`` validates one
and checks it against its FMUs. ``run.py`` runs a package like a scenario file.

Exit codes: 0 success, 2 scenario or package error, or an existing destination (nothing written).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from orchestration.interop.ssp import export_ssp, load_ssp
from orchestration.master.errors import ScenarioError
from orchestration.master.system import resolve
from orchestration.project import plan_scenario

EXIT_CODES = "exit codes: 0 success; 2 scenario or package error, or the destination exists (nothing written)"


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="ssp.py", description="Export a scenario to SSP 1.0, or check a package.",
                                     epilog=EXIT_CODES)
    sub = parser.add_subparsers(dest="command", required=True)
    exp = sub.add_parser("export", help="write a scenario as an .ssp package", epilog=EXIT_CODES)
    exp.add_argument("scenario", type=Path, help="scenario YAML file")
    exp.add_argument("dest", type=Path, help="the .ssp file to write (must not exist unless --force)")
    exp.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                     help="override a scenario key before exporting (as in run.py)")
    exp.add_argument("--data-dir", dest="data_dirs", action="append", type=Path, default=[],
                     help="folder searched first for data files named with !record (repeatable)")
    exp.add_argument("--force", action="store_true", help="replace an existing .ssp file")
    chk = sub.add_parser("check", help="validate an .ssp package and check it against its FMUs", epilog=EXIT_CODES)
    chk.add_argument("package", type=Path, help="the .ssp file to check")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        if args.command == "export":
            dest: Path = args.dest
            if dest.is_dir():
                print(f"error: {dest} is a folder; give the .ssp file to write", file=sys.stderr)
                return 2
            if dest.exists() and not args.force:
                print(f"error: {dest} exists; use --force to replace it", file=sys.stderr)
                return 2
            plan = plan_scenario(args.scenario, tuple(args.overrides), tuple(args.data_dirs))
            print(export_ssp(plan, dest))
        else:
            loaded = load_ssp(args.package)
            try:
                plan = resolve(loaded)
                sc = loaded.scenario
                print(f"{args.package}: {len(plan.descriptions)} units, {len(plan.links)} connections, "
                      f"{sc.simulation.n_steps} steps of {sc.simulation.step} s ({sc.simulation.algorithm})")
            finally:
                loaded.cleanup()
    except ScenarioError as exc:
        print(exc.report(), file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
