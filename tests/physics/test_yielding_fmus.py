"""The yielding storeys and the bounded isolator through their FMUs (fmpy), against the cores."""

from __future__ import annotations

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from components.physics.mre_isolator_core import bounded_force_law
from components.physics.shear_building_core import BuildingParams, HystereticShearBuilding, StoreyLaws

from ..support.fmu_driver import Driven

pytestmark = pytest.mark.slow  # builds every FMU once per session

FY = (900.0, 800.0, 600.0)


@pytest.mark.parametrize(("hysteresis", "p_delta"), [("bilinear", False), ("bouc-wen", False), ("bilinear", True)])
def test_yielding_building_fmu_equals_core(fmu_dir, hysteresis, p_delta):
    heights = (0.02, 0.03, 0.04)  # small: a P-Delta stiffness of a few percent
    params = {"hysteresis": hysteresis, "k_0": 12e3} | {f"fy_{j}": FY[j - 1] for j in (1, 2, 3)}
    if p_delta:
        params |= {"p_delta": True} | {f"h_{j}": heights[j - 1] for j in (1, 2, 3)}
    fmu = Driven(fmu_dir / "ShearBuilding.fmu", "bld", params)
    dyke = BuildingParams.dyke()
    core = HystereticShearBuilding(BuildingParams(dyke.m, (12e3, *dyke.k[1:]), dyke.c),
                                   StoreyLaws(hysteresis, FY, (0.05,) * 3, (2.0,) * 3, p_delta=p_delta,
                                              h=heights if p_delta else ()))
    assert any(core.kg) == p_delta
    names = fmu.outputs()
    residual = [f"residual_drift_{j}" for j in (1, 2, 3)]
    rng = np.random.default_rng(4)
    try:
        for k in range(400):
            ag, F = 8.0 * np.sin(k * 2e-3 * np.pi * 2) + rng.normal(0, 1), rng.normal(0, 100)
            fmu.set(ag=ag, F=F)
            assert fmu.get(*names) == pytest.approx(core.output_vector(ag, F).tolist(), rel=1e-12, abs=1e-12)
            fmu.step(k * 1e-3, 1e-3)
            core.step(ag, F, 1e-3)
        assert np.max(np.abs(core.storey_shears()) / FY) > 0.5
        assert fmu.get(*residual) == pytest.approx(core.residual_drifts().tolist(), rel=1e-12, abs=1e-15)
        assert max(abs(r) for r in fmu.get(*residual)) > 1e-5  # it yielded
    finally:
        fmu.close()


def test_linear_building_fmu_reports_zero_residual_drift(fmu_dir):
    fmu = Driven(fmu_dir / "ShearBuilding.fmu", "bld")
    try:
        fmu.set(ag=3.0, F=0.0)
        fmu.step(0.0, 1e-3)
        assert fmu.get("residual_drift_1", "residual_drift_2", "residual_drift_3") == [0.0, 0.0, 0.0]
    finally:
        fmu.close()


@pytest.mark.parametrize(("name", "value"), [("fy_2", -5.0), ("b_1", 1.0), ("n_3", 0.5)])
def test_building_fmu_refuses_bad_storey_parameters_before_any_step(fmu_dir, capfd, name, value):
    law = "bouc-wen" if name.startswith("n_") else "bilinear"
    unit = Driven(fmu_dir / "ShearBuilding.fmu", "b", {"hysteresis": law, name: value})
    try:
        with pytest.raises(FMICallException) as err:
            unit.step(0.0, 1e-3)
        assert err.value.status == 3
    finally:
        unit.close()
    assert f"invalid building parameters: {name}: " in capfd.readouterr().out


@pytest.mark.parametrize("beyond", ["extrapolate", "tangent", "stop"])
def test_isolator_fmu_beyond_range_equals_core(fmu_dir, beyond):
    # a stop must be stiffer than the device it stops: Table 2's law is 6.57 MN/m at 8 mm and 3 A
    stiff = {"k_stop": 1.0e7} if beyond == "stop" else {}
    fmu = Driven(fmu_dir / "MreIsolator.fmu", "iso", {"beyond_range": beyond, **stiff})
    law = bounded_force_law(beyond_range=beyond, **stiff)
    try:
        for x in (0.0, 0.005, 0.0085, -0.012, 0.016, -0.02):
            for v, i in ((0.1, 0.0), (-0.2, 2.0)):
                fmu.set(x=x, v=v, i=i)
                assert fmu.get("F") == [law(x, v, i)]
    finally:
        fmu.close()
