"""IDA studies through the command line (orchestration/ida.py): bad input, a small study, resume, Ctrl-C."""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest
import yaml

from orchestration.api import load_scenario, run
from orchestration.ida_study.ida_metrics import COLUMNS

from ..conftest import PROJECT, RECORDS

CLI = [sys.executable, str(PROJECT / "orchestration" / "ida.py")]


# Job keys include a digest of the code; pinned here so that a resume in these tests does not
# depend on nobody editing the checkout meanwhile (test_dask.py checks that the digest counts).
ENV = {**os.environ, "MRE_COSIM_CODE_VERSION": "tests"}






def ida_cli(*args: str, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, *args], cwd=cwd, capture_output=True, text=True, timeout=timeout, env=ENV)


def small_study(tmp_path: Path, **changes) -> Path:
    """Two short records (Kobe, Northridge: strong-motion windows of 15 s and 9 s, played 5x faster)."""
    folder = tmp_path / "suite"
    folder.mkdir(exist_ok=True)
    for name in ("kobe_1995_jma_ns.csv", "northridge_1994_sylmar_ns.csv"):
        shutil.copy(RECORDS / name, folder / name)
    spec = {
        "name": "mini-ida",
        "scenario": str(PROJECT / "scenarios" / "isolated_building.yaml"),
        "suite": {"folder": str(folder)},
        "time_scale": 0.2,
        "window": {"tail_s": 0.5},
        "intensity": {"measure": "sa", "levels": [0.1, 0.4]},
        "strategies": ["passive-off", "sosm"],
        "gains": str(PROJECT / "scenarios" / "sosm_gains.yaml"),
        "limit_states": {"iso15": {"quantity": "isolator_displacement", "threshold": 0.015},
                         "acc": {"quantity": "floor_acceleration", "threshold": 3.0}},
        "output": str(tmp_path / "studies"),
        **changes,
    }
    path = tmp_path / "ida.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


@pytest.mark.slow
def test_bad_input_lists_every_problem_and_computes_nothing(tmp_path):
    study = small_study(tmp_path, suite="peer-nga-west2",
                        intensity={"measure": "sa", "levels": [0.3, 0.2, 0.5]},
                        limit_states={"roof": {"quantity": "roof_drift", "threshold": 0.01}})
    out = tmp_path / "out"
    proc = ida_cli(str(study), "--out", str(out), cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    err = proc.stderr
    assert "3 problems" in err and "Traceback" not in err
    assert "unknown suite 'peer-nga-west2'" in err
    assert "must increase strictly: 0.2 after 0.3" in err
    assert "limit_states.roof.quantity" in err and "isolator_displacement" in err
    assert not out.exists() and not (tmp_path / "studies").exists()

    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "readme.txt").write_text("no record here\n")
    study = small_study(tmp_path, suite={"folder": str(empty)}, intensity={"measure": "pga", "levels": [0.2, 0.2]})
    proc = ida_cli(str(study), "--out", str(out), cwd=tmp_path)
    assert proc.returncode == 2
    assert "has no readable record" in proc.stderr and "must increase strictly" in proc.stderr
    assert not out.exists()


@pytest.mark.slow
def test_an_unreachable_scheduler_is_exit_2_before_any_work(tmp_path):
    out = tmp_path / "out"
    proc = ida_cli(str(small_study(tmp_path)), "--scheduler", "tcp://127.0.0.1:9", "--out", str(out), cwd=tmp_path)
    assert proc.returncode == 2 and "cannot reach the Dask scheduler at tcp://127.0.0.1:9" in proc.stderr
    assert not out.exists()


def test_the_scheduler_comes_from_the_option_else_the_environment(monkeypatch):
    from orchestration.batch.pool import scheduler_address

    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    assert scheduler_address(None) is None
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "tcp://10.1.2.3:8786")
    assert scheduler_address(None) == "tcp://10.1.2.3:8786"
    assert scheduler_address("tcp://127.0.0.1:8786") == "tcp://127.0.0.1:8786"


def read_results(folder: Path) -> list[dict]:
    return pq.read_table(folder / "results.parquet").to_pylist()


@pytest.mark.slow
def test_small_ida_end_to_end_then_resume(tmp_path):
    out = tmp_path / "study"
    proc = ida_cli(str(small_study(tmp_path)), "--out", str(out), "--quiet", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    rows = read_results(out)
    assert len(rows) == 8 and list(rows[0]) == list(COLUMNS)
    assert {(r["record_id"], r["intensity"], r["strategy"]) for r in rows} == {
        (rid, lvl, s) for rid in ("kobe_1995_jma_ns", "northridge_1994_sylmar_ns") for lvl in (0.1, 0.4)
        for s in ("passive-off", "sosm")}
    assert all(r["status"] in ("ok", "diverged") and r["wall_time_s"] > 0 for r in rows)
    with open(out / "results.csv") as f:
        assert len(list(csv.DictReader(f))) == 8
    with open(out / "fragility.csv") as f:
        frag = list(csv.DictReader(f))
    assert {(r["limit_state"], r["strategy"]) for r in frag} == {(ls, s) for ls in ("iso15", "acc")
                                                                for s in ("passive-off", "sosm")}
    report = (out / "report.md").read_text()
    assert "## Verdict per limit state" in report and "**iso15**" in report and "**acc**" in report
    assert (out / "report.html").read_text().count("data:image/png;base64,") == 3  # curves, fragility, spectra
    info = json.loads((out / "ida.json").read_text())
    assert info["runs_computed"] == 8 and 0.5 < info["period_s"] < 1.5

    # Each row is the peak of the same co-simulation run directly through the Python API.
    row = next(r for r in rows if r["record_id"] == "kobe_1995_jma_ns" and r["intensity"] == 0.4
               and r["strategy"] == "sosm")
    comp = next(c for c in info["components"] if c["id"] == "kobe_1995_jma_ns")
    plan = load_scenario(PROJECT / "scenarios" / "isolated_building.yaml", [
        "isolator.i_max=3.0", "controller.i_max=3.0", "ground.time_scale=0.2", *info["strategies"]["sosm"],
        f"ground.record=!record {out / 'records' / 'kobe_1995_jma_ns.csv'}",
        f"simulation.stop_time={comp['stop_time_s']!r}", f"ground.scale={row['scale']!r}"])
    direct = run(plan, out=tmp_path / "direct")
    assert row["x_base_mm"] == 1e3 * float(abs(direct["building.x_0"]).max())
    assert row["acc_3"] == float(abs(direct["building.a_3"]).max())

    # Resume a finished study: nothing is computed again, the tables are the same.
    before = (out / "results.csv").read_text()
    proc = ida_cli("--resume", str(out), "--quiet", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert json.loads((out / "ida.json").read_text())["runs_computed"] == 0
    assert (out / "results.csv").read_text() == before
    # Lose three results: a resume computes exactly those three, with the same numbers.
    for f in sorted((out / "jobs").glob("*.json"))[:3]:
        f.unlink()
    proc = ida_cli("--resume", str(out), "--quiet", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert json.loads((out / "ida.json").read_text())["runs_computed"] == 3
    assert [{k: v for k, v in r.items() if k != "wall_time_s"} for r in read_results(out)] == \
        [{k: v for k, v in r.items() if k != "wall_time_s"} for r in rows]


@pytest.mark.slow
@pytest.mark.parametrize("how", ["ctrl-c", "sigterm"])
def test_ctrl_c_cancels_what_is_pending_and_still_writes_the_report(tmp_path, how):
    """Ctrl-C (SIGINT to the whole process group, as a terminal sends it) or SIGTERM to the tool alone
    (as a service manager or ``kill`` sends it): pending runs cancelled, the report of what finished written."""
    out = tmp_path / "study"
    study = small_study(tmp_path, intensity={"measure": "pga", "levels": [0.05, 0.1, 0.15]},
                        window={"tail_s": 1.0}, time_scale=0.5)
    proc = subprocess.Popen(
        args=[*CLI, str(study), "--out", str(out), "--quiet"], cwd=tmp_path, start_new_session=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and len(list((out / "jobs").glob("*.json"))) < 2:
        time.sleep(0.2)
    if how == "ctrl-c":
        os.killpg(proc.pid, signal.SIGINT)
    else:
        proc.send_signal(signal.SIGTERM)
    stdout, stderr = proc.communicate(timeout=180)
    assert proc.returncode == 1, stderr
    assert "interrupted" in stdout and "Traceback" not in stderr
    rows = read_results(out)
    assert len(rows) == 12
    statuses = {r["status"] for r in rows}
    assert "not run" in statuses and statuses & {"ok", "diverged"}
    assert "interrupted" in (out / "report.md").read_text()
    done = sum(r["status"] in ("ok", "diverged") for r in rows)
    # finish it
    proc2 = ida_cli("--resume", str(out), "--quiet", cwd=tmp_path)
    assert proc2.returncode == 0, proc2.stderr
    assert json.loads((out / "ida.json").read_text())["runs_computed"] == 12 - done
    assert all(r["status"] in ("ok", "diverged") for r in read_results(out))


@pytest.mark.slow
@pytest.mark.parametrize("flag", ["--report"])
def test_report_regenerates_from_the_data(tmp_path, flag):
    assert ida_cli(flag, str(tmp_path / "nowhere"), cwd=tmp_path).returncode == 2


@pytest.mark.slow
def test_the_shipped_ida_studies_are_valid():
    from orchestration.ida_study.ida_config import load_ida
    from orchestration.ida_study.ida_plan import prepare_ida

    small = PROJECT / "scenarios" / "ida_shipped.yaml"
    prepared = prepare_ida(small, *load_ida(small))
    try:
        assert len(prepared.components) == 4 and len(prepared.plans) == 12
        assert prepared.period_s == pytest.approx(0.84, abs=0.01)
    finally:
        prepared.cleanup()
    loaded, problems, _ = load_ida(PROJECT / "scenarios" / "ida.yaml")
    assert not problems and loaded.spec.suite == "fema-p695-far-field"
    spec = loaded.spec
    assert len(spec.intensity.levels) * len(spec.strategies) == 24  # x 44 components = 1,056 runs
