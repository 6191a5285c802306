"""``mre-cosim compare``: the peaks of two runs against their own recorded histories, the overlays, bad input.

Two short El Centro runs (SOSM, passive at 0 A) through run.py. Every peak the table prints is checked against
the largest |value| of that run's timeseries.csv, which records every step here (an independent read of the
history, not of summary.json).
"""

from __future__ import annotations

import csv
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from orchestration.compare import main
from orchestration.run_comparison import ROLES

from ..conftest import PROJECT

RUN = [sys.executable, str(PROJECT / "orchestration" / "run.py"), str(PROJECT / "scenarios" / "elcentro.yaml"),
       "--set", "simulation.stop_time=2.5", "--no-plots"]


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> tuple[Path, Path, Path]:
    """SOSM, passive at 0 A, and passive at 0 A recording fewer variables (one drift, the top floor's acceleration:
    the master records the report's roles besides ``outputs``)."""
    root = tmp_path_factory.mktemp("compare")
    sets = {"sosm": [], "off": ["--set", "controller.mode=passive", "--set", "controller.i_passive=0"],
            "few": ["--set", "controller.mode=passive", "--set", "controller.i_passive=0",
                    "--set", "outputs=[building.x_0, controller.i]", "--set", "report.drifts=[building.drift_1]",
                    "--set", "report.floor_accelerations=[building.a_3]"]}
    for name, extra in sets.items():
        done = subprocess.run([*RUN, *extra, "--out", str(root / name)], capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr
    return root / "sosm", root / "off", root / "few"


def _history_peaks(folder: Path) -> dict[str, float]:
    with open(folder / "timeseries.csv") as f:
        rows = list(csv.reader(f))
    data = np.array(rows[1:], dtype=float)
    return {name: float(np.max(np.abs(data[:, k]))) for k, name in enumerate(rows[0])}


def test_the_table_holds_each_runs_peaks_and_the_change(runs, capsys):
    sosm, off, _ = runs
    assert main([str(sosm), str(off)]) == 0
    out = capsys.readouterr().out
    factor = {role: f for role, *_, f in ROLES}
    role_of = {"building.x_0": "base_displacement", "building.drift_1": "drifts", "building.a_3": "floor_accelerations",
               "controller.i": "current", "isolator.F": "isolator_force", "ground.ag": "ground_acceleration"}
    a, b = _history_peaks(sosm), _history_peaks(off)
    lines = {line.split()[0]: line.split() for line in out.splitlines() if line.startswith(("building.", "controller.",
                                                                                          "isolator.", "ground."))}
    for var, role in role_of.items():
        cols = lines[var]
        pa, pb = float(cols[2]), float(cols[3])
        assert pa == pytest.approx(factor[role] * a[var], rel=1e-3)  # 4 significant digits printed
        assert pb == pytest.approx(factor[role] * b[var], rel=1e-3)
        if var != "controller.i":
            assert float(cols[4]) == pytest.approx(100 * (b[var] / a[var] - 1), abs=0.06)
    assert "[1] El Centro 1940 N-S ×0.5 · SOSM control" in out and "[2] El Centro 1940 N-S ×0.5 · passive, 0 A" in out
    assert lines["controller.i"][3] == "0" and lines["controller.i"][4] == "-100.0"


def test_the_files_are_the_table_and_one_overlay_per_role(runs, tmp_path, capsys):
    sosm, off, _ = runs
    out = tmp_path / "cmp"
    assert main([str(sosm), str(off), "--out", str(out), "--format", "svg", "pdf", "--dpi", "80"]) == 0
    names = sorted(p.name for p in out.iterdir())
    roles = ["base_displacement", "current", "drifts", "floor_accelerations", "ground_acceleration", "isolator_force"]
    assert names == sorted([*(f"{r}.{e}" for r in roles for e in ("png", "svg", "pdf")), "peaks.csv"])
    with open(out / "peaks.csv") as f:
        table = {r["variable"]: r for r in csv.DictReader(f)}
    assert float(table["building.x_0"][sosm.name]) == pytest.approx(1e3 * _history_peaks(sosm)["building.x_0"],
                                                                      rel=1e-9)
    svg = ET.parse(out / "floor_accelerations.svg").getroot()
    assert svg.tag.endswith("svg")
    lines = [e for e in svg.iter() if e.tag.endswith("path") and "stroke-dasharray" in (e.get("style") or "")]
    assert lines  # the second run's dashed lines (a line style per run)
    assert (out / "drifts.pdf").read_bytes().startswith(b"%PDF")


def test_runs_of_different_variables_compare_the_common_ones(runs, capsys):
    sosm, _, few = runs
    assert main([str(sosm), str(few)]) == 0
    out = capsys.readouterr().out
    compared = [line.split()[0] for line in out.splitlines() if line.startswith(("building.", "controller.",
                                                                                 "isolator.", "ground."))]
    assert compared == ["building.x_0", "building.drift_1", "building.a_3", "controller.i", "isolator.F", "ground.ag"]
    for var, what in (("building.drift_2", "storey drift"), ("building.a_0", "absolute floor acceleration")):
        assert f"not compared: {var} ({what}): not in {few.name}" in out


@pytest.mark.parametrize("case", ["not a run", "one run", "out not empty", "dpi"])
def test_bad_input_is_exit_2_and_writes_nothing(runs, tmp_path, capsys, case):
    sosm, off, _ = runs
    plain = tmp_path / "plain"
    plain.mkdir()
    out = tmp_path / "out"
    args = {"not a run": [str(sosm), str(plain), "--out", str(out)], "one run": [str(sosm)],
            "out not empty": [str(sosm), str(off), "--out", str(plain)],
            "dpi": [str(sosm), str(off), "--dpi", "0", "--out", str(out)]}[case]
    if case == "out not empty":
        (plain / "mine.txt").write_text("the user's")
    assert main(args) == 2
    err = capsys.readouterr().err
    expected = {"not a run": f"{plain}: no summary.json (not a run folder of run.py)",
                "one run": "give at least two run folders", "out not empty": "exists and is not an empty folder",
                "dpi": "--dpi 0: give 10 to 1200"}[case]
    assert expected in err and "Traceback" not in err
    assert not out.exists()
    if case == "out not empty":
        assert [p.name for p in plain.iterdir()] == ["mine.txt"]
