"""examples/first_hour.ipynb runs from top to bottom in a fresh kernel and writes what it says it writes."""

from __future__ import annotations

import csv
import json

import pytest

from ..conftest import PROJECT

pytestmark = pytest.mark.slow  # a whole Kobe run, three 20 s runs and a small Dask study: about a minute

NOTEBOOK = PROJECT / "examples" / "first_hour.ipynb"


def test_first_hour_notebook_runs(tmp_path, monkeypatch):
    nbformat = pytest.importorskip("nbformat", reason="the test extra: pip install -e '.[test]'")
    nbclient = pytest.importorskip("nbclient", reason="the test extra: pip install -e '.[test]'")
    out = tmp_path / "out"
    monkeypatch.setenv("MRE_COSIM_NOTEBOOK_OUT", str(out))  # the kernel inherits the environment
    nb = nbformat.read(NOTEBOOK, as_version=4)
    elsewhere = tmp_path / "elsewhere"  # a kernel started outside the project: it finds the project all the same
    elsewhere.mkdir()
    nbclient.NotebookClient(nb, timeout=900, kernel_name="python3",
                            resources={"metadata": {"path": str(elsewhere)}}).execute()

    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", []) if o.output_type == "error"]
    assert not errors
    figures = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
               if "image/png" in o.get("data", {})]
    assert len(figures) == 3  # time histories, hysteresis, the swapped controllers

    kobe = json.loads((out / "kobe-sosm" / "summary.json").read_text())
    assert kobe["complete"] and kobe["end_time_s"] == 150.0  # the whole record, not a shortened one
    assert (out / "kobe-sosm" / "timeseries.csv").is_file()

    for current in (0, 3):  # the swapped unit holds the current it was given, for the whole 20 s
        summary = json.loads((out / f"elcentro-{current}A" / "summary.json").read_text())
        assert summary["complete"] and summary["end_time_s"] == 20.0
        assert summary["peak_current_A"] == current and summary["mean_current_A"] == current

    with open(out / "study" / "peaks.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert sorted((r["record"], r["strategy"]) for r in rows) == sorted(
        (record, strategy) for record in ("elcentro", "kobe") for strategy in ("passive-off", "passive-on", "sosm"))
    printed = "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", []))
    assert "exit code 0" in printed
