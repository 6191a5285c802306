"""``simulation.output_interval`` and ``simulation.output_format``: smaller results files, the same summary.

The reference is the same run at every step in CSV: the decimated file's rows are its rows (every n-th and the
last), the Parquet values its values to float32, and summary.json's peaks and statistics are identical (they
come from every step either way). Bad values are exit 2 naming the key. A study's runs take them too (their
numbers come from every step, in the run): tests/studies/test_study_outputs.py.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from orchestration.run import main as run_main

from ..conftest import PROJECT

SCENARIO = PROJECT / "scenarios" / "elcentro.yaml"
SHORT = ("--set", "simulation.stop_time=1.237", "--no-plots")  # 1237 steps: the last row is off the interval


def _run(out: Path, *sets: str) -> Path:
    assert run_main([str(SCENARIO), *SHORT, *sets, "--out", str(out)]) == 0
    return out


def _csv(path: Path) -> tuple[list[str], np.ndarray]:
    with open(path) as f:
        rows = list(csv.reader(f))
    return rows[0], np.array(rows[1:], dtype=float)


def _same_summary(a: Path, b: Path) -> None:
    sa, sb = (json.loads((p / "summary.json").read_text()) for p in (a, b))
    skip = {"run_id", "wall_time_s", "results_file", "executor", "executor_note"}
    assert {k: v for k, v in sa.items() if k not in skip} == {k: v for k, v in sb.items() if k not in skip}


@pytest.fixture(scope="module")
def full(tmp_path_factory) -> Path:
    return _run(tmp_path_factory.mktemp("full") / "run")


def test_every_nth_row_and_the_last_in_csv(full, tmp_path):
    dec = _run(tmp_path / "dec", "--set", "simulation.output_interval=10")
    names, every = _csv(full / "timeseries.csv")
    names10, some = _csv(dec / "timeseries.csv")
    assert names10 == names
    assert len(every) == 1238
    rows = [*range(0, 1238, 10), 1237]
    assert np.array_equal(some, every[rows])  # the same printed digits: the same rows
    summary = json.loads((dec / "summary.json").read_text())
    assert summary["results_file"] == {"file": "timeseries.csv", "every_nth_step": 10, "rows": len(rows)}
    _same_summary(full, dec)


def test_parquet_holds_the_rows_as_float32_and_time_as_float64(full, tmp_path):
    dec = _run(tmp_path / "pq", "--set", "simulation.output_interval=10", "--set", "simulation.output_format=parquet")
    assert not (dec / "timeseries.csv").exists()
    table = pq.read_table(dec / "timeseries.parquet")
    names, every = _csv(full / "timeseries.csv")
    assert table.column_names == names
    rows = [*range(0, 1238, 10), 1237]
    assert str(table.schema.field("time").type) == "double"
    assert np.allclose(table.column("time").to_numpy(), every[rows, 0], rtol=1e-12, atol=0)  # CSV: 12 digits
    for k, name in enumerate(names[1:], 1):
        assert str(table.schema.field(name).type) == "float"
        # the CSV's 12 digits cast to float32 give the float32 of the value itself, to its last bit
        expected = every[rows, k].astype(np.float32)
        got = table.column(name).to_numpy()
        assert np.all(np.abs(got - expected) <= np.spacing(np.abs(expected))), name
    _same_summary(full, dec)


def test_a_run_asked_for_no_results_file_writes_none_and_records_every_step(full, tmp_path):
    """``run_plan(..., results_file=False)`` (a study's run without ``timeseries: true``): no timeseries.*, the same
    summary, and the recorder still holds every step, as the full CSV has it (12 significant digits)."""
    from orchestration.building_studies.run_metrics import recorded_series
    from orchestration.engine_hooks import plan_scenario
    from orchestration.master.session import run_plan

    plan = plan_scenario(SCENARIO, ("simulation.stop_time=1.237",))
    outcome = run_plan(plan, tmp_path / "none", plots=False, results_file=False)
    assert outcome.result.complete
    assert not list((tmp_path / "none").glob("timeseries*")) and not list((tmp_path / "none").glob("*.png"))
    summary = json.loads((tmp_path / "none" / "summary.json").read_text())
    assert summary["results_file"] == {"file": None, "every_nth_step": 1, "rows": 0}
    _same_summary(full, tmp_path / "none")
    names, every = _csv(full / "timeseries.csv")
    series = recorded_series(outcome.recorder)
    assert list(series) == names
    for k, name in enumerate(names):
        assert np.allclose(series[name], every[:, k], rtol=1e-11, atol=1e-300), name


@pytest.mark.parametrize(("value", "expected"), [
    ("0", "simulation.output_interval"), ("-3", "simulation.output_interval"),
    ("1.5", "simulation.output_interval"), ("'10'", "simulation.output_interval"),
    ("true", "simulation.output_interval")])
def test_an_interval_that_is_not_a_positive_whole_number_is_exit_2(tmp_path, capsys, value, expected):
    assert run_main([str(SCENARIO), *SHORT, "--set", f"simulation.output_interval={value}",
                     "--out", str(tmp_path / "never")]) == 2
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err
    assert not (tmp_path / "never").exists()


def test_an_unknown_format_is_exit_2(tmp_path, capsys):
    assert run_main([str(SCENARIO), *SHORT, "--set", "simulation.output_format=hdf5",
                     "--out", str(tmp_path / "never")]) == 2
    assert "simulation.output_format" in capsys.readouterr().err


@pytest.mark.slow
def test_kobe_at_every_tenth_step_in_parquet_is_under_2_mb_with_the_same_peaks(tmp_path):
    """The issue's measure: the Kobe quick start (150 s, 32 recorded variables; 64 MB of CSV at every step)."""
    kobe = PROJECT / "scenarios" / "kobe.yaml"
    for name, sets in (("full", ()), ("small", ("--set", "simulation.output_interval=10", "--set",
                                                   "simulation.output_format=parquet"))):
        assert run_main([str(kobe), "--no-plots", *sets, "--out", str(tmp_path / name)]) == 0
    size = (tmp_path / "small" / "timeseries.parquet").stat().st_size
    assert size < 2_000_000, size
    assert (tmp_path / "full" / "timeseries.csv").stat().st_size > 30 * size
    _same_summary(tmp_path / "full", tmp_path / "small")
