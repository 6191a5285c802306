"""ecos (the Open Simulation Platform's lightweight engine, PyPI ``ecospy``) runs our whole system.

What ecos does (ecos 0.7, ``simulation.cpp`` and ``fixed_step_algorithm.cpp``):

* **Initialization.** Each unit enters initialization mode, then the chosen SSP parameter
  set is applied, in initialization mode (FMI 2.0 allows it; the ground unit once ignored
  it and played zeros), then values are exchanged and every unit leaves it.
* **A step from t to t + h.** Every unit (in parallel) writes its pending inputs, calls
  ``fmi2DoStep(t, h)`` and reads its outputs; then every connection copies the outputs so
  read to the connected inputs, which are written at once. Outputs read right after the
  step carry the inputs of t: a direct-feedthrough output (the isolator force, the
  building's accelerations) reaches its consumer one step late. That is libcosim's scheme,
  and :func:`orchestration.interop.libcosim_export.libcosim_scheme` (Jacobi, every connection
  delayed, inputs held) configures our master the same way.
* **Time.** ecos adds h to a double each step; with h = 2^-9 s the sum is exact, so both
  masters hand the units the same time points bit for bit (as in ``test_libcosim.py``).
* **Parameter sets.** ecos collects SSP parameter sets by *name* across components and
  applies the one ``init(parameter_set=...)`` names. Our exporter gives every unit's set
  the scenario's name, so the exported package runs in ecos as it is.
* **What it records.** After the exchange ecos writes the new inputs and reads every
  output again, so a feedthrough output read after a step holds the inputs of t + h,
  while the connections carried the value read before that (see above). Our master in
  this scheme records the value it passes on, so ecos's row k of ``isolator.F``,
  ``building.a_0`` and ``building.arel_j`` is our row k + 1; every state is the same row.

The comparison: El Centro ×0.5 (strong motion from about 1.5 s), 0-4 s, SOSM control, all
four FMUs, ecos against our master in ecos's scheme; every recorded variable, difference
divided by its peak.
"""

from __future__ import annotations

import contextlib
import zipfile
from pathlib import Path

import numpy as np
import pytest

from orchestration.engine_hooks import plan_scenario, resolve_scenario
from orchestration.interop.libcosim_export import libcosim_scheme
from orchestration.interop.ssp_package import export_ssp, load_ssp
from orchestration.master.session import run_plan

from ..conftest import PROJECT, shipped_record

ELCENTRO = PROJECT / "scenarios" / "elcentro.yaml"
STEP = 2.0**-9  # s: exact in binary, so ecos's accumulated time equals our k*h
STOP = 4.0  # s


def _ecos_reason() -> str | None:
    """None if ecospy imports and loads its library (libecosc needs Debian's libtbb12), else why not."""
    try:
        from ecospy import EcosLib

        EcosLib.version()
    except Exception as exc:  # ImportError; OSError from the shared library (e.g. libtbb.so.12 missing)
        return f"ecospy is not usable: {type(exc).__name__}: {exc}"
    return None


_REASON = _ecos_reason()
if _REASON is not None:
    print(f"test_ecos skipped: {_REASON}")
# slow: the El Centro system in ecos and in our master
pytestmark = [pytest.mark.skipif(_REASON is not None, reason=_REASON or ""), pytest.mark.slow]


def run_ecos(package: Path, workdir: Path, names: list[str], step: float, n_steps: int,
             parameter_set: str) -> tuple[np.ndarray, np.ndarray]:
    """Run an exported ``.ssp`` in ecos: (times, values[n_steps + 1, len(names)]) read after each step.

    The package is extracted into ``workdir`` (the working directory of the run, so the
    package-relative record path resolves); ``parameter_set`` is the name every unit's set has
    (the exported scenario's name).
    """
    from ecospy import EcosLib, EcosSimulation

    with zipfile.ZipFile(package) as z:
        z.extractall(workdir)
    EcosLib.set_log_level("warn")
    ids = [name.replace(".", "::", 1) for name in names]
    times = np.empty(n_steps + 1)
    data = np.empty((n_steps + 1, len(ids)))
    with contextlib.chdir(workdir):
        sim = EcosSimulation(step_size=step, ssp_path=str(workdir))
        try:
            sim.init(parameter_set=parameter_set)
            for k in range(n_steps + 1):
                if k:
                    sim.step()
                times[k] = sim.get_time()
                data[k] = [sim.get_real(i) for i in ids]
            sim.terminate()
        finally:
            sim.free()
    return times, data


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("ecos")
    shipped_record("elcentro_1940_ns.csv")
    plan = plan_scenario(ELCENTRO, ("simulation.algorithm=jacobi", f"simulation.step={STEP!r}",
                                    f"simulation.stop_time={STOP!r}"))
    package = export_ssp(plan, tmp / "elcentro.ssp")
    ours = run_plan(resolve_scenario(libcosim_scheme(load_ssp(package))), out=tmp / "ours", plots=False)
    assert ours.result.complete
    names = [f"{unit}.{var}" for unit, var in plan.recorded]
    n_steps = round(STOP / STEP)
    times, data = run_ecos(package, tmp / "ecos", names, STEP, n_steps, plan.loaded.scenario.name)
    return names, times, data, ours.recorder, plan


def _building_m0(parameters: dict) -> float:
    """Base-floor mass m_0 [kg]: the scenario's value, else the FMU's declared start value."""
    if "m_0" in parameters:
        return float(parameters["m_0"])
    from fmpy import read_model_description

    md = read_model_description(str(PROJECT / "fmus" / "ShearBuilding.fmu"))
    return float(next(v.start for v in md.modelVariables if v.name == "m_0"))


def test_elcentro_in_ecos_equals_our_master_in_ecos_scheme(runs):
    names, times, data, ours, _ = runs
    # t = 0 .. 4 s: all four units' recorded outputs and the building's 6 energy integrals
    assert data.shape == (2049, 31)
    assert {n.split(".")[0] for n in names} == {"ground", "building", "isolator", "controller"}
    col = {n: k for k, n in enumerate(names)}
    # the record is played (parameters set in initialization mode were used) and the system responds
    assert np.max(np.abs(data[:, col["ground.ag"]])) > 1.0
    assert np.max(np.abs(data[:, col["building.x_0"]])) > 1e-3
    assert np.ptp(data[:, col["controller.i"]]) > 0.5
    mine = ours.data[: ours.count]
    assert ours.names == names and mine.shape == data.shape
    np.testing.assert_array_equal(times, ours.times)  # 2^-9 s: the same time points bit for bit
    peak = np.max(np.abs(mine), axis=0)
    # ecos reads the feedthrough outputs again after writing the next step's inputs; our master (in
    # the same scheme) records them with the inputs the step ran with. Every state is the same row.
    feedthrough = {"isolator.F", "building.a_0"} | {n for n in names if n.startswith("building.arel_")}
    # Same FMUs, same inputs at the same times, same operations: equal to the last bit is
    # expected; 1e-9 of peak leaves room only for a libm difference, far below the size of the
    # differences the timing makes (0.03-0.13 of peak here) and of the scheme difference (test_libcosim.py).
    tol = 1e-9 * peak
    for name, k in col.items():
        if name not in feedthrough:  # states, and the upper floors' absolute accelerations (springs and dampers)
            assert np.max(np.abs(data[:, k] - mine[:, k])) <= tol[k], name
    # The isolator force ecos reads at t_k (inputs of t_k) is the one our master read after the step into t_k+1.
    k = col["isolator.F"]
    assert np.max(np.abs(data[:-1, k] - mine[1:, k])) <= tol[k] < np.max(np.abs(data[:, k] - mine[:, k]))
    # The building's accelerations at t_k: ecos with ag(t_k) and F passed on at t_k (our F row k), ours with
    # ag(t_k-1) and F row k-1. The model is linear: arel_j = (states) - ag - [j = 0] F/m_0, a_j = arel_j + ag.
    ag, force = mine[:, col["ground.ag"]], mine[:, col["isolator.F"]]
    d_ag, d_force = np.diff(ag), np.diff(force)
    m_0 = _building_m0(runs[4].parameters.get("building", {}))
    for name, k in col.items():
        if name.startswith("building.arel_") or name == "building.a_0":
            expected = (0.0 if name == "building.a_0" else -d_ag) - (d_force / m_0 if name.endswith("_0") else 0.0)
            error = np.abs((data[1:, k] - mine[1:, k]) - expected)
            assert np.max(error) <= tol[k] and np.max(np.abs(data[:, k] - mine[:, k])) > tol[k], name
