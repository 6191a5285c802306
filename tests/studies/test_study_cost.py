"""What a study costs: the Radau references computed once (``--verify``) and reused by content key across
studies and folders; by default none is computed (orchestration/case_study/case_run.py)."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys

import pytest

from ..conftest import PROJECT

STUDY = PROJECT / "scenarios" / "case_study.yaml"
CLI = [sys.executable, str(PROJECT / "orchestration" / "study.py")]
ARGS = ("--set", "overrides=[simulation.stop_time=1]", "--set", "records={elcentro: elcentro.yaml}",
        "--set", "strategies=[passive-off, passive-on]", "--quiet")


def _rows(path):
    with open(path) as f:
        return sorted(csv.reader(f))


@pytest.mark.slow
def test_references_computed_once_and_reused_across_folders(tmp_path):
    """Default: no reference computed; --verify computes both; a later default study in a fresh folder reuses them
    (same reference.csv, no reference job computed), and a changed input is not served from the cache."""
    env = {**os.environ, "MRE_COSIM_CACHE": str(tmp_path / "cache"), "MRE_COSIM_CODE_VERSION": "tests"}

    def study(out, *extra):
        proc = subprocess.run([*CLI, str(STUDY), *ARGS, *extra, "--out", str(tmp_path / out)], cwd=tmp_path,
                              capture_output=True, text=True, timeout=300, env=env)
        assert proc.returncode == 0, proc.stderr
        return tmp_path / out, json.loads((tmp_path / out / "study.json").read_text())

    plain, record = study("plain")
    assert record["jobs_computed"] == 2 and record["reference"] == {}
    assert not (plain / "reference.csv").exists()
    assert "not computed" in (plain / "report.md").read_text()

    verified, record = study("verified", "--verify")
    assert record["jobs_computed"] == 4 and set(record["reference"]) == {"elcentro/passive-off",
                                                                        "elcentro/passive-on"}
    assert (plain / "peaks.csv").read_text() == (verified / "peaks.csv").read_text()

    again, record = study("again")
    assert record["jobs_computed"] == 2  # the two co-simulations; the references came from the cache
    assert _rows(again / "reference.csv") == _rows(verified / "reference.csv")
    reused = [json.loads(p.read_text()) for p in (again / "jobs").glob("*.json")]
    assert sorted(j["label"] for j in reused if j.get("reused_from")) == [
        "elcentro/passive-off/reference", "elcentro/passive-on/reference"]
    assert "not computed" not in (again / "report.md").read_text()

    # another stop time is another reference: not in the cache, so not reported without --verify
    _, record = study("other", "--set", "overrides=[simulation.stop_time=0.5]")
    assert record["reference"] == {} and len(record["provenance"]["references_not_computed"]) == 2


def test_a_record_is_parsed_once_while_unchanged(tmp_path, monkeypatch):
    """The scenario checks parse each record once per process (a study plans every record many times); a changed
    file is parsed again, so its problems are still found."""
    import orchestration.engine_hooks as hooks

    calls = []
    real = hooks.read_record
    monkeypatch.setattr(hooks, "read_record", lambda p: calls.append(p) or real(p))
    rec = tmp_path / "r.csv"
    rec.write_text("time_s,accel_g\n0,0\n0.01,0.1\n0.02,-0.1\n")
    assert hooks.check_record(rec) is None and hooks.check_record(rec) is None
    assert len(calls) == 1
    rec.write_text("time_s,accel_g\n0,0\n0.01,0.1\n0.005,-0.1\n")  # time goes back: another size
    assert "does not increase" in hooks.check_record(rec)
    assert len(calls) == 2
    assert "unreadable record" in hooks.check_record(tmp_path / "missing.csv")
