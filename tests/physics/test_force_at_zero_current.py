"""The isolators' F_off, the force at 0 A along the same motion (the benchmark's J6 is max|F - F_off|), against
an independent run of the same shell at 0 A, without an FMU build."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "components" / "shells"))  # the shells by file name
sys.path.insert(0, str(ROOT / "components" / "physics"))  # their cores by plain name

H = 1e-3  # s


def _shell(kind: str, **params):
    if kind == "bouc-wen":
        from bouc_wen_isolator_fmu import BoucWenIsolator as cls
    else:
        from mre_isolator_fmu import MreIsolator as cls
    m = cls(instance_name="test", resources=str(ROOT / "components" / "physics"))
    for k, v in params.items():
        setattr(m, k, v)
    m.log = lambda msg, status=None, *a, **kw: m.__dict__.setdefault("messages", []).append((status, msg))
    return m


def _motion(n: int = 1500) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A decaying two-tone displacement up to about 12 mm (past the identified 8 mm, below the 15 mm stop) and
    a current that switches between 0 and 3 A."""
    t = np.arange(n) * H
    w1, w2 = 2 * np.pi * 1.3, 2 * np.pi * 3.1
    x = np.exp(-0.4 * t) * (0.010 * np.sin(w1 * t) + 0.002 * np.sin(w2 * t))
    v = np.gradient(x, H)
    i = np.where(np.sin(2 * np.pi * 2.0 * t) > 0, 3.0, 0.0)
    return x, v, i


def _run(m, x, v, i) -> tuple[list[float], list[float]]:
    forces, off = [], []
    for k in range(len(x)):
        m.x, m.v, m.i = float(x[k]), float(v[k]), float(i[k])
        forces.append(m._force())
        off.append(m._force_off())
        assert m.do_step(k * H, H)
    return forces, off


@pytest.mark.parametrize("kind", ["bouc-wen", "hyperbolic"])
def test_f_off_is_the_force_of_the_same_motion_at_zero_current(kind):
    x, v, i = _motion()
    forces, off = _run(_shell(kind, beyond_range="stop"), x, v, i)
    at_zero, _ = _run(_shell(kind, beyond_range="stop"), x, v, np.zeros_like(i))
    np.testing.assert_allclose(off, at_zero, rtol=1e-12, atol=1e-9)
    controllable = np.abs(np.array(forces) - np.array(off))
    assert controllable.max() > 10.0  # N: the current does change the force
    if kind == "hyperbolic":  # no memory: wherever the current is 0, nothing is controlled
        assert np.all(controllable[i == 0.0] == 0.0)


def test_bouc_wen_f_off_keeps_its_own_memory():
    """After the current was on, the Bouc-Wen state at 0 A differs from the state at the current, so F_off at 0 A
    later differs from F (memory); while the current has always been 0, F_off is F exactly."""
    x, v, i = _motion()
    m = _shell("bouc-wen")
    forces, off = _run(m, x, v, np.zeros_like(i))
    assert forces == off
    m = _shell("bouc-wen")
    forces, off = _run(m, x, v, i)
    later_at_zero = [k for k in range(len(i)) if i[k] == 0.0 and k > 300]
    assert max(abs(forces[k] - off[k]) for k in later_at_zero) > 1e-3  # N
    assert m.y != m.y_off


def test_f_off_is_a_local_in_newtons_not_an_output():
    """A local (recorded when named, skipped by ``outputs: all``): the runs that do not ask for it pay nothing."""
    for kind in ("bouc-wen", "hyperbolic"):
        m = _shell(kind)
        assert "F_off" not in m.fmi_dependencies
        assert m.fmi_units["F_off"] == "N"
        assert next(v for v in m.vars.values() if v.name == "F_off").causality.name == "local"
