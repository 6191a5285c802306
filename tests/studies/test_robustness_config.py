"""The robustness section of a study file: bad variants are exit 2, each named, nothing written."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from orchestration.case_study.case_config import load_study
from orchestration.case_study.case_run import main
from orchestration.case_study.robustness_config import VariantSpec

from ..conftest import PROJECT

BENCHMARK = PROJECT / "scenarios" / "controller_benchmark.yaml"


def _study(tmp_path, robustness: str) -> tuple:
    path = tmp_path / "study.yaml"
    out = tmp_path / "studies"
    path.write_text(f"extends: {BENCHMARK}\nname: bad\noutput: {out}\n" + textwrap.dedent(robustness))
    return path, out


def test_shipped_robustness_study_reads():
    study = load_study(PROJECT / "scenarios" / "controller_robustness.yaml")
    rob = study.spec.robustness
    assert list(rob.variants) == ["paper-law", "mass-0.8", "mass-1.2", "stiffness-0.8", "stiffness-1.2", "noise",
                                  "lag-x0.5", "lag-x3", "delay-1"]
    assert rob.variants["lag-x3"].scale == {"coil.tau": 3.0}  # factors of the nominal plant's coil lag
    assert rob.variants["lag-x0.5"].scale == {"coil.tau": 0.5}
    paper = rob.variants["paper-law"].plant["isolator"]
    assert paper.fmu.endswith("MreIsolator.fmu") and paper.parameters == {"n_isolators": 2}
    assert rob.variants["delay-1"].sensors.delay == 1
    assert rob.variants["mass-1.2"].scale["building.m_0"] == 1.2
    assert study.spec.strategies == ["passive-off", "passive-on", "best-constant", "sosm", "sosm-fig15", "on-off",
                                     "clipped-optimal", "clipped-optimal-inverse", "lyapunov", "frequency"]


def test_bad_variants_are_all_reported_with_key_and_line(tmp_path, capsys):
    path, out = _study(tmp_path, """\
        robustness:
          variants:
            typo:
              scal: {building.m_1: 1.2}
            lag:
              current_lag: -0.01
            noisy:
              sensors:
                noise_rms: {building.x_0: -1.0e-4}
            late:
              sensors: {delay: -1}
        """)
    assert main([str(path)]) == 2
    err = capsys.readouterr().err
    assert "robustness.variants.typo.scal" in err and "study.yaml:7" in err
    assert "robustness.variants.lag.current_lag" in err and "study.yaml:9" in err
    assert "CurrentLag unit's parameter tau must be > 0" in err
    assert "robustness.variants.noisy.sensors.noise_rms" in err and "noise RMS must be >= 0" in err
    assert "robustness.variants.late.sensors.delay" in err and "study.yaml:14" in err
    assert "Traceback" not in err
    assert not out.exists()


def test_robustness_without_benchmark_is_refused(tmp_path, capsys):
    path = tmp_path / "study.yaml"
    path.write_text(f"extends: {PROJECT / 'scenarios' / 'case_study.yaml'}\nname: bad\noutput: {tmp_path / 'o'}\n"
                    "robustness: {variants: {lag: {current_lag: 0.01}}}\n")
    assert main([str(path)]) == 2
    assert "robustness needs a benchmark section" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_a_variant_must_change_something():
    with pytest.raises(ValueError, match="at least one of plant, scale, set, sensors, current_lag"):
        VariantSpec()


@pytest.mark.slow
def test_variants_the_plant_cannot_take_are_refused_before_any_run(tmp_path, capsys):
    """Checked through the engine before anything is written: the controller is not part of a variant, a
    signal the controller reads needs its noise RMS, a scaled parameter must exist."""
    path, out = _study(tmp_path, """\
        strategies: [passive-off, sosm, clipped-optimal]
        records: {elcentro: elcentro.yaml}
        robustness:
          variants:
            redesign:
              scale: {controller.m_1: 1.2}
            swap:
              plant: {controller: ../fmus/LyapunovCurrentController.fmu}
            partial:
              sensors:
                noise_rms: {building.x_0: 1.0e-4}
            ghost:
              scale: {building.m_9: 1.2}
        """)
    text = path.read_text().replace("records: {elcentro: elcentro.yaml}",
                                    f"records: {{elcentro: {PROJECT / 'scenarios' / 'elcentro.yaml'}}}")
    path.write_text(text)
    assert main([str(path)]) == 2
    err = capsys.readouterr().err
    assert "robustness.variants.redesign.scale.controller.m_1" in err and "plant only" in err
    assert "robustness.variants.swap.plant.controller" in err and "cannot be swapped" in err
    assert not out.exists()
    path.write_text(text.replace("""    redesign:
      scale: {controller.m_1: 1.2}
    swap:
      plant: {controller: ../fmus/LyapunovCurrentController.fmu}
""", ""))
    assert main([str(path)]) == 2
    err = capsys.readouterr().err
    assert "robustness.variants.partial.sensors.noise_rms" in err and "no noise RMS for building.v_0" in err
    assert "robustness.variants.ghost.scale.building.m_9" in err and "no Real parameter building.m_9" in err
    assert "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize(("fmu", "said"), [("é" * 200 + ".fmu", "bytes"), ("/dev/zero", "not a regular file"),
                                           ("nowhere.fmu", "does not exist")])
def test_a_plant_fmu_that_cannot_be_a_file_is_exit_2_naming_the_key(tmp_path, capsys, fmu, said):
    """A name longer than the file system allows, a device or a missing file: exit 2, never an OSError."""
    path, out = _study(tmp_path, f"""\
        strategies: [passive-off, sosm]
        records: {{elcentro: {PROJECT / 'scenarios' / 'elcentro.yaml'}}}
        robustness:
          variants:
            swap:
              plant: {{isolator: "{fmu}"}}
        """)
    assert main([str(path)]) == 2
    err = capsys.readouterr().err
    assert "robustness.variants.swap.plant.isolator" in err and said in err and "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize(("variant", "key", "said"), [
    ("{sensors: {seed: true, delay: 1}}", "sensors.seed", "valid integer"),
    ("{sensors: {seed: 1.0, delay: 1}}", "sensors.seed", "valid integer"),
    ("{sensors: {seed: 2147483648, delay: 1}}", "sensors.seed", "less than or equal to 2147483647"),
    ("{sensors: {seed: -1, delay: 1}}", "sensors.seed", "greater than or equal to 0"),
    ("{sensors: {delay: true}}", "sensors.delay", "valid integer"),
    ("{sensors: {noise_rms: {building.x_0: '1e-4'}}}", "sensors.noise_rms.building.x_0", "valid number"),
    ("{scale: {building.m_1: true}}", "scale.building.m_1", "valid number"),
    ("{scale: {building.m_1: '1.2'}}", "scale.building.m_1", "valid number"),
    ("{current_lag: '0.01'}", "current_lag", "valid number"),
    ("{current_lag: true}", "current_lag", "valid number"),
    ("{current_lag: .nan}", "current_lag", "finite number"),
    ("{plant: {isolator: 3}}", "plant.isolator", "valid"),
    # no-ops: each would run the nominal plant unchanged
    ("{current_lag: 0}", "current_lag", "0 would insert no lag"),
    ("{scale: {building.m_1: 1.0}}", "scale", "a factor of 1 changes nothing"),
    ("{sensors: {delay: 0}}", "sensors", "exact pass-through"),
    ("{sensors: {noise_rms: {building.x_0: 0.0}}}", "sensors", "exact pass-through"),
])
def test_loose_types_and_no_op_variants_are_exit_2_naming_key_and_line(tmp_path, capsys, variant, key, said):
    path, out = _study(tmp_path, f"""\
        robustness:
          variants:
            v: {variant}
        """)
    assert main([str(path)]) == 2
    err = capsys.readouterr().err
    assert f"robustness.variants.v.{key}" in err and said in err and "study.yaml:6" in err, err
    assert "Traceback" not in err
    assert not out.exists()


def test_the_seed_range_is_the_fmi_integer_range_of_the_unit():
    """One range: the study's check, the SensorChannels FMU variable (an FMI Integer, int32) and its core."""
    from orchestration.case_study.robustness_config import MAX_SEED, SensorSpec

    assert MAX_SEED == 2**31 - 1 == np.iinfo(np.int32).max
    assert SensorSpec(seed=MAX_SEED, delay=1).seed == MAX_SEED
    with pytest.raises(ValueError):
        SensorSpec(seed=MAX_SEED + 1, delay=1)
    shell = (PROJECT / "components" / "shells" / "sensor_channels_fmu.py").read_text()
    assert 'Integer("seed"' in shell


@pytest.mark.slow
def test_no_op_plant_variants_are_refused_before_any_run(tmp_path, capsys):
    """A swap of a unit the scenario lacks, a swap to the same FMU, and the scale of a parameter that is 0 on
    the nominal plant change nothing: exit 2 naming each variant's key and line, nothing written."""
    path, out = _study(tmp_path, f"""\
        strategies: [passive-off, sosm]
        records: {{elcentro: {PROJECT / 'scenarios' / 'nominal_plant_elcentro.yaml'}}}
        robustness:
          variants:
            ghost-unit:
              plant: {{damper: {PROJECT / 'fmus' / 'MreIsolator.fmu'}}}
            same:
              plant: {{isolator: {PROJECT / 'fmus' / 'BoucWenIsolator.fmu'}}}
            zero:
              scale: {{building.k_0: 2.0}}
        """)
    assert main([str(path)]) == 2
    err = capsys.readouterr().err
    assert "robustness.variants.ghost-unit.plant.damper" in err and "no unit 'damper'" in err
    assert "robustness.variants.same.plant.isolator" in err and "change nothing" in err
    assert "robustness.variants.zero.scale.building.k_0" in err and "is 0 on the nominal plant" in err
    assert "Traceback" not in err
    assert not out.exists()


def test_bad_plant_samples_are_all_reported_with_key_and_line(tmp_path, capsys):
    path, out = _study(tmp_path, """\
        robustness:
          plant_samples: {file: plants/none.yaml, lhs: 1, sobol: 12, axes: 0}
          variants:
            lhs-001: {scale: {building.m_1: 1.2}}
        """)
    assert main([str(path)]) == 2
    err = capsys.readouterr().err
    assert "robustness.plant_samples.sobol" in err and "power of 2 (e.g. 8 or 16)" in err
    assert "robustness.plant_samples.axes" in err and "study.yaml:5" in err
    assert "lhs = 1: a spread needs at least 2 samples" in err
    assert "'lhs-001': lhs-NNN and sobol-NNNN are the sampled plants' names" in err
    assert "Traceback" not in err and not out.exists()


def test_a_plant_sample_file_that_is_missing_or_no_sample_file_is_exit_2_naming_the_key(tmp_path, capsys):
    for text, said in ((None, "cannot read"), ("kind: other\n", "not a plant-sample file")):
        if text is not None:
            (tmp_path / "samples.yaml").write_text(text)
        path, out = _study(tmp_path, f"""\
            strategies: [passive-off, passive-on]
            records: {{elcentro: {PROJECT / 'scenarios' / 'nominal_plant_elcentro.yaml'}}}
            robustness:
              plant_samples: {{file: samples.yaml, lhs: 4}}
            """)
        assert main([str(path)]) == 2
        err = capsys.readouterr().err
        assert "robustness.plant_samples.file" in err and said in err and "study.yaml:7" in err, err
        assert "Traceback" not in err and not out.exists()


def test_sampled_plants_are_variants_named_in_order():
    from orchestration.case_study.robustness_config import RobustnessSpec

    spec = RobustnessSpec.model_validate({"plant_samples": {"file": "x.yaml", "lhs": 3, "sobol": 2, "axes": 1},
                                          "variants": {"mass": {"scale": {"building.m_1": 1.1}}}})
    assert spec.variant_names() == ["mass", "lhs-001", "lhs-002", "lhs-003", *[f"sobol-{k:04d}" for k in range(1, 7)]]


def test_variant_strategies_must_be_the_studys(tmp_path, capsys):
    path, out = _study(tmp_path, """\
        strategies: [passive-off, sosm]
        robustness:
          strategies: [sosm, lyapunov]
          variants: {lag: {current_lag: 0.01}}
        """)
    assert main([str(path)]) == 2
    err = capsys.readouterr().err
    assert "robustness.strategies: 'lyapunov' not among the study's strategies (passive-off, sosm)" in err
    assert "Traceback" not in err and not out.exists()


def test_more_sobol_axes_than_the_samples_vary_along_and_a_unit_that_is_a_path_are_exit_2(tmp_path, capsys):
    """The shipped samples vary along 10 principal axes: axes = 11 would name plants the design does not draw."""
    samples = PROJECT / "scenarios" / "plants" / "plant_samples_bouc_wen-joint.yaml"
    for spec, key, said in ((f"{{file: {samples}, lhs: 0, sobol: 2, axes: 11}}", "robustness.plant_samples.axes",
                             "vary along 10 principal axes"),
                            (f"{{file: {samples}, lhs: 2, unit: ../isolator}}", "robustness.plant_samples.unit",
                             "a unit name of the scenario")):
        path, out = _study(tmp_path, f"""\
            strategies: [passive-off, passive-on]
            records: {{elcentro: {PROJECT / 'scenarios' / 'nominal_plant_elcentro.yaml'}}}
            robustness:
              plant_samples: {spec}
            """)
        assert main([str(path)]) == 2
        err = capsys.readouterr().err
        assert key in err and said in err, err
        assert "Traceback" not in err and not out.exists()
