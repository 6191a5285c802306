"""A benchmark with sampled plants (robustness.plant_samples): the design, the runs it sets, and its tables."""

from __future__ import annotations

import csv
import json
import textwrap

import numpy as np
import pytest

from components.identification.plant_samples import load_plant_samples
from components.identification.plant_sampling import COEFFICIENTS, distribution, lhs_normal
from orchestration.case_study.case_run import main

from ..conftest import PROJECT

SAMPLES = PROJECT / "scenarios" / "plants" / "plant_samples_bouc_wen-joint.yaml"


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("plant_uncertainty")
    path = tmp / "study.yaml"
    path.write_text(textwrap.dedent(f"""\
        extends: {PROJECT / 'scenarios' / 'controller_benchmark.yaml'}
        name: sampled
        records: {{elcentro: {PROJECT / 'scenarios' / 'nominal_plant_elcentro.yaml'}}}
        strategies: [passive-off, passive-on, on-off]
        overrides: [simulation.stop_time=0.5]
        robustness:
          strategies: [passive-off, passive-on]   # on-off runs on the nominal plant only
          plant_samples: {{file: {SAMPLES}, lhs: 3, sobol: 2, axes: 1, seed: 5}}
        """))
    out = tmp / "out"
    assert main([str(path), "--out", str(out), "--quiet", "--workers", "1"]) == 0
    return out


@pytest.mark.slow  # 21 runs of 0.5 s of El Centro on the nominal plant
def test_the_design_is_the_covariance_draw_and_each_run_sets_its_plant(study):
    """plant_design.csv's Latin-hypercube rows are the draw recomputed here from the sample file and the seed, and
    every sampled run's isolator ran with its row's coefficients (its manifest's parameters)."""
    design = _rows(study / "plant_design.csv")
    assert [r["variant"] for r in design] == ["lhs-001", "lhs-002", "lhs-003", *[f"sobol-{k:04d}" for k in range(1, 7)]]
    dist = distribution(*load_plant_samples(SAMPLES))
    expected = dist.coefficients(lhs_normal(3, len(dist.variances), 5))
    got = np.array([[float(r[n]) for n in COEFFICIENTS] for r in design[:3]])
    np.testing.assert_array_equal(got, expected)
    assert all(float(r[f"xi_{k}"]) == 0.0 for r in design[3:] for k in range(2, len(dist.variances) + 1))
    for row in design:
        for s in ("passive-off", "passive-on"):
            manifest = json.loads((study / "runs" / f"elcentro-{s}--{row['variant']}" / "manifest.json").read_text())
            params = manifest["scenario"]["units"]["isolator"]["parameters"]
            assert all(params[n] == float(row[n]) for n in COEFFICIENTS), (s, row["variant"])


@pytest.mark.slow
def test_the_spread_and_the_indices_come_from_the_sampled_runs(study):
    """plant_uncertainty.csv's median J3 over the Latin-hypercube plants equals the median of robustness.csv's J3
    rows of the same runs (computed apart); passive-off's J6 is 0 on every plant; sobol.csv has S1 and ST per
    criterion and axis; the report has the section."""
    spread = {(r["strategy"], r["criterion"]): r for r in _rows(study / "plant_uncertainty.csv")}
    rob = _rows(study / "robustness.csv")
    for s in ("passive-off", "passive-on"):
        j3 = [float(r["J3"]) for r in rob if r["strategy"] == s and r["variant"].startswith("lhs-")]
        assert len(j3) == 3 and float(spread[(s, "J3")]["median"]) == pytest.approx(float(np.median(j3)), rel=1e-12)
        assert spread[(s, "J3")]["valid"] == "3"
    assert float(spread[("passive-off", "J6")]["q95"]) == 0.0
    sobol = _rows(study / "sobol.csv")
    assert {(r["strategy"], r["criterion"], r["axis"]) for r in sobol} == {
        (s, j, "1") for s in ("passive-off", "passive-on") for j in ("J3", "J5")}
    assert all(np.isfinite(float(r["S1"])) and np.isfinite(float(r["ST"])) for r in sobol)
    assert not any(r["strategy"] == "on-off" for r in sobol) and ("on-off", "J3") not in spread
    assert not list((study / "runs").glob("elcentro-on-off--*")) and (study / "runs" / "elcentro-on-off").is_dir()
    report = (study / "report.md").read_text()
    assert "The plant's own uncertainty (sampled isolators)" in report and "Sobol indices" in report
    by = {(r["strategy"], r["variant"]): float(r["J5"]) for r in rob if r["variant"].startswith("lhs-")}
    lower = sum(by[("passive-off", v)] < by[("passive-on", v)] for v in ("lhs-001", "lhs-002", "lhs-003"))
    assert f"| passive-off | passive-on | elcentro | J5 | {lower} of 3 |" in report
