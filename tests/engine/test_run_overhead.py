"""What a run pays besides stepping: imports it does not use, figures drawn beside the CSV.

The figures are drawn by forked plot processes (:class:`orchestration.master.report.PlotProcess`)
that read the rows from storage shared with the run; they must write the same PNG bytes as
drawing in the run's own process, and a plot process that fails must cost the figures only.
"""

from __future__ import annotations

import itertools
import json
import os
import signal
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from components.build import pythonfmu_units
from orchestration.engine_hooks import plan_scenario
from orchestration.master import report
from orchestration.master.report import ReportHook, decimate
from orchestration.master.session import run_plan

from ..conftest import PROJECT

KOBE = PROJECT / "scenarios" / "kobe.yaml"
SHORT = ("simulation.stop_time=6",)  # 6001 rows: more than a decimated line's 4000 points


def _run_in_subprocess(code: str) -> dict:
    done = subprocess.run([sys.executable, "-c", code], cwd=PROJECT, capture_output=True, text=True, check=False,
                          env={**os.environ, "PYTHONPATH": str(PROJECT)})
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


FRESH = "MRE_TEST_FRESH_PROCESS"  # set in the interpreter a test runs again in


def forked_here(request, available: bool) -> bool:
    """Whether this test may fork here (``available``: the engine's own check, which needs Linux, two CPUs and one
    thread); if only other tests' threads stand in the way, the test runs again alone in a fresh interpreter, whose
    result is this test's, and this gives False (the caller returns)."""
    if available:
        return True
    if (os.cpu_count() or 1) < 2 or not sys.platform.startswith("linux"):
        pytest.skip("no forked writer on one CPU or off Linux")
    if os.environ.get(FRESH):
        pytest.fail("a fresh interpreter has more than one thread: the forked processes are never used")
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", request.node.nodeid],
                          cwd=PROJECT, capture_output=True, text=True, check=False, env={**os.environ, FRESH: "1"})
    assert done.returncode == 0 and " passed" in done.stdout, done.stdout[-3000:]
    return False


@pytest.fixture
def csv_process_here(request) -> bool:
    """:func:`forked_here` for the CSV process."""
    from orchestration.master.recorder import CsvProcess

    return forked_here(request, CsvProcess.wanted(CsvProcess.MIN_ROWS, ["real"]))


_COMMAND = """
import json, sys
from orchestration import run
code = run.main([{scenario!r}, "--set", "simulation.stop_time=1", "--out", {out!r}, "--quiet", *{extra!r}])
heavy = ("matplotlib", "matplotlib.pyplot", "scipy.signal", "scipy.stats", "scipy.optimize", "PIL")
print(json.dumps({{"code": code, "loaded": [m for m in heavy if m in sys.modules]}}))
"""


@pytest.mark.parametrize("extra", [["--no-plots"], []])
def test_a_run_imports_neither_matplotlib_nor_the_cores_of_units_it_does_not_use(tmp_path, extra):
    """With or without plots the run's own process imports no matplotlib (a forked plot process draws), and the
    FMU staleness check reads the shells' sources instead of importing every unit's core (scipy.signal, ...)."""
    out = tmp_path / "run"
    answer = _run_in_subprocess(_COMMAND.format(scenario=str(KOBE), out=str(out), extra=extra))
    assert answer == {"code": 0, "loaded": []}
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert pngs == ([] if extra else ["current.png", "drifts.png", "isolator_hysteresis.png",
                                      "top_floor_acceleration.png"])


def test_shells_read_from_source_are_the_shells_as_imported():
    """Every shell's class, constants and state methods, read without running it, are what importing it gives."""
    scripts = sorted(pythonfmu_units.SHELLS_DIR.glob("*_fmu.py"))
    assert scripts
    for script in scripts:
        read = pythonfmu_units._read_shell(script)
        assert read is not None, script
        name, constants, methods = pythonfmu_units._shell_by_running(script)
        assert read[0] == name and read[1] == constants, script
        for method in ("_get_fmu_state", "_set_fmu_state"):
            assert (method in read[2]) == (method in methods), (script, method)


def test_a_shell_with_computed_constants_is_imported_instead(tmp_path):
    script = tmp_path / "odd_fmu.py"
    script.write_text("from pythonfmu import Fmi2Slave\nFMU_CORE_MODULES = tuple(['a_core'])\n"
                      "class Odd(Fmi2Slave):\n    pass\n")
    assert pythonfmu_units._read_shell(script) is None
    name, constants, _ = pythonfmu_units._shell_by_running(script)
    assert (name, constants["FMU_CORE_MODULES"]) == ("Odd", ("a_core",))


def _buckets_by_loop(t: np.ndarray, y: np.ndarray, max_points: int) -> tuple[np.ndarray, np.ndarray]:
    """The decimation's definition, one bucket at a time: each bucket's first minimum and first maximum."""
    n = len(t)
    if n <= max_points:
        return t, y
    edges = np.linspace(0, n, max_points // 2 + 1).astype(np.intp)
    keep = [lo + f(y[lo:hi]) for lo, hi in itertools.pairwise(edges) if hi > lo for f in (np.argmin, np.argmax)]
    idx = np.unique(np.asarray(keep, dtype=np.intp))
    return t[idx], y[idx]


@pytest.mark.parametrize("n", [4001, 4003, 9999, 150_001])
def test_decimation_keeps_each_buckets_first_minimum_and_maximum(n):
    rng = np.random.default_rng(n)
    t = np.arange(n) * 1e-3
    for y in (rng.normal(size=n), np.round(rng.normal(size=n)), np.zeros(n)):
        y[rng.integers(0, n, 9)] = np.nan
        y[rng.integers(0, n, 3)] = np.inf
        y[rng.integers(0, n, 3)] = -np.inf
        for max_points in (4000, 11, 2):
            td, yd = decimate(t, y, max_points)
            te, ye = _buckets_by_loop(t, y, max_points)
            assert np.array_equal(td, te) and np.array_equal(yd, ye, equal_nan=True)


@pytest.mark.slow
def test_figures_drawn_by_plot_processes_are_the_bytes_drawn_in_process(tmp_path, monkeypatch):
    plan = plan_scenario(KOBE, SHORT)
    forked = run_plan(plan, tmp_path / "forked")
    monkeypatch.setattr(report.PlotProcess, "available", staticmethod(lambda: False))
    inline = run_plan(plan, tmp_path / "inline")
    assert forked.result.complete and inline.result.complete
    names = sorted(p.name for p in (tmp_path / "inline").glob("*.png"))
    assert len(names) == 4
    assert sorted(p.name for p in (tmp_path / "forked").glob("*.png")) == names
    for name in names:
        assert (tmp_path / "forked" / name).read_bytes() == (tmp_path / "inline" / name).read_bytes(), name
    csv = "timeseries.csv"
    assert (tmp_path / "forked" / csv).read_bytes() == (tmp_path / "inline" / csv).read_bytes()
    assert not [p.name for p in (tmp_path / "forked").iterdir() if p.name.endswith(".tmp.png")]


def _raises(spec, rec, run, figures) -> None:
    raise ZeroDivisionError("a bug in the figures")


_TEST_PROCESS = os.getpid()


def _dies(spec, rec, run, figures) -> None:
    if os.getpid() == _TEST_PROCESS:  # drawn inline after all: never kill the test runner itself
        raise RuntimeError("the figures were drawn in the test process, not in a plot process")
    os.kill(os.getpid(), signal.SIGKILL)


@pytest.mark.parametrize(("draw", "said"), [(_raises, "ZeroDivisionError: a bug in the figures"),
                                            (_dies, "killed by SIGKILL")])
def test_a_plot_process_that_fails_costs_the_figures_only_and_the_run_says_so(request, tmp_path, draw, said):
    if draw is _dies and not forked_here(request, report.PlotProcess.available()):
        return
    plan = plan_scenario(KOBE, SHORT)
    hook = plan.report_hook
    plan = replace(plan, report_hook=ReportHook(hook.model, hook.summarize, draw))
    outcome = run_plan(plan, tmp_path / "run")
    folder = tmp_path / "run"
    assert outcome.result.status == "failed" and not outcome.result.complete
    assert "plots (*.png)" in str(outcome.result.error) and said in str(outcome.result.error)
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["complete"] is False and said in summary["error"]
    assert summary["steps_done"] == 6000 and summary["peak_base_displacement_m"] > 0  # the run itself is whole
    rows = (folder / "timeseries.csv").read_text().splitlines()
    assert len(rows) == 6002 and rows[0].startswith("time,")
    assert json.loads((folder / "manifest.json").read_text())["complete"] is False


def test_a_cancelled_plot_process_exits_and_draws_nothing(request, tmp_path):
    if not forked_here(request, report.PlotProcess.available()):
        return
    calls = tmp_path / "calls"

    def draw(rows: int, share: tuple[int, int]) -> list[Path]:
        calls.write_text("called")
        return []

    plotter = report.PlotProcess.start(draw)
    assert plotter is not None
    pids = [pid for pid, _, _ in plotter._children]
    plotter.cancel()
    assert not calls.exists()
    for pid in pids:  # reaped: no such child any more
        with pytest.raises(ChildProcessError):
            os.waitpid(pid, os.WNOHANG)


# -- timeseries.csv written by a forked process while the units step (recorder.CsvProcess) -----------------------------

def _csv_by_process(monkeypatch, on: bool) -> None:
    """Make a short run use the CSV process (``on``) or write timeseries.csv in the run's own process."""
    from orchestration.master.recorder import CsvProcess

    if on:
        monkeypatch.setattr(CsvProcess, "MIN_ROWS", 0)
    else:
        monkeypatch.setattr(CsvProcess, "wanted", staticmethod(lambda rows, kinds: False))


@pytest.mark.slow
@pytest.mark.parametrize("overrides", [SHORT, (*SHORT, "limits.max_abs={building.x_0: 0.0005}")],
                         ids=["complete", "stopped"])
def test_the_csv_written_while_the_units_step_is_what_is_written_after_the_run(tmp_path, monkeypatch, overrides,
                                                                             csv_process_here):
    """The same bytes as the run's own writer (itself checked against Python's row-by-row '%.12g'), for a whole run
    and for one a limit stops midway (its rows up to the stop), with and without plots."""
    from orchestration.master import recorder

    if not csv_process_here:
        return
    plan = plan_scenario(KOBE, overrides)
    started, start = [], recorder.CsvProcess.start.__func__
    monkeypatch.setattr(recorder.CsvProcess, "start", classmethod(
        lambda cls, *a, **k: started.append(1) or start(cls, *a, **k)))
    outcomes = {}
    for name, on, plots in (("process", True, False), ("process_plots", True, True), ("inline", False, False)):
        with monkeypatch.context() as m:
            _csv_by_process(m, on)
            outcomes[name] = run_plan(plan, tmp_path / name, plots=plots)
    assert len(started) == 2  # the two runs meant to use it did
    statuses = {o.result.status for o in outcomes.values()}
    assert statuses == ({"complete"} if len(overrides) == 1 else {"failed"})
    expected = (tmp_path / "inline" / "timeseries.csv").read_bytes()
    rows = expected.count(b"\n") - 1
    assert rows == outcomes["inline"].recorder.count and (rows == 6001) == (len(overrides) == 1)
    for name in ("process", "process_plots"):
        assert (tmp_path / name / "timeseries.csv").read_bytes() == expected, name
        assert not [p.name for p in (tmp_path / name).iterdir() if p.name.endswith(".tmp")]


def _csv_child_dies(*args, **kwargs) -> int:
    os.kill(os.getpid(), signal.SIGKILL)
    return 0


def test_a_csv_process_that_dies_fails_the_run_naming_the_file_and_keeps_the_rest(tmp_path, monkeypatch,
                                                                                  csv_process_here):
    from orchestration.master import recorder

    if not csv_process_here:
        return
    _csv_by_process(monkeypatch, True)
    monkeypatch.setattr(recorder, "_csv_child", _csv_child_dies)
    outcome = run_plan(plan_scenario(KOBE, SHORT), tmp_path / "run", plots=False)
    assert outcome.result.status == "failed"
    assert "timeseries.csv" in str(outcome.result.error) and "killed by signal 9" in str(outcome.result.error)
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["complete"] is False and summary["steps_done"] == 6000
    assert not (tmp_path / "run" / "timeseries.csv").exists()


def test_a_cancelled_csv_process_leaves_no_file(tmp_path, csv_process_here):
    from orchestration.master.recorder import CsvProcess, RowStorage

    if not csv_process_here:
        return
    storage = RowStorage(100, 2, tmp_path, shared=True)
    writer = CsvProcess.start(tmp_path / "timeseries.csv", ["a.x", "b.y"], storage)
    storage.time[:50] = np.arange(50)
    storage.data[:50] = 1.5
    writer.rows(50)
    pid = writer._pid
    writer.cancel()
    with pytest.raises(ChildProcessError):  # reaped
        os.waitpid(pid, os.WNOHANG)
    assert list(tmp_path.iterdir()) == []


def test_rows_announced_in_uneven_ranges_give_the_file_the_writer_gives(tmp_path, csv_process_here):
    """Rows announced as a run's ticks announce them (uneven ranges, repeats, a final count below the storage's
    rows): the same bytes as :func:`write_timeseries` of those rows, NaN, infinities and -0.0 included."""
    from orchestration.master.recorder import CsvProcess, RowStorage, write_timeseries

    if not csv_process_here:
        return
    rng = np.random.default_rng(25)
    rows, final = 23_000, 21_337
    time = np.arange(rows) * 1e-3
    data = rng.normal(size=(rows, 3)) * 10.0 ** rng.integers(-20, 6, size=(rows, 3))
    data[5, 0], data[6, 1], data[7, 2] = np.nan, -np.inf, -0.0
    storage = RowStorage(rows, 3, tmp_path, shared=True)
    names = ["a.x", "b.y", "c.z"]
    writer = CsvProcess.start(tmp_path / "timeseries.csv", names, storage)
    done = 0
    for count in (1, 1, 999, 5000, 5001, 17_777, final):
        storage.time[done:count] = time[done:count]
        storage.data[done:count] = data[done:count]
        done = count
        writer.rows(count)
    writer.finish(final)
    writer.wait()
    write_timeseries(tmp_path / "expected.csv", time[:final], names, data[:final])
    assert (tmp_path / "timeseries.csv").read_bytes() == (tmp_path / "expected.csv").read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["expected.csv", "timeseries.csv"]


_EXIT = """
import atexit, ctypes, sys
from orchestration.run import exit_without_teardown
atexit.register(lambda: open(sys.argv[1], "w").write("atexit ran"))
sys.stdout.write("python's buffer, ")
ctypes.CDLL(None).printf(b"C's buffer")
exit_without_teardown(7)
"""


@pytest.mark.parametrize("profiled", [False, True])
def test_the_command_ends_without_teardown_but_with_its_exit_code_atexit_and_buffered_output(tmp_path, profiled):
    """``run.py`` ends with :func:`orchestration.run.exit_without_teardown`: its exit code, the ``atexit`` functions
    and what Python and C still buffered (stdout to a pipe is block-buffered in both) are kept; under a profiler it
    exits the usual way (the same)."""
    code = ("import sys; sys.setprofile(lambda *args: None)" if profiled else "") + _EXIT
    done = subprocess.run([sys.executable, "-c", code, str(tmp_path / "mark")], cwd=PROJECT, capture_output=True,
                          env={**os.environ, "PYTHONPATH": str(PROJECT), "PYTHONUNBUFFERED": ""}, check=False)
    assert done.returncode == 7
    if profiled:  # the usual exit flushes both too, in an order of its own
        out = done.stdout
        assert len(out) == len(b"python's buffer, C's buffer") and b"python's buffer, " in out and b"C's buffer" in out
    else:
        assert done.stdout == b"python's buffer, C's buffer"
    assert (tmp_path / "mark").read_text() == "atexit ran"
