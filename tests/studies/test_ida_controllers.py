"""IDA per controller: the case study's strategy entries in an IDA study file.

Fast: a study naming an unknown strategy, best-constant, a missing FMU, a connection to a variable the FMU
lacks or a missing strategy file is exit 2 naming the key and line, with nothing written; the names of before
give the overrides they always gave. Slow: a tiny IDA with two controllers (a shipped entry and a user's own
FMU entry with connections): each controller's fragility equals an independent maximum-likelihood fit of the
per-run outcomes the study wrote, and one of its runs equals the same run through ``run.py``.
"""

from __future__ import annotations

import csv
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy import optimize, stats

from orchestration.building_studies.gains_file import read_gains
from orchestration.building_studies.strategies import strategy_overrides
from orchestration.ida_study.ida_config import load_ida
from orchestration.ida_study.ida_plan import prepare_ida

from ..conftest import PROJECT, RECORDS

SCENARIOS = PROJECT / "scenarios"
FMUS = PROJECT / "fmus"
ENV = {**os.environ, "MRE_COSIM_CODE_VERSION": "tests"}


def _suite(tmp_path: Path, names: tuple[str, ...] = ("northridge_1994_sylmar_ns.csv",)) -> Path:
    folder = tmp_path / "suite"
    folder.mkdir(exist_ok=True)
    for name in names:
        shutil.copy(RECORDS / name, folder / name)
    return folder


def _study(tmp_path: Path, body: str) -> Path:
    """An IDA study file: the common keys, then ``body`` (YAML text, so its line numbers are known)."""
    head = (f"name: ida-ctl\nscenario: {SCENARIOS / 'isolated_building.yaml'}\n"
            f"suite: {{folder: {_suite(tmp_path)}}}\ntime_scale: 0.2\nwindow: {{tail_s: 0.5}}\n"
            "intensity: {measure: sa, levels: [0.05, 0.1]}\n"
            "limit_states: {iso: {quantity: isolator_displacement, threshold: 0.008}}\n"
            f"gains: {SCENARIOS / 'sosm_gains.yaml'}\noutput: {tmp_path / 'studies'}\n")  # 9 lines
    path = tmp_path / "ida.yaml"
    path.write_text(head + body)
    return path


def _exit_2(tmp_path: Path, study: Path, capsys: pytest.CaptureFixture[str]) -> str:
    """Run ida.py on ``study``: exit 2, nothing written; its stderr."""
    from orchestration.ida import main

    out = tmp_path / "out"
    assert main([str(study), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert not out.exists() and not (tmp_path / "studies").exists()
    return err


def test_unknown_strategy_and_best_constant_are_exit_2_at_their_lines(tmp_path, capsys):
    study = _study(tmp_path, "strategies:\n  - passive-off\n  - lqr\n  - best-constant\n")
    err = _exit_2(tmp_path, study, capsys)
    assert f"{study}:12: strategies.1: unknown strategy 'lqr' (known: passive-off, passive-on, sosm" in err
    assert f"{study}:13: strategies.2: strategy 'best-constant' is the case study's best constant current" in err
    assert "2 problems" in err


def test_missing_fmu_and_a_connection_to_a_missing_variable_are_exit_2_at_their_lines(tmp_path, capsys):
    study = _study(tmp_path, f"""strategies: [passive-off, my-lyapunov, no-fmu]
strategy_definitions:
  my-lyapunov:
    fmu: {FMUS / 'LyapunovCurrentController.fmu'}
    parameters: {{i_max: "${{i_max}}"}}
    connections:
      - {{source: building.x_0, target: controller.x, delayed: true}}
      - {{source: building.a_3, target: controller.a_9, delayed: true}}
  no-fmu:
    fmu: nowhere/Mine.fmu
""")
    err = _exit_2(tmp_path, study, capsys)
    assert f"{study}:17: strategy_definitions.my-lyapunov.connections[1]: controller (LyapunovCurrentController) " \
           "has no variable 'a_9'" in err
    assert f"{study}:19: strategy_definitions.no-fmu.fmu: FMU file {tmp_path / 'nowhere' / 'Mine.fmu'} does not " \
           "exist" in err


def test_strategy_files_missing_or_with_a_bad_parameter_are_exit_2_at_their_lines(tmp_path, capsys):
    study = _study(tmp_path, "strategies: [passive-off, mine]\nstrategy_files: [nowhere.yaml]\n")
    err = _exit_2(tmp_path, study, capsys)
    assert f"{study}:11: strategy_files.0: strategy file {tmp_path / 'nowhere.yaml'} does not exist" in err

    mine = tmp_path / "mine.yaml"
    mine.write_text(f"strategies:\n  mine:\n    fmu: {FMUS / 'SwitchingCurrentController.fmu'}\n"
                    "    parameters: {i_hihg: 2.0}\n")
    study = _study(tmp_path, "strategies: [passive-off, mine]\nstrategy_files: [mine.yaml]\n")
    err = _exit_2(tmp_path, study, capsys)
    assert f"{mine}:4: strategies.mine.parameters.i_hihg: SwitchingCurrentController has no variable 'i_hihg'" in err


def test_old_names_give_the_overrides_of_before_and_new_entries_their_own(tmp_path):
    """passive-off, passive-on, sosm and on-off: the overrides ida.py gave before strategy entries (the shipped
    entries' overrides, no connections), so old study files plan the same runs. A user's FMU without i_max
    runs without the study's controller.i_max; an entry with connections replaces those into the controller."""
    study = _study(tmp_path, f"""strategies: [passive-off, passive-on, sosm, on-off, lyapunov, hold]
strategy_definitions:
  hold:
    fmu: {FMUS / 'ConstantCurrent.fmu'}
    parameters: {{current: 1.25}}
    connections: []
""")
    prepared = prepare_ida(study, *load_ida(study))
    try:
        gains = read_gains(SCENARIOS / "sosm_gains.yaml")[1]["gains"]
        for s in ("passive-off", "passive-on", "sosm", "on-off"):
            assert prepared.strategies[s] == strategy_overrides(s, 3.0, gains if s == "sosm" else None, None)
        assert prepared.unlimited == ["hold"]
        (rid,) = {k[0] for k in prepared.plans}
        hold = prepared.plans[(rid, "hold")].plan
        assert hold.parameters["controller"] == {"current": 1.25}
        assert hold.parameters["isolator"]["i_max"] == 3.0
        lyap = prepared.plans[(rid, "lyapunov")].plan
        assert lyap.parameters["controller"]["i_max"] == 3.0
        targets = {str(c.target) for c in lyap.loaded.scenario.connections}
        assert {"controller.F", "controller.a_3"} <= targets and "controller.a" not in targets
    finally:
        prepared.cleanup()


LIMIT_STATES = {**{f"x{k}mm": {"quantity": "isolator_displacement", "threshold": k / 1000} for k in range(3, 7)},
                **{f"a{a:g}": {"quantity": "floor_acceleration", "threshold": a}
                   for a in (2.0, 2.5, 3.0, 4.0, 5.0, 6.5, 8.0, 10.0)}}


def _independent_mle(levels: np.ndarray, exceeded: np.ndarray) -> tuple[float, float]:
    """Median and dispersion maximising the Bernoulli likelihood of every run (Baker 2015), by Nelder-Mead."""

    def nll(p: np.ndarray) -> float:
        z = (np.log(levels) - p[0]) / math.exp(p[1])
        return -float(np.sum(np.where(exceeded, stats.norm.logcdf(z), stats.norm.logsf(z))))

    best = optimize.minimize(nll, [float(np.mean(np.log(levels))), math.log(0.5)], method="Nelder-Mead",
                             options={"xatol": 1e-10, "fatol": 1e-12, "maxiter": 20000})
    return math.exp(best.x[0]), math.exp(best.x[1])


@pytest.mark.slow
def test_tiny_ida_with_two_controllers_fits_and_runs_as_run_py(tmp_path):
    """Lyapunov (a shipped entry) and a user's on-off entry (its own FMU, parameters and connections) on two
    short records, 7 levels (28 runs): fragility.csv equals an independent MLE of results.csv's outcomes; a run
    equals run.py's; a resume computes nothing."""
    names = ("kobe_1995_jma_ns.csv", "northridge_1994_sylmar_ns.csv")
    user = {"label": "my on-off", "fmu": str(FMUS / "SwitchingCurrentController.fmu"),
            "parameters": {"i_high": 2.0, "i_low": 0.5},
            "connections": [{"source": f"building.{v}_0", "target": f"controller.{t}", "delayed": True}
                            for v, t in (("x", "x"), ("v", "v"), ("arel", "a"))]}
    levels = [0.03, 0.0345, 0.04, 0.046, 0.053, 0.061, 0.07]  # x 1.15: the two records' floor accelerations
    # differ by a factor 1.6-2 at one level, so some thresholds are passed by one record and not the other at
    # two levels or more (fewer leave the dispersion unidentifiable: fragility.py's "separated")
    spec = {"name": "ida-ctl", "scenario": str(SCENARIOS / "isolated_building.yaml"),
            "suite": {"folder": str(_suite(tmp_path, names))}, "time_scale": 0.2, "window": {"tail_s": 0.5},
            "intensity": {"measure": "sa", "levels": levels}, "strategies": ["lyapunov", "my-on-off"],
            "strategy_definitions": {"my-on-off": user},
            "limit_states": LIMIT_STATES,
            "output": str(tmp_path / "studies"), "workers": 2}
    study = tmp_path / "ida.yaml"
    study.write_text(yaml.safe_dump(spec))
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, str(PROJECT / "orchestration" / "ida.py"), str(study), "--out", str(out),
                           "--quiet"], capture_output=True, text=True, timeout=900, env=ENV)
    assert proc.returncode == 0, proc.stderr
    rows = list(csv.DictReader(open(out / "results.csv")))
    assert len(rows) == 2 * len(levels) * 2 and all(r["status"] in ("ok", "diverged") for r in rows)
    fits = {(r["limit_state"], r["strategy"]): r for r in csv.DictReader(open(out / "fragility.csv"))}
    assert set(fits) == {(ls, s) for ls in LIMIT_STATES for s in ("lyapunov", "my-on-off")}

    # The study's fits against an independent MLE of the per-run outcomes (thresholds applied here). Two records
    # give a finite fit only where a level has one of them beyond the threshold and not the other: the ladder of
    # thresholds makes that happen for each controller.
    column = {"isolator_displacement": ("x_base_mm", 1e-3), "floor_acceleration": ("acc_max", 1.0)}
    fitted = set()
    for (ls, s), fit in fits.items():
        (name, factor), threshold = column[LIMIT_STATES[ls]["quantity"]], LIMIT_STATES[ls]["threshold"]
        mine = [r for r in rows if r["strategy"] == s]
        im = np.array([float(r["intensity"]) for r in mine])
        hit = np.array([r["status"] == "diverged" or float(r[name]) * factor > threshold for r in mine])
        assert fit["stripes"] == " ".join(f"{x:g}:{int(hit[im == x].sum())}/{int((im == x).sum())}" for x in levels)
        if fit["fit"] != "fit":
            continue
        fitted.add(s)
        theta, beta = _independent_mle(im, hit)
        assert float(fit["median"]) == pytest.approx(theta, rel=2e-3), (ls, s)
        assert float(fit["beta"]) == pytest.approx(beta, rel=2e-3), (ls, s)
    assert fitted == {"lyapunov", "my-on-off"}, fits  # each controller has at least one finite fit

    # One point of each controller through run.py, as a user would run it by hand.
    info = yaml.safe_load((out / "ida.json").read_text())
    comp = next(c for c in info["components"] if c["id"] == "northridge_1994_sylmar_ns")
    for s in ("lyapunov", "my-on-off"):
        row = next(r for r in rows if r["record_id"] == comp["id"] and float(r["intensity"]) == 0.053
                   and r["strategy"] == s)
        sets = ["isolator.i_max=3.0", "controller.i_max=3.0", "ground.time_scale=0.2", *info["strategies"][s],
                f"ground.record=!record {out / 'records' / (comp['id'] + '.csv')}",
                f"simulation.stop_time={comp['stop_time_s']!r}", f"ground.scale={float(row['scale'])!r}"]
        run_dir = tmp_path / f"direct-{s}"
        direct = subprocess.run([sys.executable, str(PROJECT / "orchestration" / "run.py"),
                                 str(SCENARIOS / "isolated_building.yaml"), "--out", str(run_dir), "--no-plots",
                                 "--quiet", *(a for x in sets for a in ("--set", x))],
                                capture_output=True, text=True, timeout=300, env=ENV)
        assert direct.returncode == 0, direct.stderr
        ts = list(csv.DictReader(open(run_dir / "timeseries.csv")))
        x0 = max(abs(float(t["building.x_0"])) for t in ts)
        a3 = max(abs(float(t["building.a_3"])) for t in ts)
        i_mean = float(np.mean([float(t["controller.i"]) for t in ts]))
        assert float(row["x_base_mm"]) == pytest.approx(1e3 * x0, rel=1e-11, abs=0)
        assert float(row["acc_3"]) == pytest.approx(a3, rel=1e-11, abs=0)
        assert 0.0 < i_mean < 3.0 and float(row["current_max_A"]) == pytest.approx(
            max(float(t["controller.i"]) for t in ts), rel=1e-11)

    # The store still checks out: a resume of the finished folder computes nothing and changes no number.
    before = (out / "results.csv").read_text()
    proc = subprocess.run([sys.executable, str(PROJECT / "orchestration" / "ida.py"), "--resume", str(out), "--quiet"],
                          capture_output=True, text=True, timeout=600, env=ENV)
    assert proc.returncode == 0, proc.stderr
    assert yaml.safe_load((out / "ida.json").read_text())["runs_computed"] == 0
    assert (out / "results.csv").read_text() == before


@pytest.mark.slow
def test_the_shipped_controller_ida_is_valid():
    path = SCENARIOS / "ida_controllers.yaml"
    prepared = prepare_ida(path, *load_ida(path))
    try:
        assert len(prepared.components) == 4 and len(prepared.plans) == 4 * 7
        assert list(prepared.strategies) == ["passive-off", "passive-on", "sosm", "clipped-optimal", "lyapunov",
                                             "frequency", "hold-1.5A"]
        assert prepared.unlimited == ["hold-1.5A"]  # ConstantCurrent.fmu has no i_max
        # the nominal plant (nominal_plant.yaml): the Bouc-Wen isolators behind the coil lag
        assert all(pp.plan.descriptions["isolator"].model_identifier == "BoucWenIsolator"
                   and "coil" in pp.plan.descriptions for pp in prepared.plans.values())
    finally:
        prepared.cleanup()


def test_every_span_is_whole_controller_steps_on_a_multi_rate_plant(tmp_path):
    """The nominal plant couples at 0.25 ms and samples the controller at 1 ms: each component's span is rounded up
    to whole 1 ms periods (a 0.25 ms tail made it 20894 base steps, refused by the controller's own step)."""
    study = tmp_path / "ida.yaml"
    study.write_text(f"name: ida-mr\nscenario: {SCENARIOS / 'nominal_plant.yaml'}\n"
                     f"suite: {{folder: {_suite(tmp_path)}}}\ntime_scale: 0.2\nwindow: {{tail_s: 0.50025}}\n"
                     "intensity: {measure: sa, period_s: 0.84, levels: [0.05]}\n"
                     "limit_states: {iso: {quantity: isolator_displacement, threshold: 0.015}}\n"
                     f"strategies: [passive-off, lyapunov]\ngains: {SCENARIOS / 'sosm_gains.yaml'}\n"
                     f"output: {tmp_path / 'studies'}\n")
    prepared = prepare_ida(study, *load_ida(study))
    try:
        for c in prepared.components:
            periods = c.stop_time_s / 0.001
            assert abs(periods - round(periods)) < 1e-6, c.stop_time_s
        assert {s for _, s in prepared.plans} == {"passive-off", "lyapunov"}
    finally:
        prepared.cleanup()
