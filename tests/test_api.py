"""The Python API (orchestration.api): the README's example runs, results equal the run folder."""

from __future__ import annotations

import csv
import re

import numpy as np
import pytest

from orchestration.api import Results, ScenarioError, load_scenario, run

from .conftest import PROJECT


def readme_example() -> str:
    text = (PROJECT / "README.md").read_text()
    section = text[text.index("## Python API"):]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_the_readme_example_runs(tmp_path, monkeypatch, capsys):
    code = readme_example()
    # shorter records and a temporary results folder; the code is otherwise the README's
    code = code.replace("simulation.stop_time=20", "simulation.stop_time=1").replace('"runs/', f'"{tmp_path}/')
    monkeypatch.chdir(PROJECT)
    exec(compile(code, "README.md", "exec"), {})
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
                        "report.drift": "unknown key (did you mean 'drifts'?)"}
