"""The engine's one way to fork a run's helper (child_process), summary.json as a typed record, run.py's unit errors."""

from __future__ import annotations

import json
import math
import os
import signal
import sys
import time

import pytest

from orchestration.master.child_process import Child, ChildStalled, exit_text, read_all
from orchestration.master.runfolder import write_json
from orchestration.master.summary import RunSummary, VariableRange, write_summary

linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the helpers fork on Linux only")


def _summary() -> dict:
    return {
        "scenario": "s", "caption": "c", "complete": True, "status": "complete", "error": None, "run_id": "r",
        "end_time_s": 1.0, "steps_done": 10, "n_steps": 10, "wall_time_s": 0.5, "executor": "python",
        "executor_note": "no C compiler", "unit_warnings": {"a": 0},
        "results_file": {"file": "timeseries.csv", "every_nth_step": 1, "rows": 11},
        "valid": True, "invalid_reasons": [], "peak_x_m": 0.1, "energy": {"checked": True, "input_J": 2.0},
        "variables": {"a.x": {"max_abs": 0.1, "min": -0.1, "max": 0.05}},
    }


def test_a_summary_reads_back_as_the_same_keys_in_the_same_order():
    data = _summary()
    record = RunSummary.from_dict(data)
    assert record.report == {"peak_x_m": 0.1, "energy": {"checked": True, "input_J": 2.0}}
    assert record.variables == {"a.x": VariableRange(0.1, -0.1, 0.05)}
    assert record.to_dict() == data and list(record.to_dict()) == list(data)
    data["step_convergence"] = {"largest_change": 0.001}
    data["added_later"] = 1
    record = RunSummary.from_dict(data)
    assert record.step_convergence == {"largest_change": 0.001} and record.later == {"added_later": 1}
    assert list(record.to_dict()) == list(data)
    del data["executor_note"]
    assert list(RunSummary.from_dict(data).to_dict()) == list(data)


def test_the_summary_is_strict_json_a_non_finite_value_is_null_and_named(tmp_path):
    data = _summary()
    data["variables"]["a.x"]["max_abs"] = math.nan
    data["peak_x_m"] = -math.inf
    write_summary(tmp_path / "summary.json", data)
    write_json(tmp_path / "as_before.json", data)
    text = (tmp_path / "summary.json").read_text()
    assert text == (tmp_path / "as_before.json").read_text()  # the layout the readers know
    back = json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in strict JSON"))
    assert back["variables"]["a.x"]["max_abs"] is None and back["peak_x_m"] is None
    assert back["non_finite"] == {"peak_x_m": "infinite (-inf)", "variables.a.x.max_abs": "not a number (nan)"}
    again = RunSummary.read(tmp_path / "summary.json")
    assert again.non_finite == back["non_finite"] and again.to_json() == text


def test_a_summary_without_its_status_is_refused():
    data = _summary()
    del data["valid"]
    with pytest.raises(KeyError):
        RunSummary.from_dict(data)


def _echo(go: int) -> dict | None:
    text = read_all(go)
    return {"got": text.decode()} if text else None


@linux_only
def test_a_child_answers_in_json_and_a_cancelled_one_says_nothing():
    child = Child.fork(_echo, "failed")
    assert child.send("12") and child.send("34")
    child.close_go()
    assert child.answer() == {"got": "1234"} and child.reap() == 0 and child.pid == 0
    child = Child.fork(_echo, "failed")
    pid = child.pid
    child.cancel()
    with pytest.raises(ChildProcessError):
        os.waitpid(pid, os.WNOHANG)


def _raises(go: int) -> dict:
    raise ZeroDivisionError("a bug")


def _os_error(go: int) -> dict:
    raise FileNotFoundError(2, "No such file or directory")


def _dies(go: int) -> dict:
    os.kill(os.getpid(), signal.SIGKILL)
    return {}


@linux_only
def test_a_child_s_failure_is_its_answer_and_its_death_is_said_by_its_exit_status():
    child = Child.fork(_raises, "the work failed")
    answer = child.answer()
    assert answer["error"] == "the work failed (ZeroDivisionError: a bug)" and "Traceback" in answer["traceback"]
    child.reap()
    child = Child.fork(_os_error, "the work failed")
    assert child.answer() == {"error": "No such file or directory"}
    child.reap()
    child = Child.fork(_dies, "the work failed")
    assert child.answer() is None
    status = child.reap()
    assert exit_text(status) == "killed by SIGKILL" and exit_text(status, signal_number=True) == "killed by signal 9"
    assert exit_text(256) == "exit code 1"


def _sleeps(go: int) -> dict:
    time.sleep(30)
    return {}


@linux_only
def test_a_bounded_answer_kills_a_child_that_makes_no_progress_or_is_stopped():
    child = Child.fork(_sleeps, "failed")
    started = time.monotonic()
    with pytest.raises(ChildStalled, match="wrote nothing for 1 s"):
        child.answer(lambda: 0, stall_s=1.0)
    assert time.monotonic() - started < 10 and child.pid == 0
    child = Child.fork(_sleeps, "failed")
    os.kill(child.pid, signal.SIGSTOP)
    time.sleep(0.2)
    with pytest.raises(ChildStalled, match="was stopped") as caught:
        child.answer(lambda: time.monotonic(), stall_s=30.0)
    assert caught.value.pid > 0 and child.pid == 0


@linux_only
def test_a_full_pipe_drops_a_message_instead_of_blocking():
    child = Child.fork(_sleeps, "failed")
    try:
        sent = [child.send("x" * 4096) for _ in range(64)]  # more than a pipe holds
        assert sent[0] and not all(sent)
    finally:
        os.kill(child.pid, signal.SIGKILL)
        child.reap()


def test_run_py_shows_the_last_distinct_unit_errors():
    from orchestration.run import last_distinct

    said = ["[a] error: e1", "[a] error: e2", "[a] error: e1", "[a] error: e3", "[a] error: e4", "[a] error: e5",
            "[a] error: e6", "[b] fatal: f"]
    assert last_distinct(said) == ["[a] error: e3", "[a] error: e4", "[a] error: e5", "[a] error: e6", "[b] fatal: f"]
    assert last_distinct(said, 2) == ["[a] error: e6", "[b] fatal: f"]
