"""Reliability: failing units, NaN, divergence, interrupts; partial results kept and marked; outputs never lost;
hostile input.

Outputs are never deleted or lost, and write failures are never reported as complete:

* identify.py --overwrite replaces only folders it wrote itself (marker), never the working
  directory, its ancestors, the root or the home folder;
* run.py claims its run folder atomically before simulating: of two runs with the same
  --out exactly one succeeds;
* an unusable --out is a clean exit-2 error before simulating; a write failure after the
  simulation leaves no summary saying complete;
* round-off of order 1e-16 in the generalized fit is not "unphysical".

The property tests at the end take the project's real scenarios, SSP packages and records,
change one thing at a time (a key's value, a deleted key, a byte, an archive entry) and run
the command-line tools on them (``main(argv)`` in this process; a few as subprocesses).
Whatever the change, a tool must end with one of its documented exit codes and no
traceback; exit 2 writes nothing; a run writes only its run folder, and leaves no
temporary files behind.
"""

from __future__ import annotations

import contextlib
import copy
import errno
import functools
import io
import json
import os
import signal
import subprocess
import sys
import tempfile
import textwrap
import threading
import time
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from hypothesis.errors import InvalidArgument

from components.build.pythonfmu_units import FmuSource, build
from components.identification.generalized import GeneralizedFit, physical_problems
from components.physics.mre_isolator_core import TABLE2_PAPER_UNITS
from orchestration import identify, run, ssp, study, tune
from orchestration.engine_hooks import file_kind, plan_scenario
from orchestration.identification.ident_pipeline import MARKER
from orchestration.interop.ssp_package import export_ssp
from orchestration.master import session
from orchestration.master.errors import ScenarioError
from orchestration.master.runfolder import RUN_MARKER, RunFolderExists, RunFolderUnusable, new_run_folder
from orchestration.master.scenario import load_scenario
from orchestration.master.session import run_plan
from orchestration.master.yaml_source import DataFile

from ..conftest import PROJECT
from ..support.tree_mutation import key_paths, mutate

RUN = [sys.executable, str(PROJECT / "orchestration" / "run.py")]
ELCENTRO = PROJECT / "scenarios" / "elcentro.yaml"




@pytest.fixture(scope="module")
def failing_fmu(tmp_path_factory) -> Path:
    source = FmuSource(PROJECT / "tests" / "support" / "units" / "failing_unit_fmu.py", "FailingUnit", ())
    return build(source, tmp_path_factory.mktemp("failing"))


def scenario_with_saboteur(tmp_path: Path, fmu: Path, failure: str, fail_at: float = 0.5) -> Path:
    path = tmp_path / "sabotaged.yaml"
    path.write_text(textwrap.dedent(f"""\
        extends: {PROJECT / "scenarios" / "elcentro.yaml"}
        name: sabotaged
        units:
          saboteur:
            fmu: {fmu}
            parameters: {{fail_at: {fail_at}, failure: {failure}}}
        connections:
          - ground.ag -> building.ag
          - building.x_0 -> isolator.x
          - building.v_0 -> isolator.v
          - controller.i -> isolator.i
          - isolator.F -> building.F
          - {{source: building.x_0, target: controller.x, delayed: true}}
          - {{source: building.v_0, target: controller.v, delayed: true}}
          - {{source: building.arel_0, target: controller.a, delayed: true}}
          - building.x_0 -> saboteur.u
        simulation: {{stop_time: 1.0}}
        """))
    return path


def check_partial(folder: Path, rows_at_most: int) -> dict:
    summary = json.loads((folder / "summary.json").read_text())
    manifest = json.loads((folder / "manifest.json").read_text())
    assert summary["complete"] is False and manifest["complete"] is False
    lines = (folder / "timeseries.csv").read_text().splitlines()
    assert lines[0].startswith("time,") and 1 < len(lines) <= rows_at_most + 1
    assert all(len(line.split(",")) == len(lines[0].split(",")) for line in lines)
    return summary


@pytest.mark.parametrize(("failure", "expected"), [
    ("discard", "fmi2DoStep returned discard"),
    ("nan", "variable 'y'"),
    ("raise", "fmi2DoStep returned fatal"),
])
def test_a_failing_unit_stops_the_run_and_keeps_partial_results(tmp_path, failing_fmu, failure, expected):
    plan = plan_scenario(scenario_with_saboteur(tmp_path, failing_fmu, failure))
    outcome = run_plan(plan, out=tmp_path / "run", plots=False)
    assert outcome.result.status == "failed"
    error = outcome.result.error
    assert error.unit == "saboteur" and error.time == pytest.approx(0.5, abs=1.5e-3)
    assert expected in str(error)
    if failure == "discard":
        assert "deliberate failure at t = 0.5 s" in str(error)
        # the outcome carries what the unit said, as the manifest records it
        assert outcome.unit_errors == ["[saboteur] error: deliberate failure at t = 0.5 s"]
        manifest = json.loads((outcome.folder / "manifest.json").read_text())
        assert outcome.unit_errors[0] in manifest["unit_messages"]
    summary = check_partial(outcome.folder, 502)
    assert summary["error"] and "saboteur" in summary["error"]
    for unit in outcome.units:
        # FMI 2.0: after fmi2Fatal no function may be called, so that instance is abandoned
        if not (failure == "raise" and unit.name == "saboteur"):
            assert unit.freed, unit.name


@pytest.mark.slow
def test_cli_exit_code_and_message_for_a_failing_unit(tmp_path, failing_fmu):
    out = tmp_path / "run"
    proc = subprocess.run([*RUN, str(scenario_with_saboteur(tmp_path, failing_fmu, "discard")), "--out", str(out),
                           "--quiet"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1
    assert "unit 'saboteur'" in proc.stderr and "t = 0.5 s" in proc.stderr and "marked incomplete" in proc.stderr
    assert "Traceback" not in proc.stderr
    check_partial(out, 502)


def test_divergence_limit_stops_the_run(tmp_path):
    plan = plan_scenario(PROJECT / "scenarios" / "elcentro.yaml",
                         ("simulation.stop_time=5", "limits.max_abs={building.x_0: 0.002}"))
    outcome = run_plan(plan, out=tmp_path / "run", plots=False)
    error = outcome.result.error
    assert outcome.result.status == "failed" and error.unit == "building" and error.variable == "x_0"
    assert "exceeds the limit 0.002" in str(error)
    check_partial(outcome.folder, 5001)
    assert all(u.freed for u in outcome.units)


def kobe_run_stepping(out: Path, log: Path) -> subprocess.Popen:
    """``run.py`` on Kobe, returned once it is stepping: its first isolator warning (t = 10.857 s of 150 s) is on
    stderr (a file, polled; at most 120 s under load). Signalled then, the run is mid-way with rows recorded."""
    with open(log, "w") as err:
        proc = subprocess.Popen([*RUN, str(PROJECT / "scenarios" / "kobe.yaml"), "--out", str(out), "--quiet",
                                 "--no-plots"], stdout=subprocess.DEVNULL, stderr=err, text=True)
    deadline = time.monotonic() + 120
    while "[isolator] warning" not in log.read_text() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    assert proc.poll() is None, f"the run ended before it could be interrupted: {log.read_text()}"
    assert "[isolator] warning" in log.read_text(), "the run did not reach t = 10.9 s within 120 s"
    return proc


@pytest.mark.slow
def test_sigint_leaves_a_complete_readable_partial_run(tmp_path):
    out, log = tmp_path / "run", tmp_path / "stderr.txt"
    proc = kobe_run_stepping(out, log)
    proc.send_signal(signal.SIGINT)
    proc.wait(timeout=120)
    stderr = log.read_text()
    assert proc.returncode == 1, stderr
    assert "interrupted (SIGINT received)" in stderr and "Traceback" not in stderr
    summary = check_partial(out, 150_000)
    assert summary["status"] == "interrupted" and summary["steps_done"] < 150_000


@pytest.mark.slow
def test_sigterm_does_the_same(tmp_path):
    out, log = tmp_path / "run", tmp_path / "stderr.txt"
    proc = kobe_run_stepping(out, log)
    proc.send_signal(signal.SIGTERM)
    proc.wait(timeout=120)
    assert proc.returncode == 1, log.read_text()
    assert check_partial(out, 150_000)["status"] == "interrupted"


def test_unreadable_record_is_a_scenario_error_before_any_unit_loads(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("0,0\n0.02,abc\n")
    with pytest.raises(ScenarioError) as err:
        plan_scenario(PROJECT / "scenarios" / "elcentro.yaml", (f"ground.record=!record {bad}",))
    assert f"units.ground.parameters.record: unreadable record: {bad}:2: not a number" in str(err.value)


def _zip(path: Path, files: dict[str, str]) -> Path:
    with zipfile.ZipFile(path, "w") as z:
        for name, text in files.items():
            z.writestr(name, text)
    return path


FMI1 = '<?xml version="1.0"?><fmiModelDescription fmiVersion="1.0" modelName="m" modelIdentifier="m" ' \
       'guid="{1}" numberOfContinuousStates="0" numberOfEventIndicators="0"><ModelVariables/></fmiModelDescription>'
ME_ONLY = '<?xml version="1.0"?><fmiModelDescription fmiVersion="2.0" modelName="m" guid="{1}">' \
          '<ModelExchange modelIdentifier="m"/><ModelVariables/><ModelStructure/></fmiModelDescription>'


@pytest.mark.parametrize(("files", "message"), [
    (None, "not an FMU (not a zip archive)"),
    ({"other.txt": "x"}, "the zip has no modelDescription.xml"),
    ({"modelDescription.xml": FMI1}, "FMI 1.0"),
    ({"modelDescription.xml": ME_ONLY}, "invalid modelDescription.xml"),  # model exchange is accepted; no variables
])
def test_malformed_fmus_are_clear_scenario_errors(tmp_path, files, message):
    fmu = tmp_path / "bad.fmu"
    if files is None:
        fmu.write_text("plain text")
    else:
        _zip(fmu, files)
    with pytest.raises(ScenarioError) as err:
        plan_scenario(PROJECT / "scenarios" / "elcentro.yaml", (f"units.isolator.fmu={fmu}",))
    text = str(err.value)
    assert "units.isolator.fmu" in text and message in text



# -- identify.py --overwrite -------------------------------------------------------------------------


@pytest.fixture
def id_config(tmp_path: Path) -> Path:
    """A fast identification: two conditions, one repeat, the structured identifier, no figures."""
    cfg = tmp_path / "cfg" / "id.yaml"
    cfg.parent.mkdir()
    cfg.write_text(yaml.safe_dump({
        "data": {"conditions": [[4, 2, 0], [4, 2, 3]], "synthetic": {"repeats": 1}},
        "identifiers": ["hyperbolic-structured"],
        "bouc_wen_joint": {"enabled": False},
        "figures": False,
    }))
    return cfg


def _identify(cfg: Path, out: str | Path, *extra: str) -> int:
    return identify.main([str(cfg), "--out", str(out), "--no-progress", *extra])


def test_overwrite_refuses_a_folder_the_tool_did_not_write(tmp_path, id_config, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("years of work")
    assert _identify(id_config, out, "--overwrite") == 2
    err = capsys.readouterr().err
    assert "refusing" in err and MARKER in err and len(err.strip().splitlines()) == 1
    assert (out / "thesis.tex").read_text() == "years of work"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cfg", "mine"]  # no staging folder left


@pytest.mark.parametrize("target", [".", ".."])
def test_overwrite_refuses_the_working_directory_and_its_ancestors(tmp_path, id_config, monkeypatch, capsys, target):
    work = tmp_path / "work"
    work.mkdir()
    (work / "keep.txt").write_text("keep")
    (work / MARKER).write_text("{}")  # even a marked working directory is never replaced
    monkeypatch.chdir(work)
    assert _identify(id_config, target, "--overwrite") == 2
    err = capsys.readouterr().err
    assert "refusing" in err and "Traceback" not in err
    assert (work / "keep.txt").read_text() == "keep"
    assert sorted(p.name for p in work.iterdir()) == [MARKER, "keep.txt"]


def test_root_and_home_are_protected(tmp_path, monkeypatch):
    """Checked on the predicate only: a regression must not be able to reach rmtree('/')."""
    from orchestration.identification.ident_pipeline import _protected

    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.chdir(tmp_path)
    assert "root" in _protected(Path("/"))
    assert _protected(tmp_path.resolve()) and _protected(tmp_path.parent.resolve())
    assert _protected((tmp_path / "sub").resolve()) is None


def test_overwrite_refuses_the_home_folder(tmp_path, id_config, monkeypatch, capsys):
    home = tmp_path / "home"
    home.mkdir()
    (home / "keep.txt").write_text("keep")
    (home / MARKER).write_text("{}")
    monkeypatch.setenv("HOME", str(home))
    assert _identify(id_config, home, "--overwrite") == 2
    assert "home folder" in capsys.readouterr().err
    assert (home / "keep.txt").is_file()


def test_overwrite_replaces_a_previous_marked_output(tmp_path, id_config, capsys):
    out = tmp_path / "ident"
    assert _identify(id_config, out) in (0, 1)
    marker = json.loads((out / MARKER).read_text())
    assert marker["tool"] == "mre-cosim identify" and "time" in marker
    assert (out / "table2.csv").is_file()
    (out / "stale.txt").write_text("from the previous run")
    assert _identify(id_config, out) == 2  # without --overwrite: refused, untouched
    assert (out / "stale.txt").is_file()
    assert _identify(id_config, out, "--overwrite") in (0, 1)
    assert not (out / "stale.txt").exists() and (out / "table2.csv").is_file() and (out / MARKER).is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cfg", "ident"]  # no staging or old folder left
    capsys.readouterr()


# -- concurrent runs, same --out ---------------------------------------------------------------------


def test_two_threads_claiming_the_same_folder_exactly_one_wins(tmp_path):
    out = tmp_path / "run"
    barrier = threading.Barrier(8)
    won, lost = [], []

    def claim():
        barrier.wait()
        try:
            won.append(new_run_folder(tmp_path, "x", out))
        except RunFolderExists:
            lost.append(1)

    threads = [threading.Thread(target=claim) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(won) == 1 and len(lost) == 7
    assert [p.name for p in out.iterdir()] == [RUN_MARKER]


@pytest.mark.slow
@pytest.mark.parametrize("existing", [False, True], ids=["missing", "empty"])
def test_two_cli_runs_with_the_same_out_one_succeeds_one_consistent_run(tmp_path, existing):
    out = tmp_path / "same"
    if existing:
        out.mkdir()
    args = [*RUN, str(ELCENTRO), "--set", "simulation.stop_time=1", "--out", str(out), "--no-plots", "--quiet"]
    procs = [subprocess.Popen(args, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(2)]
    results = [(p.wait(timeout=300), *p.communicate()) for p in procs]
    codes = sorted(r[0] for r in results)
    assert codes == [0, 2], results
    loser = next(r for r in results if r[0] == 2)
    assert "not empty" in loser[2] and "Traceback" not in loser[2]
    summary = json.loads((out / "summary.json").read_text())
    manifest = json.loads((out / "manifest.json").read_text())
    claim = json.loads((out / RUN_MARKER).read_text())
    assert summary["complete"] and manifest["complete"]
    assert summary["run_id"] == manifest["run_id"] == claim["run_id"]
    assert sorted(p.name for p in out.iterdir()) == [RUN_MARKER, "manifest.json", "summary.json", "timeseries.csv"]
    with open(out / "timeseries.csv") as f:
        rows = sum(1 for _ in f)
    assert rows == summary["steps_done"] + 2  # header + samples at t = 0 .. stop: one run's data


# -- unusable --out, write failures ------------------------------------------------------------------


def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([*RUN, *args], cwd=cwd, capture_output=True, text=True, timeout=300)


@pytest.mark.slow
@pytest.mark.parametrize("out", ["file.txt/sub", "/proc/mre-cosim-test/run"])
def test_unusable_out_is_a_clean_exit_2_naming_the_path(tmp_path, out):
    (tmp_path / "file.txt").write_text("not a folder")
    proc = _cli(str(ELCENTRO), "--set", "simulation.stop_time=0.01", "--out", out, "--quiet", cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and out in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    assert (tmp_path / "file.txt").read_text() == "not a folder"


def test_unusable_out_is_reported_before_simulating(tmp_path, monkeypatch):
    from orchestration.engine_hooks import run_scenario

    (tmp_path / "file.txt").write_text("x")

    def no_simulation(*args, **kwargs):
        raise AssertionError("simulated although the run folder is unusable")

    monkeypatch.setattr(session, "execute", no_simulation)
    with pytest.raises(RunFolderUnusable, match="is a file, not a folder"):
        run_scenario(ELCENTRO, ("simulation.stop_time=0.01",), out=tmp_path / "file.txt" / "sub", plots=False)
    with pytest.raises(RunFolderExists, match="not empty"):
        run_scenario(ELCENTRO, ("simulation.stop_time=0.01",), out=tmp_path, plots=False)


def _disk_full(*args, **kwargs):
    raise OSError(errno.ENOSPC, "No space left on device")


def test_timeseries_write_failure_is_not_complete_and_exits_1(tmp_path, monkeypatch, capsys):
    from orchestration import run

    monkeypatch.setattr(session, "write_results", _disk_full)
    out = tmp_path / "run"
    code = run.main([str(ELCENTRO), "--set", "simulation.stop_time=0.05", "--out", str(out), "--no-plots", "--quiet"])
    err = capsys.readouterr().err
    assert code == 1
    assert "timeseries.csv" in err and "No space left on device" in err
    summary = json.loads((out / "summary.json").read_text())
    manifest = json.loads((out / "manifest.json").read_text())
    assert summary["complete"] is False and manifest["complete"] is False and summary["status"] == "failed"
    assert "timeseries.csv" in summary["error"]
    assert not (out / "timeseries.csv").exists()


def test_summary_write_failure_leaves_no_complete_summary(tmp_path, monkeypatch):
    from orchestration.engine_hooks import run_scenario

    def fail_summary(path, data):  # summary.json is written by its record's serialiser (summary.write_summary)
        assert Path(path).name == "summary.json"
        _disk_full()

    monkeypatch.setattr(session, "write_summary", fail_summary)
    outcome = run_scenario(ELCENTRO, ("simulation.stop_time=0.05",), out=tmp_path / "run", plots=False)
    assert not outcome.result.complete and "summary.json" in str(outcome.result.error)
    assert not (tmp_path / "run" / "summary.json").exists()
    assert json.loads((tmp_path / "run" / "manifest.json").read_text())["complete"] is False


# -- round-off in the generalized fit ----------------------------------------------------------------


def test_roundoff_below_zero_is_accepted_as_zero():
    """k0(0 A) = -3.966e-16 is what np.polyfit returned on an AMD EPYC for a line through 0."""
    coeffs = {**TABLE2_PAPER_UNITS, "k0_0": 12.5, "k0_1": -3.966e-16}
    means = {0.0: {"k0": 0.0}, 3.0: {"k0": 37.5}}
    assert physical_problems(GeneralizedFit("hyperbolic", means, {0.0: 1, 3.0: 1}, coeffs), 3.0) == []


def test_clearly_negative_parameter_is_refused():
    coeffs = {**TABLE2_PAPER_UNITS, "k0_0": 12.5, "k0_1": -0.05}
    problems = physical_problems(GeneralizedFit("hyperbolic", {}, {}, coeffs), 3.0)
    assert problems == ["k0(0 A) = -0.05 < 0"]
    tiny_but_real = {**TABLE2_PAPER_UNITS, "k0_0": 12.5, "k0_1": -1e-6}  # 1e-6 / 37.5 >> round-off
    assert physical_problems(GeneralizedFit("hyperbolic", {}, {}, tiny_but_real), 3.0) == ["k0(0 A) = -1e-06 < 0"]


# -- run folder names and paths ----------------------------------------------------------------------


@pytest.mark.parametrize("name", ["../escape", "a/b", ".hidden", "", "a\\b"])
def test_a_run_name_cannot_leave_the_results_folder(tmp_path, name):
    with pytest.raises(RunFolderUnusable, match="plain name"):
        new_run_folder(tmp_path / "runs", name)
    assert not (tmp_path / "runs").exists() and sorted(p.name for p in tmp_path.iterdir()) == []


def test_a_refused_out_leaves_no_folder_it_created(tmp_path):
    (tmp_path / "taken").mkdir()
    (tmp_path / "taken" / "x").write_text("x")
    with pytest.raises(RunFolderExists):
        new_run_folder(tmp_path, "x", tmp_path / "taken")
    with pytest.raises(RunFolderUnusable, match="is a file, not a folder"):
        new_run_folder(tmp_path, "x", tmp_path / "taken" / "x")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken"]
    assert [p.name for p in (tmp_path / "taken").iterdir()] == ["x"]


def test_timeseries_is_written_block_by_block_with_the_same_text(tmp_path):
    import numpy as np

    from orchestration.master.recorder import write_timeseries

    time = np.arange(45_001) * 1e-3
    data = np.column_stack([np.sin(time), np.cos(time)])
    write_timeseries(tmp_path / "t.csv", time, ["a.x", "b.y"], data)
    lines = (tmp_path / "t.csv").read_text().splitlines()
    assert lines[0] == "time,a.x,b.y" and len(lines) == 45_002
    assert lines[40_001] == f"{time[40_000]:.12g},{data[40_000, 0]:.12g},{data[40_000, 1]:.12g}"
    # every row as Python's own '%.12g' formats it (the compiled formatter must agree to the byte)
    assert lines[1:] == [f"{t:.12g},{a:.12g},{b:.12g}" for t, (a, b) in zip(time, data, strict=True)]


# -- hostile input: one change at a time to real scenarios, packages and records ---------------------

SHORT = 0.02  # s: every mutated scenario that still runs stops after 20 steps


def _runnable(path: Path) -> bool:
    try:
        load_scenario(path, (f"simulation.stop_time={SHORT}",))
    except ScenarioError:
        return False
    return True


SCENARIOS = [p for p in sorted((PROJECT / "scenarios").glob("*.yaml")) if file_kind(p) == "scenario" and _runnable(p)]
HOSTILE_VALUES = [None, True, False, 0, -1, 1e308, -1e308, 5e-324, float("inf"), float("nan"), "", "x",
                  "../../escape", "/dev/zero", "1_0", "1e-3", [], {}, [[[["deep"]]]], "A" * 2000,
                  DataFile("/dev/zero", "record"), DataFile("nowhere.csv", "data"), DataFile("x", "record")]
FAST = settings(max_examples=30, deadline=None, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


class _Dumper(yaml.SafeDumper):
    """Writes DataFile values back as !record / !data tags."""


_Dumper.add_representer(DataFile, lambda d, v: d.represent_scalar(f"!{v.kind}", v.name))
_Dumper.add_representer(float, lambda d, v: d.represent_scalar("tag:yaml.org,2002:float", repr(v).replace(
    "inf", ".inf").replace("nan", ".nan")) if v != v or v in (float("inf"), float("-inf")) else
    yaml.SafeDumper.represent_float(d, v))


@functools.cache
def _standalone(path: Path) -> dict[str, Any]:
    loaded = load_scenario(path, (f"simulation.stop_time={SHORT}", "simulation.start_time=0"))
    tree = copy.deepcopy(loaded.raw)
    for unit in tree["units"]:
        tree["units"][unit]["fmu"] = str(loaded.fmu_path(unit))
    return tree


def standalone(path: Path) -> dict[str, Any]:
    """A real scenario as one self-contained tree: ``extends`` merged, FMU paths absolute, a 20-step run."""
    return copy.deepcopy(_standalone(path))


@dataclass
class Outcome:
    code: int
    out: str
    err: str
    created: list[str]  # new entries of the working folder
    leftovers: list[str]  # new entries of the temporary folder


def run_tool(main: Callable[[list[str]], int], argv: list[str], work: Path) -> Outcome:
    """Run a tool's main(argv) in ``work`` with a private temporary folder; what it printed and left."""
    before = set(os.listdir(work))
    private_tmp = Path(tempfile.mkdtemp(prefix="tmp-", dir=work.parent))
    out, err = io.StringIO(), io.StringIO()
    saved_tmp = tempfile.tempdir
    tempfile.tempdir = str(private_tmp)
    try:
        with contextlib.chdir(work), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(argv)
            except SystemExit as exc:  # argparse
                code = exc.code if isinstance(exc.code, int) else 2
    finally:
        tempfile.tempdir = saved_tmp
    leftovers = sorted(os.listdir(private_tmp))
    created = sorted(set(os.listdir(work)) - before)
    return Outcome(code, out.getvalue(), err.getvalue(), created, leftovers)


def check_outcome(o: Outcome, allowed: set[int], out_name: str | None) -> None:
    """The properties every tool run must have, whatever its input."""
    with contextlib.suppress(InvalidArgument):  # outside a property test there is nothing to record
        event(f"exit {o.code}")  # --hypothesis-show-statistics: how many cases ran, failed, were refused
    text = o.out + o.err
    assert o.code in allowed, (o.code, text[-2000:])
    assert "Traceback" not in text and "internal error" not in text, text[-2000:]
    if o.code != 0:
        assert o.err.strip(), "a failure must say why"
    assert not o.leftovers, f"temporary files left behind: {o.leftovers}"
    if o.code in (2, 130):
        assert o.created == [], f"exit {o.code} wrote {o.created}"
        return
    if out_name is not None and o.code in (0, 1):
        assert o.created in ([out_name], []), o.created  # nothing outside the run folder
        folder = Path(out_name)
        if o.created:
            summary = json.loads((folder / "summary.json").read_text()) if (folder / "summary.json").exists() else None
            assert summary is None or summary["complete"] is (o.code == 0)


def _run_scenario_file(tmp_path: Path, text: bytes | str, use_out: bool) -> tuple[Outcome, Path]:
    work = Path(tempfile.mkdtemp(prefix="case-", dir=tmp_path))
    scenario = work / "mutated.yaml"
    scenario.write_bytes(text if isinstance(text, bytes) else text.encode())
    argv = [str(scenario), "--no-plots", "--quiet", *(["--out", str(work / "out")] if use_out else [])]
    return run_tool(run.main, argv, work), work


@pytest.mark.slow
@FAST
@given(data=st.data())
def test_one_key_changed_in_a_real_scenario(tmp_path, data):
    base = standalone(data.draw(st.sampled_from(SCENARIOS), label="scenario"))
    path = data.draw(st.sampled_from(key_paths(base)), label="key")
    op = data.draw(st.sampled_from(["replace", "replace", "delete", "add"]), label="op")
    value = data.draw(st.sampled_from(HOSTILE_VALUES), label="value")
    use_out = data.draw(st.booleans(), label="--out")
    outcome, work = _run_scenario_file(tmp_path, yaml.dump(mutate(base, path, op, value), Dumper=_Dumper), use_out)
    with contextlib.chdir(work):
        check_outcome(outcome, {0, 1, 2}, "out" if use_out else "runs")


@pytest.mark.slow
@FAST
@given(data=st.data())
def test_one_byte_changed_in_a_real_scenario(tmp_path, data):
    text = yaml.dump(standalone(data.draw(st.sampled_from(SCENARIOS), label="scenario")), Dumper=_Dumper).encode()
    at = data.draw(st.integers(0, len(text) - 1), label="offset")
    how = data.draw(st.sampled_from(["invalid utf-8", "nul", "truncate", "tab", "anchor", "alias"]), label="how")
    piece = {"invalid utf-8": b"\xe9\xff", "nul": b"\x00", "truncate": b"", "tab": b"\t", "anchor": b"&a ",
             "alias": b"*a "}[how]
    mutated = text[:at] + piece + (b"" if how == "truncate" else text[at:])
    outcome, work = _run_scenario_file(tmp_path, mutated, True)
    with contextlib.chdir(work):
        check_outcome(outcome, {0, 1, 2}, "out")


OVERRIDES = ["simulation.step=true", "simulation.stop_time=.inf", "simulation.step=1e-320", "x=&a [*a]",
             "simulation.stop_time=1e9", "controller.mode=pasive", "name=../../escape", "name=.hidden",
             "units.ground.fmu=/dev/zero", "ground.record=!data missing.csv", "ground.record=!record /dev/zero",
             "connections=[{source: ground.ag, target: building.ag, delayed: 1}]", "limits.max_abs={x: true}",
             "report.displacement_limits={a: true}", "simulation=[" * 100, "units=&a {b: *a}", "=1", "a..b=1",
             "units.ground.parameters.scale=1_0", "results.dir=\x00"]


@pytest.mark.parametrize("override", OVERRIDES)
def test_hostile_overrides_are_exit_2_naming_the_cause(tmp_path, override):
    work = tmp_path / "work"
    work.mkdir()
    argv = [str(PROJECT / "scenarios" / "elcentro.yaml"), "--set", f"simulation.stop_time={SHORT}",
            "--set", override, "--out", str(work / "out"), "--no-plots", "--quiet"]
    outcome = run_tool(run.main, argv, work)
    check_outcome(outcome, {2}, "out")


def test_a_misspelt_string_choice_is_refused_before_the_run_with_a_suggestion(tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    argv = [str(PROJECT / "scenarios" / "elcentro.yaml"), "--set", "controller.mode=pasive", "--out",
            str(work / "out"), "--quiet"]
    outcome = run_tool(run.main, argv, work)
    assert outcome.code == 2 and outcome.created == []
    assert "mode = 'pasive' is not one of 'sosm', 'passive' (did you mean 'passive'?)" in outcome.err


def test_a_run_too_large_for_its_budget_is_refused_before_any_folder(tmp_path, monkeypatch):
    monkeypatch.setenv("MRE_COSIM_MAX_RESULT_MB", "1000")  # the default (free disk) depends on the machine
    work = tmp_path / "work"
    work.mkdir()
    argv = [str(PROJECT / "scenarios" / "elcentro.yaml"), "--set", "simulation.stop_time=1e5", "--quiet"]
    outcome = run_tool(run.main, argv, work)
    assert outcome.code == 2 and outcome.created == []
    assert "100,000,001 samples" in outcome.err and "MRE_COSIM_MAX_RESULT_MB" in outcome.err


# -- SSP packages ------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def short_ssp(tmp_path_factory) -> Path:
    """The El Centro scenario, 20 steps, as an SSP package."""
    plan = plan_scenario(PROJECT / "scenarios" / "elcentro.yaml", (f"simulation.stop_time={SHORT}",))
    return export_ssp(plan, tmp_path_factory.mktemp("ssp") / "elcentro.ssp")


def _copy_zip(src: Path, dest: Path, edit: Callable[[str, bytes], bytes | None],
              extra: dict[str, bytes] | None = None) -> None:
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as zout:
        for info in zin.infolist():
            data = edit(info.filename, zin.read(info))
            if data is not None:
                zout.writestr(info.filename, data)
        for name, data in (extra or {}).items():
            zout.writestr(name, data)


SSP_VALUES = ["abc", "INF", "-INF", "NaN", "", "1e400", "../../x", "/etc/passwd", "0", "-1", "true", "1_0",
              "resources/../../x", "\u00e9"]


@pytest.mark.slow
@FAST
@given(data=st.data())
def test_one_attribute_changed_in_a_real_ssp(tmp_path, short_ssp, data):
    from lxml import etree

    with zipfile.ZipFile(short_ssp) as z:
        members = [n for n in z.namelist() if n.endswith((".ssd", ".ssv"))]
    member = data.draw(st.sampled_from(members), label="member")
    with zipfile.ZipFile(short_ssp) as z:
        root = etree.fromstring(z.read(member))
    elements = [e for e in root.iter() if isinstance(e.tag, str) and (e.attrib or (e.text and e.text.strip()))]
    element = data.draw(st.sampled_from(elements), label="element")
    choices = [*element.attrib, *(["#text"] if element.text and element.text.strip() else [])]
    attr = data.draw(st.sampled_from(choices), label="attribute")
    op = data.draw(st.sampled_from(["set", "set", "delete"]), label="op")
    value = data.draw(st.sampled_from(SSP_VALUES), label="value")
    if attr == "#text":
        element.text = value if op == "set" else ""
    elif op == "set":
        element.set(attr, value)
    else:
        del element.attrib[attr]
    mutated = etree.tostring(root)
    work = Path(tempfile.mkdtemp(prefix="case-", dir=tmp_path))
    package = work / "mutated.ssp"
    _copy_zip(short_ssp, package, lambda name, raw: mutated if name == member else raw)
    outcome = run_tool(run.main, [str(package), "--out", str(work / "out"), "--no-plots", "--quiet"], work)
    with contextlib.chdir(work):
        check_outcome(outcome, {0, 1, 2}, "out")


def _symlink_entry(name: str, target: str) -> tuple[zipfile.ZipInfo, bytes]:
    info = zipfile.ZipInfo(name)
    info.external_attr = (0o120777 << 16)
    return info, target.encode()


@pytest.mark.parametrize("case", ["traversal", "absolute", "symlink", "bomb", "entries", "no ssd", "truncated",
                                  "fmu removed", "record removed", "settings units", "results outside"])
@pytest.mark.slow
def test_hostile_ssp_archives_are_exit_2_and_extract_nothing(tmp_path, short_ssp, case):
    work = tmp_path / "work"
    work.mkdir()
    package = work / "hostile.ssp"
    keep: Callable[[str, bytes], bytes | None] = lambda name, raw: raw  # noqa: E731
    if case == "traversal":
        _copy_zip(short_ssp, package, keep, {"../../escaped.txt": b"x"})
    elif case == "absolute":
        _copy_zip(short_ssp, package, keep, {"/tmp/escaped.txt": b"x"})
    elif case == "symlink":
        _copy_zip(short_ssp, package, keep)
        with zipfile.ZipFile(package, "a") as z:
            z.writestr(*_symlink_entry("resources/link", "/etc/passwd"))
    elif case == "bomb":  # 300 MiB of zeros, 300 kB compressed
        _copy_zip(short_ssp, package, keep)
        with zipfile.ZipFile(package, "a", zipfile.ZIP_DEFLATED) as z, z.open("resources/zeros.bin", "w",
                                                                              force_zip64=True) as f:
            block = bytes(1 << 20)
            for _ in range(300):
                f.write(block)
    elif case == "entries":
        _copy_zip(short_ssp, package, keep, {f"resources/e{k}.txt": b"" for k in range(10_001)})
    elif case == "no ssd":
        _copy_zip(short_ssp, package, lambda name, raw: None if name.endswith(".ssd") else raw)
    elif case == "truncated":
        package.write_bytes(short_ssp.read_bytes()[: short_ssp.stat().st_size // 2])
    elif case == "fmu removed":
        _copy_zip(short_ssp, package, lambda name, raw: None if name.endswith("MreIsolator.fmu") else raw)
    elif case == "record removed":
        _copy_zip(short_ssp, package, lambda name, raw: None if name.endswith(".csv") else raw)
    elif case == "settings units":
        _copy_zip(short_ssp, package, lambda name, raw: raw.replace(
            b'"format": 1,', b'"format": 1, "units": {"x": {"fmu": "/etc/passwd"}},') if name.endswith(".ssd")
            else raw)
    else:
        _copy_zip(short_ssp, package, lambda name, raw: raw.replace(b'"dir": "runs"', b'"dir": "/tmp/outside"')
                  if name.endswith(".ssd") else raw)
    outcome = run_tool(run.main, [str(package), "--out", str(work / "out"), "--no-plots", "--quiet"], work)
    check_outcome(outcome, {2}, "out")
    assert not (tmp_path / "escaped.txt").exists() and not Path("/tmp/escaped.txt").exists()


# -- records and FMUs --------------------------------------------------------------------------------

RECORD_TOKENS = ["1_0", "inf", "nan", "0x10", "abc", "", "1e400", "-", "1,2,3", "\u00e9", "1e-3", "+.5"]


@pytest.mark.slow
@FAST
@given(data=st.data())
def test_one_token_changed_in_a_real_record(tmp_path, data):
    source = data.draw(st.sampled_from(sorted((PROJECT / "scenarios" / "records").glob("*.csv"))), label="record")
    lines = source.read_text().splitlines()
    k = data.draw(st.integers(0, min(len(lines) - 1, 400)), label="line")
    token = data.draw(st.sampled_from(RECORD_TOKENS), label="token")
    parts = lines[k].split(",")
    parts[data.draw(st.integers(0, len(parts) - 1), label="column")] = token
    lines[k] = ",".join(parts)
    work = Path(tempfile.mkdtemp(prefix="case-", dir=tmp_path))
    record = work / "record.csv"
    record.write_text("\n".join(lines) + "\n")
    argv = [str(PROJECT / "scenarios" / "elcentro.yaml"), "--set", f"simulation.stop_time={SHORT}", "--set",
            f"ground.record=!record {record}", "--out", str(work / "out"), "--no-plots", "--quiet"]
    outcome = run_tool(run.main, argv, work)
    with contextlib.chdir(work):
        check_outcome(outcome, {0, 2}, "out")


@pytest.mark.parametrize(("header", "message"), [
    ("NPTS= 3, DT= 1e308", "not finite"),
    ("NPTS= 3, DT= ..", "DT is not a number"),
    ("NPTS= 3, DT= inf", "must give NPTS and DT"),
    ("NPTS= 3, DT= 0", "DT must be positive"),
])
def test_at2_time_steps_must_give_finite_increasing_times(tmp_path, header, message):
    from components.physics.ground_motion_core import RecordError, read_record

    path = tmp_path / "r.at2"
    path.write_text(f"title\nx\ny\n{header}\n0.1 0.2 0.3\n")
    with pytest.raises(RecordError, match=message):
        read_record(path)


def _fmu_with(src: Path, dest: Path, how: str) -> Path:
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as zout:
        for info in zin.infolist():
            raw = zin.read(info)
            if info.filename.startswith("binaries/linux64/"):
                raw = {"garbage": b"garbage" * 1000, "truncated": raw[:4096], "empty": b"",
                       "other cpu": raw[:18] + b"\xb7\x00" + raw[20:]}.get(how, raw)
                if how == "no binary":
                    continue
            zout.writestr(info, raw)
    return dest


@pytest.mark.parametrize("how", ["garbage", "truncated", "empty", "other cpu", "no binary"])
def test_an_fmu_whose_library_cannot_load_is_exit_2_before_any_folder(tmp_path, how):
    work = tmp_path / "work"
    work.mkdir()
    fmu = _fmu_with(PROJECT / "fmus" / "MreIsolator.fmu", tmp_path / "bad.fmu", how)
    argv = [str(PROJECT / "scenarios" / "elcentro.yaml"), "--set", f"units.isolator.fmu={fmu}", "--out",
            str(work / "out"), "--quiet"]
    outcome = run_tool(run.main, argv, work)
    check_outcome(outcome, {2}, "out")
    assert "units.isolator.fmu" in outcome.err and "bad.fmu" in outcome.err


@pytest.mark.slow
def test_an_fmu_that_unpacks_beyond_the_limit_is_refused(tmp_path):
    from orchestration.master.fmu_description import FmuFormatError, read_description

    fmu = tmp_path / "bomb.fmu"
    _copy_zip(PROJECT / "fmus" / "MreIsolator.fmu", fmu, lambda name, raw: raw)
    with zipfile.ZipFile(fmu, "a", zipfile.ZIP_DEFLATED) as z, z.open("resources/zeros", "w", force_zip64=True) as f:
        for _ in range(260):
            f.write(bytes(1 << 20))
    with pytest.raises(FmuFormatError, match=r"unpacks to .* more than"):
        read_description(fmu, "x")


# -- every tool: hostile files, the crash path, interrupts ---------------------------------------------


def _hostile_file(work: Path, kind: str) -> Path:
    path = work / f"hostile-{kind.replace(' ', '_')}.yaml"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "latin-1":
        path.write_bytes(b"name: caf\xe9\n")
    elif kind == "deep":
        path.write_text("a: " + "[" * 5000 + "]" * 5000 + "\n")
    elif kind == "laughs":
        rows = ["a: &a [x, x, x, x, x, x, x, x, x, x]"]
        rows += [f"{c}: &{c} [{', '.join([f'*{p}'] * 10)}]" for p, c in zip("abcdefgh", "bcdefghi", strict=True)]
        path.write_text("\n".join(rows) + "\n")
    elif kind == "recursive":
        path.write_text("a: &a [*a]\n")
    elif kind == "folder":
        path.mkdir()
    elif kind == "device":
        return Path("/dev/zero")
    return path


TOOLS = {"run.py": (run.main, []), "study.py": (study.main, []), "tune.py": (tune.main, []),
         "identify.py": (identify.main, ["--no-progress"]), "ssp.py check": (ssp.main, None),
         "ssp.py export": (ssp.main, None)}


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["fifo", "latin-1", "deep", "laughs", "recursive", "folder", "device", "missing"])
@pytest.mark.parametrize("tool", list(TOOLS))
def test_every_tool_refuses_hostile_files_with_exit_2(tmp_path, tool, kind):
    work = tmp_path / "work"
    work.mkdir()
    path = _hostile_file(tmp_path, kind)
    main, extra = TOOLS[tool]
    if tool == "ssp.py check":
        argv = ["check", str(path)]
    elif tool == "ssp.py export":
        argv = ["export", str(path), str(work / "x.ssp")]
    else:
        argv = [str(path), *extra, "--out", str(work / "out")]
    t0 = time.monotonic()
    outcome = run_tool(main, argv, work)
    assert time.monotonic() - t0 < 30, "took too long (a hang or an expansion)"
    check_outcome(outcome, {2}, "out")


def test_an_internal_error_is_exit_3_with_one_line_and_a_log(tmp_path, monkeypatch):
    import orchestration.engine_hooks

    def bug(*args, **kwargs):
        raise ZeroDivisionError("deliberate")

    monkeypatch.setattr(orchestration.engine_hooks, "plan_scenario", bug)
    monkeypatch.setenv("MRE_COSIM_CRASH_DIR", str(tmp_path))
    work = tmp_path / "work"
    work.mkdir()
    outcome = run_tool(run.main, [str(PROJECT / "scenarios" / "elcentro.yaml"), "--quiet"], work)
    assert outcome.code == 3 and outcome.created == []
    line, = outcome.err.strip().splitlines()
    assert "internal error (this is a bug" in line and "ZeroDivisionError: deliberate" in line
    log = Path(line.rsplit("traceback in ", 1)[1])
    assert log.parent == tmp_path and "Traceback" in log.read_text() and "deliberate" in log.read_text()


@pytest.mark.slow
@pytest.mark.parametrize("delay", [0.4, 0.9])
def test_ctrl_c_while_starting_is_one_line_and_exit_130(tmp_path, delay):
    proc = subprocess.Popen(
        args=[*RUN, str(PROJECT / "scenarios" / "kobe.yaml"), "--out", str(tmp_path / "out"),
                             "--quiet", "--no-plots"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=tmp_path)
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert "Traceback" not in err
    assert proc.returncode in (1, 130), err
    if proc.returncode == 130:
        assert "nothing written" in err and not (tmp_path / "out").exists()


@pytest.mark.parametrize("dest", ["README.md/sub", "/proc/mre-cosim-test"])
def test_the_build_tool_refuses_an_unusable_dest(dest):
    proc = subprocess.run([sys.executable, "-m", "components.build", "--dest", dest], cwd=PROJECT,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
    assert not (PROJECT / "README.md").is_dir()


@pytest.mark.parametrize("tool", ["run.py", "study.py", "tune.py", "identify.py", "ssp.py"])
def test_every_tool_documents_its_exit_codes(tool, capsys):
    main = {"run.py": run.main, "study.py": study.main, "tune.py": tune.main, "identify.py": identify.main,
            "ssp.py": ssp.main}[tool]
    with pytest.raises(SystemExit) as exit_:
        main(["--help"])
    assert exit_.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "exit codes: 0" in text and "3 internal error" in text and "130 interrupted" in text
