"""Controllers compared with their uncertainty: ``python orchestration/verdict.py IDA_FOLDER --out DIR``.

``mre-cosim verdict``. From an IDA study folder's ``results.csv``, at one intensity level (``--level``, default
the lowest), for the strategies it ran: each criterion's median over the suite's records with a 95 % bootstrap
interval, and every two strategies compared by a paired Wilcoxon signed-rank test over records, Holm-corrected
over the whole family (:mod:`orchestration.ida_study.paired_verdict`). Writes ``summary.csv``, ``pairs.csv``
and ``verdict.md`` into ``--out`` (a new or empty folder) and prints the verdicts.

Exit codes: 0 success; 2 a folder without an IDA results.csv, a level it did not run, an unknown criterion or
strategy, or an output folder that is not empty (nothing written); 3 internal error (a bug; the traceback is in
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

EXIT_CODES = ("exit codes: 0 success; 2 no IDA results.csv, a level or name it lacks, or an output folder that is "
              "not empty (nothing written); " + EPILOG_COMMON)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog=invoked_as("verdict.py"), description="Controllers compared over an IDA "
                                     "study's records: medians with bootstrap intervals, paired tests (Holm).",
                                     epilog=EXIT_CODES)
    parser.add_argument("folder", type=Path, help="an IDA study folder (ida.py's), with results.csv")
    parser.add_argument("--out", type=Path, required=True, help="a new or empty folder for the tables")
    parser.add_argument("--level", type=float, help="the intensity level compared (default: the lowest)")
    parser.add_argument("--criteria", nargs="+", default=["J3", "J4", "J5"], help="criteria (default J3 J4 J5)")
    parser.add_argument("--strategies", nargs="+", help="strategies (default: all but the uncontrolled one, the "
                        "baseline every J is divided by: passive-off in the shipped studies)")
    parser.add_argument("--alpha", type=float, default=0.05, help="family-wise error rate (default 0.05)")
    return parser.parse_args(argv)


def uncontrolled(folder: Path, ran: list[str]) -> str | None:
    """The IDA's uncontrolled strategy, as its ``ida.json`` records it (one written before studies recorded their
    strategies' flags: the shipped entries'); None if the folder says none."""
    import json

    from orchestration.ida_study.ida_records import IdaInfo

    try:
        info = IdaInfo.from_json(json.loads((folder / "ida.json").read_text()))
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        info = None
    if info is not None:
        return info.uncontrolled
    from orchestration.building_studies.strategies import recorded_flags

    marked = [s for s in ran if recorded_flags({}, s).get("uncontrolled")]
    return marked[0] if len(marked) == 1 else None


def _verdict(argv: list[str] | None) -> int:
    import csv
    import math

    from mre_common.atomic_files import atomic_write
    from orchestration.ida_study.paired_verdict import CRITERIA, VerdictError, compare, levels, min_records_for
    from orchestration.ida_study.paired_verdict import read_results as read
    from orchestration.tool_files import check_input, check_output_folder, write_new_folder

    args = parse_args(argv)
    out: Path = args.out
    check_output_folder(out)
    check_input(args.folder, "folder")
    check_input(args.folder / "results.csv")
    if not 0 < args.alpha < 1:
        raise UsageError(f"--alpha {args.alpha}: give a probability between 0 and 1")
    unknown = [c for c in args.criteria if c not in CRITERIA]
    if unknown:
        raise UsageError(f"--criteria: unknown {', '.join(unknown)} (known: {', '.join(CRITERIA)})")
    try:
        rows = read(args.folder / "results.csv")
    except VerdictError as exc:
        raise UsageError(str(exc)) from None
    ran = levels(rows)
    level = ran[0] if args.level is None else args.level
    if not any(math.isclose(level, x, rel_tol=1e-9) for x in ran):
        raise UsageError(f"--level {level:g}: the study ran {', '.join(f'{x:g}' for x in ran)}")
    have = list(dict.fromkeys(r["strategy"] for r in rows))
    off = uncontrolled(args.folder, have)
    strategies = args.strategies or [s for s in have if s != off]
    missing = [s for s in strategies if s not in have]
    if missing:
        raise UsageError(f"--strategies: {', '.join(missing)} not in the study (it ran {', '.join(have)})")
    if len(strategies) < 2:
        raise UsageError("compare at least two strategies")
    summaries, pairs = compare(rows, level, strategies, tuple(args.criteria))
    n_records = len({r["record"] for r in rows})
    need = min_records_for(args.alpha / max(1, len(pairs)))
    lines = [f"# Verdict at {level:g} ({args.folder})", "",
             f"{n_records} records (a record's components averaged, geometrically; the record is the unit of the "
             "bootstrap and of the tests), criteria over "
             f"{off or 'the uncontrolled strategy'} at the same component and level, valid runs only. Paired "
             "Wilcoxon signed-rank tests on "
             f"the records' log ratios, Holm-corrected over {len(pairs)} comparisons (alpha {args.alpha:g}). The "
             f"smallest Holm-corrected p the exact test can give on n records needs n >= {need} for the first "
             "comparison to pass.", "",
             "| strategy | " + " | ".join(f"{c} median (95 % interval)" for c in args.criteria) + " | records |",
             "|---|" + "---|" * (len(args.criteria) + 1)]
    by = {(s.strategy, s.criterion): s for s in summaries}
    for st in strategies:
        cells = [f"{by[st, c].median:.3g} ({by[st, c].low:.3g}-{by[st, c].high:.3g})" for c in args.criteria]
        lines.append(f"| {st} | " + " | ".join(cells) + f" | {min(by[st, c].records for c in args.criteria)} |")
    lines += ["", "| criterion | A | B | records | median J_A/J_B | p | p (Holm) | verdict |",
              "|---|---|---|---|---|---|---|---|"]
    for p in pairs:
        lines.append(f"| {p.criterion} | {p.a} | {p.b} | {p.records} | {p.median_ratio:.3f} | {p.p:.3g} | "
                     f"{p.p_holm:.3g} | {p.verdict(args.alpha)} |")
    def write(folder: Path, written: list[Path]) -> None:
        def table(name: str, head: list[str], body: list[list[object]]) -> None:
            def rows(f) -> None:
                w = csv.writer(f)
                w.writerow(head)
                w.writerows(body)
            atomic_write(folder / name, rows)
            written.append(folder / name)

        table("summary.csv", ["strategy", "criterion", "median", "low", "high", "records"],
              [[s.strategy, s.criterion, s.median, s.low, s.high, s.records] for s in summaries])
        table("pairs.csv", ["criterion", "a", "b", "records", "median_ratio", "p", "p_holm", "verdict"],
              [[p.criterion, p.a, p.b, p.records, p.median_ratio, p.p, p.p_holm, p.verdict(args.alpha)]
               for p in pairs])
        atomic_write(folder / "verdict.md", lambda f: f.write("\n".join(lines) + "\n"))  # last: complete
        written.append(folder / "verdict.md")

    write_new_folder(out, write)
    print("\n".join(lines))
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    """Compare an IDA study's strategies with their uncertainty; returns the exit code."""
    return run_tool(_verdict, argv, "verdict.py")


if __name__ == "__main__":
    raise SystemExit(main())
