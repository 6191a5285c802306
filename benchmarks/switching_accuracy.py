"""Switching-law accuracy: the co-simulation's peaks against a sampled-data reference, per controller and record.

``python benchmarks/switching_accuracy.py [--records elcentro,kobe] [--strategies sosm,on-off] [--stop S|S,record=S]
[--plant-steps 0.001,0.00025] [--controller-step 0.001] [--out DIR]``

For every record (``scenarios/<record>.yaml``, x0.5) and strategy (``scenarios/strategies.yaml``, i_max = 3 A):

* the reference (:mod:`tests.sampled_reference`): the controller's core sampled every controller step, the
  current computed from a sample acting at once over the controller step (the co-simulation's timing) and
  held, the plant integrated by RK4 between samples and recorded at the finest plant step; run twice (the
  sub-step halved), the larger peak change is its own error;
  two more single runs measure how much the reference's peaks move when the ground acceleration is scaled
  by 1 + 1e-4 (the case's conditioning) and when the current acts one controller step after its sample (what a
  computation delay of one sample alone would do);
* the co-simulation (FMUs, :func:`orchestration.api.run`) at each plant step, the controller at the controller
  step (``units.controller.step`` when they differ; a plant step finer than the controller's is skipped, with
  a note, when the scenario schema has no such key).

Compared peaks: base displacement x_0, top-floor acceleration a_3, first-storey drift drift_1 and the isolator
force F, each on the grid the co-simulation records (the reference on the same grid). Writes
``switching_accuracy.csv`` (every number) and ``switching_accuracy.md`` (the table for docs/master.md) into
``--out`` (default ``/tmp/switching_accuracy``) and prints the table. Runs one case after the other, in
this process: quote the time it prints, measured on a quiet machine.
"""

from __future__ import annotations

import argparse
import csv
import shutil
import sys
import time
from pathlib import Path

PROJECT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(PROJECT))

from tests.support import switching_cases as cases  # noqa: E402

LABELS = {"passive-on": "passive 3 A", "sosm": "SOSM", "on-off": "on-off", "clipped-optimal": "clipped-optimal",
          "lyapunov": "Lyapunov", "frequency": "frequency"}
RECORD_LABELS = {"elcentro": "El Centro", "hachinohe": "Hachinohe", "northridge": "Northridge", "kobe": "Kobe"}
UNITS = {"x_0": (1e3, "mm"), "a_3": (1.0, "m/s²"), "drift_1": (1e3, "mm"), "F": (1e-3, "kN")}


def _floats(text: str) -> list[float]:
    return [float(x) for x in text.split(",") if x]


def _stops(text: str) -> dict[str | None, float]:
    """``6,kobe=13`` -> {None: 6.0, "kobe": 13.0} (None: every other record)."""
    out: dict[str | None, float] = {}
    for part in (p for p in text.split(",") if p):
        name, _, value = part.rpartition("=")
        out[name or None] = float(value)
    return out


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--records", default=",".join(cases.RECORDS))
    p.add_argument("--strategies", default=",".join(cases.STRATEGIES))
    p.add_argument("--stop", type=_stops, default={}, help="cut the records to this many seconds: S for every "
                   "record, record=S for one (e.g. 6,kobe=13; default: whole records)")
    p.add_argument("--plant-steps", type=_floats, default=[1e-3, 2.5e-4], help="co-simulation steps [s]")
    p.add_argument("--controller-step", type=float, default=1e-3, help="the controller's sampling period [s]")
    p.add_argument("--out", type=Path, default=Path("/tmp/switching_accuracy"))
    return p.parse_args(argv)


def _pct(x: float) -> str:
    return "—" if x != x else f"{100 * x:+.2f}"


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    H = args.controller_step
    steps = sorted(args.plant_steps, reverse=True)
    skipped = [h for h in steps if h < H * (1 - 1e-12) and not cases.multirate_supported()]
    steps = [h for h in steps if h not in skipped]
    for h in steps:
        if abs(H / h - round(H / h)) > 1e-9:
            print(f"plant step {h} s does not divide the controller step {H} s", file=sys.stderr)
            return 2
    finest = min(steps)
    every = round(H / finest)
    args.out.mkdir(parents=True, exist_ok=True)
    rows: list[dict[str, object]] = []
    started = time.perf_counter()
    for record in args.records.split(","):
        stop = args.stop.get(record, args.stop.get(None))
        for strategy in args.strategies.split(","):
            refs: dict[int | None, tuple] = {}
            for h in steps:
                latency = None
                if latency not in refs:
                    run, change, ref_seconds = cases.reference(record, strategy, H, every, stop, latency=latency)
                    cond = cases.variant_change(run, record, strategy, H, every, stop, latency, 1.0 + 1e-4)
                    # the same reference with the current acting one controller step after its sample: how much a
                    # one-sample computation delay alone moves the peaks
                    lat = cases.variant_change(run, record, strategy, H, every, stop, every)
                    refs[latency] = run, change, cond, lat
                    print(f"{record} {strategy}: reference {ref_seconds:.1f} s (peak "
                          f"change on halving {change:.1e}, on ag x (1 + 1e-4) {cond:.1e}, on the other latency "
                          f"{lat:.1e}{', stopped: ' + run.stopped if run.stopped else ''})", flush=True)
                run, change, cond, lat = refs[latency]
                expected = run.peaks(stride=round(h / finest))
                folder = args.out / "runs" / f"{record}-{strategy}-{h:g}"
                if folder.exists():  # this script's own earlier run
                    shutil.rmtree(folder)
                co = cases.cosimulate(record, strategy, h, H, stop, folder)
                err = cases.relative_errors(co.peaks, expected)
                row: dict[str, object] = {"record": record, "strategy": strategy, "plant_step_s": h,
                                          "controller_step_s": H, "stop_time_s": co.stop_time,
                                          "reference_change_on_halving": change,
                                          "reference_change_on_ag_1e-4": cond,
                                          "reference_change_on_other_latency": lat, "reference_stopped": run.stopped,
                                          "reference_max_substeps": run.max_substeps, "cosim_status": co.status,
                                          "cosim_valid": co.valid, "cosim_invalid_reasons": " | ".join(co.reasons),
                                          "cosim_seconds": round(co.seconds, 2)}
                for k in cases.PEAKS:
                    row[f"ref_{k}"], row[f"cosim_{k}"], row[f"err_{k}"] = expected[k], co.peaks[k], err[k]
                rows.append(row)
                write_csv(args.out / "switching_accuracy.partial.csv", rows)  # a stopped run keeps its rows
                print(f"  plant {h * 1e3:g} ms: {co.status}, {co.seconds:.1f} s, errors "
                      + ", ".join(f"{k} {_pct(err[k])} %" for k in cases.PEAKS), flush=True)
    total = time.perf_counter() - started
    (args.out / "switching_accuracy.partial.csv").replace(args.out / "switching_accuracy.csv")
    md = markdown(rows, steps, H, args.stop, skipped, total)
    (args.out / "switching_accuracy.md").write_text(md)
    print(md)
    print(f"written: {args.out / 'switching_accuracy.csv'}, {args.out / 'switching_accuracy.md'} ({total:.0f} s)")
    return 0


def write_csv(path: Path, rows: list[dict[str, object]]) -> None:
    """Every row so far (written to a temporary name, then renamed)."""
    partial = path.with_name(path.name + ".tmp")
    with partial.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    partial.replace(path)


def _windows(stop: dict[str | None, float]) -> str:
    if not stop:
        return "whole records"
    parts = [f"{RECORD_LABELS.get(str(r), r)} {v:g} s" for r, v in stop.items() if r is not None]
    if None in stop:
        parts.insert(0, f"first {stop[None]:g} s" + (" (" + ", ".join(parts) + ")" if parts else ""))
        return parts[0]
    return "first " + ", ".join(parts) + ", other records whole"


def markdown(rows: list[dict[str, object]], steps: list[float], H: float, stop: dict[str | None, float],
             skipped: list[float], total: float) -> str:
    """The table: per record and strategy, the reference's peaks and the co-simulation's relative errors."""
    head = " / ".join(f"{h * 1e3:g} ms" for h in steps)
    lines = [f"Controller at {H * 1e3:g} ms; co-simulation plant step {head}; "
             f"{_windows(stop)}; errors in % of the reference "
             f"(co-simulation − reference), plant steps {head}; the reference's current acts at once after its sample, "
             "as the co-simulation's does. "
             "Last columns: the largest change of a compared peak of the reference itself when its sub-step is "
             "halved, when the ground acceleration is scaled by 1 + 1e-4 (the case's conditioning), and when the "
             "current acts one controller step after its sample instead (a one-sample computation delay).", "",
             "| record ×0.5 | strategy | " + " | ".join(f"{k} [{UNITS[k][1]}] ref · error %" for k in cases.PEAKS)
             + " | ref. change: halved sub-step · ag ×(1+1e-4) · one-sample delay | notes |",
             "|---|---|" + "---|" * (len(cases.PEAKS) + 2)]
    by_case: dict[tuple[str, str], list[dict[str, object]]] = {}
    for r in rows:
        by_case.setdefault((str(r["record"]), str(r["strategy"])), []).append(r)
    for (record, strategy), rs in by_case.items():
        rs.sort(key=lambda r: -float(r["plant_step_s"]))  # type: ignore[arg-type]
        cells = []
        for k in cases.PEAKS:
            scale = UNITS[k][0]
            cells.append(f"{float(rs[-1][f'ref_{k}']) * scale:.4g} · "  # type: ignore[arg-type]
                         + " / ".join(_pct(float(r[f"err_{k}"])) for r in rs))  # type: ignore[arg-type]
        notes = []
        if rs[0]["reference_stopped"]:
            notes.append(f"reference: {rs[0]['reference_stopped']}")
        for r in rs:
            if r["cosim_status"] != "complete" or r["cosim_valid"] is False:
                reasons = "; ".join(dict.fromkeys(x.split(":")[0] for x in str(r["cosim_invalid_reasons"]).split(" | ")
                                                  if x))
                notes.append(f"co-sim {float(r['plant_step_s']) * 1e3:g} ms: {r['cosim_status']}"  # type: ignore
                             + (f", invalid ({reasons})" if r["cosim_valid"] is False else ""))
        lines.append(f"| {RECORD_LABELS.get(record, record)} | {LABELS.get(strategy, strategy)} | "
                     + " | ".join(cells) + f" | {float(rs[0]['reference_change_on_halving']):.0e} · "  # type: ignore
                     f"{float(rs[0]['reference_change_on_ag_1e-4']):.1e} · "  # type: ignore
                     f"{_pct(float(rs[0]['reference_change_on_other_latency']))} % | "  # type: ignore
                     + ("; ".join(notes) or "") + " |")
    if skipped:
        lines += ["", "Not measured (no `units.NAME.step` in the scenario schema): plant steps "
                  + ", ".join(f"{h * 1e3:g} ms" for h in skipped) + "."]
    lines += ["", f"(`python benchmarks/switching_accuracy.py`, {total:.0f} s.)"]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
