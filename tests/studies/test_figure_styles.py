"""The studies' figures for a paper: a line style and marker per strategy, a legend note where two strategies'
curves coincide (and none where they differ), words on the axes, PNG at a chosen dpi with SVG or PDF beside."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from types import SimpleNamespace

import matplotlib
import pytest
from PIL import Image

from orchestration.building_studies.strategies import builtin_strategies, recorded_flags
from orchestration.case_study.benchmark_report import pareto_figure, pareto_plot
from orchestration.case_study.case_figures import profiles_figure, save
from orchestration.figure_axes import coincident, strategy_style
from orchestration.ida_study.ida_figures import ida_figure
from orchestration.master.figure_files import FigureFiles

matplotlib.use("Agg")
import matplotlib.pyplot as plt

STRATEGIES = ["passive-off", "passive-on", "best-constant", "sosm"]
NOTE = "passive-on coincides with best-constant"


def legend_texts(fig) -> list[str]:
    legends = [*(ax.get_legend() for ax in fig.axes if ax.get_legend()), *fig.legends]
    return [t.get_text() for legend in legends for t in legend.get_texts()]


def study(records=("elcentro", "kobe"), figure_units: dict | None = None) -> SimpleNamespace:
    return SimpleNamespace(strategies=STRATEGIES, records={r: SimpleNamespace(scale=0.5, masses_kg=[1.0] * 4)
                                                           for r in records},
                           config={"figure_units": figure_units} if figure_units else {},
                           flags=lambda s: recorded_flags({}, s))  # the shipped entries' styles


def metrics(best_offset: float) -> dict:
    """Peaks per (record, strategy); best-constant is passive-on plus ``best_offset`` (mm and m/s²)."""
    out = {}
    for r, base in (("elcentro", 1.0), ("kobe", 2.0)):
        for k, s in enumerate(STRATEGIES):
            shift = best_offset if s == "best-constant" else 0.0
            value = base + (0.6 if s in ("passive-on", "best-constant") else 0.3 * k)
            out[(r, s)] = {**{f"drift_{j}_mm": value * j + shift for j in (1, 2, 3)},
                           **{f"acc_{j}": value + 0.1 * j + shift for j in range(4)}}
    return out


def test_every_shipped_strategy_has_its_own_line_style_marker_and_colour():
    """The styles are the entries' (scenarios/strategies.yaml), each its own; a strategy without one gets one by
    its place, with a marker no shipped entry uses."""
    shipped = builtin_strategies()
    looks = [strategy_style(name, list(shipped), s.entry.style.model_dump()) for name, s in shipped.items()]
    pairs = [(str(look["ls"]), look["marker"]) for look in looks]
    assert len(set(pairs)) == len(pairs) and len({m for _, m in pairs}) == len(pairs)
    assert len({look["color"] for look in looks}) == len(looks)
    order = ["mine", "yours", *shipped]
    mine, yours = strategy_style("mine", order), strategy_style("yours", order)
    assert mine != yours and not {mine["marker"], yours["marker"]} & {m for _, m in pairs}
    assert strategy_style("sosm-fig15", order, {"line": [6.0, 2.0]})["ls"] == (0, (6.0, 2.0))  # dashes
    assert strategy_style("x", order, {"line": []})["ls"] == "-"  # no dashes: solid


def test_curves_coincide_within_half_a_percent_of_the_axis_span():
    assert coincident({"a": [0.0, 1.0], "b": [0.004, 1.0]}, 1.0) == [("a", "b")]
    assert coincident({"a": [0.0, 1.0], "b": [0.006, 1.0]}, 1.0) == []
    assert coincident({"a": [[1.0, 1.0]], "b": [[1.0, 1.4]]}, (1.0, 100.0)) == [("a", "b")]  # a span per column
    assert coincident({"a": [0.0, 1.0], "b": [0.0, 1.0, 2.0]}, 1.0) == []  # other shapes: not compared


def test_fig17_notes_coinciding_strategies_and_only_those():
    fig = profiles_figure(study(), metrics(0.0))
    texts = legend_texts(fig)
    assert f"{NOTE} (every record)" in texts
    assert set(STRATEGIES) <= set(texts)
    assert [t for t in texts if "coincides" in t] == [f"{NOTE} (every record)"]
    lines = {line.get_label(): (str(line.get_linestyle()), line.get_marker()) for line in fig.axes[0].get_lines()}
    assert len(set(lines.values())) == len(STRATEGIES)  # each strategy its own line style and marker
    assert fig.axes[0].get_xlabel() == "peak drift [mm]"
    plt.close(fig)
    fig = profiles_figure(study(), metrics(0.5))  # 0.5 mm apart: several % of the axis
    assert not [t for t in legend_texts(fig) if "coincides" in t]
    plt.close(fig)


def test_fig16_legend_sits_under_the_panels_and_notes_coinciding_records():
    """One legend for the figure (a legend in a panel hid the motion), each strategy once, and a note naming the
    records where two strategies' time histories coincide (passive-on and best-constant: not drawn in Fig. 16, so
    here passive-on made equal to sosm on Kobe only)."""
    import numpy as np

    from orchestration.case_study.case_figures import top_acceleration_figure

    t = np.linspace(0.0, 20.0, 2001)
    base = np.sin(2 * np.pi * t) * np.exp(-0.1 * t)
    series = {}
    for r, scale in (("elcentro", 1.0), ("kobe", 2.0)):
        for k, s in enumerate(STRATEGIES):
            same = r == "kobe" and s == "passive-on"
            series[(r, s)] = {"time": t, "building.a_top": scale * base * (1.0 if same or s == "sosm" else 0.5 + k)}
    st = study()
    st.uncontrolled = "passive-off"
    st.paper = lambda part: [s for s in STRATEGIES if st.flags(s).get("paper_figures") == part]
    st.records = {r: SimpleNamespace(scale=0.5, masses_kg=[1.0] * 4, name=None) for r in ("elcentro", "kobe")}
    fig = top_acceleration_figure(st, series)
    assert not [ax for ax in fig.axes if ax.get_legend()] and len(fig.legends) == 1
    texts = legend_texts(fig)
    assert [t for t in texts if "coincides" in t] == ["passive-on coincides with sosm (kobe ×0.5)"]
    assert [t for t in texts if "coincides" not in t] == ["passive-off", "passive-on", "sosm"]
    plt.close(fig)


def test_fig17_in_g_and_drift_ratio():
    """figure_units: each drift over its storey's height in %, each acceleration over 9.80665 m/s2."""
    heights = [3.0, 2.5, 2.0]
    fig = profiles_figure(study(figure_units={"acceleration": "g", "drift": "ratio", "storey_heights": heights}),
                          metrics(0.0))
    m = metrics(0.0)[("elcentro", "sosm")]
    drift, acc = ({line.get_label(): line.get_xdata() for line in fig.axes[k].get_lines()} for k in (0, 1))
    assert fig.axes[0].get_xlabel() == "drift ratio [%]" and fig.axes[1].get_xlabel() == "peak abs. acceleration [g]"
    assert list(drift["sosm"]) == pytest.approx([100 * 1e-3 * m[f"drift_{j}_mm"] / heights[j - 1] for j in (1, 2, 3)],
                                                rel=1e-12)
    assert list(acc["sosm"]) == pytest.approx([m[f"acc_{j}"] / 9.80665 for j in range(4)], rel=1e-12)
    plt.close(fig)


def test_study_figure_units_are_checked_where_written(tmp_path):
    from orchestration.case_study.case_config import load_study
    from orchestration.case_study.case_plan import prepare
    from orchestration.master.errors import ScenarioError

    from ..conftest import PROJECT

    def problems(units: str) -> list:
        path = tmp_path / "study.yaml"
        path.write_text(f"extends: {PROJECT / 'scenarios' / 'case_study.yaml'}\nfigure_units: {units}\n")
        with pytest.raises(ScenarioError) as err:
            prepare(load_study(path))
        return err.value.problems

    (p,) = problems("{drift: ratio}")
    assert p.key == "figure_units" and "storey_heights" in p.message and p.line == 2
    (p,) = problems("{storey_heights: [3.0, -1.0]}")
    assert p.key == "figure_units.storey_heights" and "positive" in p.message
    (p,) = problems("{drift: ratio, storey_heights: ['3', 3, 3]}")  # text is not a length
    assert p.key == "figure_units.storey_heights"
    (p,) = problems("{acceleration: ft/s2}")
    assert p.key == "figure_units.acceleration"
    (p,) = problems("{drift: ratio, storey_heights: [3.0, 3.0]}")
    assert p.key == "figure_units.storey_heights" and "3 storeys" in p.message and p.line == 2


def pareto_rows(best_j5: float) -> list[dict]:
    rows = []
    for r in ("elcentro", "kobe"):
        rows += [{"record": r, "strategy": "passive-off", "J3": 1.0, "J5": 1.0},
                 {"record": r, "strategy": "passive-on", "J3": 0.5, "J5": 0.8},
                 {"record": r, "strategy": "best-constant", "J3": 0.5, "J5": best_j5 if r == "kobe" else 0.8},
                 {"record": r, "strategy": "sosm", "J3": 0.7, "J5": 0.6}]
    return rows


def test_pareto_plot_notes_coinciding_points_and_only_those():
    fig = pareto_figure(pareto_rows(0.8), ["elcentro", "kobe"], "best-constant", "passive-off")
    assert f"{NOTE} (every record)" in legend_texts(fig)
    plt.close(fig)
    fig = pareto_figure(pareto_rows(0.7), ["elcentro", "kobe"], "best-constant", "passive-off")
    assert [t for t in legend_texts(fig) if "coincides" in t] == [f"{NOTE} (elcentro)"]
    plt.close(fig)
    fig = pareto_figure(pareto_rows(0.5), ["kobe"], "best-constant", "passive-off")
    assert not [t for t in legend_texts(fig) if "coincides" in t]
    plt.close(fig)


@pytest.mark.parametrize("dpi, formats", [(None, ()), (300, ("svg",)), (72, ("svg", "pdf"))])
def test_study_and_ida_figures_at_a_chosen_dpi_with_vector_files(tmp_path, dpi, formats):
    files = FigureFiles(dpi, formats)
    save(profiles_figure(study(), metrics(0.0)), tmp_path / "fig17_profiles.png", files)
    pareto_plot(pareto_rows(0.8), ["elcentro", "kobe"], "best-constant", "passive-off",
                tmp_path / "benchmark_pareto_J3_J5.png", files)
    rows = [{"intensity": level, "strategy": s, "status": "ok", "record_id": c, "x_base_mm": level * 100 + k}
            for level in (0.05, 0.1) for k, s in enumerate(STRATEGIES) for c in ("a", "b")]
    ida_figure(tmp_path / "ida_curves.png", SimpleNamespace(name="tiny", measure="pga"), rows, STRATEGIES, files)
    for name, default in (("fig17_profiles", 100), ("benchmark_pareto_J3_J5", 100), ("ida_curves", 110)):
        want = dpi or default
        assert Image.open(tmp_path / f"{name}.png").info["dpi"] == pytest.approx((want, want), abs=0.05)
        assert (tmp_path / f"{name}.svg").is_file() == ("svg" in formats)
        assert (tmp_path / f"{name}.pdf").is_file() == ("pdf" in formats)
        if "svg" in formats:
            assert ET.parse(tmp_path / f"{name}.svg").getroot().tag == "{http://www.w3.org/2000/svg}svg"
        if "pdf" in formats:
            assert (tmp_path / f"{name}.pdf").read_bytes()[:4] == b"%PDF"
    assert not list(tmp_path.glob(".*.tmp.*"))
