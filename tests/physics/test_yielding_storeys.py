"""Yielding storeys of the shear building: Steel01 = OpenSees, Bouc-Wen = solve_ivp, linear unchanged."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from components.physics.shear_building_core import (
    BoucWen,
    BuildingParams,
    HystereticShearBuilding,
    ParameterError,
    ShearBuilding,
    Steel01,
    StoreyLaws,
    make_building,
)

PROJECT = Path(__file__).resolve().parents[2]
# A building with a soft base spring (so it does not drift away) and storey dampers.
GROUNDED = BuildingParams(m=(98.3,) * 4, k=(12e3, 516e3, 684e3, 684e3), c=(50.0, 125.0, 50.0, 50.0))
FY = (500.0, 400.0, 260.0)


def drift_history(n: int = 400, seed: int = 3, amplitude: float = 5e-3) -> np.ndarray:
    """A random drift path with reversals, several yield drifts wide [m]."""
    rng = np.random.default_rng(seed)
    steps = rng.normal(0.0, amplitude / 8, n)
    steps[rng.random(n) < 0.05] *= 10  # large jumps: yield within one increment
    return np.cumsum(steps)


def ground(n: int, seed: int = 1, h: float = 1e-3) -> np.ndarray:
    """A 2 Hz ground acceleration [m/s^2] with noise, ramped in over 0.5 s."""
    t = np.arange(n) * h
    return 6.0 * np.sin(2 * np.pi * 2.0 * t) * np.minimum(1.0, t / 0.5) + np.random.default_rng(seed).normal(0, 0.5, n)


def simulate(building, ag: np.ndarray, h: float = 1e-3) -> np.ndarray:
    out = np.empty((len(ag), 6 * building.n_levels - 2))
    for k, a in enumerate(ag):
        building.step(a, 0.0, h)
        out[k] = building.output_vector(a, 0.0)
    return out


# -- the bilinear law is OpenSees' Steel01 ----------------------------------------------------------
OPENSEES_STEEL01 = """
import json, sys
from components.physics.opensees_building_core import import_opensees
ops = import_opensees()
fy, E0, b, a, path = json.loads(sys.stdin.read())
ops.wipe()
ops.uniaxialMaterial("Steel01", 1, fy, E0, b, *a)  # a = []: a1..a4 left out (OpenSees' defaults 0, 1, 0, 1)
ops.testUniaxialMaterial(1)
out = []
for e in path:
    ops.setStrain(e)  # trial strain, then commit
    out.append((ops.getStress(), ops.getTangent()))
print("RESULT" + json.dumps(out))
"""


def opensees_steel01(fy: float, E0: float, b: float, path: np.ndarray, a: tuple[float, ...] = ()) -> np.ndarray:
    """Force and tangent of openseespy's own Steel01 along a drift path (in a subprocess: one model per process)."""
    try:
        from components.physics.opensees_building_core import OpenSeesUnavailable, import_opensees
    except ImportError as exc:
        pytest.skip(f"the OpenSees building core is not available: {exc}")
    try:
        import_opensees()
    except OpenSeesUnavailable as exc:
        pytest.skip(f"openseespy is not installed or does not import: {exc}")
    proc = subprocess.run([sys.executable, "-c", OPENSEES_STEEL01], capture_output=True, text=True, cwd=PROJECT,
                          input=json.dumps([fy, E0, b, list(a), path.tolist()]), timeout=120)
    line = next((x for x in proc.stdout.splitlines() if x.startswith("RESULT")), None)
    assert line is not None, proc.stderr[-2000:]
    return np.array(json.loads(line[len("RESULT"):]))


@pytest.mark.parametrize("b", [0.0, 0.05, 0.3])
def test_bilinear_storey_is_opensees_steel01(b):
    fy, k = 400.0, 684e3
    path = drift_history()
    assert np.max(np.abs(path)) > 3 * fy / k  # the path yields both ways
    expected = opensees_steel01(fy, k, b, path)
    law = Steel01(fy, k, b)
    got = []
    for d in path:
        got.append(law.trial(d))
        law.commit()
    got = np.array(got)
    assert got[:, 0] == pytest.approx(expected[:, 0], rel=1e-12, abs=1e-9)
    assert np.array_equal(got[:, 1], expected[:, 1])


def test_steel01_elastic_commit_is_trial_and_commit():
    fy, k, b = 400.0, 684e3, 0.05
    full, fast = Steel01(fy, k, b, 0.4, 1.0, 0.4, 1.0), Steel01(fy, k, b, 0.4, 1.0, 0.4, 1.0)  # with hardening
    for d in drift_history(seed=11):
        lower, upper = fast.elastic_band()
        c = fast.c_stress + k * (d - fast.c_strain)
        full.trial(d)
        full.commit()
        if b * k * d - lower <= c <= b * k * d + upper:
            fast.commit_elastic(d)
        else:
            fast.trial(d)
            fast.commit()
        committed = [a for a in Steel01.__slots__ if not a.startswith("t_")]  # t_*: scratch of the next trial
        assert [getattr(fast, a) for a in committed] == [getattr(full, a) for a in committed]
    assert full.c_shift_n != 1.0 and full.c_shift_p != 1.0  # reversals happened, with hardening


def test_steel01_yield_force_post_yield_slope_and_unloading():
    fy, k, b = 400.0, 684e3, 0.05
    dy = fy / k
    law = Steel01(fy, k, b)
    f, kt = law.trial(0.5 * dy)
    assert (f, kt) == (pytest.approx(0.5 * fy, rel=1e-14), k)  # elastic
    law.commit()
    f, kt = law.trial(3 * dy)
    assert f == pytest.approx(fy + b * k * 2 * dy, rel=1e-12) and kt == pytest.approx(b * k)  # post-yield b k
    law.commit()
    f2, kt2 = law.trial(3 * dy - 0.5 * dy)
    assert f2 == pytest.approx(f - 0.5 * k * dy, rel=1e-12) and kt2 == k  # unloading at k
    law.commit()
    f3, _ = law.trial(-10 * dy)  # reversed yield: on the lower bound b k d - fy (1 - b)
    assert f3 == pytest.approx(b * k * (-10 * dy) - fy * (1 - b), rel=1e-12)


def test_steel01_with_four_literal_zeros_is_wrong_as_in_opensees():
    # OpenSees' pitfall, reproduced: a2 = a4 = 0 make the isotropic shifts 0 * inf = NaN at the first
    # reversal; NaN bounds never bind, so the storey no longer yields after it (silently wrong forces).
    fy, k, b = 400.0, 684e3, 0.05
    path = drift_history(seed=5)
    zeros, default = Steel01(fy, k, b, 0.0, 0.0, 0.0, 0.0), Steel01(fy, k, b)
    got, right = [], []
    for d in path:
        got.append(zeros.trial(d)[0])
        right.append(default.trial(d)[0])
        zeros.commit()
        default.commit()
    assert np.max(np.abs(np.array(got) - right)) > fy  # far off the intended law
    expected = opensees_steel01(fy, k, b, path, (0.0, 0.0, 0.0, 0.0))
    assert np.array(got) == pytest.approx(expected[:, 0], rel=1e-12, abs=1e-9)  # ... exactly as OpenSees is


# -- Bouc-Wen against a tight ODE integration -----------------------------------------------------------
def test_bouc_wen_building_matches_solve_ivp_at_1ms():
    fy, b, n = FY, (0.05,) * 3, (2.0,) * 3
    N, h = 900, 1e-3
    ag = ground(N)
    laws = StoreyLaws("bouc-wen", fy, b, n, substeps=1)
    got = simulate(HystereticShearBuilding(GROUNDED, laws), ag, h)
    m, ks, cs = np.array(GROUNDED.m), np.array(GROUNDED.k[1:]), np.array(GROUNDED.c[1:])
    fy_, b_, n_ = np.array(fy), np.array(b), np.array(n)
    dy = fy_ / ks

    def rhs(_t, y, a):  # Wen (1976) with A = 1, z dimensionless, beta = gamma = 0.5
        x, v, z = y[:4], y[4:8], y[8:]
        dv = np.diff(v)
        f = b_ * ks * np.diff(x) + (1 - b_) * fy_ * z + cs * dv
        load = -m * a
        load[0] -= GROUNDED.k[0] * x[0] + GROUNDED.c[0] * v[0]
        load[:-1] += f
        load[1:] -= f
        zdot = dv / dy * (1 - np.abs(z) ** n_ * (0.5 * np.sign(dv * z) + 0.5))
        return np.concatenate([v, load / m, zdot])

    y, ref = np.zeros(11), np.empty((N, 11))
    for k in range(N):  # inputs held over each step, as the unit holds them
        y = solve_ivp(rhs, (0, h), y, args=(ag[k],), method="DOP853", rtol=1e-11, atol=1e-13).y[:, -1]
        ref[k] = y
    assert np.max(np.abs(ref[:, 8:])) > 0.99  # the storeys reached their yield plateau
    drift = np.diff(ref[:, :4], axis=1)
    peak = np.max(np.abs(drift), axis=0)
    assert np.max(np.abs(got[:, 16:19] - drift)) < 3e-3 * peak.max()  # whole history
    assert np.max(np.abs(got[:, 16:19]), axis=0) == pytest.approx(peak, rel=1e-3)


def test_bouc_wen_law_saturates_at_yield_and_unloads_elastically():
    fy, k, b = 400.0, 684e3, 0.0
    law = BoucWen(fy, k, b, n=2.0)
    for d in np.linspace(0, 20 * fy / k, 200)[1:]:
        f, _ = law.trial(d)
        law.commit()
    assert f == pytest.approx(fy, rel=1e-6)  # z -> 1
    _, kt = law.trial(law.c_d - 1e-7)
    assert kt == pytest.approx(k, rel=1e-6)  # beta = gamma: unloading at k


# -- the integration is accurate at the 1 ms step ----------------------------------------------------
def test_bilinear_building_at_1ms_matches_a_100x_finer_newmark_reference():
    laws = StoreyLaws("bilinear", FY, (0.05,) * 3)  # default substeps
    ag = ground(700)
    bld = HystereticShearBuilding(GROUNDED, laws)
    got = simulate(bld, ag)
    # reference: Newmark everywhere (no exact elastic path) with 100 x smaller steps (10 us)
    ref = simulate(HystereticShearBuilding(GROUNDED, replace(laws, substeps=100), exact_elastic=False), ag)
    ratio = np.max(np.abs(ref[:, 19:]), axis=0) / np.array(FY)
    assert ratio.max() > 1.4  # the storeys yielded (peak shear / fy: 1.45, 1.21, 0.96)
    assert 0 < bld.newmark_steps < len(ag)  # both paths were taken
    peak_ref, peak = np.max(np.abs(ref), axis=0), np.max(np.abs(got), axis=0)
    assert peak[16:] == pytest.approx(peak_ref[16:], rel=1e-3)  # drifts and shears
    assert peak[8:12] == pytest.approx(peak_ref[8:12], rel=1e-3)  # absolute accelerations
    assert np.max(np.abs(got[:, 16:19] - ref[:, 16:19])) < 2e-3 * peak_ref[16:19].max()


def test_bilinear_building_that_never_yields_follows_the_linear_one():
    ag = ground(1000)
    lin = simulate(ShearBuilding(GROUNDED), ag)
    elastic = simulate(HystereticShearBuilding(GROUNDED, StoreyLaws("bilinear", (1e9,) * 3, (0.05,) * 3)), ag)
    assert np.max(np.abs(elastic - lin)) <= 1e-9 * np.max(np.abs(lin))


def test_residual_drift_is_the_drift_at_rest_after_yielding():
    laws = StoreyLaws("bilinear", FY, (0.05,) * 3)
    damped = replace(GROUNDED, c=(3000.0, 2000.0, 2000.0, 2000.0))
    bld = HystereticShearBuilding(damped, laws)
    ag = np.concatenate([ground(800), np.zeros(5000)])  # shaking, then 5 s of free decay
    simulate(bld, ag)
    assert np.max(np.abs(bld.v)) < 1e-7  # at rest
    residual = bld.residual_drifts()
    assert np.max(np.abs(residual)) > 1e-4  # a permanent set
    # at rest nothing loads the storeys: their forces vanish and the drift left is the residual drift
    assert np.max(np.abs(bld.restoring_forces())) < 1e-3 * min(FY)
    assert residual == pytest.approx(bld.drifts(), rel=1e-3)
    elastic = HystereticShearBuilding(GROUNDED, StoreyLaws("bilinear", (1e9,) * 3, (0.05,) * 3))
    simulate(elastic, ground(300))
    assert np.max(np.abs(elastic.residual_drifts())) < 1e-15


# -- linear: today's model, bit for bit ------------------------------------------------------------
def _old_core():
    """The shear-building core as it was before yielding storeys (git history), or skip."""
    try:
        text = subprocess.run(["git", "show", "2f29943:components/physics/shear_building_core.py"], cwd=PROJECT,
                              capture_output=True, text=True, timeout=30, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        pytest.skip("the pre-change core is not in this checkout's git history")
    import types

    module = types.ModuleType("old_shear_building_core")
    sys.modules[module.__name__] = module  # dataclasses look their module up
    try:
        exec(compile(text, "old_shear_building_core.py", "exec"), module.__dict__)
    finally:
        sys.modules.pop(module.__name__, None)
    return module.__dict__


def test_linear_is_bit_identical_to_the_old_core():
    old = _old_core()
    p = BuildingParams.dyke()
    new = make_building(p, StoreyLaws())
    assert type(new) is ShearBuilding
    ref = old["ShearBuilding"](old["BuildingParams"].dyke())
    rng = np.random.default_rng(7)
    for ag, F in zip(rng.normal(0, 3, 3000), rng.normal(0, 500, 3000), strict=True):
        new.step(ag, F, 1e-3)
        ref.step(ag, F, 1e-3)
        assert np.array_equal(new.output_vector(ag, F), ref.output_vector(ag, F))


# -- bad input -----------------------------------------------------------------------------------
@pytest.mark.parametrize(("laws", "name"), [
    (StoreyLaws("bilinear", (500.0, 0.0, 260.0), (0.05,) * 3), "fy_2"),
    (StoreyLaws("bilinear", (500.0, 400.0, float("nan")), (0.05,) * 3), "fy_3"),
    (StoreyLaws("bilinear", FY, (1.0, 0.05, 0.05)), "b_1"),
    (StoreyLaws("bilinear", FY, (0.05, -0.1, 0.05)), "b_2"),
    (StoreyLaws("bouc-wen", FY, (0.05,) * 3, (2.0, 0.5, 2.0)), "n_2"),
    (StoreyLaws("bouc-wen", FY, (0.05,) * 3, (2.0,) * 3, bw_beta=0.2, bw_gamma=0.5), "bw_beta"),
    (StoreyLaws("elastoplastic", FY, (0.05,) * 3), "hysteresis"),
    (StoreyLaws("bilinear", FY, (0.05,) * 3, substeps=0), "substeps"),
])
def test_bad_storey_parameters_are_refused_by_name(laws, name):
    with pytest.raises(ParameterError) as info:
        make_building(GROUNDED, laws)
    assert info.value.parameter == name and str(info.value).startswith(f"{name}: ")


def test_parameter_problem_names_the_parameter_from_fmu_names():
    from components.physics.shear_building_core import parameter_problem

    dyke = BuildingParams.dyke()
    values = {f"{p}_{j}": getattr(dyke, p)[j] for p in "mkc" for j in range(4)}
    values |= {f"fy_{j}": 3000.0 for j in (1, 2, 3)} | {f"b_{j}": 0.05 for j in (1, 2, 3)}
    assert parameter_problem(values) is None
    assert parameter_problem(values | {"hysteresis": "bilinear"}) is None
    assert parameter_problem(values | {"hysteresis": "bilinear", "b_3": 1.5})[0] == "b_3"
    assert parameter_problem(values | {"hysteresis": "bouc-wen"})[0] == "n_1"  # no exponents given
    assert parameter_problem(values | {"hysteresis": "bilinear", "k_2": 0.0})[0] == "k_2"


# -- P-Delta -------------------------------------------------------------------------------------------
def _period(drift: np.ndarray, h: float) -> float:
    """Mean period [s] from the upward zero crossings of a free vibration."""
    up = np.flatnonzero((drift[:-1] < 0) & (drift[1:] >= 0))
    t = (up + drift[up] / (drift[up] - drift[up + 1])) * h  # linear interpolation between samples
    return float(np.mean(np.diff(t)))


@pytest.mark.parametrize("hysteresis", ["linear", "bilinear"])
def test_p_delta_softens_a_storey_as_k_minus_weight_over_height(hysteresis):
    # one storey on a (practically) fixed base: omega^2 = (k - m g / h) / m, closed form
    m1, k1 = 98.3, 516e3
    h1 = m1 * 9.80665 / (0.3 * k1)  # the P-Delta stiffness is 30 % of k1
    params = BuildingParams(m=(98.3, m1), k=(1e11, k1), c=(0.0, 0.0))
    laws = StoreyLaws(hysteresis, (1e9,), (0.05,), p_delta=True, h=(h1,))  # bilinear: never yields
    bld = make_building(params, laws)
    ag = np.zeros(3000)
    ag[:5] = 20.0  # a short pulse, then free vibration
    drift = simulate(bld, ag, h=1e-4)[:, 8]  # columns: x, v, a, arel (2 each), drift, shear
    expected = 2 * np.pi / np.sqrt(0.7 * k1 / m1)
    assert _period(drift[100:], 1e-4) == pytest.approx(expected, rel=2e-4)
    plain = simulate(make_building(params, replace(laws, p_delta=False)), ag, h=1e-4)[:, 8]
    assert _period(plain[100:], 1e-4) == pytest.approx(2 * np.pi / np.sqrt(k1 / m1), rel=2e-4)


def test_p_delta_elastic_bilinear_equals_linear_and_bad_heights_are_refused():
    laws = StoreyLaws("bilinear", (1e9,) * 3, (0.05,) * 3, p_delta=True, h=(0.05, 0.05, 0.05))
    ag = ground(800)
    lin = simulate(make_building(GROUNDED, replace(laws, hysteresis="linear")), ag)
    bil = simulate(make_building(GROUNDED, laws), ag)
    assert np.max(np.abs(bil - lin)) <= 1e-9 * np.max(np.abs(lin))
    newmark = simulate(HystereticShearBuilding(GROUNDED, replace(laws, substeps=10), exact_elastic=False), ag)
    assert np.max(np.abs(newmark - lin)) <= 1e-3 * np.max(np.abs(lin))  # the Newmark path carries P-Delta too
    for h, name in (((0.05, 0.0, 0.05), "h_2"), ((0.05, 0.05, 1e-4), "h_3"), ((0.05,), "h_1")):
        with pytest.raises(ParameterError) as info:
            make_building(GROUNDED, replace(laws, h=h))
        assert info.value.parameter == name
