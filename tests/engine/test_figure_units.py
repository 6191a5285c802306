"""The run figures' units: acceleration in m/s2 or g, drift in mm or as a ratio of the storey height."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from orchestration.building_report import BuildingReport, plot
from orchestration.master.report import RunDescription

from .test_validity import Rows

T = np.linspace(0.0, 1.0, 11)
COLUMNS = {"building.a_3": 9.80665 * np.sin(T), "building.drift_1": 0.003 * T, "building.drift_2": 0.002 * T}
RUN = RunDescription({}, {"building": "ShearBuilding"})


class Drawn:
    """The part of Figures that plot() uses, keeping what it was asked to draw."""

    head = "test"

    def __init__(self) -> None:
        self.calls: dict[str, tuple[str, list]] = {}
        self._pending: tuple[str, list] | None = None

    def time_figure(self, t, title, ylabel, lines, window, note):
        self._pending = (ylabel, lines)
        return title

    def save(self, fig, file):
        assert self._pending is not None
        self.calls[file] = self._pending


def _draw(**report) -> dict[str, tuple[str, list]]:
    spec = BuildingReport.model_validate({"floor_accelerations": ["building.a_3"],
                                          "drifts": ["building.drift_1", "building.drift_2"], **report})
    figures = Drawn()
    plot(spec, Rows(T, COLUMNS), RUN, figures)  # type: ignore[arg-type]
    return figures.calls


def test_default_units_are_m_s2_and_mm():
    calls = _draw()
    label, lines = calls["top_floor_acceleration.png"]
    assert label == "acceleration [m/s²]" and np.array_equal(lines[0][0], COLUMNS["building.a_3"])
    label, lines = calls["drifts.png"]
    assert label == "drift [mm]" and np.allclose(lines[0][0], 3.0 * T)


def test_g_and_drift_ratio_divide_by_standard_gravity_and_the_storey_height():
    """a / 9.80665 m/s2 is sin(t) exactly here; drift_1 / 3 m and drift_2 / 2.5 m in per cent."""
    calls = _draw(acceleration_unit="g", drift_unit="ratio", storey_heights=[3.0, 2.5])
    label, lines = calls["top_floor_acceleration.png"]
    assert label == "acceleration [g]"
    np.testing.assert_allclose(lines[0][0], np.sin(T), rtol=1e-15)
    label, lines = calls["drifts.png"]
    assert label == "drift ratio [%]"
    np.testing.assert_allclose(lines[0][0], 100 * 0.003 * T / 3.0, rtol=1e-15)
    np.testing.assert_allclose(lines[1][0], 100 * 0.002 * T / 2.5, rtol=1e-15)


@pytest.mark.parametrize(("report", "said"), [
    ({"drift_unit": "ratio"}, "drift_unit: ratio needs report.storey_heights"),
    ({"drift_unit": "ratio", "storey_heights": [3.0]}, "storey_heights gives 1 heights for 2 drifts"),
    ({"storey_heights": [3.0, -1.0]}, "finite positive lengths"),
    ({"acceleration_unit": "ft/s2"}, "'m/s2' or 'g'"),
])
def test_bad_figure_units_are_refused(report, said):
    with pytest.raises(ValidationError, match=said):
        BuildingReport.model_validate({"drifts": ["building.drift_1", "building.drift_2"], **report})
