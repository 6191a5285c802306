"""Run one co-simulation scenario: ``python orchestration/run.py scenarios/kobe.yaml``.

Writes a new run folder (never overwrites one): ``timeseries.csv``, ``summary.json``,
``manifest.json`` and the figures (PNG; ``--dpi N``, ``--format svg pdf``). Exit codes: 0 success,
1 simulation failure or interruption (partial results written and marked incomplete), 2 scenario error
(nothing written), 3 internal error (a bug; the traceback is in the log file named),
130 interrupted before the run started (nothing written).
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
import json
import signal

from orchestration.cli import EPILOG_COMMON, EXIT_FAILED, EXIT_OK, invoked_as, run_tool
from orchestration.figure_options import add_figure_arguments, figure_files
from orchestration.master.figure_files import RUN_DPI

EPILOG = ("exit codes: 0 success (also for a complete run that is numerically invalid: its last lines say so); 1 "
          "simulation failure or interruption (partial results written, marked "
          "incomplete); 2 scenario error (nothing written); " + EPILOG_COMMON + ". Relative paths are relative "
          "to the current folder.")
UNIT_ERRORS_SHOWN = 5


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog=invoked_as("run.py"), description="Run a co-simulation scenario and write a run folder.", epilog=EPILOG)
    parser.add_argument("scenario", type=Path, help="scenario YAML file or SSP package (.ssp)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a scenario key; UNIT.PARAM=VALUE sets a unit parameter "
                             "(e.g. --set controller.mode=passive)")
    parser.add_argument("--out", type=Path, help="run folder to create (must not exist or be empty)")
    parser.add_argument("--data-dir", dest="data_dirs", action="append", type=Path, default=[],
                        help="folder searched first for !record and !data files (repeatable)")
    parser.add_argument("--no-plots", action="store_true", help="skip the figures")
    add_figure_arguments(parser, default_note=str(RUN_DPI))
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--verify-step", action="store_true",
                        help="run again with the plant's coupling step halved and the controller's period fixed; "
                             "each peak's change goes into summary.json (step_convergence)")
    args = parser.parse_args(argv)
    args.figure_files = figure_files(args)
    return args


def last_distinct(messages: list[str], limit: int = UNIT_ERRORS_SHOWN) -> list[str]:
    """The last ``limit`` distinct messages, in the order they came."""
    distinct = list(dict.fromkeys(reversed(messages)))[:limit]
    return list(reversed(distinct))


def _run(argv: list[str] | None) -> int:
    args = parse_args(argv)
    from orchestration.engine_hooks import plan_scenario
    from orchestration.master.execution import StopRequest
    from orchestration.master.session import run_plan

    # Ctrl-C or SIGTERM while the scenario is checked (and FMUs built): nothing written, exit 130
    plan = plan_scenario(args.scenario, tuple(args.overrides), tuple(args.data_dirs))
    stop = StopRequest()

    def on_signal(signum: int, frame: object) -> None:
        stop.set(f"{signal.Signals(signum).name} received")

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        outcome = run_plan(plan, args.out, not args.no_plots, not args.quiet, stop, args.figure_files)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        cleanup = getattr(plan.loaded, "cleanup", None)  # an SSP package's extracted files
        if cleanup is not None:
            cleanup()
    if args.verify_step and outcome.result.complete:
        from orchestration.step_check import verify_step

        verify_step(args.scenario, tuple(args.overrides), tuple(args.data_dirs), plan, outcome, not args.quiet)
    warnings = sum(outcome.summary.get("unit_warnings", {}).values())
    if outcome.result.complete:
        print(f"run complete: {outcome.folder} ({warnings} unit warning{'s' if warnings != 1 else ''})")
        print(*verdict_lines(outcome.summary), *peak_lines(outcome.summary), *period_lines(outcome.summary), sep="\n")
        note = outcome.summary.get("executor_note")
        if note and outcome.summary.get("executor") != "native":  # e.g. no C compiler: slower, not wrong
            print(f"note: the master's C loop was not used ({note}); the Python executor ran it, with the same "
                  "results, more slowly (docs/performance.md)", file=sys.stderr)
        return EXIT_OK
    print(*verdict_lines(outcome.summary), sep="\n")
    print(f"run {outcome.result.status}: {outcome.result.error}", file=sys.stderr)
    said = str(outcome.result.error)
    errors = [m for m in last_distinct(outcome.unit_errors) if m.split(": ", 1)[-1] not in said]
    if errors and outcome.result.status == "failed":
        print("the units said:", *(f"  {m}" for m in errors), sep="\n", file=sys.stderr)
    print(f"{results_note(outcome.folder)}: {outcome.folder}", file=sys.stderr)
    return EXIT_FAILED


def verdict_lines(summary: dict) -> list[str]:
    """The run's two verdicts, kept apart: numerical validity (``valid``, ``invalid_reasons``) and, where the
    application's report gives one, the physical outcome (a result, not a defect)."""
    lines = []
    if summary.get("valid") is False:
        reasons = summary.get("invalid_reasons") or []
        lines.append("numerically INVALID (its numbers are not to be ranked or trusted): " + "; ".join(reasons))
    elif summary.get("valid"):
        energy = summary.get("energy") or {}
        detail = ""
        if energy.get("checked"):
            parts = [f"residual {100 * abs(energy.get('max_residual_fraction') or 0):.2g} %"]
            if energy.get("max_coupling_error_fraction") is not None:
                parts.append(f"coupling energy error {100 * energy['max_coupling_error_fraction']:.2g} %")
            detail = f" (energy balance: {', '.join(parts)} of the input energy)"
        elif energy:
            detail = f" (energy {energy.get('note', 'not checked')})"
        step = summary.get("step_convergence")
        if step:
            detail += f"; step: largest peak change {100 * step['largest_change']:.2g} % with the plant's step halved"
        lines.append("numerically valid" + detail)
    physical = summary.get("physical") or {}
    if physical:
        parts = []
        if physical.get("peak_base_displacement_m") is not None:
            parts.append(f"peak base displacement {1e3 * physical['peak_base_displacement_m']:.3g} mm, "
                         f"{physical['time_beyond_identified_range_s']:.3g} s beyond the identified "
                         f"±{1e3 * physical['identified_range_m']:g} mm, {physical['time_at_device_limit_s']:.3g} s "
                         f"at the {1e3 * physical['device_limit_m']:g} mm device limit"
                         + (" (its stop)" if physical.get("beyond_range") == "stop" else ""))
        if physical.get("peak_isolator_force_N") is not None:
            parts.append(f"peak isolator force {physical['peak_isolator_force_N'] / 1e3:.4g} kN")
        lines.append("physical outcome: " + "; ".join(parts))
    return lines


def peak_lines(summary: dict) -> list[str]:
    """The run's key peaks from ``summary.json`` (its building's drift and absolute acceleration, the current),
    each with the variable it was reached in; nothing for a system that has none of them."""
    parts = []
    for key, what, unit, scale in (("peak_drift_m", "storey drift", "mm", 1e3),
                                   ("peak_abs_acceleration_m_s2", "absolute acceleration", "m/s²", 1.0)):
        peaks = {k: v for k, v in (summary.get(key) or {}).items() if isinstance(v, (int, float))}
        if peaks:
            name, value = max(peaks.items(), key=lambda item: abs(item[1]))
            g = f" = {abs(value) / 9.81:.3g} g" if unit == "m/s²" else ""
            parts.append(f"{what} {scale * abs(value):.4g} {unit}{g} ({name})")
    if isinstance(summary.get("peak_current_A"), (int, float)):
        mean = summary.get("mean_current_A")
        parts.append(f"current {summary['peak_current_A']:.3g} A"
                     + (f" (mean {mean:.3g} A)" if isinstance(mean, (int, float)) else ""))
    return ["peaks: " + "; ".join(parts)] if parts else []


def period_lines(summary: dict) -> list[str]:
    """The building's periods from ``summary.json``'s ``periods`` section (fixed base, isolated at 0 A and
    i_max), or why they are absent; nothing for a system without the section."""
    periods = summary.get("periods")
    if not isinstance(periods, dict):
        return []
    if "fixed_base_s" not in periods:
        return [f"periods: {periods.get('note', 'not computed')}"]
    fixed = ", ".join(f"{t:.3g}" for t in periods["fixed_base_s"])
    return [f"periods: fixed base {fixed} s; isolated T1 {periods['isolated_0A_s']:.3g} s at 0 A, "
            f"{periods['isolated_i_max_s']:.3g} s at {periods['i_max_A']:g} A (isolators' secant stiffness at "
            f"{1e3 * periods['reference_displacement_m']:g} mm)"]


def results_note(folder: Path) -> str:
    """How an incomplete run's folder is marked: what its summary.json (or manifest.json) says, read back."""
    for name in ("summary.json", "manifest.json"):
        try:
            if json.loads((folder / name).read_text()).get("complete") is False:
                return "partial results (marked incomplete)"
        except (OSError, ValueError, AttributeError):
            continue
    return ("partial results, NOT marked incomplete (neither summary.json nor manifest.json could be written; "
            f"treat the folder as incomplete; it holds {_what_exists(folder)})")


def _what_exists(folder: Path) -> str:
    """The files of a run folder with their sizes, e.g. ``timeseries.csv (361 B), .mre-cosim-run (132 B)``."""
    try:
        found = sorted((p.name, p.stat().st_size) for p in folder.iterdir() if p.is_file())
    except OSError as exc:
        return f"nothing readable ({exc.strerror or exc})"
    return ", ".join(f"{name} ({size} B)" for name, size in found) if found else "no file"


def main(argv: list[str] | None = None) -> int:
    """Run a scenario from the command line; returns the exit code."""
    return run_tool(_run, argv, "run.py")


def exit_without_teardown(code: int) -> None:
    """End the process with ``code`` once the run folder is written, skipping the interpreter's teardown.

    Everything a normal exit does for the outside world is done first: the ``atexit`` functions
    (logging's flush, temporary folders' cleanup), Python's and C's buffered output. What is
    skipped is only the freeing of every module and object and the C libraries' destructors, which take
    far longer than the exit itself after a run (docs/performance.md). Where a flush fails
    (stdout closed, a broken pipe), and under a profiler or a tracer (``python -m cProfile``,
    coverage: they write their data after the script returns), the process exits the usual way.
    """
    import atexit
    import ctypes
    import os

    if sys.getprofile() is not None or sys.gettrace() is not None:
        raise SystemExit(code)
    atexit._run_exitfuncs()
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (AttributeError, OSError, ValueError):
        raise SystemExit(code) from None
    try:
        ctypes.CDLL(None).fflush(None)  # C stdio buffers (an FMU's own printing)
    except (AttributeError, OSError):
        raise SystemExit(code) from None
    os._exit(code)


if __name__ == "__main__":
    exit_without_teardown(main())
