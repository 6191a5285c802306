"""In-process units stepped by the engine's CouplingAlgorithm (orchestration.inprocess) against three
independent expectations: the hand-written monolithic oracle (tests/support/monolithic_oracle.py), the engine's own
numpy executor (CouplingAlgorithm.step), and the FMU co-simulation of the same scenario (slow)."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
import yaml

from components.physics.ground_motion_core import GroundMotion, read_record
from components.physics.monolithic import SystemSetup, Trajectory
from components.physics.sosm_controller_core import HAND_PICKED_GAINS
from orchestration.inprocess import CONNECTIONS, build_units, simulate_coupled
from orchestration.inprocess.scalar_executor import ScalarExecutor, ScalarUnavailable
from orchestration.master.algorithm import CouplingAlgorithm
from orchestration.master.graph import Link

from ..conftest import PROJECT
from ..support.fake_units import clock, gain
from ..support.monolithic_oracle import simulate_coupled as oracle

FIELDS = ("t", "x", "v", "a", "arel", "F", "i", "ag")
SCHEMES = [("gauss-seidel", "step-mean"), ("gauss-seidel", "hold"), ("jacobi", "step-mean"), ("jacobi", "hold")]
MODES = {"sosm": None, "passive-0A": 0.0, "passive-3A": 3.0}


def setup_for(record: Path, current: float | None, **extra) -> SystemSetup:
    return SystemSetup(GroundMotion(read_record(record), scale=0.5), passive_current=current, **extra)


def assert_identical(got: Trajectory, expected: Trajectory, fields=FIELDS) -> None:
    for name in fields:
        a, b = getattr(got, name), getattr(expected, name)
        assert a.shape == b.shape, name
        assert np.array_equal(a, b), f"{name}: largest difference {np.max(np.abs(a - b)):.3g}"


@pytest.mark.parametrize(("scheme", "inputs"), SCHEMES)
@pytest.mark.parametrize("mode", MODES)
def test_equals_the_hand_written_oracle_bit_for_bit(elcentro, scheme, inputs, mode):
    """Same cores, same order, estimate and propagation: the same floating-point operations, so the same bits."""
    setup = setup_for(elcentro, MODES[mode])
    n = 3000
    got = simulate_coupled(setup, 1e-3, n, scheme, inputs)
    assert_identical(got, oracle(setup, 1e-3, n, scheme, inputs))
    assert got.t[-1] == n * 1e-3 and np.max(np.abs(got.x[:, 0])) > 1e-3  # a real response, not a rest state
    if mode == "sosm":
        assert 0.0 < np.max(got.i) <= 3.0


def test_equals_the_oracle_with_other_gains_base_floor_and_step(kobe):
    """Base-sensitivity variants (a heavier base floor tied to the ground), other gains, current limit and step."""
    from components.physics.shear_building_core import BuildingParams

    dyke = BuildingParams.dyke()
    building = BuildingParams((2 * dyke.m[0], *dyke.m[1:]), (2e4, *dyke.k[1:]), (50.0, *dyke.c[1:]))
    setup = setup_for(kobe, None, gains=HAND_PICKED_GAINS, building=building, i_max=2.5)
    assert_identical(simulate_coupled(setup, 5e-4, 4000), oracle(setup, 5e-4, 4000))


@pytest.mark.parametrize("storeys", [2, 5])
def test_other_building_sizes_agree_with_the_oracle_to_rounding(kobe, storeys):
    """The building unit computes its relative accelerations as the FMU shell does, as rows of one product with
    all its outputs (ShearBuilding.output_vector); the oracle takes them from a product with those rows alone
    (relative_acceleration). BLAS sums a row in an order that can depend on the matrix's shape: for 3 storeys the
    two agree bit for bit, for 2 and 5 storeys in the last bits, and the SOSM loop carries that on (< 1e-12)."""
    from components.physics.shear_building_core import BuildingParams

    setup = setup_for(kobe, None, building=BuildingParams.uniform(storeys))
    got, expected = simulate_coupled(setup, 1e-3, 12000), oracle(setup, 1e-3, 12000)
    assert got.x.shape == (12001, storeys + 1)
    for name in FIELDS:
        a, b = getattr(got, name), getattr(expected, name)
        assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(b)), name


@pytest.mark.parametrize(("scheme", "inputs"), SCHEMES)
def test_scalar_executor_equals_the_engine_step(elcentro, scheme, inputs):
    """The scalar executor runs CouplingAlgorithm.program(); the engine's step() runs it with numpy arrays."""
    setup = setup_for(elcentro, None)
    scalar = simulate_coupled(setup, 1e-3, 2000, scheme, inputs, executor="scalar")
    engine = simulate_coupled(setup, 1e-3, 2000, scheme, inputs, executor="python")
    assert_identical(scalar, engine)


def test_scalar_executor_leaves_the_algorithm_as_step_would(elcentro):
    """After a run, the algorithm's values, history and count equal those of the same steps done by step()."""
    algorithms = []
    for use_scalar in (True, False):
        alg = CouplingAlgorithm(build_units(setup_for(elcentro, None)), CONNECTIONS, [("building", "x_3")])
        alg.initialize(0.0, 0.5)
        if use_scalar:
            ScalarExecutor(alg, [("building", "x_3")]).run(0, 500, lambda k: k * 1e-3)
        else:
            for k in range(500):
                alg.step(k * 1e-3, (k + 1) * 1e-3 - k * 1e-3)
        algorithms.append(alg)
    a, b = algorithms
    assert np.array_equal(a.values, b.values) and a.known == b.known == 501
    assert all(np.array_equal(x, y) for x, y in zip(a.history, b.history, strict=True))


def test_scalar_executor_refuses_units_without_a_fast_path():
    alg = CouplingAlgorithm([clock(), gain()], [Link(("clock", "y"), ("gain", "u"))], [("gain", "w")])
    alg.initialize(0.0, 1.0)
    with pytest.raises(ScalarUnavailable, match="fast path"):
        ScalarExecutor(alg, [("gain", "w")])


def _yaml_connections(path: Path) -> set[Link]:
    links = set()
    for conn in yaml.safe_load(path.read_text())["connections"]:
        if isinstance(conn, str):
            source, target = (p.strip() for p in conn.split("->"))
            delayed = False
        else:
            source, target, delayed = conn["source"], conn["target"], bool(conn.get("delayed", False))
        links.add(Link(tuple(source.split(".")), tuple(target.split(".")), delayed))
    return links


def test_connections_are_those_of_the_scenario():
    assert set(CONNECTIONS) == _yaml_connections(PROJECT / "scenarios" / "isolated_building.yaml")
    assert len(CONNECTIONS) == len(set(CONNECTIONS))


def test_gauss_seidel_order_is_the_scenarios(elcentro):
    """ground, controller, building, isolator: the order a scenario run of the FMUs uses (graph.gauss_seidel_order)."""
    alg = CouplingAlgorithm(build_units(setup_for(elcentro, None)), CONNECTIONS)
    assert [u.name for u in alg.order] == ["ground", "controller", "building", "isolator"]


def test_the_engine_does_not_import_the_inprocess_package():
    for path in (PROJECT / "orchestration" / "master").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            assert not any(n.startswith("orchestration.inprocess") for n in names), path


@pytest.mark.slow
def test_equals_the_fmu_cosimulation(tmp_path, elcentro):
    """The FMUs of scenarios/elcentro.yaml through the master, against the in-process units: every exchanged
    value equals bit for bit. Only the absolute accelerations differ, by rounding (< 1e-15 of their peak): the
    trajectory's are arel + ag, the building FMU's a_j sums the same terms in one row product."""
    from orchestration.engine_hooks import plan_scenario, run_scenario

    T = 4.0
    compared = {"building.x_0": ("x", 0), "building.x_3": ("x", 3), "building.v_0": ("v", 0),
                "building.v_3": ("v", 3), "building.arel_0": ("arel", 0), "building.arel_3": ("arel", 3),
                "isolator.F": ("F", None), "controller.i": ("i", None), "ground.ag": ("ag", None)}
    for mode, overrides, current in (("sosm", (), None),
                                     ("passive", ("controller.mode=passive", "controller.i_passive=3"), 3.0)):
        args = (f"simulation.stop_time={T}", *overrides)
        outcome = run_scenario(PROJECT / "scenarios" / "elcentro.yaml", args, out=tmp_path / mode, plots=False)
        assert outcome.result.complete
        got = simulate_coupled(setup_for(elcentro, current), 1e-3, round(T / 1e-3))
        rec = outcome.recorder
        assert np.array_equal(np.asarray(rec.times), got.t)
        for name, (field, j) in compared.items():
            expected = getattr(got, field) if j is None else getattr(got, field)[:, j]
            assert np.array_equal(rec.column(name), expected), name
        for j in range(4):
            a = rec.column(f"building.a_{j}")
            assert np.max(np.abs(a - got.a[:, j])) <= 1e-15 * np.max(np.abs(a)), j
        if mode == "sosm":
            assert 0.0 < np.max(got.i) <= 3.0
    # the adapters declare the FMUs' variables and direct-feedthrough dependencies
    plan = plan_scenario(PROJECT / "scenarios" / "elcentro.yaml", ())
    assert set(plan.links) == set(CONNECTIONS)
    for unit in build_units(setup_for(elcentro, None)):
        fmu = plan.descriptions[unit.name]
        for name, var in unit.description.variables.items():
            assert (fmu.variables[name].causality, fmu.variables[name].unit) == (var.causality, var.unit), name
            if var.causality == "output":
                assert set(fmu.feedthrough(name)) == set(unit.description.feedthrough(name)), name
        fmu_ports = {n for n, v in fmu.variables.items() if v.causality in ("input", "output")}
        assert fmu_ports == set(unit.description.variables), unit.name


def test_units_refuse_undeclared_references_and_other_types(elcentro):
    building = build_units(setup_for(elcentro, None))[1]
    variables = building.description.variables
    ag_F = building.prepare([variables["ag"].vr, variables["F"].vr])
    building.set_real(ag_F, np.array([1.0, -50.0]))
    arel = building.prepare([variables["arel_0"].vr, variables["x_0"].vr])
    # at rest: the base's relative acceleration is -ag - F / m_0 (Eq. 23 with x = v = 0)
    assert building.get_real(arel).tolist() == [pytest.approx(-1.0 + 50.0 / 98.3, rel=1e-15), 0.0]
    with pytest.raises(KeyError, match="not declared"):
        building.prepare([len(variables)])
    with pytest.raises(KeyError, match="only outputs"):
        building.get_real(ag_F)
    with pytest.raises(KeyError, match="only inputs"):
        building.set_real(arel, np.zeros(2))
    with pytest.raises(KeyError, match="Real variables only"):
        building.get_values("Integer", [0])
