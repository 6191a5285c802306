"""Figures for a paper: a run's figures as PNG at a chosen dpi, SVG and PDF beside them, bad options exit 2."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from PIL import Image

from orchestration.api import FigureFiles, load_scenario, run
from orchestration.master.figure_files import DPI_RANGE, save_figure

from ..conftest import PROJECT

KOBE = PROJECT / "scenarios" / "kobe.yaml"
FIGURES = ["current", "drifts", "isolator_hysteresis", "top_floor_acceleration"]


def check_files(folder: Path, names: list[str], dpi: float, formats: tuple[str, ...]) -> None:
    """Each figure's PNG at ``dpi``, a valid SVG (XML, an <svg> root) and PDF where asked for, no other file."""
    for name in names:
        png = Image.open(folder / f"{name}.png")
        assert png.info["dpi"] == pytest.approx((dpi, dpi), abs=0.05), name
        for ext in ("svg", "pdf"):
            assert (folder / f"{name}.{ext}").is_file() == (ext in formats), (name, ext)
        if "svg" in formats:
            assert ET.parse(folder / f"{name}.svg").getroot().tag == "{http://www.w3.org/2000/svg}svg"
        if "pdf" in formats:
            assert (folder / f"{name}.pdf").read_bytes().startswith(b"%PDF")
    assert not list(folder.glob(".*.tmp.*")), "temporary files left behind"


def test_figure_options_are_checked():
    assert FigureFiles().problem() is None and FigureFiles(300, ("svg", "pdf")).problem() is None
    for dpi in (0, DPI_RANGE[0] - 1, DPI_RANGE[1] + 1, 1.5, True):
        assert "dpi" in FigureFiles(dpi).problem()  # type: ignore[arg-type]
    assert "'eps'" in FigureFiles(None, ("svg", "eps")).problem()


def test_save_figure_writes_each_format_the_same_bytes_each_time(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for k in range(2):
        fig, ax = plt.subplots()
        ax.plot([0, 1], [1, 2], marker="o", label="a")
        ax.legend()
        (tmp_path / str(k)).mkdir()
        made = save_figure(fig, tmp_path / str(k) / "f.png", FigureFiles(123, ("svg", "pdf")), 100)
        plt.close(fig)
        assert [p.name for p in made] == ["f.png", "f.svg", "f.pdf"]
        check_files(tmp_path / str(k), ["f"], 123, ("svg", "pdf"))
    for ext in ("png", "svg", "pdf"):  # no date, no random ids: a figure's files are reproducible
        assert (tmp_path / "0" / f"f.{ext}").read_bytes() == (tmp_path / "1" / f"f.{ext}").read_bytes(), ext


def test_a_runs_figures_at_a_chosen_dpi_with_svg_and_pdf(tmp_path):
    plan = load_scenario(KOBE, ["simulation.stop_time=0.5"])
    res = run(plan, tmp_path / "paper", plots=True, figure_files=FigureFiles(150, ("svg", "pdf")))
    assert res.complete
    check_files(tmp_path / "paper", FIGURES, 150, ("svg", "pdf"))
    assert run(plan, tmp_path / "default", plots=True).complete
    check_files(tmp_path / "default", FIGURES, 110, ())  # the default: PNG only, at 110 dpi as before


@pytest.mark.parametrize("args, says", [
    (["--dpi", "0"], "--dpi 0: give 10 to 1200"), (["--dpi", "1201"], "--dpi 1201"),
    (["--dpi", "1.5"], "argument --dpi"), (["--format", "eps"], "argument --format"),
    (["--format", "png"], "argument --format")])
@pytest.mark.parametrize("tool", ["run", "study", "ida", "compare"])
def test_bad_figure_options_are_exit_2_with_nothing_written(tmp_path, capsys, tool, args, says):
    from orchestration.console import main

    out = tmp_path / "out"
    given = {"run": [str(KOBE)], "study": [str(PROJECT / "scenarios" / "case_study.yaml")],
             "ida": [str(PROJECT / "scenarios" / "ida_shipped.yaml")], "compare": [str(tmp_path), str(tmp_path)]}
    try:
        code = main([tool, *given[tool], *args, "--out", str(out)])
    except SystemExit as exc:  # argparse's own refusal
        code = exc.code
    assert code == 2
    assert says in capsys.readouterr().err
    assert not out.exists()
