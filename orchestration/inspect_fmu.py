"""An FMU's variables, and whether it can play a role of the isolated building.

``python orchestration/inspect_fmu.py FMU [--role controller|isolator|building] [--map OURS=THEIRS ...]``
(``mre-cosim inspect``) prints the FMU's kind, its inputs, outputs and parameters with their
units and start values, then, with ``--role``, each variable the role needs (:mod:`orchestration.roles`)
and the FMU's variable that plays it. ``--map i=u`` says the FMU calls our ``i`` ``u`` (a strategy
entry's ``current: u``; ``--map i_max=imax`` is its ``limit: imax``). No binary is loaded.

Exit codes: 0 the FMU can play the role (or no role asked); 1 it cannot (each reason on stderr);
2 no readable FMU, an unknown role or a bad ``--map``; 3 internal error (a bug; the traceback is in
the log file named); 130 interrupted.
"""

from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from mre_common.guard import quiet_interrupts  # standard library only: installed before any other import

if __name__ == "__main__":
    quiet_interrupts()

import argparse

from orchestration.cli import EPILOG_COMMON, EXIT_OK, UsageError, invoked_as, run_tool

EXIT_CODES = ("exit codes: 0 the FMU can play the role (or no --role); 1 it cannot (each reason on stderr); 2 no "
              "readable FMU, unknown role or bad --map; " + EPILOG_COMMON)
EXIT_MISMATCH = 1


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    from orchestration.roles import ROLES

    parser = argparse.ArgumentParser(prog=invoked_as("inspect_fmu.py"),
                                     description="An FMU's variables, checked against a role of the isolated "
                                                 "building.", epilog=EXIT_CODES)
    parser.add_argument("fmu", type=Path, help="the .fmu file")
    parser.add_argument("--role", choices=sorted(ROLES), help="check it against this role")
    parser.add_argument("--map", dest="names", action="append", default=[], metavar="OURS=THEIRS",
                        help="the FMU's name for one of the role's variables (repeatable), e.g. i=u")
    return parser.parse_args(argv)


def _names(pairs: list[str], role: str | None) -> dict[str, str]:
    """``--map`` pairs as our name -> the FMU's; UsageError for a malformed pair or a name the role lacks."""
    from orchestration.roles import ROLES

    out = {}
    for pair in pairs:
        ours, eq, theirs = pair.partition("=")
        if not eq or not ours.strip() or not theirs.strip():
            raise UsageError(f"--map {pair!r}: give OURS=THEIRS, e.g. i=u")
        if role is None:
            raise UsageError("--map needs --role")
        known = [v.name for v in ROLES[role]]
        if ours.strip() not in known:
            raise UsageError(f"--map {pair!r}: the {role} role has no variable {ours.strip()!r} "
                             f"(its variables: {', '.join(known)})")
        out[ours.strip()] = theirs.strip()
    return out


def _start(v: object) -> str:
    start = getattr(v, "start", None)
    return "" if start in (None, "") else f" = {start}"


def _inspect(argv: list[str] | None) -> int:
    from orchestration.master.fmu_description import FmuFormatError
    from orchestration.roles import ROLES, check_role, describe_variable, read_unit
    from orchestration.tool_files import check_input

    args = parse_args(argv)
    names = _names(args.names, args.role)
    check_input(args.fmu)
    try:
        unit = read_unit(args.fmu, args.fmu.stem)
    except FmuFormatError as exc:
        raise UsageError(str(exc)) from None
    print(f"{args.fmu}: {unit.model_identifier}, FMI {unit.fmi_version}")
    for causality in ("input", "output", "parameter"):
        found = [v for v in unit.variables.values() if v.causality == causality]
        print(f"  {causality}s:{' none' if not found else ''}")
        for v in found:
            print(f"    {describe_variable(v)}{_start(v)}{'  ' + v.description if v.description else ''}")
    if args.role is None:
        return EXIT_OK
    problems, warnings = check_role(unit, args.role, names)
    print(f"as the {args.role}:")
    for rv in ROLES[args.role]:
        name = names.get(rv.name, rv.name)
        have = unit.variables.get(name)
        if have is None and not rv.required:
            print(f"  {rv.name} ({rv.causality}, {rv.unit}): none (optional: {rv.what})")
        else:
            print(f"  {rv.name} ({rv.causality}, {rv.unit}): {describe_variable(have) if have else 'missing'}"
                  f" - {rv.what}")
    for w in warnings:
        print(f"warning: {w}")
    if problems:  # the reasons on stderr, as every tool's failure
        for p in problems:
            print(f"problem: {p}", file=sys.stderr)
        print(f"{args.fmu}: cannot play the {args.role}", file=sys.stderr)
        return EXIT_MISMATCH
    print(f"{args.fmu}: can play the {args.role} ({len(warnings)} warning{'s' if len(warnings) != 1 else ''})")
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    """Print an FMU's variables and check it against a role; returns the exit code."""
    return run_tool(_inspect, argv, "inspect_fmu.py")


if __name__ == "__main__":
    raise SystemExit(main())
