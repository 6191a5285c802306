"""``mre-cosim``: one console command for the project's command-line tools.

``mre-cosim TOOL ARGS...`` calls the same ``main(argv)`` as the tool's script, with the
same arguments, output and exit codes: ``mre-cosim run scenarios/kobe.yaml`` is
``python orchestration/run.py scenarios/kobe.yaml`` and ``mre-cosim build`` is
``python -m components.build``. Exit codes are the tool's; an unknown tool is exit 2.
Installed by ``pip install -e .`` as a ``[project.scripts]`` entry.
"""

from __future__ import annotations

import difflib
import importlib
import sys
from collections.abc import Sequence

from mre_common.guard import EXIT_OK, EXIT_USAGE, set_invoked_as

PROG = "mre-cosim"

TOOLS: dict[str, tuple[str, str]] = {
    "run": ("orchestration.run", "run one co-simulation scenario and write a run folder (orchestration/run.py)"),
    "study": ("orchestration.study", "run a case study: records x strategies (orchestration/study.py)"),
    "ida": ("orchestration.ida", "incremental dynamic analysis and fragility (orchestration/ida.py)"),
    "identify": ("orchestration.identify", "identify the isolator models from shake-table data "
                                           "(orchestration/identify.py)"),
    "tune": ("orchestration.tune", "tune the SOSM gains, or the strategies of a study's strategy_tuning "
                                   "(orchestration/tune.py)"),
    "compare": ("orchestration.compare", "compare run folders: peaks and overlays of their report roles "
                                         "(orchestration/compare.py)"),
    "verdict": ("orchestration.verdict", "compare an IDA study's strategies: medians with intervals, paired "
                                         "tests (orchestration/verdict.py)"),
    "inspect": ("orchestration.inspect_fmu", "list an FMU's variables and check it against a role "
                                             "(orchestration/inspect_fmu.py)"),
    "ssp": ("orchestration.ssp", "export a scenario to an SSP 1.0 package (orchestration/ssp.py)"),
    "build": ("components.build.project_fmus", "build every FMU of the project into fmus/ "
                                               "(python -m components.build)"),
}
"""Tool name -> (module whose ``main(argv) -> int`` runs it, one-line description)."""


def usage() -> str:
    """The help text: every tool with its description."""
    width = max(len(name) for name in TOOLS)
    lines = [f"usage: {PROG} TOOL [ARGS...]", "",
             "Semi-active seismic isolation by co-simulation: the project's command-line tools.", "", "tools:"]
    lines += [f"  {name:<{width}}  {text}" for name, (_, text) in TOOLS.items()]
    lines += ["", f"'{PROG} TOOL --help' shows a tool's arguments and exit codes (the tool's own);",
              f"'{PROG} --version' the version."]
    return "\n".join(lines)


def tool_main(name: str):
    """The ``main(argv)`` function of tool ``name`` (imported on demand: each tool imports what it needs)."""
    return importlib.import_module(TOOLS[name][0]).main


def main(argv: Sequence[str] | None = None) -> int:
    """``mre-cosim TOOL ARGS...``; returns the tool's exit code (2 for an unknown or missing tool)."""
    args = list(sys.argv[1:] if argv is None else argv)
    if args and args[0] in ("-h", "--help"):
        print(usage())
        return EXIT_OK
    if args and args[0] in ("-V", "--version"):
        from orchestration.provenance import package_version

        print(f"{PROG} {package_version()}")
        return EXIT_OK
    if not args or args[0] not in TOOLS:
        what = f"unknown tool {args[0]!r}" if args else "no tool given"
        close = difflib.get_close_matches(args[0], TOOLS, n=1) if args else []
        if close:
            what += f"; did you mean {close[0]!r}?"
        print(f"{usage()}\n\n{PROG}: error: {what} (choose from {', '.join(TOOLS)})", file=sys.stderr)
        return EXIT_USAGE
    if argv is None:  # the console command: Ctrl-C while the tool's modules import is one line and exit 130
        from orchestration.cli import quiet_interrupts

        quiet_interrupts()
    set_invoked_as(f"{PROG} {args[0]}")  # its usage lines say what the user typed, not the script's name
    try:
        return tool_main(args[0])(args[1:])
    finally:
        set_invoked_as(None)


if __name__ == "__main__":
    raise SystemExit(main())
