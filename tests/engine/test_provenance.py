"""manifest.json records the SHA-256 of what the run read: hashed when checked, verified after the units read it."""

from __future__ import annotations

import hashlib
import json
import shutil
import zipfile

import pytest

from orchestration.engine_hooks import plan_scenario
from orchestration.master.session import run_plan

from ..conftest import PROJECT, shipped_record

SHORT = "simulation.stop_time=0.05"


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


@pytest.fixture
def record(tmp_path):
    path = tmp_path / "r.csv"
    shutil.copy(shipped_record("elcentro_1940_ns.csv"), path)
    return path


def _plan(record, *more):
    return plan_scenario(PROJECT / "scenarios" / "elcentro.yaml", (SHORT, f"ground.record=!record {record}", *more))


def test_the_plan_holds_the_hash_of_every_input_as_checked(record):
    plan = _plan(record)
    assert plan.input_hashes[str(record.resolve())] == _digest(record.read_bytes())
    for path in plan.fmu_paths.values():
        assert plan.input_hashes[str(path)] == _digest(path.read_bytes())
    assert plan.changed_inputs() == []


def test_a_record_rewritten_before_the_units_read_it_fails_the_run_naming_it(record, tmp_path):
    plan = _plan(record)
    record.write_text("time_s,accel_g\n0,0\n0.01,0.5\n0.02,-0.5\n0.05,0\n")  # another record, still valid
    outcome = run_plan(plan, tmp_path / "out", plots=False)
    assert outcome.result.status == "failed" and outcome.result.steps_done == 0
    text = str(outcome.result.error)
    assert "changed between the checks and the units' initialization" in text and str(record.resolve()) in text
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["complete"] is False


def test_a_record_rewritten_after_the_units_read_it_keeps_the_hash_of_what_was_played(record, tmp_path, monkeypatch):
    plan = _plan(record)
    original = _digest(record.read_bytes())
    check = plan.changed_inputs

    def check_then_rewrite() -> list[str]:  # the units have read the record: a later rewrite changes nothing played
        found = check()
        record.write_text("time_s,accel_g\n0,0\n0.01,9\n")
        return found

    monkeypatch.setattr(plan, "changed_inputs", check_then_rewrite)
    outcome = run_plan(plan, tmp_path / "out", plots=False)
    assert outcome.result.complete
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert manifest["data_files"]["ground.record"]["sha256"] == original != _digest(record.read_bytes())


def test_an_fmu_replaced_by_another_valid_fmu_after_the_checks_fails_the_run(tmp_path):
    fmu = tmp_path / "iso.fmu"
    shutil.copy(PROJECT / "fmus" / "MreIsolator.fmu", fmu)
    plan = plan_scenario(PROJECT / "scenarios" / "elcentro.yaml", (SHORT, f"units.isolator.fmu={fmu}"))
    with zipfile.ZipFile(fmu, "a") as z:  # still an FMU that loads, but not the one checked
        z.writestr("resources/extra.txt", "changed")
    outcome = run_plan(plan, tmp_path / "out", plots=False)
    assert outcome.result.status == "failed" and str(fmu) in str(outcome.result.error)
    assert "SHA-256" in str(outcome.result.error)


def test_a_plan_moved_to_other_copies_checks_only_the_inputs_it_knows(record, tmp_path):
    """A batch worker runs a plan whose files are content-addressed copies (checked by their SHA-256 when copied):
    the client's paths are not what it reads, so they are not checked there."""
    from dataclasses import replace

    plan = _plan(record)
    copy = tmp_path / "copy.csv"
    shutil.copy(record, copy)
    moved = replace(plan, data_files={"ground.record": copy})
    record.write_text("changed on the client after the plan was sent\n")
    assert moved.changed_inputs() == []
    assert [text.split(" ")[0] for text in plan.changed_inputs()] == [str(record.resolve())]
