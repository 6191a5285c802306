"""What a study keeps of its runs: the numbers each run computed from its every step (``metrics.json``), the few
series its figures draw, and its time series only when asked (``timeseries: true``, at the runs'
``simulation.output_interval`` and ``output_format``).

The independent expectation is the run's own every-step time series: the same study with ``timeseries: true`` at
every step in CSV, whose columns give the numbers through the functions a report used to apply to them. A
decimated or float32 results file must change no number of any table.
"""

from __future__ import annotations

import csv
import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from orchestration.building_studies.run_metrics import read_timeseries
from orchestration.case_study.run_numbers import (
    FIGURE_ROWS,
    FIGURE_SERIES_FILE,
    NUMBERS_FILE,
    NumberInputs,
    figure_rows,
    numbers_json,
    read_numbers,
    run_numbers,
)

from ..conftest import PROJECT

CLI = [sys.executable, str(PROJECT / "orchestration" / "study.py")]
MASSES = [6.0 * 98.3, 98.3, 98.3, 98.3]  # not used by a run: only by the unit tests' synthetic series


def _study(tmp: Path, name: str, *lines: str) -> Path:
    path = tmp / f"{name}.yaml"
    path.write_text(f"extends: {PROJECT / 'scenarios' / 'controller_benchmark.yaml'}\nname: {name}\n"
                    f"records: {{elcentro: {PROJECT / 'scenarios' / 'nominal_plant_elcentro.yaml'}}}\n"
                    "strategies: [passive-off, passive-on, sosm]\nreference: {enabled: false}\n" + "\n".join(lines)
                    + "\n")
    return path


def _run(study: Path, out: Path, *extra: str) -> None:
    done = subprocess.run([*CLI, str(study), "--out", str(out), "--quiet", *extra], capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr


def _rows(path: Path) -> dict[tuple[str, str], dict[str, str]]:
    with open(path) as f:
        return {(r["record"], r["strategy"]): r for r in csv.DictReader(f)}


def _close(a: dict[tuple[str, str], dict[str, str]], b: dict[tuple[str, str], dict[str, str]], rel: float) -> None:
    assert a.keys() == b.keys()
    for key, row in a.items():
        for column, text in row.items():
            try:
                x, y = float(text), float(b[key][column])
            except ValueError:
                assert text == b[key][column], (key, column)
                continue
            assert (math.isnan(x) and math.isnan(y)) or x == pytest.approx(y, rel=rel, abs=1e-300), (key, column)


@pytest.fixture(scope="module")
def studies(tmp_path_factory) -> dict[str, Path]:
    """The same 2 s benchmark three ways: every step in CSV kept; every 10th step in Parquet kept; none kept."""
    tmp = tmp_path_factory.mktemp("outputs")
    runs = {"csv": ("overrides: [simulation.stop_time=2]", "timeseries: true"),
            "parquet": ("overrides: [simulation.stop_time=2, simulation.output_interval=10, "
                        "simulation.output_format=parquet]", "timeseries: true"),
            "none": ("overrides: [simulation.stop_time=2]",)}
    out = {}
    for name, lines in runs.items():
        out[name] = tmp / name
        _run(_study(tmp, name, *lines), out[name])
    return out


@pytest.mark.slow
def test_the_tables_do_not_depend_on_what_the_runs_keep(studies):
    """Every number of peaks.csv, indices.csv and criteria.csv is the same whether the runs keep every step in CSV,
    every 10th in float32 Parquet, or nothing: the numbers come from every step, in the run."""
    for table in ("peaks.csv", "indices.csv", "criteria.csv", "criteria_passive-on.csv"):
        full = _rows(studies["csv"] / table)
        for other in ("parquet", "none"):
            assert _rows(studies[other] / table) == full, (table, other)  # the same digits: the same numbers


@pytest.mark.slow
def test_each_run_keeps_what_was_asked(studies):
    run = "runs/elcentro-sosm"
    assert (studies["csv"] / run / "timeseries.csv").is_file()
    kept = pq.read_table(studies["parquet"] / run / "timeseries.parquet")
    assert kept.num_rows == len(range(0, 8001, 10))  # 2 s at 0.25 ms: every 10th of 8001 rows (the last is one)
    summary = json.loads((studies["none"] / run / "summary.json").read_text())
    assert summary["results_file"] == {"file": None, "every_nth_step": 1, "rows": 0}
    assert sorted(p.name for p in (studies["none"] / run).iterdir() if not p.name.startswith(".")) == [
        FIGURE_SERIES_FILE, "manifest.json", NUMBERS_FILE, "summary.json"]
    none = sum(p.stat().st_size for p in (studies["none"] / "runs").rglob("*") if p.is_file())
    every = sum(p.stat().st_size for p in (studies["csv"] / "runs").rglob("*") if p.is_file())
    assert none < every / 5  # the time series were most of a study's bytes


@pytest.mark.slow
def test_the_numbers_are_those_of_the_runs_every_step(studies):
    """metrics.json equals the numbers computed from the run's own every-step CSV (12 significant digits), and the
    figure series holds the run's rows (every step here: 8001 rows is below FIGURE_ROWS) to float32."""
    folder = studies["csv"]
    doc = json.loads((folder / "study.json").read_text())
    for entry in doc["runs"]:
        run = folder / entry["folder"]
        summary = json.loads((run / "summary.json").read_text())
        series = read_timeseries(run / "timeseries.csv")
        info = doc["records"][entry["record"]]
        gains = doc["gain_sets"].get(entry["strategy"], {}).get("gains")
        inputs = NumberInputs(info["masses_kg"], 3.0, (0.0, 2.5), gains, info["n_isolators"] or 2)
        expected = run_numbers(series, summary.get("energy"), inputs)
        got = json.loads((run / NUMBERS_FILE).read_text())
        assert got["rows"] == expected["rows"] == 8001
        for part in ("metrics", "criteria", "sosm_conditions"):
            if expected[part] is None:
                assert got[part] is None and entry["strategy"] != "sosm"
                continue
            for k, v in expected[part].items():
                if isinstance(v, bool):
                    assert got[part][k] is v, (part, k)
                elif math.isfinite(v):
                    assert got[part][k] == pytest.approx(v, rel=1e-9, abs=1e-12), (entry["key"], part, k)
                else:
                    assert got[part][k] is None
        drawn = read_timeseries(run / FIGURE_SERIES_FILE)
        assert len(drawn["time"]) == 8001
        for name in ("building.x_0", "isolator.F", "controller.i"):
            assert np.allclose(drawn[name], series[name].astype(np.float32), rtol=1e-6, atol=1e-9), name
        assert np.allclose(drawn["building.a_top"], series["building.a_3"].astype(np.float32), rtol=1e-6, atol=1e-9)


@pytest.mark.slow
def test_a_folder_without_the_runs_numbers_is_reported_from_its_time_series(studies, tmp_path):
    """A study folder written before runs kept their numbers (no metrics.json, every step in timeseries.csv):
    --report computes them from the CSV, to the tables' digits."""
    old = tmp_path / "old"
    shutil.copytree(studies["csv"], old)
    for path in old.rglob(NUMBERS_FILE):
        path.unlink()
    for path in old.rglob(FIGURE_SERIES_FILE):
        path.unlink()
    done = subprocess.run([*CLI, "--report", str(old)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    for table in ("peaks.csv", "indices.csv", "criteria.csv"):
        _close(_rows(old / table), _rows(studies["csv"] / table), rel=1e-9)
    assert (old / "figures" / "fig16_top_acceleration.png").stat().st_size > 0  # drawn from timeseries.csv


def test_the_figure_series_keeps_at_most_its_rows_and_the_first():
    for count in (1, 2, 8001, FIGURE_ROWS, FIGURE_ROWS + 1, 150_001, 10**7):
        rows = range(count)[figure_rows(count)]
        assert 0 < len(rows) <= FIGURE_ROWS and rows[0] == 0
        assert rows.step == 1 or len(range(count)[slice(0, count, rows.step - 1)]) > FIGURE_ROWS  # the smallest k


def test_numbers_round_trip_through_strict_json_with_nan_as_null(tmp_path):
    t = np.linspace(0.0, 1.0, 1001)
    x = 0.004 * np.sin(2 * np.pi * t)
    series = {"time": t, "building.x_0": x, "building.v_0": np.gradient(x, t), "isolator.F": 1e5 * x,
              "controller.i": np.clip(3 * np.sin(2 * np.pi * t), 0, 3), "building.shear_1": 2e4 * x}
    for j in range(4):
        series[f"building.a_{j}"] = (j + 1) * np.sin(2 * np.pi * t)
    for j in range(1, 4):
        series[f"building.drift_{j}"] = x / (j + 1)
    numbers = run_numbers(series, None, NumberInputs(MASSES, 3.0, (0.0, 2.5)))
    assert math.isnan(numbers["criteria"]["J6"]) and math.isnan(numbers["criteria"]["J9"])  # no F_off, no energy
    (tmp_path / NUMBERS_FILE).write_text(numbers_json(numbers))
    json.loads((tmp_path / NUMBERS_FILE).read_text(), parse_constant=lambda c: pytest.fail(f"not strict: {c}"))
    back = read_numbers(tmp_path, NumberInputs(MASSES, 3.0, (0.0, 2.5)), None)
    assert math.isnan(back["criteria"]["J6"]) and back["sosm_conditions"] is None
    assert back["metrics"] == pytest.approx({k: v for k, v in numbers["metrics"].items()}, nan_ok=True)
    assert back["metrics"]["x_base_mm"] == pytest.approx(4.0, rel=1e-6)  # the hand value: 4 mm amplitude
    assert back["metrics"]["current_share_at_limit"] == pytest.approx(np.mean(series["controller.i"] >= 3 - 1e-6))
    assert read_numbers(tmp_path / "nothing", NumberInputs(MASSES, 3.0, (0.0, 2.5)), None) is None


@pytest.mark.parametrize(("text", "says"), [
    ("{nope", "not JSON"), ("[1]", "a JSON list"), ('{"metrics": [1], "criteria": {}}', "'metrics' is not a mapping"),
    ('{"metrics": {"acc_3": "x"}, "criteria": {}}', "metrics.acc_3 = 'x' is not a number"),
    ('{"metrics": {"acc_3": true}, "criteria": {}}', "metrics.acc_3 = True is not a number"),
    ('{"metrics": {"acc_3": 1.0}, "criteria": {}}', "metrics has no x_base_mm"),
])
def test_a_damaged_metrics_file_is_named_not_read(tmp_path, text, says):
    """A run's metrics.json that is not what a run wrote: RunFileError naming the file (study.py --report: exit 2,
    nothing written; reliability corpus class 45/run files)."""
    from orchestration.case_study.run_numbers import RunFileError

    (tmp_path / NUMBERS_FILE).write_text(text)
    with pytest.raises(RunFileError) as err:
        read_numbers(tmp_path, NumberInputs(MASSES, 3.0, (0.0, 2.5)), None)
    assert says in str(err.value) and str(tmp_path / NUMBERS_FILE) in str(err.value)
    (tmp_path / NUMBERS_FILE).unlink()
    (tmp_path / NUMBERS_FILE).mkdir()
    with pytest.raises(RunFileError, match="is a folder"):
        read_numbers(tmp_path, NumberInputs(MASSES, 3.0, (0.0, 2.5)), None)
