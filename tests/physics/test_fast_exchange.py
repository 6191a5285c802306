"""The shells' shared fast set_real/get_real paths (components/shells/fast_exchange.py)."""

from __future__ import annotations

import copy
import importlib.util
import zipfile
from pathlib import Path

import pytest

PROJECT = Path(__file__).resolve().parents[2]
SHELLS = PROJECT / "components" / "shells"
# under a name of its own: the bare name ``fast_exchange`` is the FMUs' (they share this interpreter)
_spec = importlib.util.spec_from_file_location("_fast_exchange_under_test", SHELLS / "fast_exchange.py")
fast_exchange = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fast_exchange)


class _Var:
    def __init__(self, name, vr, value):
        self.name, self.value_reference, self.getter = name, vr, value


class _Slave:
    """Stands in for Fmi2Slave: pythonfmu's generic paths by variable."""

    def __init__(self):
        self.vars = {}

    def set_real(self, vrs, values):
        for vr, value in zip(vrs, values, strict=True):
            setattr(self, self.vars[vr].name, ("generic", value))

    def get_real(self, vrs):
        return [("generic", self.vars[vr].name) for vr in vrs]


class _Unit(fast_exchange.FastExchange, _Slave):
    def __init__(self):
        super().__init__()
        self.a = self.b = 0.0
        self.p = 0.0
        for vr, name in enumerate(("a", "b", "p", "y0", "y1", "y2")):
            self.vars[vr] = _Var(name, vr, None)
        self.exchange_fast(inputs=("a", "b"), outputs=("y0", "y1", "y2"))
        self.evaluations = 0

    def _exchanged_outputs(self):
        self.evaluations += 1
        return [self.a + self.b, self.a - self.b, self.a * self.b]


def test_inputs_in_order_subsets_and_others():
    u = _Unit()
    u.set_real([0, 1], [2.0, 3.0])
    assert (u.a, u.b) == (2.0, 3.0)
    u.set_real([1, 0], [5.0, 7.0])
    assert (u.a, u.b) == (7.0, 5.0)
    u.set_real([1], [1.0])
    assert (u.a, u.b) == (7.0, 1.0)
    u.set_real([0, 2], [4.0, 9.0])  # p is no fast input: pythonfmu's path for the whole request
    assert (u.a, u.p) == (("generic", 4.0), ("generic", 9.0))


def test_outputs_any_order_or_subset_from_one_evaluation():
    u = _Unit()
    u.set_real([0, 1], [2.0, 3.0])
    assert u.get_real([3, 4, 5]) == [5.0, -1.0, 6.0]
    assert u.get_real([5, 3]) == [6.0, 5.0]
    assert u.get_real([4]) == [-1.0]
    assert u.evaluations == 3
    assert u.get_real([3, 0]) == [("generic", "y0"), ("generic", "a")]
    assert u.get_real([]) == []
    for _ in range(20):  # more requests than pickers kept: still right
        assert u.get_real([5, 4, 3]) == [6.0, -1.0, 5.0]
    assert len(u._fast_pickers) <= fast_exchange.MAX_PICKERS


def test_one_output_shell_and_a_deep_copied_state():
    class One(fast_exchange.FastExchange, _Slave):
        def __init__(self):
            super().__init__()
            self.x = 0.0
            self.vars = {0: _Var("x", 0, None), 1: _Var("F", 1, None)}
            self.exchange_fast(inputs=("x",), outputs=("F",))

        def _exchanged_value(self):
            return 2.0 * self.x

    u = One()
    u.set_real([0], [1.5])
    assert u.get_real([1]) == [3.0] and u.get_real([1, 1]) == [3.0, 3.0]
    state = copy.deepcopy(dict(vars(u)))  # the shells' FMU state deep-copies every attribute they add
    u.set_real([0], [4.0])
    vars(u).update(state)
    assert u.get_real([1]) == [3.0]


def test_inputs_must_be_attribute_names():
    with pytest.raises(ValueError, match="attribute names"):
        fast_exchange._assigner(("x", "not a name"))


@pytest.mark.slow
def test_every_fmu_carrying_it_carries_it_as_it_is_in_the_tree(fmu_dir):
    """pythonfmu FMUs share one interpreter: every copy of the module must be the tree's, byte for byte."""
    source = (SHELLS / "fast_exchange.py").read_bytes()
    carrying = [p for p in sorted(fmu_dir.glob("*.fmu"))
                if "resources/fast_exchange.py" in zipfile.ZipFile(p).namelist()]
    assert {"ShearBuilding", "MreIsolator", "SosmCurrentController", "GroundMotionSource",
            "BoucWenIsolator"} <= {p.stem for p in carrying}
    for path in carrying:
        with zipfile.ZipFile(path) as fmu:
            assert fmu.read("resources/fast_exchange.py") == source, path.name
            assert "resources/shared_copies.py" in fmu.namelist(), path.name
