"""Case study (orchestration/study.py): a shortened study end to end, failures, indices, tuning."""

from __future__ import annotations

import csv
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from components.physics.sosm_controller_core import SosmGains
from components.physics.switching_controller_core import SwitchingLaw
from orchestration.batch.runner import Job, run_jobs
from orchestration.building_studies.gains_file import read_gains
from orchestration.building_studies.in_process_model import system_setup
from orchestration.building_studies.run_metrics import indices, run_metrics
from orchestration.building_studies.run_settings import run_overrides
from orchestration.case_study.case_config import ObjectiveSpec, TuningSpec, load_study
from orchestration.case_study.case_metrics import PEAK_TABLE_COLUMNS
from orchestration.case_study.objective import objective, peak_values
from orchestration.case_study.tuning import tune
from orchestration.engine_hooks import plan_scenario
from orchestration.inprocess import simulate_coupled

from ..conftest import PROJECT

STUDY = PROJECT / "scenarios" / "case_study.yaml"
CLI = [sys.executable, str(PROJECT / "orchestration" / "study.py")]
INDEX_HEADER = ["record", "strategy", "J1", "J2", "J3", "J4", "J5", "J7", "J8"]


def study_cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, *args], cwd=cwd, capture_output=True, text=True, timeout=240)


def read_csv(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with open(path) as f:
        rows = list(csv.reader(f))
    return rows[0], [dict(zip(rows[0], r, strict=True)) for r in rows[1:]]


@pytest.mark.slow
def test_shortened_study_end_to_end(tmp_path, elcentro):
    """First 3 s of two records, passive-off and both SOSM gain sets, with the Radau reference, through the CLI."""
    out = tmp_path / "study"
    proc = study_cli(str(STUDY), "--set", "overrides=[simulation.stop_time=3]",
                     "--set", "records={elcentro: elcentro.yaml, hachinohe: hachinohe.yaml}",
                     "--set", "strategies=[passive-off, sosm, sosm-fig15]", "--set", "timeseries=true",
                     "--out", str(out), "--quiet", "--verify", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "beyond the identified ±8 mm" in proc.stderr  # El Centro at 0 A goes beyond 8 mm in its first 3 s
    for name in ("peaks.csv", "indices.csv", "reference.csv", "report.md", "report.html", "study.json",
                 "figures/fig15_current.png", "figures/fig16_top_acceleration.png", "figures/fig17_profiles.png",
                 "figures/hysteresis_elcentro.png", "figures/hysteresis_hachinohe.png"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    assert not list(out.rglob(".*.tmp*")), "temporary files left behind"

    header, peaks = read_csv(out / "peaks.csv")
    assert header == list(PEAK_TABLE_COLUMNS)
    assert {(r["record"], r["strategy"]) for r in peaks} == {(r, s) for r in ("elcentro", "hachinohe")
                                                            for s in ("passive-off", "sosm", "sosm-fig15")}
    header, idx = read_csv(out / "indices.csv")
    assert header == INDEX_HEADER and len(idx) == 6
    for row in idx:
        if row["strategy"] == "passive-off":
            assert all(float(row[k]) == 1.0 for k in INDEX_HEADER[2:])

    gains, _ = read_gains(PROJECT / "scenarios" / "sosm_gains.yaml")
    study = json.loads((out / "study.json").read_text())
    assert study["gains"]["gains"]["lambda"] == gains.lam and study["gains"]["gains"]["zeta"] == gains.zeta
    for row in peaks:
        ts_path = out / "runs" / f"{row['record']}-{row['strategy']}" / "timeseries.csv"
        with open(ts_path) as f:
            names = next(csv.reader(f))
        data = np.loadtxt(ts_path, delimiter=",", skiprows=1)
        col = {n: data[:, k] for k, n in enumerate(names)}
        assert data[-1, 0] == pytest.approx(3.0)
        # Newton for the whole building: sum of m_j a_j over all levels is the isolator force (k_0 = c_0 = 0).
        assert float(row["base_shear_N"]) == pytest.approx(np.max(np.abs(col["isolator.F"])), rel=1e-6)
        i = col["controller.i"]
        if row["strategy"] == "passive-off":
            assert float(row["current_max_A"]) == 0.0 and np.all(i == 0.0)
        else:
            limit = 2.5 if row["strategy"] == "sosm-fig15" else 3.0  # the second gain set's own limit
            assert 0.0 <= i.min() and i.max() <= limit and float(row["current_mean_A"]) > 0.0

    # SOSM through the FMUs equals the in-process stepping of the same cores with the tuned gains.
    plan = plan_scenario(PROJECT / "scenarios" / "elcentro.yaml", ("simulation.stop_time=3",))
    sim = plan.loaded.scenario.simulation
    ref = simulate_coupled(system_setup(plan, None, gains), sim.step, sim.n_steps, sim.algorithm,
                           **({"inputs": sim.inputs} if hasattr(sim, "inputs") else {}))
    sosm = next(r for r in peaks if r["record"] == "elcentro" and r["strategy"] == "sosm")
    assert float(sosm["acc_3"]) == pytest.approx(np.max(np.abs(ref.a[:, 3])), rel=1e-6)
    assert float(sosm["x_base_mm"]) == pytest.approx(1e3 * np.max(np.abs(ref.x[:, 0])), rel=1e-6)

    # Passive-off against the monolithic Radau reference, within the study file's tolerance (25 %; docs/master.md).
    header, ref_rows = read_csv(out / "reference.csv")
    assert {r["record"] for r in ref_rows} == {"elcentro", "hachinohe"}
    assert all(abs(float(r["rel_error"])) < 0.25 for r in ref_rows)

    report = (out / "report.md").read_text()
    assert "## The paper's claims on our system" in report
    for record in ("elcentro", "hachinohe"):
        assert f"### {record}" in report
    assert "### elcentro (El Centro 1940 N-S)" in report  # the id, and the scenario's name of the record
    assert "**sosm** vs **passive-off**" in report and "**sosm** current:" in report
    assert "**sosm-fig15** vs **passive-off**" in report and "### Current statistics (Fig. 15)" in report
    assert "**amplitude reading**" in report
    assert (out / "figures" / "pareto.png").stat().st_size > 0  # from the second gain set's tuning evaluations
    html = (out / "report.html").read_text()
    assert html.count("data:image/png;base64,") == 7  # Fig. 15-17, pareto, 2 hysteresis, response spectra
    assert (out / "figures" / "spectra.png").stat().st_size > 0  # T1 from the runs' summary.json periods

    # Regenerating the report from the data gives the same tables.
    before = (out / "peaks.csv").read_text()
    (out / "peaks.csv").unlink()
    proc = study_cli("--report", str(out), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert (out / "peaks.csv").read_text() == before

    # Never overwrite a study folder.
    proc = study_cli(str(STUDY), "--set", "overrides=[simulation.stop_time=0.01]", "--out", str(out), cwd=tmp_path)
    assert proc.returncode == 2 and "not empty" in proc.stderr
    assert (out / "peaks.csv").read_text() == before


@pytest.mark.slow
def test_a_failed_run_does_not_lose_the_others(tmp_path):
    """One record's runs stop on a displacement limit; the other record's results are complete and reported."""
    bad = tmp_path / "bad.yaml"
    fmus = {u: {"fmu": str(PROJECT / "fmus" / f"{n}.fmu")} for u, n in (
        ("ground", "GroundMotionSource"), ("building", "ShearBuilding"), ("isolator", "MreIsolator"),
        ("controller", "SosmCurrentController"))}  # FMU paths are relative to the scenario file
    bad.write_text(f"extends: {PROJECT / 'scenarios' / 'hachinohe.yaml'}\n" + yaml.safe_dump(
        {"name": "bad", "units": fmus, "limits": {"max_abs": {"building.x_0": 0.0005}}}))
    spec = tmp_path / "study.yaml"
    spec.write_text(yaml.safe_dump({
        "name": "mini", "records": {"good": str(PROJECT / "scenarios" / "hachinohe.yaml"), "bad": str(bad)},
        "strategies": ["passive-off", "on-off"], "overrides": ["simulation.stop_time=2"],
        "reference": {"enabled": False}, "gains": "none.yaml", "timeseries": True}))
    out = tmp_path / "study"
    proc = study_cli(str(spec), "--out", str(out), "--quiet", cwd=tmp_path)
    assert proc.returncode == 1, proc.stderr
    _, peaks = read_csv(out / "peaks.csv")
    assert {(r["record"], r["strategy"]) for r in peaks} == {("good", "passive-off"), ("good", "on-off")}
    report = (out / "report.md").read_text()
    assert "## Failed runs" in report
    failed = [line for line in report.splitlines() if line.startswith("| bad/")]
    assert len(failed) == 2 and all("x_0" in line and "exceeds the limit" in line for line in failed)
    # the failed runs keep their partial results, marked incomplete
    summary = json.loads((out / "runs" / "bad-passive-off" / "summary.json").read_text())
    assert summary["complete"] is False
    # the on-off law through the master: i_max while the sampled base moves away from 0, else 0 (one step later)
    ts = out / "runs" / "good-on-off" / "timeseries.csv"
    with open(ts) as f:
        names = next(csv.reader(f))
    data = np.loadtxt(ts, delimiter=",", skiprows=1)
    x, v, i = (data[:, names.index(n)] for n in ("building.x_0", "building.v_0", "controller.i"))
    np.testing.assert_array_equal(i[1:], np.where(x[:-1] * v[:-1] > 0, 3.0, 0.0))
    assert 0 < np.mean(i) < 3.0


@pytest.mark.slow
def test_a_study_resumes_from_its_stored_jobs(tmp_path):
    """A finished study resumed computes nothing; a lost result is computed again, to the same numbers."""
    out = tmp_path / "study"
    args = ("--set", "overrides=[simulation.stop_time=1.5]", "--set", "records={kobe: kobe.yaml}",
            "--set", "strategies=[passive-off, on-off]", "--set", "reference={enabled: false}")
    env = {**os.environ, "MRE_COSIM_CODE_VERSION": "tests"}  # others may edit the checkout meanwhile
    run = lambda *a: subprocess.run([*CLI, *a], cwd=tmp_path, capture_output=True, text=True, timeout=240, env=env)  # noqa: E731
    proc = run(str(STUDY), *args, "--out", str(out), "--quiet")
    assert proc.returncode == 0, proc.stderr
    peaks = (out / "peaks.csv").read_text()
    assert json.loads((out / "study.json").read_text())["jobs_computed"] == 2
    assert run("--resume", str(out), "--quiet").returncode == 0
    assert json.loads((out / "study.json").read_text())["jobs_computed"] == 0
    assert (out / "peaks.csv").read_text() == peaks
    next(iter(sorted((out / "jobs").glob("*.json")))).unlink()
    assert run("--resume", str(out), "--quiet").returncode == 0
    assert json.loads((out / "study.json").read_text())["jobs_computed"] == 1
    assert (out / "peaks.csv").read_text() == peaks


def test_switching_law():
    law = SwitchingLaw(i_high=2.0, i_low=0.5, i_max=1.5)
    assert law.current(0.01, 0.1) == 1.5 and law.current(-0.01, -0.1) == 1.5  # moving away: high, clipped
    assert law.current(0.01, -0.1) == 0.5 and law.current(0.0, 0.1) == 0.5  # returning or at 0: low
    with pytest.raises(ValueError):
        SwitchingLaw(i_max=0.0)


def _ok(payload: dict) -> int:
    return payload["n"] * 2


def _raises(payload: dict) -> int:
    raise RuntimeError("broken model")


def _dies(payload: dict) -> int:
    os._exit(3)


@pytest.mark.slow
def test_runner_isolates_crashes(tmp_path):
    jobs = [Job("dies", _dies, {}), Job("raises", _raises, {}, tmp_path / "raises.log"), Job("ok", _ok, {"n": 21})]
    seen = []
    res = run_jobs(jobs, workers=2, on_done=lambda r: seen.append(r.key))
    assert sorted(seen) == ["dies", "ok", "raises"]
    assert res["ok"].ok and res["ok"].value == 42
    assert not res["raises"].ok and res["raises"].error == "RuntimeError: broken model"
    assert "Traceback" in (tmp_path / "raises.log").read_text()
    assert not res["dies"].ok and "code 3" in res["dies"].error


@pytest.mark.parametrize(("override", "message"), [
    ("strategies=[sosm]", "passive-off"),
    ("colour=blue", "unknown key"),
    ("records={x: nowhere.yaml}", "does not exist"),
])
@pytest.mark.slow
def test_bad_study_config_exits_2_and_writes_nothing(tmp_path, override, message):
    out = tmp_path / "study"
    proc = study_cli(str(STUDY), "--set", override, "--out", str(out), cwd=tmp_path)
    assert proc.returncode == 2
    assert message in proc.stderr and "Traceback" not in proc.stderr
    assert not out.exists()


def test_metrics_and_indices_of_known_signals():
    """Peaks, RMS and base shear of sinusoids whose values are known in closed form."""
    t = np.linspace(0.0, 10.0, 100001)
    w = 2 * np.pi
    ts = {"time": t, "building.x_0": 0.004 * np.sin(w * t), "controller.i": 1.0 + np.sin(w * t),
          "isolator.F": np.zeros_like(t), "building.shear_1": 50.0 * np.cos(w * t)}
    masses = [100.0, 100.0, 100.0, 100.0]
    for j in range(4):
        ts[f"building.a_{j}"] = (j + 1) * np.sin(w * t)
    for j in range(1, 4):
        ts[f"building.drift_{j}"] = 1e-3 * j * np.cos(w * t)
    m = run_metrics(ts, masses)
    assert m["x_base_mm"] == pytest.approx(4.0, rel=1e-6)
    assert m["rms_x_base_mm"] == pytest.approx(4.0 / math.sqrt(2), rel=1e-4)
    assert m["drift_3_mm"] == pytest.approx(3.0) and m["drift_max_mm"] == pytest.approx(3.0)
    assert m["acc_3"] == pytest.approx(4.0, rel=1e-6) and m["rms_acc_max"] == pytest.approx(4 / math.sqrt(2), rel=1e-4)
    assert m["base_shear_N"] == pytest.approx(100.0 * (1 + 2 + 3 + 4), rel=1e-6)
    assert m["current_max_A"] == pytest.approx(2.0) and m["current_mean_A"] == pytest.approx(1.0, abs=1e-4)
    assert m["time_beyond_8mm_s"] == 0.0
    half = {**ts, **{k: 0.5 * v for k, v in ts.items() if k.startswith("building.")}}
    j = indices(run_metrics(half, masses), m)
    assert all(v == pytest.approx(0.5, rel=1e-9) for v in j.values())


@pytest.mark.slow
def test_tuning_is_reproducible_and_returns_its_best_point():
    """A tiny tuning (2 s of El Centro, 3 samples, 4 Nelder-Mead evaluations)."""
    study = load_study(STUDY)
    plan = plan_scenario(study.scenario_path("elcentro"), run_overrides(study.spec))
    spec = TuningSpec(stop_time=2.0, n_samples=3, max_evals=4, seed=7)
    obj = ObjectiveSpec()
    a = tune(plan, spec, obj, 3.0)
    b = tune(plan, spec, obj, 3.0)
    g: SosmGains = a["gains"]
    assert g == b["gains"] and a["objective"] == b["objective"]
    assert g.zeta * g.theta > g.rho  # Eq. (39)
    for key, attr in (("lam", "lam"), ("rho", "rho"), ("theta", "theta")):
        lo, hi = spec.bounds[key]
        assert lo * (1 - 1e-9) <= getattr(g, attr) <= hi * (1 + 1e-9)
    assert a["objective"] == min(h["J"] for h in a["history"]) <= a["objective_default_gains"]
    # the objective of the returned gains, recomputed independently
    sim = plan.loaded.scenario.simulation
    n = round(2.0 / sim.step)
    extra = {"inputs": sim.inputs} if hasattr(sim, "inputs") else {}
    off = peak_values(simulate_coupled(system_setup(plan, 0.0), sim.step, n, sim.algorithm, **extra))
    mine = peak_values(simulate_coupled(system_setup(plan, None, g), sim.step, n, sim.algorithm, **extra))
    assert objective(mine, off, obj) == pytest.approx(a["objective"], rel=1e-12)
    assert g.s_release == 0.0 and all(h["s_release"] == 0.0 for h in a["history"])  # 4-D: the paper's law


@pytest.mark.slow
def test_tuning_with_a_release_band_searches_it_as_a_fifth_dimension():
    """Bounds naming s_release (the release band, not in the paper) make it a tuned gain; w_zero adds the
    share of time at 0 A to J. A tiny tuning: 3 s of El Centro, 3 samples, 4 Nelder-Mead evaluations."""
    study = load_study(STUDY)
    plan = plan_scenario(study.scenario_path("elcentro"), run_overrides(study.spec))
    bounds = {"lam": (0.5, 50.0), "rho": (0.5, 50.0), "theta": (0.1, 10.0), "ratio": (1.05, 20.0),
              "s_release": (1e-3, 0.05)}
    spec = TuningSpec(stop_time=3.0, n_samples=3, max_evals=4, seed=7, bounds=bounds)
    obj = ObjectiveSpec(w_saturation=1.0, w_zero=1.0)
    a = tune(plan, spec, obj, 2.5)
    g: SosmGains = a["gains"]
    assert all(1e-3 * (1 - 1e-9) <= h["s_release"] <= 0.05 * (1 + 1e-9) for h in a["history"])
    # it is searched, not fixed: the start (its lower bound) and each Latin-hypercube point have their own
    assert a["history"][0]["s_release"] == pytest.approx(1e-3, rel=1e-12)
    assert len({h["s_release"] for h in a["history"][:4]}) == 4
    assert g.s_release == min(a["history"], key=lambda h: h["J"])["s_release"] and g.i_max == 2.5
    # J of the returned gains recomputed from the trajectories: peaks and the shares at 2.5 A and at 0 A
    sim = plan.loaded.scenario.simulation
    n = round(3.0 / sim.step)
    extra = {"inputs": sim.inputs} if hasattr(sim, "inputs") else {}
    off = simulate_coupled(system_setup(plan, 0.0), sim.step, n, sim.algorithm, **extra)
    tr = simulate_coupled(system_setup(plan, None, g), sim.step, n, sim.algorithm, **extra)
    top = lambda t: np.max(np.abs(t.a[:, -1]))  # noqa: E731
    drift = lambda t: np.max(np.abs(t.drift))  # noqa: E731
    j = (0.5 * top(tr) / top(off) + 0.5 * drift(tr) / drift(off)
         + 10.0 * max(0.0, np.max(np.abs(tr.x[:, 0])) / 0.015 - 1.0)
         + np.mean(tr.i >= 2.5 - 1e-6) + np.mean(tr.i <= 1e-6))
    assert j == pytest.approx(a["objective"], rel=1e-12)  # the same numbers summed in another order
    with pytest.raises(ValueError, match="s_release"):
        TuningSpec(bounds={**bounds, "gamma": (1.0, 2.0)})


def test_shipped_gains_file_fits_the_study():
    study = load_study(STUDY)
    gains, doc = read_gains(study.gains_path)
    assert gains.i_max == study.spec.i_max and gains.zeta * gains.theta > gains.rho
    assert doc["procedure"]["record"] == study.spec.tuning.record
    assert set(doc["check_other_records"]) == set(study.spec.records)
