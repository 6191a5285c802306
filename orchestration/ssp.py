"""SSP 1.0 packages from the command line.

``python orchestration/ssp.py export scenarios/kobe.yaml kobe.ssp [--set K=V] [--data-dir D] [--force]``
writes a scenario as a package; ``python orchestration/ssp.py check kobe.ssp`` validates one
and checks it against its FMUs. ``run.py`` runs a package like a scenario file.

Exit codes: 0 success, 2 scenario or package error, an existing destination, or one that
cannot be written (nothing written), 3 internal error (a bug; the traceback is in the log
file named), 130 interrupted (nothing written).
"""

from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from mre_common.guard import quiet_interrupts  # standard library only: installed before any other import

if __name__ == "__main__":
    quiet_interrupts()  # Ctrl-C or SIGTERM while starting: one line, exit 130, no traceback

import argparse

from orchestration.cli import EPILOG_COMMON, EXIT_OK, UsageError, invoked_as, run_tool

EXIT_CODES = ("exit codes: 0 success; 2 scenario or package error, or the destination exists or cannot be written "
              "(nothing written); " + EPILOG_COMMON)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog=invoked_as("ssp.py"),
                                     description="Export a scenario to SSP 1.0, or check a package.",
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


def _export(args: argparse.Namespace) -> None:
    from orchestration.engine_hooks import plan_scenario
    from orchestration.interop.ssp_package import export_ssp

    dest: Path = args.dest
    if dest.is_dir():
        raise UsageError(f"{dest} is a folder; give the .ssp file to write")
    if (dest.exists() or dest.is_symlink()) and not args.force:
        raise UsageError(f"{dest} exists; use --force to replace it")
    if dest.exists() and not dest.is_file():
        raise UsageError(f"{dest} is not a regular file; refusing to replace it")
    plan = plan_scenario(args.scenario, tuple(args.overrides), tuple(args.data_dirs))
    try:
        print(export_ssp(plan, dest))
    except OSError as exc:  # the package is written to a temporary name first: nothing was written
        where = exc.filename or dest
        raise UsageError(f"cannot write {dest} ({where}: {exc.strerror or exc}); nothing was written") from None


def _check(args: argparse.Namespace) -> None:
    from orchestration.building_report import REPORT
    from orchestration.interop.ssp_package import load_ssp
    from orchestration.master.resolve import ResolveHooks, resolve

    loaded = load_ssp(args.package)
    try:
        plan = resolve(loaded, hooks=ResolveHooks(report=REPORT))  # the FMUs as packaged: nothing is built
        sc = loaded.scenario
        print(f"{args.package}: {len(plan.descriptions)} units, {len(plan.links)} connections, "
              f"{sc.simulation.n_steps} steps of {sc.simulation.step} s ({sc.simulation.algorithm})")
    finally:
        loaded.cleanup()


def _ssp(argv: list[str] | None) -> int:
    args = parse_args(argv)
    (_export if args.command == "export" else _check)(args)
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    """Export or check an SSP package from the command line; returns the exit code."""
    return run_tool(_ssp, argv, "ssp.py")


if __name__ == "__main__":
    raise SystemExit(main())
