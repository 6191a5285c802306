"""What each FMU declares: a valid model description, SI units as docs/fmu_variables.md gives them, its runtime needs.

* Every FMU the project builds passes fmpy's validation; one that declares a variable twice is
  a scenario error (exit 2) quoting fmpy's reason, before anything runs.
* Every unit string is what the "FMU variables" table of docs/fmu_variables.md says, read as
  written (m/s², N·s/m, A·s^½/m^½, "–" for none) and turned into FMI unit syntax, and a valid
  SI unit: each declared ``Unit`` is parsed here into SI base exponents (N = kg·m·s⁻²) and
  compared with the ``BaseUnit`` the modelDescription gives (none may be given only where a
  power is fractional).
* The pythonfmu units carry their runtime requirements, documentation and FMU-state support.
"""

from __future__ import annotations

import re
import zipfile
from fractions import Fraction

import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from components.build.pythonfmu_units import discover
from orchestration.api import ScenarioError, load_scenario

from ..conftest import PROJECT

FMU_NAMES = [source.fmu_name.removesuffix(".fmu") for source in discover()] + ["MreIsolatorC"]


@pytest.mark.parametrize("name", FMU_NAMES)
def test_fmu_is_valid(fmu_dir, name):
    """Every FMU the project builds passes fmpy's validation with zero problems."""
    assert validate_fmu(str(fmu_dir / f"{name}.fmu")) == []


def test_sosm_gain_units_are_declared_with_their_fractional_powers(fmu_dir):
    """theta [m^0.5 s^-1.5] and zeta [A s^0.5 m^-0.5]: declared by name only (no integer base-unit exponents)."""
    md = read_model_description(str(fmu_dir / "SosmCurrentController.fmu"))
    units = {v.name: v.unit for v in md.modelVariables}
    assert units["theta"] == "m0.5/s1.5" and units["zeta"] == "A.s0.5/m0.5"
    declared = {u.name: u for u in md.unitDefinitions}
    assert declared["m0.5/s1.5"].baseUnit is None and declared["A.s0.5/m0.5"].baseUnit is None


@pytest.mark.parametrize("name", [s.fmu_name.removesuffix(".fmu") for s in discover() if s.handles_state])
def test_fmu_ships_its_runtime_requirements(fmu_dir, name):
    with zipfile.ZipFile(fmu_dir / f"{name}.fmu") as z:
        text = z.read("resources/requirements.txt").decode()
        assert "Python >= 3.11" in text
        assert "documentation/index.html" in z.namelist()
        assert 'canGetAndSetFMUstate="true"' in z.read("modelDescription.xml").decode()


DERIVED = {"N": {"kg": 1, "m": 1, "s": -2}, "J": {"kg": 1, "m": 2, "s": -2}}
BASE = {"kg", "m", "s", "A", "K", "mol", "cd"}


def si_exponents(unit: str) -> dict[str, Fraction]:
    """SI base exponents of an FMI-style unit string such as ``N.s/(m.A)`` or ``m0.5/s1.5``."""
    if unit == "1":
        return {}
    numerator, _, denominator = unit.partition("/")
    out: dict[str, Fraction] = {}
    for part, sign in ((numerator, 1), (denominator.strip("()"), -1)):
        if not part or part == "1":
            continue
        for factor in re.split(r"\.(?=[a-zA-Z])", part):  # "A.s0.5": a dot before a letter joins factors
            m = re.fullmatch(r"([a-zA-Z]+)(-?\d+(?:\.\d+)?)?", factor)
            assert m, f"{unit!r}: cannot read the factor {factor!r}"
            symbol, power = m.group(1), Fraction(m.group(2) or "1")
            assert symbol in BASE or symbol in DERIVED, f"{unit!r}: {symbol!r} is not an SI unit symbol"
            for base, exp in DERIVED.get(symbol, {symbol: 1}).items():
                out[base] = out.get(base, Fraction(0)) + sign * power * exp
    return {k: v for k, v in out.items() if v != 0}


def table_units() -> dict[str, dict[str, str | None]]:
    """FMU -> variable name pattern -> unit in FMI syntax (None: no unit), from the table of docs/fmu_variables.md."""
    text = (PROJECT / "docs" / "fmu_variables.md").read_text()
    table = text[text.index("## FMU variables"):]
    table = table[: table.index("\n## ", 3)]
    out: dict[str, dict[str, str | None]] = {}
    fmu = ""
    for line in table.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 5 or not cells[1].startswith("`"):
            continue
        if cells[0]:
            fmu = re.match(r"\*\*(\w+)\*\*", cells[0]).group(1)
        names_text, units_text = cells[1], cells[3]
        if "…" in names_text or units_text in ("SI", "as the isolator", ""):
            continue  # ranges checked against another unit below (or only for being SI)
        names = [re.sub(r"_j\b", r"_\\d+", n) for n in re.findall(r"`([^`]+)`", names_text)]
        units = [u.strip() for u in units_text.replace(" / ", ",").split(",")]
        if len(units) == 1:
            units *= len(names)
        assert len(units) == len(names), f"table row {line!r}: {len(names)} variables, {len(units)} units"
        for name, unit in zip(names, units, strict=True):
            out.setdefault(fmu, {})[name] = None if unit in ("–", "-") else _fmi_syntax(unit)
    return out


def _fmi_syntax(unit: str) -> str:
    return unit.replace("²", "2").replace("·", ".").replace("^½", "0.5").replace("^1.5", "1.5")


def _declared(fmu_dir, name: str) -> tuple[dict[str, str | None], dict]:
    md = read_model_description(str(fmu_dir / f"{name}.fmu"))
    return {v.name: v.unit for v in md.modelVariables}, {u.name: u for u in md.unitDefinitions}


FMUS = ["GroundMotionSource", "ShearBuilding", "MreIsolator", "MreIsolatorC", "SosmCurrentController",
        "ConstantCurrent", "SwitchingCurrentController", "BoucWenIsolator", "SensorChannels", "CurrentLag"]


@pytest.mark.parametrize("name", FMUS)
def test_declared_units_are_si_and_match_their_base_units(fmu_dir, name):
    units, definitions = _declared(fmu_dir, name)
    assert set(filter(None, units.values())) <= set(definitions)
    for unit, definition in definitions.items():
        exponents = si_exponents(unit)
        base = definition.baseUnit
        if base is None:  # allowed only where FMI's integer exponents cannot say it
            assert any(e.denominator != 1 for e in exponents.values()), unit
        else:
            given = {k: getattr(base, k) for k in ("kg", "m", "s", "A", "K", "mol", "cd") if getattr(base, k)}
            assert given == exponents, (unit, given, exponents)


@pytest.mark.parametrize("name", FMUS)
def test_declared_units_are_the_documented_units(fmu_dir, name):
    table = table_units()
    units, _ = _declared(fmu_dir, name)
    if name == "MreIsolatorC":  # the table: "as MreIsolator"
        assert units == _declared(fmu_dir, "MreIsolator")[0]
        return
    rows = table[name]
    checked = set()
    for pattern, unit in rows.items():
        matching = [v for v in units if re.fullmatch(pattern, v)]
        assert matching, f"the table names {name}.{pattern}, which the FMU does not have"
        for variable in matching:
            assert units[variable] == unit, f"{name}.{variable}: declared {units[variable]!r}, table {unit!r}"
            checked.add(variable)
    if name == "SosmCurrentController":  # "c0_0 … beta_1 (6): as the isolator"
        isolator, _ = _declared(fmu_dir, "MreIsolator")
        for variable in ("c0_0", "k0_0", "alpha_0", "alpha_1", "beta_0", "beta_1"):
            assert units[variable] == isolator[variable], variable
            checked.add(variable)
    unchecked = {v for v, u in units.items() if u is not None} - checked
    if name == "BoucWenIsolator":  # its coefficients are "SI" in the table: checked for that above
        unchecked -= {"k_0", "k_1", "c_0", "c_1", "alpha_0", "alpha_1", "beta_0", "beta_1", "gamma_0", "gamma_1",
                      "delta", "n", "F0", "y"}  # y: the internal hysteretic state, not in the table
    assert not unchecked, f"{name}: units the table does not give: {sorted(unchecked)}"


def _with_duplicate_variable(src, dest) -> None:
    """Copy an FMU, declaring its parameter ``current`` a second time under another value reference."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dest, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                xml = data.decode()
                m = re.search(r'<ScalarVariable\s+name="current".*?</ScalarVariable>', xml, re.S)
                duplicate = re.sub(r'valueReference="\d+"', 'valueReference="999"', m.group(0))
                xml = xml.replace("</ModelVariables>", duplicate + "\n</ModelVariables>")
                data = xml.encode()
            zout.writestr(item, data)


def test_an_fmu_declaring_a_variable_twice_is_refused_with_fmpys_reason(tmp_path, fmu_dir):
    # fmpy's own validation rejects this FMU; before, the master bound one of the two and ran.
    bad = tmp_path / "ConstantCurrent.fmu"
    _with_duplicate_variable(fmu_dir / "ConstantCurrent.fmu", bad)
    with pytest.raises(ScenarioError) as info:
        load_scenario(PROJECT / "scenarios" / "elcentro_constant_current.yaml", [f"units.controller.fmu={bad}"])
    [problem] = info.value.problems
    assert problem.key == "units.controller.fmu"
    assert "invalid modelDescription.xml" in problem.message and "current" in problem.message
