"""Benchmarks (not part of the test suite): ``python benchmarks/run.py [--quick] [--rounds N] [--out FILE]``.

Writes a Markdown report (default ``benchmarks/results.md``), **ratios first**. Every ratio
compares two things measured side by side in this one run (alternating, repeated, medians),
so the machine's load cancels as far as it can:

1. Kobe, co-simulation / in-process cores: the whole command
   ``python orchestration/run.py scenarios/kobe.yaml --out DIR --quiet`` and its stepping
   (native executor), against ``orchestration.inprocess.simulate_coupled`` stepping the
   same physics cores with the same scheme; where the whole command's time goes (phases of
   an instrumented run, and a cProfile summary when a target is missed);
2. native executor / bare FMU calls: the same FMI calls of the step program made from a bare
   C loop (no input estimation, no value transfers, no recording);
3. master overhead / libcosim's (libcosimpy), same FMUs coupled the way libcosim couples;
4. identification per condition / the structured identifier
   (``benchmarks/identification_bench.py``'s ``measure()`` when that file exists, else FFOA
   per condition against the structured identifier here);
5. the whole identification command (``python orchestration/identify.py scenarios/identification.yaml``)
   against its 60 s target; 5b. the studies' batch-layer overhead (``benchmarks/study_overhead.py``: the
   case study and ``scenarios/ida_shipped.yaml``, each default command once): wall time / (sum of the
   jobs' compute times / workers), against 1.15;

then absolute numbers: accuracy against cost and scaling. Absolute times depend on the
machine and its load: the report names both.
"""

from __future__ import annotations

import argparse
import ctypes
import importlib.util
import io
import json
import os
import platform
import pstats
import resource
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from collections.abc import Callable
from ctypes import Structure, c_double, c_int64, c_uint, c_void_p
from pathlib import Path
from typing import Any

import numpy as np

PROJECT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(PROJECT))

from components.build.pythonfmu_units import build, discover  # noqa: E402
from components.physics.ground_motion_core import GroundMotion, read_record  # noqa: E402
from components.physics.monolithic import SystemSetup, simulate_radau  # noqa: E402
from mre_common.c_compile import CompileFailed, CompilerMissing, compile_c  # noqa: E402
from orchestration.engine_hooks import plan_scenario  # noqa: E402
from orchestration.inprocess import simulate_coupled  # noqa: E402
from orchestration.master.session import run_plan  # noqa: E402

SCENARIOS = PROJECT / "scenarios"
RECORDS = PROJECT / "scenarios" / "records"
RUN_PY = PROJECT / "orchestration" / "run.py"
TARGET_WHOLE = 2.0  # target: the whole Kobe command within 2x the in-process stepping of the same cores
TARGET_OWN = 1.25  # target: the whole Kobe command within 1.25x its own stepping (the rest under a quarter)
TARGET_BATCH = 1.15  # target: a study's wall time within 1.15x the sum of its jobs' compute times / workers
TARGET_IDENTIFY_S = 60.0  # target: the whole identification command within 60 s
STUDIES = ("case_study", "ida_shipped")


def table(header: list[str], rows: list[list[object]]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(out)


def load() -> str:
    one, five, fifteen = os.getloadavg()
    return f"{one:.2f} / {five:.2f} / {fifteen:.2f}"


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return (f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, {platform.platform()}, "
            f"numpy {np.__version__}")


def _row_by_row_writer(path: Path, time_: np.ndarray, names: list[str], data: np.ndarray) -> None:
    """The earlier timeseries.csv writer, '%.12g' row by row in Python: the baseline the compiled one replaced."""
    row = ",".join(["%.12g"] * (len(names) + 1)) + "\n"
    with open(path, "w") as f:
        f.write(",".join(["time", *names]) + "\n")
        for start in range(0, len(time_), 20000):
            block = np.column_stack([time_[start: start + 20000], data[start: start + 20000]]).tolist()
            f.write("".join(row % tuple(r) for r in block))


def median(values: list[float]) -> float:
    return statistics.median(values)


def timed_run(scenario: Path, overrides: tuple[str, ...], tmp: Path) -> tuple[float, float, Any]:
    """(execution wall time [s], total wall including writing [s], outcome)."""
    plan = plan_scenario(scenario, overrides)
    t0 = time.perf_counter()
    out = run_plan(plan, out=Path(tempfile.mkdtemp(dir=tmp)) / "run", plots=False)
    total = time.perf_counter() - t0
    if not out.result.complete:
        raise RuntimeError(f"{scenario.name} {overrides}: {out.result.error}")
    return out.result.wall_time, total, out


# -- the whole command -------------------------------------------------------------------------------

def children_cpu() -> float:
    """CPU time (user + system) of the finished child processes so far [s]."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def whole_command(tmp: Path, extra: tuple[str, ...] = (), env: dict[str, str] | None = None) -> tuple[float,
                                                                                                   dict[str, Any]]:
    """Wall time of ``python orchestration/run.py scenarios/kobe.yaml --out DIR --quiet`` and its summary
    (with the process's CPU time under ``"cpu_s"``)."""
    out = Path(tempfile.mkdtemp(dir=tmp)) / "run"
    command = [sys.executable, str(RUN_PY), str(SCENARIOS / "kobe.yaml"), "--out", str(out), "--quiet", *extra]
    cpu = children_cpu()
    t0 = time.perf_counter()
    done = subprocess.run(command, cwd=PROJECT, capture_output=True, text=True, check=False,
                          env={**os.environ, **env} if env else None)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed: {done.stderr[-2000:]}")
    summary = json.loads((out / "summary.json").read_text())
    summary["cpu_s"] = children_cpu() - cpu
    return wall, summary


# Runs orchestration/run.py's main() with timers around its phases (the session's own functions,
# looked up by name so the driver follows whatever the session calls). Prints one JSON line.
PHASES_DRIVER = r"""
import json, sys, time
T0 = time.perf_counter()
root, scenario, out = sys.argv[1:4]
extra = sys.argv[4:]
sys.path.insert(0, root)
timers, marks = {}, {}

def timed(owner, name, label):
    function = getattr(owner, name, None)
    if function is None:
        return
    def wrapper(*args, **kwargs):
        marks.setdefault(label, time.perf_counter() - T0)
        t = time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            timers[label] = timers.get(label, 0.0) + time.perf_counter() - t
    setattr(owner, name, wrapper)

import orchestration.master.native_stepper as native_stepper
import orchestration.master.recorder as recorder
import orchestration.master.report as report
import orchestration.master.resolve as resolve
import orchestration.master.session as session
import orchestration.engine_hooks as project
import orchestration.run as cli
imported = time.perf_counter() - T0
timed(project, "plan_scenario", "plan")
timed(project, "run_plan", "run_plan")
timed(session, "run_plan", "run_plan")
timed(session, "execute", "execute")
timed(native_stepper.NativeStepper, "run", "stepping")
timed(session, "write_timeseries", "csv")
timed(recorder.Recorder, "write_csv", "csv")
timed(recorder.CsvProcess, "start", "csv_fork")
timed(recorder.CsvProcess, "wait", "csv_wait")
timed(resolve.SystemPlan, "create_units", "units")
timed(session, "plot", "plots")
timed(report.PlotProcess, "start", "plot_fork")
timed(report.PlotProcess, "wait", "plots_wait")
timed(session, "report_summary", "summary")
timed(session, "write_json", "json")
code = cli.main([scenario, "--out", out, "--quiet", *extra])
total = time.perf_counter() - T0
print(json.dumps({"code": code, "imported": imported, "total": total, "timers": timers, "marks": marks}))
getattr(cli, "exit_without_teardown", sys.exit)(code)  # the process ends as run.py's does
"""


def phases(tmp: Path, extra: tuple[str, ...] = ()) -> tuple[float, dict[str, Any]]:
    """One instrumented whole command: (wall of the process [s], its phase timers)."""
    driver = tmp / "phases_driver.py"
    driver.write_text(PHASES_DRIVER)
    out = Path(tempfile.mkdtemp(dir=tmp)) / "run"
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, str(driver), str(PROJECT), str(SCENARIOS / "kobe.yaml"), str(out), *extra],
                          cwd=PROJECT, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(f"instrumented run failed: {done.stderr[-2000:]}")
    return wall, json.loads(done.stdout.strip().splitlines()[-1])


def profile_whole_command(tmp: Path, top: int = 22, extra: tuple[str, ...] = ()) -> str:
    """cProfile of the whole command: the entries with the most own time, then the most cumulative time."""
    prof = tmp / "kobe.prof"
    out = Path(tempfile.mkdtemp(dir=tmp)) / "run"
    subprocess.run([sys.executable, "-m", "cProfile", "-o", str(prof), str(RUN_PY), str(SCENARIOS / "kobe.yaml"),
                    "--out", str(out), "--quiet", *extra], cwd=PROJECT, capture_output=True, text=True, check=True)
    text = []
    for key, n in (("tottime", top), ("cumulative", top)):
        buffer = io.StringIO()
        stats = pstats.Stats(str(prof), stream=buffer)
        stats.sort_stats(key).print_stats(n)
        lines = buffer.getvalue().splitlines()
        start = next(k for k, line in enumerate(lines) if line.lstrip().startswith("ncalls"))
        body = [line.replace(str(PROJECT) + "/", "").replace(str(Path(np.__file__).parents[1]) + "/", "")
                for line in lines[start:] if line.strip()]
        text.append(f"sorted by {key} (top {n}):\n" + "\n".join(body))
    return "\n\n".join(text)


def kobe_setup() -> SystemSetup:
    """The Kobe scenario's physics for the in-process stepping (record x0.5, SOSM, default gains, 2 isolators)."""
    return SystemSetup(GroundMotion(read_record(RECORDS / "kobe_1995_jma_ns.csv"), 0.5), passive_current=None)


def bench_kobe(tmp: Path, stop: float, rounds: int, profile: bool) -> tuple[dict[str, Any], str]:
    extra = () if stop == 150.0 else (f"--set=simulation.stop_time={stop:g}",)
    setup = kobe_setup()
    n = round(stop / 1e-3)
    rows, mono, whole, stepping, executors = [], [], [], [], set()
    mono_cpu, whole_cpu = [], []
    whole_command(tmp, extra)  # builds stale FMUs and compiles the kernel outside the measurement
    for r in range(rounds):
        order = ("mono", "whole") if r % 2 == 0 else ("whole", "mono")
        for what in order:
            if what == "mono":
                c0, t0 = time.process_time(), time.perf_counter()
                simulate_coupled(setup, 1e-3, n)
                mono.append(time.perf_counter() - t0)
                mono_cpu.append(time.process_time() - c0)
            else:
                wall, summary = whole_command(tmp, extra)
                whole.append(wall)
                whole_cpu.append(summary["cpu_s"])
                stepping.append(summary["wall_time_s"])
                executors.add(summary["executor"])
        rows.append([r + 1, f"{whole[-1]:.2f}", f"{stepping[-1]:.2f}", f"{mono[-1]:.2f}",
                     f"{whole[-1] / stepping[-1]:.2f}", f"{whole[-1] / mono[-1]:.2f}", f"{stepping[-1] / mono[-1]:.2f}",
                     f"{whole_cpu[-1]:.2f} / {mono_cpu[-1]:.2f}", load()])
    _, py_summary = whole_command(tmp, (*extra, "--set=simulation.executor=python"))
    t0 = time.perf_counter()
    simulate_coupled(setup, 1e-3, n)
    py_mono = time.perf_counter() - t0
    no_plots, _ = whole_command(tmp, (*extra, "--no-plots"))
    t0 = time.perf_counter()
    simulate_coupled(setup, 1e-3, n)
    no_plots_mono = time.perf_counter() - t0
    csv_sides: dict[str, list[float]] = {"process": [], "inline": []}  # timeseries.csv by the CSV process or not
    for r in range(min(rounds, 3)):
        for side in (("process", "inline") if r % 2 == 0 else ("inline", "process")):
            wall, summary = whole_command(tmp, extra, {"MRE_COSIM_CSV_PROCESS": "1" if side == "process" else "0"})
            csv_sides[side].append(wall / summary["wall_time_s"])
    phase_wall, ph = phases(tmp, extra)
    m = {"mono": median(mono), "whole": median(whole), "stepping": median(stepping),
         "python_stepping": py_summary["wall_time_s"], "python_mono": py_mono,
         "no_plots": no_plots, "no_plots_mono": no_plots_mono, "stop": stop, "rounds": rounds,
         "whole_cpu": median(whole_cpu), "mono_cpu": median(mono_cpu)}
    m["ratio_whole"] = m["whole"] / m["mono"]
    m["ratio_own"] = median([w / s for w, s in zip(whole, stepping, strict=True)])  # pairs of the same run
    m["ratio_stepping"] = m["stepping"] / m["mono"]
    m["ratio_python"] = m["python_stepping"] / py_mono
    m["ratio_no_plots"] = no_plots / no_plots_mono
    m["csv_sides"] = {k: median(v) for k, v in csv_sides.items()}
    text = [f"## 1. Kobe: co-simulation / in-process stepping of the same cores ({stop:g} s at 1 ms, "
            f"{n} steps, SOSM, Gauss-Seidel, step-mean)\n",
            f"Whole command: `python orchestration/run.py scenarios/kobe.yaml --out DIR --quiet"
            f"{' ' + ' '.join(extra) if extra else ''}` (a fresh process: start-up, FMU staleness checks, "
            f"FMU loading, stepping, `timeseries.csv`, plots, JSON). Stepping: `wall_time_s` of that run's "
            f"`summary.json` (executor: {', '.join(sorted(executors))}; it includes instantiating and freeing "
            f"the FMUs). In-process: `orchestration.inprocess.simulate_coupled` on the same cores, same "
            f"scheme, in the benchmark's process. Rounds alternate the order.\n",
            table(["round", "whole command [s]", "stepping [s]", "in-process cores [s]", "whole / its stepping",
                   "whole / in-process",
                   "stepping / in-process", "CPU time, whole / in-process [s]", "load after (1/5/15 min)"], rows),
            f"\nMedians: whole command **{m['whole']:.2f} s**, stepping **{m['stepping']:.2f} s**, in-process "
            f"**{m['mono']:.2f} s**: whole / its own stepping **{m['ratio_own']:.2f}×** (median of the rounds' "
            f"ratios; target ≤ {TARGET_OWN:.2f}×), whole / in-process **{m['ratio_whole']:.2f}×** "
            f"(target ≤ {TARGET_WHOLE:.1f}×), "
            f"stepping / in-process **{m['ratio_stepping']:.2f}×**. In CPU time (user + system, all threads; "
            f"less sensitive to the load than wall time): {m['whole_cpu']:.2f} s / {m['mono_cpu']:.2f} s = "
            f"{m['whole_cpu'] / m['mono_cpu']:.2f}×.\n",
            f"Side by side, once each: without plots (`--no-plots`) the whole command took {no_plots:.2f} s "
            f"against {no_plots_mono:.2f} s in-process ({m['ratio_no_plots']:.2f}×); with the Python executor the "
            f"stepping took {m['python_stepping']:.2f} s against {py_mono:.2f} s in-process "
            f"({m['ratio_python']:.2f}×).\n",
            f"`timeseries.csv` written by the CSV process while the units step, or in the run's process after "
            f"them (`MRE_COSIM_CSV_PROCESS=0`), alternately, {len(csv_sides['process'])} rounds each: whole command / "
            f"its own stepping {m['csv_sides']['process']:.2f}× and {m['csv_sides']['inline']:.2f}× (medians).\n"]
    if ph is not None:
        t = ph["timers"]
        execute = t.get("execute", 0.0)
        step = t.get("stepping", 0.0)
        parts = [
            ("interpreter start and exit (outside the driver's clock)", phase_wall - ph["total"]),
            ("imports (run.py, engine, project)", ph["imported"]),
            ("scenario: load, check, FMU staleness checks", t.get("plan", 0.0)),
            ("units created (FMU interfaces chosen, nothing loaded yet)", t.get("units", 0.0)),
            ("FMUs: extract, load, instantiate, initialize, free", execute - step),
            ("stepping (the C loop and the FMUs)", step),
            ("timeseries.csv written in the run's process (only where no CSV process could be forked)",
             t.get("csv", 0.0)),
            ("timeseries.csv: forking the CSV process (it writes the rows while the units step)",
             t.get("csv_fork", 0.0)),
            ("timeseries.csv: waiting for the CSV process's last rows", t.get("csv_wait", 0.0)),
            ("plots: forking the plot processes (before the FMUs load)", t.get("plot_fork", 0.0)),
            ("plots: drawn in-process (only where no plot process could be forked)", t.get("plots", 0.0)),
            ("plots: waiting for the plot processes (they import matplotlib while the FMUs step and draw once the "
             "run ends, while the summary is computed)", t.get("plots_wait", 0.0)),
            ("summary and JSON", t.get("summary", 0.0) + t.get("json", 0.0)),
        ]
        accounted = sum(v for _, v in parts)
        parts.append(("the rest (run folder, manifest hashes, ...)", phase_wall - accounted))
        m["phases"] = {k: v for k, v in parts}
        m["phase_wall"] = phase_wall
        m["plots"] = t.get("plots", 0.0) + t.get("plots_wait", 0.0)
        m["csv"] = t.get("csv", 0.0) + t.get("csv_fork", 0.0) + t.get("csv_wait", 0.0)
        m["outside"] = phase_wall - step - (execute - step)  # what the command adds to its wall_time_s
        text.append(f"Where the whole command's time goes (one instrumented run, {phase_wall:.2f} s, load {load()}):\n")
        text.append(table(["phase", "wall [s]", "share"],
                          [[k, f"{v:.2f}", f"{100 * v / phase_wall:.0f} %"] for k, v in parts]))
    writers = compare_csv_writers(tmp, stop, rounds)
    m["csv_writers"] = writers
    text.append(f"\n`timeseries.csv` of this run ({writers['rows']} rows × {writers['columns']} columns), both writers "
                f"side by side (median of {rounds}): row by row in Python (the writer before the compiled one) "
                f"{writers['row_by_row']:.2f} s, compiled (`recorder.write_timeseries`, the same bytes) "
                f"{writers['compiled']:.2f} s ({writers['row_by_row'] / writers['compiled']:.1f}× faster). "
                f"The whole command uses {writers['session_uses']}.")
    if profile and (m["ratio_whole"] > TARGET_WHOLE or m["ratio_own"] > TARGET_OWN):
        m["profile"] = profile_whole_command(tmp, extra=extra)
    return m, "\n".join(text) + "\n"


def compare_csv_writers(tmp: Path, stop: float, rounds: int) -> dict[str, Any]:
    """The two timeseries.csv writers on the same recorded Kobe run, alternating; checks they write the same bytes."""
    from orchestration.master import recorder as recorder_module
    from orchestration.master import session

    _, _, out = timed_run(SCENARIOS / "kobe.yaml", (f"simulation.stop_time={stop:g}",), tmp)
    rec = out.recorder
    args = (rec.times, rec.names, rec.data[: rec.count])
    times: dict[str, list[float]] = {"row_by_row": [], "compiled": []}
    for r in range(rounds):
        for name in (("row_by_row", "compiled") if r % 2 == 0 else ("compiled", "row_by_row")):
            writer = _row_by_row_writer if name == "row_by_row" else recorder_module.write_timeseries
            t0 = time.perf_counter()
            writer(tmp / f"{name}.csv", *args)
            times[name].append(time.perf_counter() - t0)
    if (tmp / "row_by_row.csv").read_bytes() != (tmp / "compiled.csv").read_bytes():
        raise RuntimeError("the two timeseries.csv writers wrote different bytes")
    uses = getattr(session, "write_timeseries", None)
    where = ("the compiled writer" if uses is recorder_module.write_timeseries else
             "the row-by-row writer" if uses is _row_by_row_writer else "another writer")
    return {"row_by_row": median(times["row_by_row"]), "compiled": median(times["compiled"]), "rows": rec.count,
            "columns": len(rec.names) + 1, "session_uses": where}


# -- bare FMU calls from C ---------------------------------------------------------------------------

BARE_LOOP_C = r"""
#include <stddef.h>
#include <stdint.h>
typedef int (*set_fn)(void *, const unsigned int *, size_t, const double *);
typedef int (*get_fn)(void *, const unsigned int *, size_t, double *);
typedef int (*step_fn)(void *, double, double, int);
typedef struct {
    int64_t kind; void *component; void *function; const unsigned int *vrs; int64_t n;
    double *buf;    /* get: where the values go */
    int64_t offset; /* set: where its values are in a row of the inputs table */
} Call;
/* Every step, the calls in order: kind 0 fmi2SetReal (the values the real run set, from row s of
 * inputs), 1 fmi2DoStep, 2 fmi2GetReal. Returns the worst status. */
int64_t bare_calls(const Call *calls, int64_t n_calls, const double *inputs, int64_t row, double start, double step,
                   double stop, int64_t n_steps) {
    int64_t worst = 0;
    for (int64_t s = 0; s < n_steps; ++s) {
        /* the executor's time grid: t(s) = start + s step, the last step ending exactly at stop */
        double t = start + (double)s * step, t_next = s + 1 == n_steps ? stop : start + (double)(s + 1) * step;
        double h = t_next - t;
        const double *values = inputs + s * row;
        for (int64_t c = 0; c < n_calls; ++c) {
            const Call *k = &calls[c];
            int status;
            if (k->kind == 0) status = ((set_fn)k->function)(k->component, k->vrs, (size_t)k->n, values + k->offset);
            else if (k->kind == 1) status = ((step_fn)k->function)(k->component, t, h, 1);
            else status = ((get_fn)k->function)(k->component, k->vrs, (size_t)k->n, k->buf);
            if (status > worst) worst = status;
        }
    }
    return worst;
}
"""


class _Call(Structure):
    _fields_ = [("kind", c_int64), ("component", c_void_p), ("function", c_void_p), ("vrs", c_void_p),
                ("n", c_int64), ("buf", c_void_p), ("offset", c_int64)]


_BARE: Any = None


def bare_library(tmp: Path) -> Any:
    """The bare call loop, compiled with the system C compiler (None without one)."""
    global _BARE
    if _BARE is None:
        source, target = tmp / "bare_calls.c", tmp / "bare_calls.so"
        source.write_text(BARE_LOOP_C)
        try:
            compile_c(source, target, ("-shared", "-fPIC", "-O2"))
        except (CompilerMissing, CompileFailed):
            return None
        _BARE = ctypes.PyDLL(str(target))  # holds the GIL, as the native executor's kernel does
        _BARE.bare_calls.argtypes = [c_void_p, c_int64, c_void_p, c_int64, c_double, c_double, c_double, c_int64]
        _BARE.bare_calls.restype = c_int64
    return _BARE


Call = tuple[str, str, list[int]]  # (set/step/get, unit name, value references)


def program_calls(algorithm: Any) -> list[Call]:
    """The FMI calls of one step of the algorithm's program, in order."""
    return [(op.kind, op.unit.name, [] if op.kind == "step" else list(op.handle.vrs)[: op.handle.n])
            for op in algorithm.program()]


def inputs_of_a_run(plan: Any, n_steps: int) -> tuple[list[Call], np.ndarray]:
    """(the step program's calls, the values each of its set calls passed at each step) of a real run
    of the plan with the Python executor (the same values the native one passes)."""
    algorithm = plan.create_algorithm(plan.create_units())
    log: list[np.ndarray] = []
    try:
        algorithm.initialize(plan.loaded.scenario.simulation.start_time, plan.loaded.scenario.simulation.stop_time)
        for unit in algorithm.units.values():
            def logged(handle, values, _set=unit.set_real):
                _set(handle, values)
                log.append(np.array(handle.view, dtype=float))
            unit.set_real = logged
        from orchestration.master.execution import time_grid

        sim = plan.loaded.scenario.simulation
        _, t_of = time_grid(sim.start_time, sim.stop_time, sim.step)
        for k in range(n_steps):
            algorithm.step(t_of(k), t_of(k + 1) - t_of(k))
        calls = program_calls(algorithm)
    finally:
        for unit in algorithm.units.values():
            unit.terminate()
    per_step = len(log) // n_steps
    return calls, np.concatenate(log).reshape(n_steps, -1) if per_step else np.zeros((n_steps, 0))


def bare_calls_seconds(tmp: Path, plan: Any, calls: list[Call], inputs: np.ndarray,
                       sets: list[int] | None = None) -> float | None:
    """Wall time of ``calls`` every step, from C, on freshly initialized units of the plan; set call j passes
    the values of set call ``sets[j]`` (default j) of each row of ``inputs`` (as :func:`inputs_of_a_run` logged)."""
    library = bare_library(tmp)
    if library is None:
        return None
    n_steps = len(inputs)
    sim = plan.loaded.scenario.simulation
    algorithm = plan.create_algorithm(plan.create_units())
    try:
        algorithm.initialize(sim.start_time, sim.stop_time)
        natives = {name: u.native_functions() for name, u in algorithm.units.items()}
        offsets, k = [], 0
        for kind, _, refs in program_calls(algorithm):
            if kind == "set":
                offsets.append(k)
                k += len(refs)
        rows = np.ascontiguousarray(inputs, dtype=float)
        table_ = (_Call * len(calls))()
        keep: list[Any] = []
        j = 0
        for slot, (kind, name, refs) in zip(table_, calls, strict=True):
            component, set_real, get_real, do_step = natives[name]
            slot.kind = {"set": 0, "step": 1, "get": 2}[kind]
            slot.component = component
            slot.function = {"set": set_real, "step": do_step, "get": get_real}[kind]
            if kind != "step":
                vrs, buf = (c_uint * max(len(refs), 1))(*refs), (c_double * max(len(refs), 1))()
                keep += [vrs, buf]
                slot.vrs, slot.buf, slot.n = ctypes.addressof(vrs), ctypes.addressof(buf), len(refs)
            if kind == "set":
                slot.offset = offsets[sets[j] if sets is not None else j]
                j += 1
        t0 = time.perf_counter()
        worst = library.bare_calls(ctypes.addressof(table_), len(calls), rows.ctypes.data, rows.shape[1],
                                   sim.start_time, sim.step, sim.stop_time, n_steps)
        wall = time.perf_counter() - t0
    finally:
        for unit in algorithm.units.values():
            unit.terminate()
    if worst > 1:
        raise RuntimeError(f"an FMU call failed in the bare loop (status {worst})")
    return wall


def stepping_seconds(plan: Any, executor: str) -> float:
    """Wall time of the steps alone (as execute() runs them, without instantiating and freeing the units)."""
    from orchestration.master.execution import time_grid
    from orchestration.master.monitor import Monitor
    from orchestration.master.native_stepper import NativeStepper
    from orchestration.master.recorder import Recorder

    sim = plan.loaded.scenario.simulation
    n, t_of = time_grid(sim.start_time, sim.stop_time, sim.step)
    algorithm = plan.create_algorithm(plan.create_units())
    observers = [Recorder(algorithm, plan.recorded, n), Monitor(algorithm, plan.limits)]
    try:
        algorithm.initialize(sim.start_time, sim.stop_time)
        for obs in observers:
            obs.record(0, sim.start_time)
        if executor == "native":
            stepper = NativeStepper(algorithm, observers, sim.start_time, sim.stop_time, sim.step, n)
            t0 = time.perf_counter()
            stepper.run(0, n, t_of)
            wall = time.perf_counter() - t0
            assert stepper.done == n
        else:
            t0 = time.perf_counter()
            for k in range(n):
                t, t_next = t_of(k), t_of(k + 1)
                algorithm.step(t, t_next - t)
                for obs in observers:
                    obs.record(k + 1, t_next)
            wall = time.perf_counter() - t0
    finally:
        for unit in algorithm.units.values():
            unit.terminate()
    return wall


def bench_native_vs_bare(tmp: Path, stop: float, rounds: int) -> tuple[dict[str, Any], str]:
    title = "## 3. Native executor / bare FMU calls"
    plan = plan_scenario(SCENARIOS / "kobe.yaml", (f"simulation.stop_time={stop:g}",))
    n = plan.loaded.scenario.simulation.n_steps
    calls, inputs = inputs_of_a_run(plan, n)
    native, bare = [], []
    for r in range(rounds):
        for what in (("native", "bare") if r % 2 == 0 else ("bare", "native")):
            if what == "native":
                native.append(stepping_seconds(plan, "native"))
                continue
            seconds = bare_calls_seconds(tmp, plan, calls, inputs)
            if seconds is None:
                return {}, f"{title}\n\nnot measured: no C compiler for the bare call loop\n"
            bare.append(seconds)
    m = {"native": median(native), "bare": median(bare), "calls": len(calls), "n": n}
    m["ratio"] = m["native"] / m["bare"]
    rows = [[k + 1, f"{a:.2f}", f"{b:.2f}", f"{a / b:.2f}"] for k, (a, b) in enumerate(zip(native, bare, strict=True))]
    text = (f"{title} (Kobe, first {stop:g} s, {n} steps, Gauss-Seidel, step-mean)\n\n"
            + table(["round", "native executor, steps [s]", "bare FMU calls [s]", "ratio"], rows)
            + f"\n\nMedian ratio **{m['ratio']:.2f}×** ({1e6 * m['native'] / n:.1f} µs against "
              f"{1e6 * m['bare'] / n:.1f} µs per step). Bare: the same {len(calls)} FMI calls per step as the "
              "executor's step program (set, step, get, in the same order, on initialized units of the same "
              "FMUs, each set passing the values the real run passed) from a minimal C loop. Both times are the "
              "steps alone (units instantiated before, freed after). The difference is what the master adds: "
              "input estimates, value copies, recording and the monitor's checks.\n")
    return m, text


# -- libcosim ----------------------------------------------------------------------------------------

def bench_libcosim(tmp: Path, stop: float, rounds: int) -> tuple[dict[str, Any], str]:
    title = "## 4. Master overhead per step / libcosim's"
    try:
        from orchestration.interop.libcosim_export import libcosim_available, libcosim_scheme
        from orchestration.interop.ssp_package import export_ssp
    except ImportError as exc:
        return {}, f"{title}\n\nnot measured: {exc}\n"
    reason = libcosim_available()
    if reason:
        return {}, f"{title}\n\nnot measured: {reason}\n"
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    overrides = (f"simulation.stop_time={stop:g}", "outputs=[building.x_0, building.a_3, isolator.F, controller.i]")
    plan = plan_scenario(SCENARIOS / "kobe.yaml", overrides)
    same = plan_scenario(SCENARIOS / "kobe.yaml", overrides)
    same.loaded = libcosim_scheme(same.loaded)
    n = plan.loaded.scenario.simulation.n_steps
    package = Path(tempfile.mkdtemp(dir=tmp)) / "kobe.ssp"
    export_ssp(plan, package)
    work = Path(tempfile.mkdtemp(dir=tmp))
    with zipfile.ZipFile(package) as z:
        z.extractall(work)
    log_output_level(CosimLogLevel.ERROR)

    ours_plan = same  # our master, coupled as libcosim couples
    program, inputs = inputs_of_a_run(ours_plan, n)
    first_set: dict[str, tuple[int, list[int]]] = {}  # unit -> its first set call (index among the sets, refs)
    k = 0
    for kind, name, refs in program:
        if kind == "set":
            first_set.setdefault(name, (k, refs))
            k += 1
    lc_calls: list[Call] = []
    sets: list[int] = []
    for u in ours_plan.create_units():
        get_refs = [v.vr for v in u.description.outputs() if (u.name, v.name) in plan.recorded
                    or any(link.source == (u.name, v.name) for link in plan.links)]
        if u.name in first_set:
            lc_calls.append(("set", u.name, first_set[u.name][1]))
            sets.append(first_set[u.name][0])
        lc_calls += [("step", u.name, []), ("get", u.name, get_refs)]

    def ours(executor: str) -> float:
        return stepping_seconds(ours_plan, executor)

    def libcosim() -> float:
        cwd = os.getcwd()
        os.chdir(work)
        try:
            execution = CosimExecution.from_ssp_file(str(work / "SystemStructure.ssd"), step_size=1_000_000)
            slaves = {info.name.decode(): info.index for info in execution.slave_infos()}
            refs = {(u, v.name.decode()): v.reference for u, i in slaves.items()
                    for v in execution.slave_variables(i)}
            observer = CosimObserver.create_time_series(buffer_size=n + 16)
            execution.add_observer(observer)
            for port in same.recorded:
                observer.start_time_series(slaves[port[0]], refs[port], CosimVariableType.REAL)
            t0 = time.perf_counter()
            ok = execution.simulate_until(n * 1_000_000)
            wall = time.perf_counter() - t0
        finally:
            os.chdir(cwd)
        if not ok:
            raise RuntimeError("libcosim run failed")
        return wall

    def bare() -> float | None:
        """libcosim's minimum: per unit, set its connected inputs (the values our run held), step, get its
        connected or recorded outputs."""
        return bare_calls_seconds(tmp, ours_plan, lc_calls, inputs, sets)

    walls: dict[str, list[float]] = {"native": [], "python": [], "libcosim": [], "bare": []}
    for r in range(rounds):
        order = ["native", "libcosim", "bare", "python"]
        for what in (order if r % 2 == 0 else order[::-1]):
            value = {"native": lambda: ours("native"), "python": lambda: ours("python"), "libcosim": libcosim,
                     "bare": bare}[what]()
            if value is None:
                return {}, f"{title}\n\nnot measured: no C compiler for the bare call loop\n"
            walls[what].append(value)
    med = {k: median(v) for k, v in walls.items()}
    over = {k: (med[k] - med["bare"]) / n for k in ("native", "python", "libcosim")}
    m = {"over": over, "per_step": {k: v / n for k, v in med.items()}, "n": n,
         "ratio_native": over["native"] / over["libcosim"], "ratio_python": over["python"] / over["libcosim"]}
    rows = [["this master, native executor", f"{1e6 * med['native'] / n:.1f}", f"{1e6 * over['native']:.1f}"],
            ["this master, Python executor", f"{1e6 * med['python'] / n:.1f}", f"{1e6 * over['python']:.1f}"],
            ["libcosim 0.0.6 via libcosimpy", f"{1e6 * med['libcosim'] / n:.1f}", f"{1e6 * over['libcosim']:.1f}"],
            ["bare FMU calls from C (set, step, get per unit)", f"{1e6 * med['bare'] / n:.1f}", "—"]]
    text = (f"{title} (Kobe, first {stop:g} s, {n} steps, 1 ms, Jacobi, every connection delayed, inputs held)\n\n"
            + table(["engine", "wall per step [µs]", "overhead per step [µs]"], rows)
            + f"\n\nOverhead = wall − the bare FMU calls (the calls either engine must make, from a C loop). "
              f"All walls are the stepping alone (units instantiated before, freed after). "
              f"Ratios of overheads (ours / libcosim): native **{m['ratio_native']:.3f}**, Python "
              f"**{m['ratio_python']:.2f}**. Medians of {rounds} rounds; both engines record the same "
              f"{len(same.recorded)} variables every step. The libcosim wall includes its thread-pool hand-offs; "
              "pythonfmu units take the GIL, so they run one at a time in both engines.\n")
    return m, text


# -- identification ----------------------------------------------------------------------------------

def _identification_bench() -> Callable[[], dict] | None:
    """``measure`` of benchmarks/identification_bench.py, if that file exists and loads."""
    path = Path(__file__).resolve().parent / "identification_bench.py"
    if not path.is_file():
        return None
    try:
        spec = importlib.util.spec_from_file_location("identification_bench", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    except Exception as exc:  # a benchmark being written elsewhere must not stop this one
        print(f"benchmarks/identification_bench.py does not load: {exc}", file=sys.stderr)
        return None
    measure = getattr(module, "measure", None)
    return measure if callable(measure) else None


def _render(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _dict_report(data: dict) -> str:
    """A measure() result as tables: its scalars, then each list of records."""
    scalars = [[k, _render(v)] for k, v in data.items() if not isinstance(v, (dict, list))]
    parts = [table(["quantity", "value"], scalars)] if scalars else []
    for key, value in data.items():
        if isinstance(value, dict):
            parts.append(f"**{key}**\n\n" + table(["quantity", "value"], [[k, _render(v)] for k, v in value.items()]))
        elif isinstance(value, list) and value and all(isinstance(r, dict) for r in value):
            columns = list(dict.fromkeys(c for r in value for c in r))
            parts.append(f"**{key}**\n\n" + table(columns, [[_render(r.get(c, "")) for c in columns] for r in value]))
        elif isinstance(value, list):
            parts.append(f"**{key}**: " + ", ".join(_render(v) for v in value))
    return "\n\n".join(parts)


def _ratio_from(data: dict) -> tuple[str, float] | None:
    """The measure() entry for identification per condition / the structured identifier (else its first ratio)."""
    ratios = [(k, float(v)) for k, v in data.items() if "ratio" in k.lower() and isinstance(v, (int, float))]
    preferred = [(k, v) for k, v in ratios if "over_structured" in k.lower() and "ffoa" in k.lower()]
    return (preferred or ratios or [None])[0]


def bench_identification(quick: bool) -> tuple[dict[str, Any], str]:
    title = "## 5. Identification: per condition / the structured identifier"
    measure = _identification_bench()
    if measure is not None:
        try:
            data = measure()
        except Exception as exc:  # report, do not fail the whole benchmark
            data = None
            note = f"benchmarks/identification_bench.py measure() failed: {exc}; falling back to FFOA here.\n\n"
        else:
            found = _ratio_from(data)
            return ({"ratio": found[1] if found else None, "ratio_key": found[0] if found else None,
                     "source": "identification_bench", "data": data},
                    f"{title} (`benchmarks/identification_bench.py`, `measure()`)\n\n" + _dict_report(data) + "\n")
    else:
        note = ("`benchmarks/identification_bench.py` is not there (yet): FFOA per condition (the paper's "
                "identification) against the structured identifier, measured here.\n\n")
    from components.identification.ffoa import FFOASettings
    from components.identification.identifiers import Acceptance, identify_hyperbolic_ffoa, identify_structured
    from orchestration.identification.ident_config import load_config
    from orchestration.identification.ident_pipeline import group, load_records

    path = SCENARIOS / "identification.yaml"
    cfg = load_config(path)
    records = load_records(cfg, path.parent)
    if quick:
        keep = {(1.0, 2.0, 0.0), (2.0, 4.0, 1.0), (4.0, 8.0, 2.0), (4.0, 2.0, 3.0)}
        records = [r for r in records if tuple(map(float, r.condition)) in keep]
    data = group(records, cfg["fit"]["first_cycle"], cfg["fit"]["cycles"])
    f, st = cfg["ffoa"], cfg["structured"]
    settings = FFOASettings(n_pop=f["n_pop"], n_iter=f["n_iter"], step=f["step"])
    acc = Acceptance(**cfg["acceptance"])
    rows, totals, ratios = [], [0.0, 0.0], []
    for k, (cond, d) in enumerate(data.items()):
        ffoa = identify_hyperbolic_ffoa(d, np.random.default_rng([f["seed"], k, 0]), settings, acc)
        fast = identify_structured(d, acc, beta_bounds=(st["beta_min"], st["beta_max"]), n_grid=st["n_grid"])
        totals[0] += ffoa.seconds
        totals[1] += fast.seconds
        ratios.append(ffoa.seconds / fast.seconds)
        rows.append([f"{cond[0]:g} Hz, {cond[1]:g} mm, {cond[2]:g} A", f"{ffoa.seconds:.2f}", f"{fast.seconds:.3f}",
                     f"{ratios[-1]:.2f}", f"{ffoa.rms:.3f}", f"{fast.rms:.3f}",
                     f"{d.noise_rms:.3f}" if d.noise_rms else "—"])
    rows.append(["total", f"{totals[0]:.1f}", f"{totals[1]:.2f}", f"{totals[0] / totals[1]:.2f}", "", "", ""])
    m = {"ratio": median(ratios), "total_ratio": totals[0] / totals[1], "ffoa": totals[0], "structured": totals[1],
         "conditions": len(data), "source": "FFOA here"}
    return m, (f"{title} (FFOA, N_pop {f['n_pop']}, N_iter {f['n_iter']}, vs structured; {len(data)} conditions, "
               f"SYNTHETIC data)\n\n" + note
               + table(["condition", "FFOA [s]", "structured [s]", "FFOA / structured", "FFOA RMS [N]",
                        "structured RMS [N]", "noise RMS [N]"], rows)
               + f"\n\nMedian ratio per condition **{m['ratio']:.2f}×**, in all {m['total_ratio']:.2f}×. "
                 "Synthetic shake-table data (Table 1 parameters + 2 % force noise), as "
                 "`scenarios/identification.yaml` generates them; the paper's measurements are not public. "
                 "Times are the optimisation only.\n")


def identification_wall(tmp: Path) -> dict[str, Any]:
    """Wall time of the whole ``python orchestration/identify.py scenarios/identification.yaml`` (a fresh process)."""
    out = Path(tempfile.mkdtemp(dir=tmp)) / "identification"
    command = [sys.executable, str(PROJECT / "orchestration" / "identify.py"), str(SCENARIOS / "identification.yaml"),
               "--out", str(out), "--quiet"]
    t0 = time.perf_counter()
    done = subprocess.run(command, cwd=PROJECT, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    return {"wall": wall, "code": done.returncode, "error": done.stderr.strip().splitlines()[-1:] if done.returncode
            else [], "load": load()}


# -- studies: the batch layer's overhead ------------------------------------------------------------------------

def _study_overhead_module() -> Any:
    spec = importlib.util.spec_from_file_location("study_overhead", PROJECT / "benchmarks" / "study_overhead.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def bench_studies(tmp: Path) -> tuple[dict[str, Any], str]:
    """Each study's default command once (``benchmarks/study_overhead.py``): wall time / (jobs' compute / workers)."""
    overhead = _study_overhead_module()
    results: dict[str, Any] = {}
    rows = []
    for name in STUDIES:
        try:
            r = overhead.run(name, Path(tempfile.mkdtemp(dir=tmp)), [])
        except SystemExit as exc:  # study_overhead says why a command failed
            results[name] = {"error": str(exc.code)[-500:]}
            rows.append([name, "failed", "", "", "", "", "", str(exc.code).splitlines()[0][:120], load()])
            continue
        r["load"] = load()
        results[name] = r
        rows.append([name, f"{r['command_s']:.1f}", f"{r['study_span_s']:.1f}", f"{r['jobs_compute_s']:.1f}",
                     f"{r['workers']}", f"{r['jobs']} ({r['reused']} reused)", f"**{r['overhead_span']:.3f}**",
                     f"{r['overhead_command']:.3f}", r["load"]])
    text = ("## 5b. Studies: the batch layer's overhead (each default command once)\n\n"
            "overhead = wall time / (sum of the jobs' compute times / workers); the jobs' compute times are their "
            "`wall_time_s` in `jobs/*.json` (each measured where it ran, from its child's fork to its result; jobs "
            "reused from the cache left out). **By span**: the study's own record of its start and end "
            "(`study.json`, `ida.json`), which leaves out the cluster's start and the checks of every scenario "
            "before anything runs; **by command**: the whole command's wall time. Commands: `python "
            "orchestration/study.py scenarios/case_study.yaml --out DIR --quiet` and `python orchestration/ida.py "
            "scenarios/ida_shipped.yaml --out DIR --quiet` (`benchmarks/study_overhead.py` runs and measures them).\n\n"
            + table(["study", "command [s]", "span [s]", "jobs' compute [s]", "workers", "jobs", "overhead, span",
                     "overhead, command", "load after"], rows) + "\n")
    return results, text


# -- absolute: accuracy and scaling --------------------------------------------------------------------

def bench_accuracy(tmp: Path, stop: float) -> str:
    record = RECORDS / "elcentro_1940_ns.csv"
    setup = SystemSetup(GroundMotion(read_record(record), 0.5), passive_current=0.0)
    h_ref = 1e-4
    ref = simulate_radau(setup, stop, np.arange(round(stop / h_ref) + 1) * h_ref)
    rows = []
    for scheme in ("gauss-seidel", "jacobi"):
        for inputs in ("step-mean", "hold"):
            for h in (2e-3, 1e-3, 5e-4, 2e-4, 1e-4):
                wall, _, out = timed_run(SCENARIOS / "elcentro.yaml", (
                    f"simulation.stop_time={stop:g}", f"simulation.step={h:g}", f"simulation.algorithm={scheme}",
                    f"simulation.inputs={inputs}", "controller.mode=passive",
                    "outputs=[building.x_0, building.drift_1, building.drift_2, building.drift_3, building.a_0, "
                    "building.a_1, building.a_2, building.a_3]"), tmp)
                stride = round(h / h_ref)
                err = 0.0
                for name, series in (("building.x_0", ref.x[:, 0]), ("building.a_0", ref.a[:, 0]),
                                     ("building.a_1", ref.a[:, 1]), ("building.a_2", ref.a[:, 2]),
                                     ("building.a_3", ref.a[:, 3]), ("building.drift_1", ref.drift[:, 0]),
                                     ("building.drift_2", ref.drift[:, 1]), ("building.drift_3", ref.drift[:, 2])):
                    peak_ref = np.max(np.abs(series[::stride]))
                    peak = np.max(np.abs(out.recorder.column(name)))
                    err = max(err, abs(peak - peak_ref) / peak_ref)
                rows.append([scheme, inputs, f"{1e3 * h:g}", f"{100 * err:.3f} %", f"{wall:.2f}"])
    ok = [r for r in rows if float(r[3].split()[0]) < 1.0]
    cheapest = min(ok, key=lambda r: float(r[4])) if ok else None
    text = (f"## 6. Accuracy against cost (El Centro ×0.5, passive 0 A, first {stop:g} s; absolute times, "
            f"load {load()})\n\n"
            + table(["algorithm", "inputs", "step [ms]", "max peak error vs Radau", "wall [s]"], rows))
    if cheapest:
        text += (f"\n\nCheapest run within 1 %: {cheapest[0]}, {cheapest[1]}, {cheapest[2]} ms "
                 f"({cheapest[3]}, {cheapest[4]} s).")
    return text + "\n"


def bench_scaling(tmp: Path, quick: bool) -> str:
    rows = []
    storeys = (3, 10, 30) if quick else (3, 10, 30, 100)
    fmu_dir = Path(tempfile.mkdtemp(dir=tmp))
    for n in storeys:
        source = next(s for s in discover((n,)) if s.storeys == n and s.script.name == "shear_building_fmu.py")
        path = build(source, fmu_dir)
        wall, _, out = timed_run(SCENARIOS / "kobe.yaml", ("simulation.stop_time=30", f"units.building.fmu={path}"),
                                 tmp)
        rows.append([f"{n} storeys, 30 s", out.result.n_steps, f"{wall:.2f}", f"{1e6 * wall / out.result.n_steps:.1f}"])
    for stop in ((30.0, 60.0) if quick else (30.0, 60.0, 150.0)):
        wall, _, out = timed_run(SCENARIOS / "kobe.yaml", (f"simulation.stop_time={stop:g}",), tmp)
        rows.append([f"3 storeys, {stop:g} s", out.result.n_steps, f"{wall:.2f}",
                     f"{1e6 * wall / out.result.n_steps:.1f}"])
    return (f"## 7. Scaling (Kobe, SOSM, 1 ms, native executor; every output recorded; absolute times, load {load()})"
            "\n\n" + table(["case", "steps", "wall [s]", "per step [µs]"], rows) + "\n")


# -- the report ----------------------------------------------------------------------------------------

def verdict(value: float, target: float) -> str:
    """``**met**`` or ``**missed**``, by how much (a value at most ``target`` meets it)."""
    if value <= target:
        return f"**met** ({100 * (1 - value / target):.0f} % to spare)"
    return f"**missed** by {100 * (value / target - 1):.0f} %"


def summary_table(kobe: dict, bare: dict, lc: dict, ident: dict, studies: dict | None = None,
                  ident_wall: dict | None = None) -> str:
    rows = []
    if kobe:
        own = kobe["ratio_own"]
        rows.append([f"Kobe ({kobe['stop']:g} s), whole command / its own stepping (`wall_time_s`)",
                     f"**{own:.2f}×** (median of the rounds' ratios; medians {kobe['whole']:.2f} s / "
                     f"{kobe['stepping']:.2f} s)",
                     f"≤ {TARGET_OWN:.2f}×: " + verdict(own, TARGET_OWN) + (
                         "" if own <= TARGET_OWN else
                         f" (about {kobe['whole'] - TARGET_OWN * kobe['stepping']:.2f} s too slow)")])
        verdict_whole = verdict(kobe["ratio_whole"], TARGET_WHOLE) + (
            "" if kobe["ratio_whole"] <= TARGET_WHOLE else
            f" ({kobe['whole'] - TARGET_WHOLE * kobe['mono']:.2f} s too slow)")
        rows.append([f"Kobe ({kobe['stop']:g} s), whole command / in-process stepping of the same cores",
                     f"**{kobe['ratio_whole']:.2f}×** ({kobe['whole']:.2f} s / {kobe['mono']:.2f} s; in CPU time "
                     f"{kobe['whole_cpu'] / kobe['mono_cpu']:.2f}×)", f"≤ {TARGET_WHOLE:.1f}×: {verdict_whole}"])
    for name, r in (studies or {}).items():
        if "error" in r:
            rows.append([f"study `{name}`: batch-layer overhead", "failed (section 5b)",
                         f"≤ {TARGET_BATCH:.2f}: **not measured**"])
            continue
        rows.append([f"study `{name}`: batch-layer overhead = wall / (jobs' compute / workers), by span",
                     f"**{r['overhead_span']:.3f}** ({r['study_span_s']:.1f} s / ({r['jobs_compute_s']:.1f} s / "
                     f"{r['workers']}); whole command {r['overhead_command']:.3f}, {r['command_s']:.1f} s)",
                     f"≤ {TARGET_BATCH:.2f}: " + verdict(r["overhead_span"], TARGET_BATCH)])
    if ident_wall:
        ok = ident_wall["code"] == 0
        rows.append(["identification, whole `python orchestration/identify.py scenarios/identification.yaml`",
                     f"**{ident_wall['wall']:.1f} s**" + ("" if ok else f" (exit {ident_wall['code']})"),
                     f"≤ {TARGET_IDENTIFY_S:.0f} s: " + (verdict(ident_wall["wall"], TARGET_IDENTIFY_S) if ok
                                                         else "**failed**")])
    if kobe:
        rows.append([f"Kobe ({kobe['stop']:g} s), stepping (native executor) / in-process stepping",
                     f"**{kobe['ratio_stepping']:.2f}×** ({kobe['stepping']:.2f} s / {kobe['mono']:.2f} s)", "–"])
        rows.append([f"Kobe ({kobe['stop']:g} s), stepping (Python executor) / in-process stepping",
                     f"{kobe['ratio_python']:.2f}× ({kobe['python_stepping']:.2f} s / {kobe['python_mono']:.2f} s)",
                     "–"])
    if bare:
        rows.append(["native executor / bare FMU calls (same FMI calls from a C loop)",
                     f"**{bare['ratio']:.2f}×** ({1e6 * bare['native'] / bare['n']:.1f} / "
                     f"{1e6 * bare['bare'] / bare['n']:.1f} µs per step)", "–"])
    if lc:
        rows.append(["master overhead per step / libcosim's (native; Python executor)",
                     f"**{lc['ratio_native']:.3f}**; {lc['ratio_python']:.2f} "
                     f"({1e6 * lc['over']['native']:.1f}; {1e6 * lc['over']['python']:.1f} vs "
                     f"{1e6 * lc['over']['libcosim']:.1f} µs)", "≤ 1.0: met" if lc["ratio_native"] <= 1 else "≤ 1.0"])
    if ident:
        ratio = ident.get("ratio")
        label = ("identification per condition / structured identifier"
                 + (f" (`identification_bench.py`: {ident.get('ratio_key')})"
                    if ident.get("source") == "identification_bench" else " (FFOA per condition / structured)"))
        rows.append([label, f"**{ratio:.2f}×**" if isinstance(ratio, float) else "see section 5", "–"])
    return ("## Ratios (each measured side by side in this run)\n\n"
            + table(["ratio", "measured", "target"], rows) + "\n")


def where_the_time_goes(kobe: dict) -> str:
    if not kobe or (kobe["ratio_whole"] <= TARGET_WHOLE and kobe["ratio_own"] <= TARGET_OWN):
        return ""
    missed = [f"{TARGET_WHOLE:.1f}× the in-process stepping: "
              + ("met" if kobe["ratio_whole"] <= TARGET_WHOLE else
                 f"missed by {100 * (kobe['ratio_whole'] / TARGET_WHOLE - 1):.0f} %"),
              f"{TARGET_OWN:.2f}× its own stepping: "
              + ("met" if kobe["ratio_own"] <= TARGET_OWN else
                 f"missed by {100 * (kobe['ratio_own'] / TARGET_OWN - 1):.0f} %")]
    text = [f"## 2. The targets for the whole command: {'; '.join(missed)}\n",
            f"The whole command took {kobe['whole']:.2f} s against {kobe['stepping']:.2f} s of its own stepping and "
            f"{kobe['mono']:.2f} s of in-process stepping. The in-process number is stepping only; the command "
            f"also starts Python, checks and loads the FMUs, writes {round(kobe['stop'] * 1000) + 1} rows of CSV, "
            "draws the plots and writes the JSON files (phases above). The stepping itself is "
            f"{kobe['ratio_stepping']:.2f}× the in-process stepping: each step makes the FMI calls of the step "
            "program, and each call into a pythonfmu unit crosses C++ into Python (building argument lists, "
            "looking the method up, draining the log queue) before the unit's own Python runs.\n"]
    if "profile" in kobe:
        text.append("cProfile of the whole command (one run; the profiler inflates the Python-heavy parts, and "
                    "`native_stepper.run` holds the time spent in C: the kernel, the FMI calls and "
                    "pythonfmu's C++ layer around them; the figures are drawn by forked plot processes, which "
                    "the profile does not see: `PlotProcess.wait` is the time the command waited for them; likewise "
                    "`timeseries.csv` is written by a forked CSV process while the units step, and `CsvProcess.wait` "
                    "is the time the command waited for its last rows):\n")
        text.append("```\n" + kobe["profile"] + "\n```\n")
    return "\n".join(text)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Run the benchmarks and write a Markdown report, ratios first.")
    parser.add_argument("--quick", action="store_true", help="shorter runs (a few minutes)")
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds per ratio (default 3)")
    parser.add_argument("--out", type=Path, default=PROJECT / "benchmarks" / "results.md")
    parser.add_argument("--no-profile", action="store_true", help="skip the cProfile run of the whole command")
    parser.add_argument("--only", nargs="*", help="sections to run (kobe, bare, libcosim, identification, "
                                                  "studies, accuracy, scaling); default all")
    args = parser.parse_args(argv)
    wanted = set(args.only or ("kobe", "bare", "libcosim", "identification", "studies", "accuracy", "scaling"))
    started = load()
    kobe = bare = lc = ident = studies = ident_wall = {}
    sections: list[str] = []
    with tempfile.TemporaryDirectory(prefix="mre_bench_") as tmp:
        tmp = Path(tmp)

        def step(name: str, action: Callable[[], Any]) -> Any:
            print(f"benchmark: {name} ... (load {load()})", file=sys.stderr, flush=True)
            return action()

        if "kobe" in wanted:
            kobe, text = step("Kobe", lambda: bench_kobe(tmp, 30.0 if args.quick else 150.0, args.rounds,
                                                          not args.no_profile))
            sections.append(text)
        if "bare" in wanted:
            bare, text = step("native vs bare", lambda: bench_native_vs_bare(tmp, 10.0 if args.quick else 60.0,
                                                                             args.rounds))
            sections.append(text)
        if "libcosim" in wanted:
            lc, text = step("libcosim", lambda: bench_libcosim(tmp, 5.0 if args.quick else 20.0,
                                                               max(1, min(args.rounds, 2))))
            sections.append(text)
        if "identification" in wanted:
            ident, text = step("identification", lambda: bench_identification(args.quick))
            ident_wall = step("identification, whole command", lambda: identification_wall(tmp))
            text += (f"\nThe whole `python orchestration/identify.py scenarios/identification.yaml --out DIR --quiet` "
                     f"took **{ident_wall['wall']:.1f} s** (exit {ident_wall['code']}; load after "
                     f"{ident_wall['load']}).\n")
            sections.append(text)
        if "studies" in wanted:
            studies, text = step("studies", lambda: bench_studies(tmp))
            sections.append(text)
        if "accuracy" in wanted:
            sections.append(step("accuracy", lambda: bench_accuracy(tmp, 4.0 if args.quick else 10.0)))
        if "scaling" in wanted:
            sections.append(step("scaling", lambda: bench_scaling(tmp, args.quick)))
    header = [
        "# Benchmarks\n",
        f"Machine: {machine()}. Load average (1/5/15 min) at the start {started}, at the end {load()}; the "
        f"machine is shared, so absolute times vary with its load (ratios much less: each is measured side by "
        f"side, alternating, median of {args.rounds} rounds). Command: `python benchmarks/run.py"
        f"{' --quick' if args.quick else ''}{f' --rounds {args.rounds}' if args.rounds != 3 else ''}`; "
        f"generated {time.strftime('%Y-%m-%d %H:%M:%S %Z')}.\n",
        summary_table(kobe, bare, lc, ident, studies, ident_wall),
    ]
    body = [sections[0]] if kobe else []
    body.append(where_the_time_goes(kobe))
    body += sections[1:] if kobe else sections
    text = "\n".join(header + [b for b in body if b])
    args.out.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
