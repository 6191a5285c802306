"""The plain-C MRE isolator FMU and the pythonfmu one are interchangeable.

Every per-unit check runs against both implementations (``isolator`` is parametrised):
the force equals :func:`components.physics.mre_isolator_core.isolator_force`, it is direct
feedthrough, the current is clipped, non-finite inputs give an FMI error with a message,
the range warnings fire on entry, and ``fmpy validate`` finds no problem. Then the two
interfaces are compared variable by variable, and a co-simulation of El Centro with the
C isolator (scenarios/elcentro_c_isolator.yaml) equals the Python-isolator run.
"""

from __future__ import annotations

import ast
import math
import os
import re
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

import components.build.c_isolator as cbuild
from components.build.c_isolator import C_FMU_NAME, build_c_isolator, ensure_c_isolator, is_stale
from components.build.model_description import BuildError
from components.build.pythonfmu_units import build, discover
from components.physics.mre_isolator_core import (
    BEYOND_RANGE,
    TABLE2,
    GeneralizedCoefficients,
    bounded_force_law,
    isolator_force,
)

from ..support.fmu_driver import Driven

PROJECT = Path(__file__).resolve().parents[2]
IMPLEMENTATIONS = ("python", "c")


@pytest.fixture(scope="module")
def isolator_fmus(tmp_path_factory) -> dict[str, Path]:
    """Both isolator FMUs, freshly built into a temporary folder."""
    dest = tmp_path_factory.mktemp("isolators")
    (source,) = [s for s in discover() if s.class_name == "MreIsolator"]
    return {"python": build(source, dest), "c": build_c_isolator(dest)}


@pytest.fixture(params=IMPLEMENTATIONS)
def isolator(request, isolator_fmus) -> Path:
    return isolator_fmus[request.param]


def _driven(path: Path, parameters: dict | None = None) -> Driven:
    return Driven(path, "iso", parameters)


def test_fmu_is_valid(isolator):
    assert validate_fmu(str(isolator)) == []


def test_force_equals_core_and_is_direct_feedthrough(isolator):
    rng = np.random.default_rng(21)
    iso = _driven(isolator)
    try:
        for k in range(300):
            x, v, i = rng.uniform(-0.012, 0.012), rng.uniform(-0.4, 0.4), rng.uniform(0, 3)
            iso.set(x=x, v=v, i=i)
            # the output reflects the inputs just set, before any step
            assert iso.get("F")[0] == isolator_force(x, v, i, TABLE2, 0.0, 2)
            iso.step(k * 1e-3, 1e-3)
            assert iso.get("F")[0] == isolator_force(x, v, i, TABLE2, 0.0, 2)
    finally:
        iso.close()


def test_parameters_and_current_clipping(isolator):
    iso = _driven(isolator, {"n_isolators": 3, "F0": 2.0, "k0_1": 5000.0, "i_max": 2.5})
    coeffs = GeneralizedCoefficients(**{**TABLE2.as_dict(), "k0_1": 5000.0})
    try:
        iso.set(x=0.003, v=0.05, i=1.2)
        assert iso.get("F")[0] == isolator_force(0.003, 0.05, 1.2, coeffs, 2.0, 3)
        iso.set(i=4.0)  # clipped to i_max = 2.5 A
        assert iso.get("F")[0] == isolator_force(0.003, 0.05, 2.5, coeffs, 2.0, 3)
        iso.set(i=-1.0)  # clipped to 0 A
        assert iso.get("F")[0] == isolator_force(0.003, 0.05, 0.0, coeffs, 2.0, 3)
        # large displacement: sinh overflows to inf, as in the Python core
        iso.set(x=5.0, i=0.0)
        assert iso.get("F")[0] == math.inf
    finally:
        iso.close()


@pytest.mark.parametrize("variable", ["x", "v", "i"])
@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_input_gives_an_fmi_error(isolator, capfd, variable, bad):
    iso = _driven(isolator)
    try:
        iso.set(**{variable: bad})
        with pytest.raises(FMICallException) as err:
            iso.step(0.5, 1e-3)
        assert err.value.status >= 2  # discard or worse
        logged = capfd.readouterr().out
        assert f"input {variable} = " in logged
        assert "not finite at t = 0.5 s" in logged and "[ERROR]" in logged
    finally:
        iso.close()


def _warnings(capfd) -> list[str]:
    return [line for line in capfd.readouterr().out.splitlines() if line.startswith("[WARNING]")]


def test_range_warnings_fire_on_entry(isolator, capfd):
    iso = _driven(isolator)
    try:
        capfd.readouterr()
        sequence = [(0.001, 1.0), (0.009, 1.0), (0.010, 1.0), (0.016, 1.0), (0.001, 1.0), (-0.009, 3.5), (0, 2.0)]
        counts = []
        for k, (x, i) in enumerate(sequence):
            iso.set(x=x, i=i)
            iso.step(k * 0.1, 0.1)
            counts.append(len(_warnings(capfd)))
        # entering the identified range, then the limit, leaving, re-entering with a current above i_max
        assert counts == [0, 1, 0, 1, 0, 2, 0]
    finally:
        iso.close()


def _log_of_a_run(path: Path, capfd) -> list[str]:
    iso = _driven(path)
    capfd.readouterr()
    rng = np.random.default_rng(5)
    try:
        for k in range(200):
            iso.set(x=rng.uniform(-0.02, 0.02), v=rng.uniform(-0.4, 0.4), i=rng.uniform(-1, 4))
            iso.step(k * 1e-3, 1e-3)
    finally:
        iso.close()
    return _warnings(capfd)


def test_both_implementations_log_the_same_warnings(isolator_fmus, capfd):
    python, c = (_log_of_a_run(isolator_fmus[name], capfd) for name in IMPLEMENTATIONS)
    assert len(python) > 20
    assert c == python


def _interface(path: Path) -> dict:
    md = read_model_description(str(path))
    return {
        "variables": [
            (v.name, v.valueReference, v.type, v.causality, v.variability, v.unit, v.description)
            for v in md.modelVariables
        ],
        "starts": {v.name: float(v.start) for v in md.modelVariables if v.start is not None and v.type != "String"},
        "string_starts": {v.name: v.start for v in md.modelVariables if v.type == "String"},
        "outputs": [(o.variable.name, [d.name for d in o.dependencies]) for o in md.outputs],
        "units": sorted((u.name, repr(u.baseUnit)) for u in md.unitDefinitions),
    }


def test_interfaces_are_identical(isolator_fmus):
    python, c = (_interface(isolator_fmus[name]) for name in IMPLEMENTATIONS)
    # pythonfmu writes start values with 16 significant digits (beta_0: 132.2 for 132.20000000000002)
    assert c.pop("starts") == pytest.approx(python.pop("starts"), rel=1e-15, abs=0)
    assert c == python
    assert ("F", ["x", "v", "i"]) in c["outputs"]


@pytest.mark.parametrize("implementation", IMPLEMENTATIONS)
def test_runtime_defaults_are_table2(isolator_fmus, implementation):
    iso = _driven(isolator_fmus[implementation])
    try:
        names = list(TABLE2.as_dict())
        assert dict(zip(names, iso.get(*names), strict=True)) == TABLE2.as_dict()
        assert iso.get("i_max", "x_identified", "x_limit", "F0") == [3.0, 0.008, 0.015, 0.0]
    finally:
        iso.close()


@pytest.mark.parametrize("beyond_range", BEYOND_RANGE)
def test_force_beyond_the_range_equals_bounded_force_law(isolator, beyond_range):
    """Both units against mre_isolator_core.bounded_force_law on random inputs, inside and beyond +-x_identified
    and past the stop at +-x_limit (non-default parameters, currents outside [0, i_max] clipped first).

    Bit for bit, not to a tolerance: the C unit does the same operations in the same order, compiled
    with -ffp-contract=off (no fused multiply-adds) and calling the same libm sinh/cosh as Python's math
    module, so every rounding is the same. (A reordered but equivalent formula would differ by a few ulps
    of the largest term; near the cancellation F ~ 0 that is no relative bound at all.)"""
    # k_stop above the three devices' tangent beyond 7 mm at 2.5 A (2.44 MN/m): a stop stiffer than what it stops
    params = {"beyond_range": beyond_range, "x_identified": 0.007, "x_limit": 0.012, "k_stop": 1.0e7,
              "c_stop": 9.0e3, "n_isolators": 3, "F0": 1.5, "i_max": 2.5}
    law = bounded_force_law(TABLE2, 1.5, 3, beyond_range, 0.007, 0.012, 1.0e7, 9.0e3)
    iso = _driven(isolator, params)
    rng = np.random.default_rng(24)
    beyond = stopped = 0
    try:
        assert iso.fmu.getString([iso.vars["beyond_range"].valueReference]) == [beyond_range.encode()]
        for k in range(400):
            x, v, i = rng.uniform(-0.025, 0.025), rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 3.5)
            iso.set(x=x, v=v, i=i)
            assert iso.get("F")[0] == law(x, v, min(max(i, 0.0), 2.5))
            iso.step(k * 1e-3, 1e-3)
            beyond += abs(x) > 0.007
            stopped += abs(x) > 0.012
        assert beyond > 100 and stopped > 50  # the inputs exercised every branch
        # at the boundary the policies agree with Eq. 17 (C0), and they differ from it beyond
        iso.set(x=0.007, v=0.1, i=1.0)
        assert iso.get("F")[0] == isolator_force(0.007, 0.1, 1.0, TABLE2, 1.5, 3)
        iso.set(x=0.02, v=0.0, i=0.0)
        assert (iso.get("F")[0] == isolator_force(0.02, 0.0, 0.0, TABLE2, 1.5, 3)) == (beyond_range == "extrapolate")
    finally:
        iso.close()


@pytest.mark.parametrize(("parameters", "text"), [
    ({"beyond_range": "clamp"}, "beyond_range = 'clamp' is not one of"),
    ({"beyond_range": "stop", "x_limit": 0.005}, "x_limit = "),
    ({"beyond_range": "stop", "k_stop": -1.0}, "k_stop = "),
    ({"beyond_range": "stop", "c_stop": -1.0}, "c_stop = "),
    ({"beyond_range": "tangent", "x_identified": 0.0}, "x_identified = "),
])
def test_out_of_domain_parameters_fail_the_first_step(isolator, capfd, parameters, text):
    iso = _driven(isolator, parameters)
    try:
        logged = capfd.readouterr().out
        assert "invalid isolator parameters: " in logged and text in logged and "[ERROR]" in logged
        iso.set(x=0.001, v=0.0, i=1.0)
        assert math.isnan(iso.get("F")[0])
        with pytest.raises(FMICallException):
            iso.step(0.0, 1e-3)
    finally:
        iso.close()


def test_c_declared_starts_are_its_runtime_values(isolator_fmus):
    starts = _interface(isolator_fmus["c"])["starts"]
    iso = _driven(isolator_fmus["c"])
    try:
        reals = [n for n in starts if n != "n_isolators"]
        assert dict(zip(reals, iso.get(*reals), strict=True)) == {n: starts[n] for n in reals}
        assert iso.fmu.getInteger([12]) == [2] == [int(starts["n_isolators"])]
    finally:
        iso.close()


def test_c_fmu_state_save_restore_and_serialize(isolator_fmus, capfd):
    md = read_model_description(str(isolator_fmus["c"]))
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
    iso = _driven(isolator_fmus["c"])
    try:
        iso.set(x=0.001, v=0.01, i=1.0)
        iso.step(0.0, 0.1)
        F_saved = iso.get("F")[0]
        state = iso.fmu.getFMUstate()
        blob = iso.fmu.serializeFMUstate(state)
        capfd.readouterr()
        iso.set(x=0.009, v=0.2, i=2.0)
        iso.step(0.1, 0.1)
        assert len(_warnings(capfd)) == 1  # entered |x| > 8 mm
        iso.fmu.setFMUstate(state)
        assert iso.get("x", "v", "i", "F") == [0.001, 0.01, 1.0, F_saved]
        iso.set(x=0.009, v=0.2, i=2.0)
        iso.step(0.1, 0.1)
        # the restored state is "inside the range" again, so entering warns again
        assert len(_warnings(capfd)) == 1
        restored = iso.fmu.deSerializeFMUstate(blob)
        iso.fmu.setFMUstate(restored)
        assert iso.get("F")[0] == F_saved
        iso.fmu.freeFMUstate(restored)
        iso.fmu.freeFMUstate(state)
        with pytest.raises(FMICallException):
            iso.fmu.deSerializeFMUstate(blob[:-1])
    finally:
        iso.close()


def test_c_fmu_refuses_a_parameter_change_after_initialization(isolator_fmus, capfd):
    iso = _driven(isolator_fmus["c"])
    try:
        with pytest.raises(FMICallException):
            iso.set(k0_1=1.0)
        assert "parameter k0_1 is fixed after initialization" in capfd.readouterr().out
    finally:
        iso.close(terminate=False)


def test_c_builder_staleness_and_compiler_errors(tmp_path, monkeypatch):
    fmu = ensure_c_isolator(tmp_path)
    assert fmu == tmp_path / C_FMU_NAME and not is_stale(fmu)
    built = fmu.stat().st_mtime_ns
    assert ensure_c_isolator(tmp_path).stat().st_mtime_ns == built  # up to date: not rebuilt
    newer = tmp_path / "newer.c"
    newer.write_text("")
    monkeypatch.setattr(cbuild, "sources", lambda: [newer])
    future = fmu.stat().st_mtime + 10
    os.utime(newer, (future, future))
    assert is_stale(fmu)
    monkeypatch.setenv("CC", "false")
    with pytest.raises(BuildError, match=r"compiling mre_isolator\.c failed"):
        build_c_isolator(tmp_path / "other")
    assert not (tmp_path / "other" / C_FMU_NAME).exists()


@pytest.mark.slow
def test_elcentro_with_the_c_isolator_equals_the_python_isolator(elcentro, tmp_path):
    from orchestration.engine_hooks import run_scenario

    ensure_c_isolator()  # into fmus/, where the scenario points (the master builds only pythonfmu units)
    overrides = ("simulation.stop_time=3",)
    runs = {}
    for name in ("elcentro", "elcentro_c_isolator"):
        outcome = run_scenario(PROJECT / "scenarios" / f"{name}.yaml", overrides, out=tmp_path / name, plots=False)
        assert outcome.result.complete
        runs[name] = outcome
    python, c = runs["elcentro"], runs["elcentro_c_isolator"]
    manifest = (c.folder / "manifest.json").read_text()
    assert re.search(r"MreIsolatorC\.fmu", manifest)
    assert c.recorder.names == python.recorder.names
    np.testing.assert_array_equal(c.recorder.times, python.recorder.times)
    F = python.recorder.column("isolator.F")
    assert np.max(np.abs(F)) > 10.0  # the isolator carries real load
    assert np.max(python.recorder.column("controller.i")) > 0.1  # and the current varies
    a, b = c.recorder.data[: c.recorder.count], python.recorder.data[: python.recorder.count]
    # relative to each value; where a value crosses zero, to 1e-12 of its column's peak
    floor = 1e-12 * np.max(np.abs(b), axis=0)
    with np.errstate(invalid="ignore"):  # 0 / 0 in a column that stays 0 (equal values: no error)
        relative = np.where(a == b, 0.0, np.abs(a - b) / np.maximum(np.abs(b), floor))
    assert np.all(np.isfinite(a)) and np.max(relative) <= 1e-12


# -- the C unit held to the law's one module (mre_isolator_core) ----------------------------------------------


def _c_expression(text: str) -> float:
    """The value of a C constant expression of the fallback macros: a number, or numbers with + - * / ( )."""
    tree = ast.parse(text.strip(), mode="eval")
    for node in ast.walk(tree):
        if not isinstance(node, ast.Expression | ast.BinOp | ast.UnaryOp | ast.Constant | ast.operator
                          | ast.unaryop) or (isinstance(node, ast.Constant) and type(node.value) not in (int, float)):
            raise AssertionError(f"not a plain C constant expression: {text!r}")
    return eval(compile(tree, "<macro>", "eval"), {"__builtins__": {}})  # numbers and operators only


def c_fallback_defaults() -> dict[str, float]:
    """The defaults mre_isolator.c defines for compiling it alone (``#ifndef NAME / #define NAME value``)."""
    pairs = re.findall(r"^#ifndef (DEFAULT_\w+)\n#define \1 (.+)$", cbuild.C_SOURCE.read_text(), flags=re.M)
    return {name: _c_expression(value) for name, value in pairs}


def test_the_c_source_s_own_defaults_are_the_law_module_s():
    """mre_isolator.c keeps its Table 2 (and limits, stop) defaults for compiling alone: each equals, as a double,
    the value the build feeds from components/physics/mre_isolator_core.py."""
    fed = {v.macro: v.start for v in cbuild.variables() if v.macro is not None}
    assert set(fed) >= {f"DEFAULT_{name.upper()}" for name in TABLE2.as_dict()}
    own = c_fallback_defaults()
    assert sorted(own) == sorted(fed)
    assert {name: own[name] for name in fed} == {name: float(value) for name, value in fed.items()}


def test_the_fallback_scan_reads_a_changed_default(monkeypatch, tmp_path):
    changed = tmp_path / "mre_isolator.c"
    changed.write_text(cbuild.C_SOURCE.read_text().replace("(5.8161 / 1e-3)", "(5.8162 / 1e-3)"))
    monkeypatch.setattr(cbuild, "C_SOURCE", changed)
    assert c_fallback_defaults()["DEFAULT_K0_0"] == 5.8162 / 1e-3 != TABLE2.k0_0


def test_force_over_a_grid_equals_the_law_module(isolator):
    """F over a grid of x (to the device limit, +-15 mm), v and i in [0, 3] A equals isolator_force, bit for bit."""
    iso = _driven(isolator)
    points = 0
    try:
        for x in np.linspace(-0.015, 0.015, 31):
            for v in (-0.5, -0.05, 0.0, 0.05, 0.5):
                for i in np.linspace(0.0, 3.0, 7):
                    iso.set(x=float(x), v=v, i=float(i))
                    assert iso.get("F")[0] == isolator_force(float(x), v, float(i), TABLE2, 0.0, 2), (x, v, i)
                    points += 1
    finally:
        iso.close()
    assert points == 31 * 5 * 7
