"""A real (loopback) Dask cluster: ``dask scheduler`` and two ``dask worker`` processes on 127.0.0.1.

The same small IDA study runs on the embedded local cluster and on the loopback cluster
(``--scheduler ADDRESS``); the results are identical. The workers get the FMU and record
bytes through Dask (nothing tells them where the study's files are).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from ..conftest import PROJECT
from ..studies.test_ida import ENV, ida_cli, small_study

pytestmark = pytest.mark.slow  # a scheduler and two workers started as processes


def _start(args: list[str], cwd: Path, log: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "dask", *args], cwd=cwd, env={**ENV, "PYTHONPATH": str(PROJECT)},
                            stdout=open(log, "w"), stderr=subprocess.STDOUT)


@pytest.fixture
def loopback_cluster(tmp_path):
    """Scheduler and two single-threaded workers on 127.0.0.1 (free ports), stopped afterwards."""
    info = tmp_path / "scheduler.json"
    procs = [_start(["scheduler", "--host", "127.0.0.1", "--port", "0", "--dashboard-address", ":0",
                     "--scheduler-file", str(info)], tmp_path, tmp_path / "scheduler.log")]
    try:
        deadline = time.monotonic() + 120
        while not info.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        assert info.exists(), (tmp_path / "scheduler.log").read_text()
        address = json.loads(info.read_text())["address"]
        for k in range(2):
            procs.append(_start(["worker", "--scheduler-file", str(info), "--nthreads", "1", "--nworkers", "1",
                                 "--no-dashboard", "--host", "127.0.0.1", "--name", f"w{k}"], tmp_path,
                                tmp_path / f"worker{k}.log"))
        yield address
    finally:
        for proc in reversed(procs):
            proc.terminate()
        for proc in procs:
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def comparable(folder: Path) -> list[dict]:
    return [{k: v for k, v in row.items() if k != "wall_time_s"} for row in
            pq.read_table(folder / "results.parquet").to_pylist()]


def test_a_study_on_a_loopback_cluster_equals_the_local_default(tmp_path, loopback_cluster):
    records = tmp_path / "one"
    records.mkdir()
    (records / "northridge.csv").write_bytes((PROJECT / "scenarios" / "records" /
                                              "northridge_1994_sylmar_ns.csv").read_bytes())
    study = small_study(tmp_path, suite={"folder": str(records)}, strategies=["passive-off", "on-off"],
                        intensity={"measure": "pga", "levels": [0.2, 0.5]})
    local, remote = tmp_path / "local", tmp_path / "remote"
    proc = ida_cli(str(study), "--out", str(local), "--quiet", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    proc = ida_cli(str(study), "--out", str(remote), "--quiet", "--scheduler", loopback_cluster, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert f"scheduler {loopback_cluster}, 2 workers" in proc.stderr
    rows = comparable(remote)
    assert len(rows) == 4 and all(r["status"] == "ok" for r in rows)
    assert rows == comparable(local)
    engine = json.loads((remote / "ida.json").read_text())["batch"]
    assert engine["scheduler"] == loopback_cluster and engine["workers"] == 2
    assert (remote / "report.html").is_file()
