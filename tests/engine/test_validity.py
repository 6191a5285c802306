"""Two verdicts on every run, kept apart: numerical validity (energy books, non-finite values) and the physical
outcome; the energy section from what the units exchanged; bad tolerances refused with the key named."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from components.physics.shear_building_core import ENERGY_NAMES, BuildingParams, ShearBuilding
from orchestration.building_report import BuildingReport, energy_section, physical_outcome
from orchestration.master.report import RunDescription, non_finite, report_summary
from orchestration.run import verdict_lines

from ..conftest import PROJECT

H = 1e-3
SPEC = BuildingReport.model_validate({"base_displacement": "building.x_0", "isolator_force": "isolator.F"})
RUN = RunDescription({"isolator": {"x_identified": 0.008, "x_limit": 0.015, "beyond_range": "stop"}},
                     {"building": "ShearBuilding", "isolator": "MreIsolator"})


class Rows:
    """What the report reads of a recorder: names, kinds, times, columns."""

    def __init__(self, t: np.ndarray, columns: dict[str, np.ndarray]) -> None:
        self.names = list(columns)
        self.kinds = ["real"] * len(columns)
        self.time = np.asarray(t, float)
        self.data = np.column_stack([np.asarray(c, float) for c in columns.values()])
        self.count = len(t)

    @property
    def times(self) -> np.ndarray:
        return self.time

    def column(self, name: str) -> np.ndarray:
        return self.data[:, self.names.index(name)]


def kelvin_run(n: int = 3000, k: float = 2e5, c: float = 800.0, overshoot: float = 0.0) -> Rows:
    """The building on a Kelvin isolator F = k x + c v, coupled as a co-simulation does: the building holds the
    isolator force over each step, the force it is given being the isolator's mean over the step (the trapezoid
    of its values at both ends, found by fixed-point iteration), plus ``overshoot`` times the last step's change
    (a force estimate that overshoots a jump, as a mid-step extrapolation does)."""
    b = ShearBuilding(BuildingParams.dyke())
    t = np.arange(n + 1) * H
    ag = 2.0 * np.sin(2 * np.pi * 1.1 * t) * np.exp(-0.2 * t)
    cols = {name: [] for name in ("building.x_0", "isolator.F", *(f"building.{e}" for e in ENERGY_NAMES))}

    def force() -> float:
        return k * b.x[0] + c * b.v[0]

    def record() -> None:
        cols["building.x_0"].append(b.x[0])
        cols["isolator.F"].append(force())
        for name, value in zip(ENERGY_NAMES, b.energies(), strict=True):
            cols[f"building.{name}"].append(value)

    record()
    previous = 0.0
    for j in range(n):
        q, work, f0 = b.q.copy(), b.work.copy(), force()
        f_in = f0
        for _ in range(30):  # the trapezoid of the isolator's force over the step, consistent with the step
            b.step(ag[j], f_in, H)
            f_in = 0.5 * (f0 + force())
            b.q, b.work = q, work.copy()
        held = f_in + overshoot * (f0 - previous)
        previous = f0
        b.step(ag[j], held, H)
        record()
        cols.setdefault("held", []).append(held)
    rows = Rows(t, {k: v for k, v in cols.items() if k != "held"})
    rows.held = np.asarray(cols["held"])  # the force the building integrated over each step
    return rows


def test_a_consistent_coupling_keeps_the_books_and_is_valid():
    rows = kelvin_run()
    energy, reasons = energy_section(SPEC, rows, RUN)
    assert reasons == []
    assert energy["checked"] and energy["input_J"] > 0
    assert abs(energy["max_residual_fraction"]) < 1e-10
    # the building integrated the trapezoid of the isolator's own force: the two works agree to the iteration
    assert abs(energy["max_coupling_error_fraction"]) < 1e-9
    # the isolator's share: what the Kelvin element took, by its own books (dashpot dissipation + spring energy)
    share = energy["isolator_J"] / energy["input_J"]
    assert energy["isolator_share"] == pytest.approx(share)
    assert 0 < share < 1


def test_a_force_estimate_that_overshoots_is_a_coupling_energy_error():
    rows = kelvin_run(overshoot=40.0)
    energy, reasons = energy_section(SPEC, rows, RUN)
    assert abs(energy["max_residual_fraction"]) < 1e-10  # the building's own books still close
    assert energy["max_coupling_error_fraction"] > SPEC.energy_tolerance
    assert len(reasons) == 1 and reasons[0].startswith("coupling energy error")
    assert "report.energy_tolerance" in reasons[0]
    # expected: step by step, the held force less the isolator's own mean force, times the step's displacement
    x, force = rows.column("building.x_0"), rows.column("isolator.F")
    expected = sum((rows.held[k] - 0.5 * (force[k] + force[k + 1])) * (x[k + 1] - x[k]) for k in range(len(x) - 1))
    assert energy["coupling_error_J"] == pytest.approx(expected, rel=1e-9)
    assert abs(expected) > 0.1 * energy["input_J"]


def test_a_building_without_energy_integrals_is_not_checked():
    rows = Rows(np.arange(3) * H, {"building.x_0": np.zeros(3), "isolator.F": np.zeros(3)})
    energy, reasons = energy_section(SPEC, rows, RunDescription({}, {"building": "OpenSeesBuilding"}))
    assert energy["checked"] is False and "not checked" in energy["note"] and "OpenSeesBuilding" in energy["note"]
    assert reasons == []


def test_books_that_do_not_close_are_invalid():
    rows = kelvin_run(n=500)
    rows.data[:, rows.names.index("building.E_kinetic")] *= 0.5  # a kinetic energy that lost half
    energy, reasons = energy_section(SPEC, rows, RUN)
    assert energy["max_residual_fraction"] > SPEC.energy_tolerance
    assert any(r.startswith("energy balance does not close") for r in reasons)


def test_non_finite_values_are_the_engine_s_reason_and_join_the_application_s():
    t = np.arange(4) * H
    rows = Rows(t, {"a.y": [0.0, 1.0, math.nan, 2.0], "a.z": [0.0, math.inf, 1.0, 1.0], "a.w": [1.0] * 4})
    found = non_finite(rows)
    assert len(found) == 2 and "a.y = nan at t = 0.002 s" in found[0] and "a.z = inf at t = 0.001 s" in found[1]

    class Hook:
        model = BuildingReport

        @staticmethod
        def summarize(spec, rec, run):
            return {"invalid_reasons": ["energy balance does not close: test"], "x": 1}

        plot = None

    summary = report_summary(rows, BuildingReport(), Hook, RunDescription({}, {}))
    assert summary["valid"] is False
    assert summary["invalid_reasons"] == [*found, "energy balance does not close: test"]
    assert list(summary)[:2] == ["valid", "invalid_reasons"] and summary["x"] == 1
    ok = report_summary(Rows(t, {"a.w": [1.0] * 4}), BuildingReport(), None, RunDescription({}, {}))
    assert ok["valid"] is True and ok["invalid_reasons"] == []


def test_the_physical_outcome_is_kept_apart_and_uses_the_run_s_limits():
    t = np.arange(6) * H
    x = np.array([0.0, 0.009, 0.016, 0.015, -0.010, 0.0])
    rows = Rows(t, {"building.x_0": x, "isolator.F": [0.0, 1e3, -5e3, 2e3, 0.0, 0.0]})
    out = physical_outcome(SPEC, rows, RUN)
    assert out["time_beyond_identified_range_s"] == pytest.approx(4 * H)
    assert out["time_at_device_limit_s"] == pytest.approx(2 * H)
    assert out["peak_isolator_force_N"] == 5e3 and out["beyond_range"] == "stop"
    wider = RunDescription({"isolator": {"x_identified": 0.0155, "x_limit": 0.02}}, {})
    assert physical_outcome(SPEC, rows, wider)["time_beyond_identified_range_s"] == pytest.approx(H)


def test_run_prints_both_verdicts():
    invalid = {"valid": False, "invalid_reasons": ["coupling energy error: x"],
               "physical": {"peak_base_displacement_m": 0.0136, "identified_range_m": 0.008,
                            "time_beyond_identified_range_s": 1.49, "device_limit_m": 0.015,
                            "time_at_device_limit_s": 0.0, "peak_isolator_force_N": 495e3}}
    lines = verdict_lines(invalid)
    assert lines[0].startswith("numerically INVALID") and "coupling energy error: x" in lines[0]
    assert lines[1].startswith("physical outcome: peak base displacement 13.6 mm, 1.49 s beyond")
    valid = {"valid": True, "invalid_reasons": [], "energy": {"checked": True, "max_residual_fraction": 1e-14,
                                                               "max_coupling_error_fraction": 3e-5}}
    assert verdict_lines(valid) == ["numerically valid (energy balance: residual 1e-12 %, coupling energy error "
                                    "0.003 % of the input energy)"]


@pytest.mark.parametrize("value", ["0", "-0.01", ".nan", ".inf", "many"])
def test_a_bad_energy_tolerance_is_refused_naming_the_key(value, tmp_path):
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "orchestration/run.py", "scenarios/elcentro.yaml", "--set",
                           f"report.energy_tolerance={value}", "--out", str(out), "--no-plots", "--quiet"],
                          cwd=PROJECT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    assert "report.energy_tolerance" in proc.stderr and "Traceback" not in proc.stderr
    assert not out.exists()


@pytest.mark.slow
def test_short_el_centro_run_is_valid_and_closes_its_books(tmp_path):
    from orchestration.api import load_scenario, run

    results = run(load_scenario(PROJECT / "scenarios" / "elcentro.yaml", ["simulation.stop_time=3"]),
                  out=tmp_path / "r")
    assert results.complete and results.valid is True and results.invalid_reasons == []
    energy = results.summary["energy"]
    assert energy["checked"] and abs(energy["max_residual_fraction"]) < 1e-10
    assert abs(energy["max_coupling_error_fraction"]) < 1e-3
    assert results.physical["device_limit_m"] == 0.015
    on_disk = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert on_disk["valid"] is True and on_disk["energy"] == energy


@pytest.mark.slow
def test_frequency_control_on_hachinohe_is_complete_but_invalid(tmp_path):
    # The paper's law, switched 0 -> 3 A at x_0 = -13.4 mm near t = 6.58 s: the coupling goes unstable
    # (a tangent stiffness of ~360 MN/m at 13.4 mm and 3 A, omega h ~ 1.9). A result, exit 0, but invalid.
    scenario = tmp_path / "hachinohe_frequency.yaml"
    scenario.write_text(f"""extends: {PROJECT / 'scenarios' / 'hachinohe.yaml'}
name: hachinohe_frequency
units:
  controller:
    fmu: {PROJECT / 'fmus' / 'FrequencyCurrentController.fmu'}
    parameters: {{i_max: 3.0, window: 2000, update_every: 20}}
connections:
  - ground.ag -> building.ag
  - building.x_0 -> isolator.x
  - building.v_0 -> isolator.v
  - controller.i -> isolator.i
  - isolator.F -> building.F
  - {{source: ground.ag, target: controller.ag, delayed: true}}
simulation: {{stop_time: 8.0}}
""")
    proc = subprocess.run([sys.executable, "orchestration/run.py", str(scenario), "--out", str(tmp_path / "r"),
                           "--no-plots", "--quiet"], cwd=PROJECT, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "run complete" in proc.stdout and "numerically INVALID" in proc.stdout
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert summary["complete"] is True and summary["valid"] is False
    assert any(r.startswith("coupling energy error") for r in summary["invalid_reasons"])


def test_ida_rows_carry_validity_and_an_invalid_run_counts_for_no_limit_state(tmp_path):
    from orchestration.ida_study.ida_metrics import exceeded, read_rows, result_row, write_tables
    from orchestration.ida_study.ida_records import ComponentInfo, RunOutcome
    from orchestration.ida_study.ida_rendering import not_counted

    comp = ComponentInfo("kobe-ns", "kobe", "ns", "shipped", (0.0, 10.0), 12.0, 0.4, 0.8)
    metrics = {"x_base_mm": 16.0, "drift_1_mm": 2.0, "drift_2_mm": 1.0, "drift_3_mm": 0.5, "drift_max_mm": 2.0}

    def row(valid: bool | None, status: str = "ok") -> dict:
        value = {"status": status, "error": None, "end_time_s": 12.0, "metrics": metrics}
        if valid is not None:
            value.update(valid=valid, invalid_reasons=[] if valid else ["coupling energy error: test"])
        return result_row(comp, "pga", 0.4, "sosm", RunOutcome("kobe-ns/0.4/sosm", True, "ok", value, None, 1.0),
                          None)

    good, bad, old = row(True), row(False), row(None)
    assert good["valid"] is True and bad["valid"] is False and bad["invalid_reasons"] == "coupling energy error: test"
    assert old["valid"] is None  # stored before runs said so: counted as before
    # 16 mm is beyond a 15 mm isolator limit state: a physical exceedance counts, an invalid run does not count
    assert exceeded(good, "isolator_displacement", 0.015) is True and exceeded(old, "isolator_displacement", 0.015)
    assert exceeded(bad, "isolator_displacement", 0.015) is None
    diverged = row(False, status="diverged")
    assert exceeded(diverged, "isolator_displacement", 0.015) is True  # stopped by the divergence limit
    write_tables(tmp_path, [good, bad, old])
    back = read_rows(tmp_path)
    assert [r["valid"] for r in back] == [True, False, None]
    assert "coupling energy error: test" in (tmp_path / "results.csv").read_text()
    assert not_counted(["sosm", "passive-off"], [good, bad, old]) == " Not counted, numerically invalid: 1 run of sosm."


def _bench_row(strategy: str, j5: float, valid: bool | None = True, step_j5: float | None = None) -> dict:
    row = {"record": "hachinohe", "strategy": strategy, **{f"J{k}": 1.0 for k in range(1, 10)}, "J5": j5,
           "J3": 1.0, "valid": valid, "invalid_reasons": "" if valid else "coupling energy error: x"}
    if step_j5 is not None:
        row["step_changes"] = {"J5": step_j5}
    return row


def test_the_benchmark_ranks_and_judges_valid_rows_only():
    from orchestration.case_study.benchmark_report import ranking, verdicts

    rows = [_bench_row("passive-off", 1.0), _bench_row("best-constant", 0.5), _bench_row("lyapunov", 0.45),
            _bench_row("frequency", 0.1, valid=False)]
    assert [s for s, _ in ranking(rows, "hachinohe")] == ["lyapunov", "best-constant", "passive-off"]
    text = verdicts(rows, "best-constant", ["hachinohe"])
    freq = next(t for t in text if t.startswith("**frequency**"))
    assert freq == "**frequency**: no record with both runs valid (invalid on hachinohe)"
    lyap = next(t for t in text if t.startswith("**lyapunov**"))
    assert "beats the best constant current on 1 of 1 records, by 10.0 % in J5" in lyap


def test_a_verdict_closer_than_the_step_s_change_is_a_tie():
    from orchestration.case_study.benchmark_report import tie_margin, verdicts

    best, lyap = _bench_row("best-constant", 0.5, step_j5=0.01), _bench_row("lyapunov", 0.485, step_j5=-0.025)
    assert tie_margin(lyap, best, "J5") == pytest.approx(0.035)
    assert tie_margin(_bench_row("a", 1.0), _bench_row("b", 1.0), "J5") == 0.01  # unverified: the 1 % tie
    (text,) = verdicts([best, lyap], "best-constant", ["hachinohe"])
    assert "beats the best constant current on 0 of 1 records" in text and "ties (within 1 %, or the step's change, " \
                                                                          "up to 3.5 %) on 1" in text


def test_a_run_prints_its_key_peaks_with_where_they_were_reached():
    from orchestration.run import peak_lines

    summary = {"peak_drift_m": {"building.drift_1": 0.0113, "building.drift_2": -0.0151},
               "peak_abs_acceleration_m_s2": {"building.a_0": 9.81, "building.a_3": 4.0},
               "peak_current_A": 3.0, "mean_current_A": 2.5}
    assert peak_lines(summary) == ["peaks: storey drift 15.1 mm (building.drift_2); absolute acceleration "
                                   "9.81 m/s² = 1 g (building.a_0); current 3 A (mean 2.5 A)"]
    assert peak_lines({"peak_current_A": None}) == []  # a system without a building or a current says nothing
