"""The Python API (orchestration.api): the example of docs/running.md runs, results equal the run folder."""

from __future__ import annotations

import csv
import json
import logging
import re

import numpy as np
import pytest

from orchestration.api import Results, ScenarioError, load_scenario, run

from ..conftest import PROJECT

EL_CENTRO_X3 = (PROJECT / "scenarios" / "elcentro.yaml", ["simulation.stop_time=2", "ground.scale=3"])


def run_keeping_unit_records(tmp_path, level: int) -> tuple[Results, list[logging.LogRecord]]:
    """El Centro x3 for 2 s through the API, with the records the ``mre_cosim.units`` logger gets at ``level``."""
    records: list[logging.LogRecord] = []

    class Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            records.append(record)

    logger, keep = logging.getLogger("mre_cosim.units"), Keep(level)
    logger.addHandler(keep)
    try:
        return run(load_scenario(*EL_CENTRO_X3), out=tmp_path / "run"), records
    finally:
        logger.removeHandler(keep)


def docs_example() -> str:
    text = (PROJECT / "docs" / "running.md").read_text()
    section = text[text.index("## Python API"):]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_the_docs_example_runs(tmp_path, monkeypatch, capsys):
    code = docs_example()
    # shorter records and a temporary results folder; the code is otherwise the doc's
    code = code.replace("simulation.stop_time=20", "simulation.stop_time=1").replace('"runs/', f'"{tmp_path}/')
    monkeypatch.chdir(PROJECT)
    exec(compile(code, "docs/running.md", "exec"), {})
    printed = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in printed] == ["SOSM", "3"]
    assert all(" True " in line for line in printed)
    assert (tmp_path / "kobe-sosm-20s" / "summary.json").is_file()


def test_results_are_the_run_folders_time_series(tmp_path):
    plan = load_scenario(PROJECT / "scenarios" / "elcentro.yaml", ["simulation.stop_time=0.5"])
    res = run(plan, out=tmp_path / "run")
    assert isinstance(res, Results) and res.complete and res.error is None
    with open(res.folder / "timeseries.csv") as f:
        rows = list(csv.reader(f))
    header, values = rows[0], np.array(rows[1:], dtype=float)
    assert header == ["time", *res]
    # the CSV is written with 12 significant digits: equal to that precision
    np.testing.assert_allclose(values[:, 0], res.time, rtol=1e-11, atol=0)
    for k, name in enumerate(res, start=1):
        np.testing.assert_allclose(values[:, k], res[name], rtol=1e-11, atol=1e-300)
    assert res.time[-1] == 0.5 and len(res.time) == 501
    assert res.summary["complete"] is True
    with pytest.raises(KeyError, match="was not recorded"):
        res["building.nothing"]


def test_a_bad_scenario_raises_every_problem(tmp_path):
    with pytest.raises(ScenarioError) as info:
        load_scenario(PROJECT / "scenarios" / "elcentro.yaml", ["simulation.stop_tme=1", "report.drift=1"])
    messages = {p.key: p.message for p in info.value.problems}
    assert messages == {"simulation.stop_tme": "unknown key (did you mean 'stop_time' or 'start_time'?)",
                        "report.drift": "unknown key (did you mean 'drifts' or 'drift_unit'?)"}


def test_unit_messages_reach_logging_and_the_api_prints_nothing(tmp_path, capsys):
    # El Centro ×3 drives the base beyond the isolator's identified ±8 mm within 2 s: the
    # isolator warns. Through the API nothing is printed; each warning reaches a handler of
    # the "mre_cosim.units" logger, the same messages the run folder's manifest keeps.
    res, records = run_keeping_unit_records(tmp_path, logging.DEBUG)
    assert res.complete
    captured = capsys.readouterr()
    assert captured.err == "" and captured.out == ""
    manifest = json.loads((res.folder / "manifest.json").read_text())
    warned = [m for m in manifest["unit_messages"] if "] warning: " in m]
    assert len(warned) == res.summary["unit_warnings"]["isolator"] > 0
    shown = [r for r in records if r.levelno == logging.WARNING]
    assert [r.getMessage() for r in shown] == warned
    assert all((r.unit, r.fmi_status) == ("isolator", "warning") for r in shown)


def test_warnings_beyond_those_shown_say_where_the_rest_are(tmp_path, monkeypatch):
    from orchestration.master import session

    monkeypatch.setattr(session, "WARNINGS_SHOWN", 1)
    res, records = run_keeping_unit_records(tmp_path, logging.WARNING)
    warned = [m for m in json.loads((res.folder / "manifest.json").read_text())["unit_messages"] if "] warning: " in m]
    assert len(warned) >= 2  # more than the one shown
    shown = [r.getMessage() for r in records]
    assert shown[0] == warned[0] and len(shown) == 2
    assert "the rest are not shown here" in shown[1] and "manifest.json" in shown[1]


def test_a_passive_current_beyond_the_limit_is_said_with_the_current_held(tmp_path):
    plan = load_scenario(PROJECT / "scenarios" / "kobe.yaml", ["simulation.stop_time=0.01", "controller.mode=passive",
                                                                "controller.i_passive=5"])
    res = run(plan, out=tmp_path / "run")
    assert res.complete and res.summary["peak_current_A"] == 3.0  # clipped to i_max
    messages = json.loads((res.folder / "manifest.json").read_text())["unit_messages"]
    warned = [m for m in messages if "i_passive" in m]
    assert warned == ["[controller] warning: i_passive = 5 A is outside [0, i_max = 3 A]: the current is held at 3 A"]


def test_the_command_line_prints_the_unit_warnings(tmp_path, capsys):
    from orchestration import run as run_tool

    argv = [str(PROJECT / "scenarios" / "elcentro.yaml"), "--set", "simulation.stop_time=2", "--set",
            "ground.scale=3", "--out", str(tmp_path / "run"), "--quiet", "--no-plots"]
    assert run_tool.main(argv) == 0
    manifest = json.loads((tmp_path / "run" / "manifest.json").read_text())
    warned = [m for m in manifest["unit_messages"] if "] warning: " in m]
    assert warned and capsys.readouterr().err.splitlines() == warned


def test_a_run_without_a_c_compiler_says_it_ran_the_slower_way(tmp_path):
    import os
    import subprocess
    import sys

    env = {**os.environ, "CC": str(tmp_path / "no-such-compiler"), "MRE_COSIM_CACHE": str(tmp_path / "cache")}
    done = subprocess.run([sys.executable, str(PROJECT / "orchestration" / "run.py"), str(PROJECT / "scenarios" /
                           "kobe.yaml"), "--set", "simulation.stop_time=0.05", "--out", str(tmp_path / "run"),
                           "--quiet", "--no-plots"], capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "the master's C loop was not used" in done.stderr and "no-such-compiler" in done.stderr, done.stderr
    assert "peaks: storey drift" in done.stdout
