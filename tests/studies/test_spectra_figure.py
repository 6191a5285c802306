"""Response spectra of a study's records as the runs play them, with the building's periods marked."""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
from scipy.signal import lsim

from components.physics.ground_motion_core import read_record
from orchestration.case_study.case_figures import run_periods
from orchestration.ida_study import ida_figures
from orchestration.ida_study.intensity import measure
from orchestration.ida_study.suites import record_csv
from orchestration.spectrum_figure import spectrum

from ..conftest import RECORDS


def test_spectrum_of_a_scaled_and_time_scaled_record_equals_an_independent_sdof_solution():
    """PSa of the record played at amplitude x0.5 and time x0.2 against scipy's lsim of the SDOF on that signal."""
    rec = read_record(RECORDS / "elcentro_1940_ns.csv")
    n = 1500  # the first 30 s at 0.02 s, played as 6 s
    t, ag = rec.time[:n], rec.accel_g[:n]
    periods = np.array([0.2, 0.84])
    got = spectrum(t, ag, 0.5, 0.2, periods)
    for period, value in zip(periods, got, strict=True):
        w = 2 * math.pi / period
        _, u, _ = lsim(([-1.0], [1.0, 2 * 0.05 * w, w * w]), 0.5 * ag, 0.2 * (t - t[0]), interp=True)
        assert abs(value / (w * w * np.max(np.abs(u))) - 1) < 1e-6  # both exact for linear interpolation


def ida_info(tmp_path, period: float, level: float):
    """An IDA folder's records and the parts of its ida.json the spectra figure reads (two shipped records)."""
    records = tmp_path / "records"
    records.mkdir()
    components = []
    for name in ("elcentro_1940_ns", "kobe_1995_jma_ns"):
        rec = read_record(RECORDS / f"{name}.csv")
        (records / f"{name}.csv").write_text(record_csv(rec, name))
        components.append(SimpleNamespace(id=name, im=measure(rec, "sa", 0.2, period)))
    config = {"intensity": {"levels": [level], "damping": 0.05}, "time_scale": 0.2}
    return SimpleNamespace(config=config, components=components, period_s=period, measure="sa"), records


def test_ida_spectra_pass_through_the_level_at_t1(tmp_path, monkeypatch):
    """Each component is drawn as the runs play it: scaled so that its Sa(T1) is the first level."""
    info, records = ida_info(tmp_path, 0.84, 0.06)
    drawn = {}
    monkeypatch.setattr(ida_figures, "_save", lambda fig, path, files: drawn.setdefault("fig", fig))
    assert ida_figures.spectra_figure(tmp_path / "spectra.png", info, records)
    ax = drawn["fig"].axes[0]
    assert any(line.get_label().startswith("T1 (isolated) = 0.84") for line in ax.get_lines())
    for c in info.components:  # the figure's own scaling, at T1 itself
        rec = read_record(records / f"{c.id}.csv")
        assert abs(spectrum(rec.time, rec.accel_g, 0.06 / c.im, 0.2, np.array([0.84]))[0] - 0.06) < 1e-12


def test_ida_spectra_are_skipped_when_the_records_are_not_there(tmp_path):
    info, records = ida_info(tmp_path, 0.84, 0.06)
    (records / "kobe_1995_jma_ns.csv").unlink()
    assert not ida_figures.spectra_figure(tmp_path / "spectra.png", info, records)
    assert not (tmp_path / "spectra.png").exists()


def test_case_study_marks_the_periods_its_runs_report(tmp_path):
    study = SimpleNamespace(runs=[SimpleNamespace(folder="runs/a"), SimpleNamespace(folder="runs/b")])
    assert run_periods(tmp_path, study) == {}  # no run folder: no mark, no error
    (tmp_path / "runs" / "b").mkdir(parents=True)
    (tmp_path / "runs" / "b" / "summary.json").write_text(json.dumps(
        {"periods": {"isolated_0A_s": 0.84, "isolated_i_max_s": 0.21, "i_max_A": 3.0}}))
    assert run_periods(tmp_path, study) == {"T1 at 0 A": 0.84, "T1 at 3 A": 0.21}
