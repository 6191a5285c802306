"""Hostile inputs of the study files: values set but unused by the chosen law, strategies defined but not listed,
a NUL in a string, a bound on every wait for the Dask workers, and a full disk that is said to be what it is."""

from __future__ import annotations

import errno
import json
import os
import resource
import signal
import socket
import subprocess
import sys
import time
import zlib
from pathlib import Path

import pytest

from mre_common.guard import guarded
from orchestration import run as run_tool
from orchestration.batch.jobs import write_run_files
from orchestration.batch.pool import BatchPool, BatchUnavailable
from orchestration.building_report import REPORT
from orchestration.case_study.case_config import load_study
from orchestration.engine_hooks import resolve_scenario
from orchestration.master.errors import ScenarioError
from orchestration.master.resolve import typed_parameter
from orchestration.master.scenario import load_scenario
from orchestration.master.unit import Variable

from ..conftest import PROJECT

SCENARIOS = PROJECT / "scenarios"
RUN = [sys.executable, str(PROJECT / "orchestration" / "run.py")]


def _problems(scenario: str | Path, overrides: tuple[str, ...] = ()) -> list:
    path = SCENARIOS / f"{scenario}.yaml" if isinstance(scenario, str) else scenario
    try:
        resolve_scenario(load_scenario(path, overrides, REPORT.model))
    except ScenarioError as exc:
        return exc.problems
    return []


# -- a value the chosen law does not use: in its domain, and not set at all ----------------------------------
# (scenario, overrides, the parameter named, a text the problem must hold)
UNUSED = [
    ("kobe", ("building.n_1=3.0",), "n_1", "set but unused with hysteresis: linear"),
    ("kobe", ("building.n_2=0.5",), "n_2", "must be >= 1 (checked although hysteresis: linear"),
    ("kobe_yielding", ("building.n_3=4.0",), "n_3", "set but unused with hysteresis: bilinear"),
    ("kobe", ("building.fy_1=4000.0",), "fy_1", "set but unused with hysteresis: linear"),
    ("kobe", ("building.b_2=1.5",), "b_2", "must be in [0, 1)"),
    ("kobe", ("building.bw_beta=-1.0",), "bw_beta", "Bouc-Wen needs beta > 0"),
    ("kobe", ("building.bw_gamma=5.0",), "bw_gamma", "|gamma| <= beta"),
    ("kobe", ("building.substeps=0",), "substeps", "must be an integer in [1, 1000]"),
    ("kobe", ("building.h_1=3.0",), "h_1", "set but unused with p_delta: false"),
    ("kobe", ("building.h_2=-3.0",), "h_2", "must be > 0"),
    ("kobe", ("isolator.k_stop=1e6",), "k_stop", "set but unused with beyond_range: extrapolate"),
    ("kobe", ("isolator.beyond_range=tangent", "isolator.c_stop=-5.0"), "c_stop", "must not be negative"),
    ("elcentro_c_isolator", ("isolator.c_stop=100.0",), "c_stop", "set but unused with beyond_range: extrapolate"),
]


@pytest.mark.parametrize(("scenario", "overrides", "parameter", "text"), UNUSED,
                         ids=[f"{c[0]}-{c[1][-1]}" for c in UNUSED])
def test_a_value_the_law_does_not_use_is_refused_at_its_key_and_line(scenario, overrides, parameter, text):
    (problem,) = _problems(scenario, overrides)
    assert problem.key.endswith(f".parameters.{parameter}")
    assert text in problem.message
    assert problem.file == f"--set {next(o for o in overrides if f'.{parameter}=' in o)}"


@pytest.mark.parametrize("overrides", [
    ("building.hysteresis=bouc-wen", "building.n_1=3.0"),  # used
    ("building.hysteresis=bilinear", "building.fy_1=4000.0", "building.b_1=0.1"),  # used
    ("building.p_delta=true", "building.h_1=3.0", "building.h_2=3.0", "building.h_3=3.0"),  # used
    ("isolator.beyond_range=stop", "isolator.k_stop=1e8", "isolator.c_stop=100.0"),  # used
    ("building.n_1=2.0", "building.h_1=0.0", "isolator.k_stop=5e6"),  # unused, but the declared start: not "set"
])
def test_a_used_value_or_the_declared_start_passes(overrides):
    assert _problems("kobe", overrides) == []


def test_switching_the_yielding_building_back_to_linear_passes():
    # kobe_yielding's fy_j and b_j are the FMU's declared starts: the same building, run linear
    assert _problems("kobe_yielding", ("building.hysteresis=linear",)) == []


def test_the_yaml_line_of_an_unused_value_is_named(tmp_path):
    scenario = tmp_path / "s.yaml"
    scenario.write_text(f"extends: {SCENARIOS / 'kobe.yaml'}\nname: s\nunits:\n  building:\n    parameters:\n"
                        "      n_2: 3.0\n")
    (problem,) = _problems(scenario)
    assert (problem.file, problem.line, problem.key) == (str(scenario), 6, "units.building.parameters.n_2")


def test_run_py_refuses_an_unused_value_with_exit_2_and_writes_nothing(tmp_path):
    proc = subprocess.run([*RUN, str(SCENARIOS / "elcentro.yaml"), "--set", "building.n_1=3", "--out", "out",
                           "--quiet", "--no-plots"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2
    assert "building.n_1=3" in proc.stderr and "set but unused" in proc.stderr
    assert list(tmp_path.iterdir()) == []


# -- a strategy the study defines is checked whether it is listed or not -------------------------------------
@pytest.mark.parametrize(("definition", "key"), [
    ("{x: {parameters: {current: .nan}}}", "strategy_definitions.x.parameters.current"),
    ("{x: {parameters: {i_passive: -.inf}}}", "strategy_definitions.x.parameters.i_passive"),
    ("{x: {parameters: {gains: [1.0, .inf]}}}", "strategy_definitions.x.parameters.gains"),
])
def test_a_non_finite_number_in_an_unlisted_strategy_is_refused(definition, key):
    with pytest.raises(ScenarioError) as caught:
        load_study(SCENARIOS / "case_study.yaml", (f"strategy_definitions={definition}",))
    (problem,) = caught.value.problems
    assert problem.key.startswith(key) and "must be a finite number" in problem.message
    assert "strategy 'x'" in problem.message


@pytest.mark.parametrize(("definition", "key"), [
    ('{x: {parameters: {mode: "passive\\0"}}}', "strategy_definitions.x.parameters.mode"),
    ('{x: {fmu: "a\\0.fmu"}}', "strategy_definitions.x.fmu"),
])
def test_a_nul_in_an_unlisted_strategy_is_refused(definition, key):
    with pytest.raises(ScenarioError) as caught:
        load_study(SCENARIOS / "case_study.yaml", (f"strategy_definitions={definition}",))
    (problem,) = caught.value.problems
    assert problem.key == key and "NUL" in problem.message


def test_a_finite_unlisted_strategy_is_accepted():
    study = load_study(SCENARIOS / "case_study.yaml", ("strategy_definitions={x: {parameters: {i_passive: 1.5}}}",))
    assert "x" in study.library


def test_a_strategy_file_with_a_nan_is_refused_at_its_line(tmp_path):
    path = tmp_path / "mine.yaml"
    path.write_text("strategies:\n  calm:\n    parameters:\n      mode: passive\n      i_passive: .nan\n")
    with pytest.raises(ScenarioError) as caught:
        load_study(SCENARIOS / "case_study.yaml", (f"strategy_files=[{path}]",))
    (problem,) = caught.value.problems
    assert (problem.file, problem.line) == (str(path), 5)


# -- a NUL inside a String would be cut on its way to the C API ----------------------------------------------
def test_a_nul_in_a_string_value_is_refused():
    var = Variable("script", 1, "String", "parameter", "fixed", start="")
    assert typed_parameter(var, "model.py")[1] is None
    _, why = typed_parameter(var, "model.py\0rm -rf")
    assert "NUL" in why and "position 8" in why


def test_a_nul_in_a_scenario_string_names_file_line_and_key(tmp_path):
    scenario = tmp_path / "s.yaml"
    scenario.write_text(f'extends: {SCENARIOS / "elcentro.yaml"}\nname: s\nunits:\n  controller:\n'
                        '    parameters:\n      mode: "passive\\0sosm"\n')
    (problem,) = _problems(scenario)
    assert (problem.file, problem.line, problem.key) == (str(scenario), 6, "units.controller.parameters.mode")
    assert "NUL" in problem.message


def test_a_nul_in_an_fmu_path_is_a_scenario_error(tmp_path):
    scenario = tmp_path / "s.yaml"
    scenario.write_text(f'extends: {SCENARIOS / "elcentro.yaml"}\nname: s\nunits:\n  isolator:\n'
                        f'    fmu: "{PROJECT / "fmus" / "MreIsolator.fmu"}\\0"\n')
    (problem,) = _problems(scenario)  # was ValueError: embedded null byte (exit 3)
    assert (problem.line, problem.key) == (5, "units.isolator.fmu") and "NUL" in problem.message


# -- every wait for the Dask workers is bounded ----------------------------------------------------------------
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.slow
def test_a_stuck_worker_is_refused_within_the_answer_bound(tmp_path):
    """A real scheduler and worker; the worker is stopped (SIGSTOP) after it registered, so it never answers."""
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    dask = str(Path(sys.executable).parent / "dask")
    log = open(tmp_path / "dask.log", "w")
    scheduler = subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                                  "--dashboard-address", ":0"], stdout=log, stderr=log, cwd=tmp_path)
    worker = None
    try:
        worker = subprocess.Popen([dask, "worker", address, "--no-nanny", "--nthreads", "1"], stdout=log,
                                  stderr=log, cwd=PROJECT)
        from distributed import Client

        with Client(address, timeout="60s") as client:
            client.wait_for_workers(1, timeout=120)
        os.kill(worker.pid, signal.SIGSTOP)
        t0 = time.monotonic()
        with pytest.raises(BatchUnavailable) as caught:
            BatchPool(address, answer_timeout_s=3.0).start()
        waited = time.monotonic() - t0
        assert waited < 30.0
        assert address in str(caught.value) and "within 3 s" in str(caught.value)
    finally:
        for proc in (worker, scheduler):
            if proc is not None:
                os.kill(proc.pid, signal.SIGCONT)
                proc.kill()
                proc.wait()
        log.close()


# -- a full disk: "marked incomplete" only when a file says so, and what exists otherwise --------------------
def _run_limited(tmp_path: Path, limit: int) -> subprocess.CompletedProcess:
    """run.py with every file it writes limited to ``limit`` bytes (RLIMIT_FSIZE: the kernel refuses a write beyond
    it with EFBIG, as a full disk refuses one with ENOSPC)."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()

    def limited() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return subprocess.run([*RUN, str(SCENARIOS / "kobe.yaml"), "--set", "simulation.stop_time=5", "--out", "out",
                           "--quiet", "--no-plots"], cwd=tmp_path, capture_output=True, text=True, timeout=600,
                          preexec_fn=limited, env={**os.environ, "TMPDIR": str(tmp), "PYTHONDONTWRITEBYTECODE": "1"})


@pytest.mark.slow
def test_a_results_file_that_cannot_be_written_is_marked(tmp_path):
    proc = _run_limited(tmp_path, 1 << 20)  # the units load; timeseries.csv (several MiB) cannot be written
    assert proc.returncode == 1
    assert "timeseries.csv" in proc.stderr and "partial results (marked incomplete)" in proc.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["complete"] is False and "timeseries.csv" in summary["error"]


@pytest.mark.slow
def test_an_unmarked_folder_is_said_to_be_unmarked_with_what_it_holds(tmp_path):
    proc = _run_limited(tmp_path, 512)  # not even summary.json (3 KiB) nor manifest.json can be written
    assert proc.returncode == 1
    assert "(marked incomplete)" not in proc.stderr and "NOT marked incomplete" in proc.stderr
    folder = tmp_path / "out"
    assert not (folder / "summary.json").exists() and not (folder / "manifest.json").exists()
    for path in folder.iterdir():  # every file the folder holds is named with its size
        assert f"{path.name} ({path.stat().st_size} B)" in proc.stderr
    assert run_tool.results_note(folder).endswith(")")


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EDQUOT, errno.EFBIG])
def test_a_full_disk_is_exit_1_with_one_line_not_a_bug(code, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("MRE_COSIM_CRASH_DIR", str(tmp_path))

    def work(argv):
        with open(tmp_path / "big", "wb") as f:
            f.write(b"x")
        raise OSError(code, os.strerror(code), str(tmp_path / "big"))

    assert guarded(work, [], "tool") == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"could not write {tmp_path / 'big'}: {os.strerror(code)}" in err
    assert not list(tmp_path.glob("*crash*"))  # not an internal error: no crash log


def test_another_os_error_is_still_a_bug(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("MRE_COSIM_CRASH_DIR", str(tmp_path))

    def work(argv):
        raise OSError(errno.EBADF, "Bad file descriptor")

    assert guarded(work, [], "tool") == 3


def test_a_run_folder_that_cannot_be_written_whole_has_no_summary(tmp_path):
    """A real write failure: timeseries.csv cannot replace the folder that stands at its name."""
    folder = tmp_path / "run"
    folder.mkdir()
    (folder / "summary.json").write_text(json.dumps({"complete": True}))  # from an earlier attempt
    (folder / "timeseries.csv").mkdir()
    files = {name: zlib.compress(b"{}" if name.endswith(".json") else b"t\n0\n")
             for name in ("manifest.json", "summary.json", "timeseries.csv")}
    with pytest.raises(OSError):
        write_run_files(folder, files)
    assert not (folder / "summary.json").exists() and not (folder / "manifest.json").exists()
    (folder / "timeseries.csv").rmdir()
    write_run_files(folder, files)
    assert sorted(p.name for p in folder.iterdir()) == ["manifest.json", "summary.json", "timeseries.csv"]
    summary, series = (folder / "summary.json").stat().st_mtime_ns, (folder / "timeseries.csv").stat().st_mtime_ns
    assert summary >= series  # written last


# -- found by the corpus: an SSP reference too long for the file system ---------------------------------------
def test_an_ssp_parameter_naming_a_file_too_long_is_a_scenario_error(tmp_path):
    import re
    import zipfile

    from orchestration.engine_hooks import plan_scenario
    from orchestration.interop.ssp_package import export_ssp, load_ssp

    package = export_ssp(plan_scenario(SCENARIOS / "elcentro.yaml", ("simulation.stop_time=0.05",)),
                         tmp_path / "p.ssp")
    bad = tmp_path / "bad.ssp"
    with zipfile.ZipFile(package) as src, zipfile.ZipFile(bad, "w") as dst:
        for name in src.namelist():
            data = src.read(name)
            if name.endswith("ground.ssv"):  # the record's String value: 3000 characters, beyond NAME_MAX (255)
                data, n = re.subn(rb'(<ssv:String value=")[^"]*(")', rb"\g<1>" + b"x" * 3000 + rb"\g<2>", data)
                assert n == 1
            dst.writestr(name, data)
    with pytest.raises(ScenarioError) as caught:  # was OSError: File name too long (exit 3)
        resolve_scenario(load_ssp(bad))
    assert any(p.key == "units.ground.parameters.record" for p in caught.value.problems)
