"""The robustness section of a study file (issue 23, part 4): bad variants are exit 2, each named, nothing written."""

from __future__ import annotations

import textwrap

import pytest

from orchestration.case_study.case_config import load_study
from orchestration.case_study.case_run import main
from orchestration.case_study.robustness_config import VariantSpec

from .conftest import PROJECT

BENCHMARK = PROJECT / "scenarios" / "controller_benchmark.yaml"


def _study(tmp_path, robustness: str) -> tuple:
    path = tmp_path / "study.yaml"
    out = tmp_path / "studies"
    path.write_text(f"extends: {BENCHMARK}\nname: bad\noutput: {out}\n" + textwrap.dedent(robustness))
    return path, out


def test_shipped_robustness_study_reads():
    study = load_study(PROJECT / "scenarios" / "controller_robustness.yaml")
    rob = study.spec.robustness
    assert list(rob.variants) == ["bouc-wen", "mass-0.8", "mass-1.2", "stiffness-0.8", "stiffness-1.2", "noise",
                                  "lag-10ms", "lag-30ms", "delay-1"]
    assert rob.variants["lag-30ms"].current_lag == 0.030
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
    assert "CurrentLag unit's parameter tau must be >= 0" in err
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
    with pytest.raises(ValueError, match="at least one of plant, scale, sensors, current_lag"):
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
