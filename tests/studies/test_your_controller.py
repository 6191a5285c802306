"""docs/your_controller.md under test: a controller FMU with foreign names and no i_max joins every study.

The page's files (a `` `path`: `` line before a code block) and commands (its ``bash`` blocks) are run as
written, from a folder holding ``my_controller/`` beside links to the project's ``scenarios/`` and ``fmus/``.
Fast: the FMU is built with pythonfmu's own command, ``mre-cosim inspect`` prints what the page shows, the three
studies plan the foreign unit's runs (its output wired to the device, no ``i_max`` set, ``limit: umax`` set to the
study's limit) and a wrong mapping is exit 2 at the entry's line. Slow: the page's studies run, and the foreign
controller's recorded current obeys its own law (checked sample by sample from the recorded base motion).
"""

from __future__ import annotations

import csv
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ..conftest import PROJECT

PAGE = PROJECT / "docs" / "your_controller.md"
BIN = Path(sys.executable).parent


def page() -> tuple[dict[str, str], list[str], list[str]]:
    """The page's files (path -> text), its commands (one per line of its bash blocks) and its text blocks."""
    text = PAGE.read_text()
    files, commands, texts = {}, [], []
    for m in re.finditer(r"(?:^`([^`]+)`:\n\n)?^```(\w+)\n(.*?)^```$", text, re.M | re.S):
        name, lang, body = m.groups()
        if name:
            files[name] = body
        elif lang == "bash":
            commands += [line for line in body.splitlines() if line.strip()]
        elif lang == "text":
            texts.append(body)
    return files, commands, texts


def run(command: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """One of the page's command lines, in ``cwd``, with this interpreter's scripts (pythonfmu, mre-cosim) first."""
    env = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}",
           "MRE_COSIM_CODE_VERSION": "tests"}
    return subprocess.run(["bash", "-c", command], cwd=cwd, env=env, capture_output=True, text=True, timeout=900)


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """A user's folder: the page's files in my_controller/, the project's scenarios and FMUs linked, the FMU built."""
    root = tmp_path_factory.mktemp("yours")
    for name in ("scenarios", "fmus"):
        (root / name).symlink_to(PROJECT / name, target_is_directory=True)
    files, commands, _ = page()
    for name, body in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(body)
    build = run(commands[0], root)
    assert build.returncode == 0, build.stderr
    assert (root / "my_controller" / "DisplacementSwitch.fmu").is_file()
    return root


def test_the_page_has_its_files_and_commands():
    files, commands, texts = page()
    assert set(files) == {"my_controller/displacement_switch.py", "my_controller/my_benchmark.yaml",
                          "my_controller/my_case_study.yaml", "my_controller/my_ida.yaml"}
    assert commands[0].startswith("cd my_controller && pythonfmu build")
    assert [c.split()[1] for c in commands[1:]] == ["inspect", "study", "study", "ida"]
    assert len(texts) == 2


def test_inspect_prints_what_the_page_shows(folder):
    _, commands, texts = page()
    out = run(commands[1], folder)
    assert out.returncode == 0, out.stderr
    for line in texts[0].splitlines():
        assert line in out.stdout.splitlines(), (line, out.stdout)
    unmapped = run(commands[1].replace(" --map i=u", ""), folder)
    assert unmapped.returncode == 1
    assert "problem: DisplacementSwitch has no output 'i'" in unmapped.stderr and "its outputs: u" in unmapped.stderr


def _plans(folder: Path, name: str, overrides: tuple[str, ...] = ()):
    """The planned runs of the page's study ``name``: strategy -> the plan of its first record's run."""
    from orchestration.building_studies.run_settings import run_overrides
    from orchestration.case_study.case_config import load_study
    from orchestration.case_study.case_plan import prepare, run_strategy_overrides
    from orchestration.engine_hooks import plan_scenario

    study = load_study(folder / "my_controller" / name, overrides)
    prepared = prepare(study)  # every record x strategy through the engine's checks
    record = next(iter(study.spec.records))
    path = study.scenario_path(record)
    out = {}
    for s in study.spec.strategies:
        if s == "best-constant":
            continue
        strategy = study.strategy(s)
        extra = run_strategy_overrides(study, s, path, study.spec.i_max, None, 0.0)
        out[s] = plan_scenario(path, (*strategy.common(run_overrides(study.spec)), *extra))
    return prepared, out


def _links(plan) -> set[tuple[str, str]]:
    return {(".".join(link.source), ".".join(link.target)) for link in plan.links}


def test_the_benchmark_wires_its_output_and_sets_no_limit(folder):
    """The benchmark's plant has the coil lag: the foreign output drives it; no i_max is forced on the FMU."""
    _, plans = _plans(folder, "my_benchmark.yaml", ("i_max=2.0", "fig15.i_max=2.0"))
    mine, ours = plans["displacement-switch"], plans["on-off"]
    assert ("controller.u", "coil.i_cmd") in _links(mine)
    assert ("controller.i", "coil.i_cmd") in _links(ours)
    assert not any(src == "controller.i" for src, _ in _links(mine))
    assert mine.parameters.get("controller", {}) == {}  # umax stays its own 3 A, though the study's limit is 2 A
    assert ours.parameters["controller"]["i_high"] == 2.0
    assert str(mine.loaded.scenario.report.current) == "controller.u"
    assert mine.parameters["isolator"]["i_max"] == 2.0  # the plant still gets the study's limit


def test_the_case_study_sets_the_mapped_limit(folder):
    """``limit: umax``: the study's i_max is set on the FMU's own limit; the output drives the isolator directly."""
    _, plans = _plans(folder, "my_case_study.yaml", ("i_max=2.0", "fig15.i_max=2.0"))
    mine = plans["displacement-switch"]
    assert mine.parameters["controller"] == {"umax": 2.0}
    assert ("controller.u", "isolator.i") in _links(mine)
    assert plans["passive-on"].parameters["controller"]["i_max"] == 2.0


def test_the_ida_plans_the_foreign_unit(folder):
    from orchestration.ida_study.ida_config import load_ida
    from orchestration.ida_study.ida_plan import prepare_ida

    study = folder / "my_controller" / "my_ida.yaml"
    prepared = prepare_ida(study, *load_ida(study))
    try:
        assert prepared.unlimited == ["displacement-switch"]
        for (_, s), pp in prepared.plans.items():
            plan = pp.plan
            if s == "displacement-switch":
                assert ("controller.u", "coil.i_cmd") in _links(plan)
                assert "umax" not in plan.parameters.get("controller", {})
                assert "controller.u" in [str(o) for o in plan.loaded.scenario.outputs]
    finally:
        prepared.cleanup()


@pytest.mark.parametrize(("line", "key", "expected"), [
    ("    current: uu", "current", "controller has no output 'uu' for the current command of strategy "
                                   "'displacement-switch'; its outputs: u (output, no unit)"),
    ("    current: xb", "current", "controller.xb is an input, the current command of strategy "
                                   "'displacement-switch' must be an output; its outputs: u (output, no unit)"),
    ("    current: u\n    limit: imax", "limit", "controller has no parameter 'imax' for the current limit of "
                                                 "strategy 'displacement-switch'; its parameters: umax"),
])
def test_a_wrong_mapping_is_exit_2_at_its_line(folder, line, key, expected):
    """Named at the entry's key and line, with what the FMU has, once (not again as the engine's own problem)."""
    good = (folder / "my_controller" / "my_benchmark.yaml").read_text()
    bad = folder / "my_controller" / f"bad_{abs(hash(line))}.yaml"
    bad.write_text(re.sub(r"^    current: u\b.*$", line, good, count=1, flags=re.M))
    number = next(k for k, text in enumerate(bad.read_text().splitlines(), 1) if text.startswith(f"    {key}:"))
    out = run(f"mre-cosim study {shlex.quote(str(bad))} --out {shlex.quote(str(folder / 'never'))}", folder)
    assert out.returncode == 2, out.stderr
    assert f"{bad}:{number}: strategy_definitions.displacement-switch.{key}: {expected}" in out.stderr
    assert "1 problem" in out.stderr
    assert not (folder / "never").exists()


def test_the_page_shows_the_error_a_missing_output_gives(folder):
    """The page's error example is what a study says (its line is the entry's ``current:`` line)."""
    _, _, texts = page()
    shown = texts[1].strip().splitlines()[1].strip().removeprefix("- ")
    file, number, rest = shown.split(":", 2)
    lines = (folder / file).read_text().splitlines()
    assert lines[int(number) - 1] == "    current: u                           # its output that is the current " \
                                     "command [A]"
    assert rest.startswith(" strategy_definitions.displacement-switch.current: controller has no output 'uu'")


def _series(run_folder: Path) -> dict[str, np.ndarray]:
    with open(run_folder / "timeseries.csv") as f:
        rows = list(csv.reader(f))
    return {name: np.array([float(r[k]) for r in rows[1:]]) for k, name in enumerate(rows[0])}


@pytest.mark.slow
def test_the_page_runs_end_to_end(folder):
    """The page's three study commands, as written: every run valid, and the foreign controller's recorded current
    is its own law of the base motion it read (delayed: the samples at the start of each 1 ms controller step)."""
    _, commands, _ = page()
    for command in commands[2:]:
        out = run(command, folder)
        assert out.returncode == 0, (command, out.stderr[-3000:])
    bench = folder / "my_controller" / "benchmark"
    with open(bench / "criteria.csv") as f:
        rows = {r["strategy"]: r for r in csv.DictReader(f)}
    assert set(rows) == {"passive-off", "passive-on", "best-constant", "on-off", "displacement-switch"}
    mine = rows["displacement-switch"]
    assert mine["valid"] == "True" and 0 < float(mine["mean_current_A"]) < 3.0
    ts = _series(bench / "runs" / "elcentro-displacement-switch")
    t, x, v, u = ts["time"], ts["building.x_0"], ts["building.v_0"], ts["controller.u"]
    # the controller steps every 1 ms (4 plant steps of 0.25 ms): the rows after the sample at t_n hold the decision
    # from x_0(t_n), v_0(t_n) until the next sample's decision (the rows t_n+h ... t_n+4h)
    k = np.arange(1, len(t))
    sample = ((k - 1) // 4) * 4
    expected = np.where(x[sample] * v[sample] > 0, 3.0 * np.minimum(1.0, np.abs(x[sample]) / 0.005), 0.0)
    assert np.max(np.abs(u[k] - expected)) < 1e-9  # the CSV's 12 significant digits
    assert np.count_nonzero(expected) > len(k) / 10  # the law was exercised, not a run at 0 A
    case = folder / "my_controller" / "case_study"
    assert (case / "peaks.csv").read_text().count("displacement-switch") == 1
    ida = folder / "my_controller" / "ida"
    with open(ida / "fragility.csv") as f:
        fits = [r for r in csv.DictReader(f) if r["strategy"] == "displacement-switch"]
    assert fits and all(r["stripes"] for r in fits)  # a fragility row per limit state from the foreign runs


def test_our_constant_current_fmu_is_a_strategy_of_the_case_study(tmp_path):
    """ConstantCurrent.fmu has no i_max: the study no longer forces one on it (it did: exit 2 citing a --set)."""
    study = tmp_path / "hold.yaml"
    study.write_text(f"extends: {PROJECT / 'scenarios' / 'case_study.yaml'}\nname: hold\n"
                     f"records: {{elcentro: {PROJECT / 'scenarios' / 'elcentro.yaml'}}}\n"
                     "strategies: [passive-off, hold]\nreference: {enabled: false}\n"
                     "strategy_definitions:\n"
                     f"  hold: {{fmu: {PROJECT / 'fmus' / 'ConstantCurrent.fmu'}, parameters: {{current: 1.5}}, "
                     "connections: []}\n")
    from orchestration.building_studies.run_settings import run_overrides
    from orchestration.case_study.case_config import load_study
    from orchestration.case_study.case_plan import prepare, run_strategy_overrides
    from orchestration.engine_hooks import plan_scenario

    loaded = load_study(study)
    prepare(loaded)
    path = loaded.scenario_path("elcentro")
    hold = loaded.strategy("hold")
    plan = plan_scenario(path, (*hold.common(run_overrides(loaded.spec)),
                                *run_strategy_overrides(loaded, "hold", path, 3.0, None, 0.0)))
    assert plan.parameters["controller"] == {"current": 1.5}
    assert ("controller.i", "isolator.i") in _links(plan)


@pytest.mark.parametrize(("args", "expected"), [
    (["nope.fmu"], "nope.fmu: No such file or directory"),
    (["not_an_fmu.fmu"], "not_an_fmu.fmu"),
    (["{fmus}/ShearBuilding.fmu", "--role", "building", "--map", "zz=1"],
     "the building role has no variable 'zz' (its variables: ag, F, x_0"),
    (["{fmus}/ShearBuilding.fmu", "--map", "i=u"], "--map needs --role"),
    (["{fmus}/ShearBuilding.fmu", "--role", "controller", "--map", "i"], "give OURS=THEIRS"),
])
def test_inspect_bad_input_is_exit_2(tmp_path, capsys, args, expected):
    from orchestration.inspect_fmu import main

    (tmp_path / "not_an_fmu.fmu").write_text("plain text")
    args = [a.format(fmus=PROJECT / "fmus") for a in args]
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        assert main(args) == 2
    finally:
        os.chdir(cwd)
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err


def test_inspect_a_building_in_the_controller_role_is_exit_1(capsys):
    """Our ShearBuilding cannot be a controller: no current output; its outputs are listed, with their units."""
    from orchestration.inspect_fmu import main

    assert main([str(PROJECT / "fmus" / "ShearBuilding.fmu"), "--role", "controller"]) == 1
    said = capsys.readouterr()
    assert "problem: ShearBuilding has no output 'i' for the current command" in said.err
    assert "x_0 (output, m)" in said.out and "cannot play the controller" in said.err


@pytest.mark.parametrize("value", ["''", "' u'", "'u -> x'"])
def test_a_mapping_that_is_no_variable_name_is_exit_2(folder, value):
    good = (folder / "my_controller" / "my_benchmark.yaml").read_text()
    bad = folder / "my_controller" / f"name_{abs(hash(value))}.yaml"
    bad.write_text(re.sub(r"^    current: u\b.*$", f"    current: {value}", good, count=1, flags=re.M))
    out = run(f"mre-cosim study {shlex.quote(str(bad))} --out {shlex.quote(str(folder / 'never'))}", folder)
    assert out.returncode == 2, out.stderr
    assert "strategy_definitions.displacement-switch.current" in out.stderr
    assert "must be the name of one of the controller FMU's variables" in out.stderr
    assert not (folder / "never").exists()
