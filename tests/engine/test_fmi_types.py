"""Every FMI type through the master: connections, parameters, start values, recording.

Fast tests drive the coupling algorithm with fake units (tests/support/fake_units.py) whose values are
plain Python; the others run two C units written for this (tests/support/typed/*.c, built by
tests/support/typed_build.py) and compare with fmpy's own simulator on the same FMU: integers,
Booleans, enumerations, strings and Float32 values must be equal exactly; Reals to 1e-12
relative (both sides compute them with the same operations; the values are short decimals,
the bound only leaves room for CSV formatting, '%.12g').
"""

from __future__ import annotations

from pathlib import Path

import fmpy
import numpy as np
import pandas as pd
import pytest

from orchestration.master.algorithm import CouplingAlgorithm
from orchestration.master.errors import ScenarioError, SimulationError
from orchestration.master.execution import execute
from orchestration.master.graph import Link
from orchestration.master.recorder import Recorder, write_timeseries
from orchestration.master.resolve import resolve
from orchestration.master.scenario import load_scenario
from orchestration.master.session import run_plan

from ..support.fake_units import FakeUnit, clock
from ..support.typed_build import ITEMS, TYPES2, TYPES3, build_typed2, build_typed3

H, STEPS = 0.1, 12


# -- fake units: the algorithm's rules for values of other types ----------------------------------------


def counter(name: str = "src", calls: list | None = None, kinds: tuple[str, ...] = ("Integer", "String")) -> FakeUnit:
    """Outputs n (steps done) as an Integer and f"s{n}" as a String; no inputs."""
    return FakeUnit(name, [], ["n", "s"], lambda st, i: {"n": st["n"], "s": f"s{st['n']}"},
                    lambda st, i, t, h: {"n": st["n"] + 1}, state={"n": 0}, calls=calls,
                    types=dict(zip(("n", "s"), kinds, strict=True)))


def holder(name: str = "dst", calls: list | None = None) -> FakeUnit:
    """Holds the inputs it saw when its last step started (no feedthrough)."""
    return FakeUnit(name, ["u", "w"], ["zu", "zw"], lambda st, i: {"zu": st["u"], "zw": st["w"]},
                    lambda st, i, t, h: {"u": i["u"], "w": i["w"]}, state={"u": -1, "w": "none"}, calls=calls,
                    types={"u": "Integer", "w": "String", "zu": "Integer", "zw": "String"})


def run_fakes(units, links, watched, scheme, steps=5):
    algo = CouplingAlgorithm(units, links, watched, scheme)
    rec = Recorder(algo, list(watched), steps)
    result = execute(algo, 0.0, steps * H, H, [rec], executor="python")
    assert result.complete, result.error
    return algo, rec


@pytest.mark.parametrize(("scheme", "delayed", "lag"), [("gauss-seidel", False, 0), ("jacobi", False, 1),
                                                        ("gauss-seidel", True, 1)])
def test_discrete_values_pass_as_they_are_with_the_scheme_ordering(scheme, delayed, lag):
    links = [Link(("src", "n"), ("dst", "u"), delayed), Link(("src", "s"), ("dst", "w"), delayed)]
    watched = [("src", "n"), ("dst", "zu"), ("dst", "zw")]
    algo, rec = run_fakes([counter(), holder()], links, watched, scheme)
    # the holder's outputs after step k are the inputs it got for step k: the source's value after
    # that step (Gauss-Seidel, the source stepped first) or at its start (Jacobi, delayed)
    n = rec.column("src.n")
    assert n.tolist() == [0, 1, 2, 3, 4, 5]
    assert rec.column("dst.zu").tolist() == [-1] + [k + 1 - lag for k in range(5)]
    assert rec.column("dst.zw").tolist() == ["none"] + [f"s{k + 1 - lag}" for k in range(5)]
    assert algo.typed_value(("dst", "zw")) == f"s{5 - lag}"
    assert {op.kind for op in algo.program()} == {"tset", "step", "tget"}


def test_a_real_only_system_runs_the_real_program():
    algo = CouplingAlgorithm([clock(), FakeUnit("g", ["u"], ["w"], lambda s, i: {"w": 2 * i["u"]},
                                                dependencies={"w": ("u",)})],
                             [Link(("clock", "y"), ("g", "u"))], [("g", "w")])
    assert {op.kind for op in algo.program()} == {"set", "step", "get"} and algo.typed == []


def test_discrete_reals_are_held_not_averaged():
    # y = t, declared discrete: the receiver gets y(t + h) (Gauss-Seidel, fresh), not the
    # step mean t + h/2 it gets from the same output declared continuous
    def system(discrete):
        src = FakeUnit("clock", [], ["y"], lambda s, i: {"y": s["t"]}, lambda s, i, t, h: {"t": t + h},
                       state={"t": 0.0}, discrete=("y",) if discrete else ())
        dst = FakeUnit("dst", ["u"], ["z"], lambda s, i: {"z": s["z"]}, lambda s, i, t, h: {"z": i["u"]},
                       state={"z": -1.0})
        return run_fakes([src, dst], [Link(("clock", "y"), ("dst", "u"))], [("dst", "z")], "gauss-seidel")[1]

    held, averaged = system(True).column("dst.z"), system(False).column("dst.z")
    np.testing.assert_allclose(held[1:], H * np.arange(1, 6), rtol=0, atol=1e-15)
    np.testing.assert_allclose(averaged[1:], H * np.arange(1, 6) - H / 2, rtol=0, atol=1e-15)


@pytest.mark.parametrize("scheme", ["gauss-seidel", "jacobi"])
def test_feedthrough_of_other_types_is_propagated_to_the_end_of_step(scheme):
    # plus1.w = u + 1 depends directly on its Integer input: after every step it must be
    # consistent with the source's value at the same time, whatever the scheme
    plus1 = FakeUnit("plus1", ["u"], ["w"], lambda s, i: {"w": i["u"] + 1}, dependencies={"w": ("u",)},
                     types={"u": "Integer", "w": "Integer"})
    _, rec = run_fakes([plus1, counter()], [Link(("src", "n"), ("plus1", "u"))], [("src", "n"), ("plus1", "w")],
                       scheme)
    assert (rec.column("plus1.w") - rec.column("src.n")).tolist() == [1.0] * 6


def test_big_integers_pass_exactly_but_are_not_recorded_inexactly():
    big = 2**63 - 1  # not a float64
    src = FakeUnit("src", [], ["n"], lambda s, i: {"n": big - s["k"]}, lambda s, i, t, h: {"k": s["k"] + 1},
                   state={"k": 0}, types={"n": "Int64"})
    dst = FakeUnit("dst", ["u"], ["z"], lambda s, i: {"z": s["z"]}, lambda s, i, t, h: {"z": i["u"]},
                   state={"z": 0}, types={"u": "Int64", "z": "Int64"})
    algo = CouplingAlgorithm([src, dst], [Link(("src", "n"), ("dst", "u"))], [])
    algo.initialize(0.0, 1.0)
    for k in range(3):
        algo.step(k * H, H)
        assert dst.state["z"] == big - (k + 1)  # exact: no float in between
    recorded = CouplingAlgorithm([src, dst], [Link(("src", "n"), ("dst", "u"))], [("dst", "z")])
    with pytest.raises(SimulationError, match=r"cannot be recorded .* 2\^53") as info:
        recorded.initialize(0.0, 1.0)
        for k in range(3):
            recorded.step(k * H, H)
    assert info.value.unit == "dst" and info.value.variable == "z"


def test_csv_columns_of_every_kind_read_back_exactly_with_pandas(tmp_path):
    texts = ["plain", 'a "quoted", comma', "two\nlines", "", "ünï ∆", "12"]
    n = len(texts)
    time = np.arange(n) * H
    ints = np.array([0, -1, 2**53, -(2**53), 1234567890123, 7], dtype=float)  # %.12g would round the large ones
    bools = np.array([1, 0, 1, 1, 0, 0], dtype=float)
    reals = np.array([0.1, -2.5e-7, 3.0, 1e300, -0.0, 2 / 3])
    data = np.column_stack([reals, ints, np.full(n, np.nan), bools])
    path = tmp_path / "t.csv"
    write_timeseries(path, time, ["a.r", "a.i", "a.s", "a.b"], data, ["real", "integer", "string", "integer"],
                     {2: texts})
    frame = pd.read_csv(path, dtype={"a.s": str}, keep_default_na=False)
    assert frame["a.s"].tolist() == texts
    assert frame["a.i"].dtype == np.int64 and frame["a.i"].tolist() == [int(x) for x in ints]
    assert frame["a.b"].tolist() == [1, 0, 1, 1, 0, 0]
    np.testing.assert_array_equal(frame["a.r"].to_numpy(), [float(f"{x:.12g}") for x in reals])
    # the Real-only writer is unchanged: same bytes with and without kinds
    write_timeseries(tmp_path / "a.csv", time, ["a.r"], reals[:, None])
    write_timeseries(tmp_path / "b.csv", time, ["a.r"], reals[:, None], ["real"], {})
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()


# -- the C units: our master against fmpy on the same FMUs ----------------------------------------


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("typed")
    return {"2": build_typed2(folder), "3": build_typed3(folder)}


def scenario(tmp_path: Path, units: dict, connections=(), outputs="all", extra: str = "",
             name: str = "types") -> Path:
    lines = [f"name: {name}", "units:"]
    for unit, (fmu, params) in units.items():
        lines += [f"  {unit}:", f"    fmu: {fmu}"]
        if params:
            lines.append("    parameters:")
            lines += [f"      {k}: {v}" for k, v in params.items()]
    lines.append("connections:" + ("" if connections else " []"))
    lines += [f"  - {c}" for c in connections]
    lines.append(f"outputs: {outputs}")
    lines += ["simulation:", f"  step: {H}", f"  stop_time: {STEPS * H:.10g}", extra,
              f"results:\n  dir: {tmp_path / 'results'}"]
    path = tmp_path / f"{name}.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def run(path: Path, out: Path):
    outcome = run_plan(resolve(load_scenario(path)), out, plots=False)
    frame = pd.read_csv(out / "timeseries.csv", dtype=str, keep_default_na=False)
    return outcome, frame


def fmpy_strings(fmu: Path, version: str, start: dict, names: list[str]) -> dict[str, list[str]]:
    """String outputs at every communication point, stepping the FMU with fmpy's own classes."""
    md = fmpy.read_model_description(str(fmu))
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    directory = fmpy.extract(str(fmu))
    cls = fmpy.fmi2.FMU2Slave if version == "2" else fmpy.fmi3.FMU3Slave
    slave = cls(guid=md.guid, unzipDirectory=directory, modelIdentifier=md.coSimulation.modelIdentifier)
    slave.instantiate()
    for k, v in start.items():
        setter = {str: slave.setString, bool: slave.setBoolean, float: getattr(slave, "setReal", None)
                  or slave.setFloat64}[type(v)]
        setter([vrs[k]], [v])
    if version == "2":
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
    else:
        slave.enterInitializationMode(startTime=0.0)
        slave.exitInitializationMode()
    out = {n: [] for n in names}
    for k in range(STEPS + 1):
        for n in names:
            out[n].append(slave.getString([vrs[n]])[0])
            out[n][-1] = out[n][-1].decode() if isinstance(out[n][-1], bytes) else out[n][-1]
        if k < STEPS:
            slave.doStep(k * H, H)
    slave.terminate()
    slave.freeInstance()
    return out


LABEL = 'a "b", c'


@pytest.mark.parametrize("version", ["2", "3"])
def test_a_unit_of_every_type_equals_fmpy_simulate_fmu(fmus, tmp_path, version):
    types = TYPES2 if version == "2" else TYPES3
    params = {"label": f"'{LABEL}'", "first": "high", "start": 1.5} | ({"k": -2147483000} if version == "2"
                                                                      else {"k8": -7})
    path = scenario(tmp_path, {"g": (fmus[version], params)})
    outcome, frame = run(path, tmp_path / "run")
    assert outcome.result.complete, outcome.result.error
    assert outcome.summary["executor"] == "python"
    assert "not Real (g.y_" in outcome.summary["executor_note"]  # the Python executor, and why
    start = {"first": 5, "start": 1.5} | ({"k": -2147483000} if version == "2" else {"k8": -7})
    numeric = [f"y_{t}" for t in types if t != "String"]
    ref = fmpy.simulate_fmu(str(fmus[version]), stop_time=STEPS * H, output_interval=H, start_values=start,
                            output=numeric)
    assert len(ref) == len(frame) == STEPS + 1
    for name in numeric:
        ours = frame[f"g.{name}"]
        if name == "y_Float32":  # '%.12g' keeps the 9 digits a float32 needs: equal as float32
            assert ours.astype(float).astype(np.float32).tolist() == ref[name].astype(np.float32).tolist()
        elif name in ("y_Real", "y_Float64"):  # start + 0.25 n: 12 digits hold them, 1e-12 is CSV rounding room
            np.testing.assert_allclose(ours.astype(float), ref[name].astype(float), rtol=1e-12, atol=0)
        else:  # integers, enumerations, Booleans (0/1): exactly, written as whole numbers
            assert ours.map(int).tolist() == [int(x) for x in ref[name]], name
    strings = fmpy_strings(fmus[version], version, {"label": LABEL}, ["y_String"])
    assert frame["g.y_String"].tolist() == strings["y_String"] == [f"{LABEL}|{k}" for k in range(STEPS + 1)]
    # every output of the unit is a column, the enumeration follows its items
    assert list(frame.columns) == ["time", *(f"g.y_{t}" for t in types)]
    assert set(frame["g.y_Enumeration"].map(int)) <= {v for _, v in ITEMS}


@pytest.mark.parametrize(("version", "scheme", "lag"), [("2", "gauss-seidel", 0), ("2", "jacobi", 1),
                                                        ("3", "gauss-seidel", 0), ("3", "jacobi", 1)])
def test_a_chain_passes_every_type_exactly(fmus, tmp_path, version, scheme, lag):
    types = TYPES2 if version == "2" else TYPES3
    units = {"gen": (fmus[version], {"label": f"'{LABEL}'", "start": 0.1}),
             "echo": (fmus[version], {"echo": "true"})}
    connections = [f"gen.y_{t} -> echo.u_{t}" for t in types]
    outputs = "\n" + "\n".join(f"  - {u}.y_{t}" for u in ("gen", "echo") for t in types)
    path = scenario(tmp_path, units, connections, outputs, extra=f"  algorithm: {scheme}")
    outcome, frame = run(path, tmp_path / "run")
    assert outcome.result.complete, outcome.result.error
    for t in types:  # the echo's value after step k is what it received for step k: the source at k (or k - 1)
        assert frame[f"echo.y_{t}"].tolist()[1:] == frame[f"gen.y_{t}"].tolist()[1 - lag: len(frame) - lag], t


def test_fmi3_64_bit_extremes_pass_exactly_and_are_refused_for_recording(fmus, tmp_path):
    units = {"gen": (fmus["3"], {"big": "true"}), "echo": (fmus["3"], {"echo": "true"})}
    connections = [f"gen.y_{t} -> echo.u_{t}" for t in ("Int64", "UInt64")]
    plan = resolve(load_scenario(scenario(tmp_path, units, connections, outputs="[]")))
    created = plan.create_units()
    algo = plan.create_algorithm(created)
    echo = algo.units["echo"]
    vr = {t: echo.description.variables[f"y_{t}"].vr for t in ("Int64", "UInt64")}
    try:
        algo.initialize(0.0, STEPS * H)
        for k in range(3):
            algo.step(k * H, H)
            assert echo.get_values("Int64", [vr["Int64"]]) == [-(2**63) + k + 1]
            assert echo.get_values("UInt64", [vr["UInt64"]]) == [2**64 - 1 - (k + 1)]
    finally:
        for unit in created:
            unit.terminate()
    outcome = run_plan(resolve(load_scenario(scenario(tmp_path, {"gen": units["gen"]}, name="big"))),
                       tmp_path / "big", plots=False)
    assert outcome.result.status == "failed"
    # INT64_MIN = -2^63 is a float64; UINT64_MAX is not: the first value refused, at t = 0
    assert "unit 'gen', variable 'y_UInt64', t = 0 s" in outcome.summary["error"]
    assert "2^53" in outcome.summary["error"]


def test_type_problems_are_scenario_errors_naming_both_ends(fmus, tmp_path):
    units = {"a": (fmus["2"], {"first": "hihg", "echo": 1, "k": 2**31, "label": 3}),
             "b": (fmus["3"], {"k8": 200, "first": 4, "big": "false"})}
    connections = ["a.y_Integer -> a.u_Real", "b.y_Int64 -> a.u_Integer", "b.y_Int32 -> b.u_Int32",
                   "b.y_Float64 -> a.u_Real", "b.y_Enumeration -> a.u_Enumeration", "a.y_Boolean -> b.u_Boolean",
                   "a.y_Integer -> b.u_Int32", "a.y_Real -> b.u_Float32"]
    path = scenario(tmp_path, units, connections, outputs="[a.y_Real]",
                    extra="limits:\n  max_abs:\n    a.y_String: 1")
    with pytest.raises(ScenarioError) as info:
        resolve(load_scenario(path))
    text = str(info.value)
    assert "did you mean 'high'" in text and "'echo' is Boolean, got 1" in text
    assert "'k' is Integer, 2147483648 is out of its range" in text and "'label' is String, got 3" in text
    assert "'k8' is Int8, 200 is out of its range [-128, 127]" in text
    assert "'first' is an Enumeration with items low = 1, mid = 2, high = 5, neg = -3, got 4" in text
    assert "type mismatch: a.y_Integer is Integer, a.u_Real is Real" in text
    assert "type mismatch: b.y_Int64 is Int64, a.u_Integer is Integer" in text
    assert "type mismatch: a.y_Real is Real, b.u_Float32 is Float32" in text
    assert "a.y_String is a String: max_abs needs a number" in text
    # equal value sets connect (FMI 3.0 Float64/Int32 and FMI 2.0 Real/Integer, enumerations, Booleans)
    for ok in ("b.y_Float64 -> a.u_Real", "b.y_Enumeration", "a.y_Boolean -> b.u_Boolean", "a.y_Integer -> b.u_Int32",
               "b.y_Int32 -> b.u_Int32"):
        assert not any(ok in line and "mismatch" in line for line in text.splitlines()), ok
