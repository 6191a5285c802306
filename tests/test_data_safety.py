"""Data safety: outputs are never deleted or lost, write failures are never reported as complete.

* identify.py --overwrite replaces only folders it wrote itself (marker), never the working
  directory, its ancestors, the root or the home folder;
* run.py claims its run folder atomically before simulating: of two runs with the same
  --out exactly one succeeds;
* an unusable --out is a clean exit-2 error before simulating; a write failure after the
  simulation leaves no summary saying complete;
* round-off of order 1e-16 in the generalized fit is not "unphysical".
"""

from __future__ import annotations

import errno
import json
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest
import yaml

from components.identification.generalized import GeneralizedFit, physical_problems
from components.physics.mre_isolator_core import TABLE2_PAPER_UNITS
from orchestration import identify
from orchestration.identification.ident_pipeline import MARKER
from orchestration.master import session
from orchestration.master.runfolder import RUN_MARKER, RunFolderExists, RunFolderUnusable, new_run_folder

PROJECT = Path(__file__).resolve().parents[1]
RUN = [sys.executable, str(PROJECT / "orchestration" / "run.py")]
ELCENTRO = PROJECT / "scenarios" / "elcentro.yaml"


@pytest.fixture(autouse=True)
def _keep_signal_handlers():
    """The CLIs' main() install SIGTERM/SIGINT handlers; restore them after each test."""
    saved = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    yield
    for sig, handler in saved.items():
        signal.signal(sig, handler)


# ----------------------------------------------------------------------------- 1. identify.py --overwrite


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


# ----------------------------------------------------------------------------- 2. concurrent runs, same --out


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


# ----------------------------------------------------------------------------- 3. unusable --out, write failures


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

    monkeypatch.setattr(session, "write_timeseries", _disk_full)
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

    real = session.write_json

    def fail_summary(path, data):
        if Path(path).name == "summary.json":
            _disk_full()
        real(path, data)

    monkeypatch.setattr(session, "write_json", fail_summary)
    outcome = run_scenario(ELCENTRO, ("simulation.stop_time=0.05",), out=tmp_path / "run", plots=False)
    assert not outcome.result.complete and "summary.json" in str(outcome.result.error)
    assert not (tmp_path / "run" / "summary.json").exists()
    assert json.loads((tmp_path / "run" / "manifest.json").read_text())["complete"] is False


# ----------------------------------------------------------------------------- 4. round-off in the generalized fit


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


# ----------------------------------------------------------------------------- 5. run folder names and paths


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
