"""An IDA study folder's outputs, regenerated from its data: tables, fragility, figures and report.

:func:`write_outputs` is what the end of a run and ``--report DIR`` call: the numbers from
:mod:`~orchestration.ida_study.ida_metrics`, the figures from
:mod:`~orchestration.ida_study.ida_figures`, the text from
:mod:`~orchestration.ida_study.ida_rendering`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from orchestration.ida_study.fragility import Fit
from orchestration.ida_study.ida_config import IdaSpec
from orchestration.ida_study.ida_figures import fragility_figure, ida_figure, spectra_figure
from orchestration.ida_study.ida_metrics import (
    collapse_margins,
    fragilities,
    fragility_rows,
    table_csv,
    write_tables,
)
from orchestration.ida_study.ida_records import IdaInfo
from orchestration.ida_study.ida_rendering import report_html, report_markdown
from orchestration.master.figure_files import PNG_ONLY, FigureFiles
from orchestration.master.runfolder import write_text


def write_report(folder: Path, info: IdaInfo, spec: IdaSpec, rows: list[dict[str, Any]],
                 fits: dict[str, dict[str, Fit]], files: FigureFiles = PNG_ONLY) -> None:
    """Figures (PNG, and each of ``files.formats``), report.md and report.html (which embed the PNGs) of a study
    folder."""
    (folder / "figures").mkdir(exist_ok=True)
    ida_figure(folder / "figures" / "ida_curves.png", info, rows, list(info.strategies), files)
    fragility_figure(folder / "figures" / "fragility.png", info, spec, fits, files)
    spectra = spectra_figure(folder / "figures" / "spectra.png", info, folder / "records", files)
    markdown = report_markdown(info, spec, rows, fits, spectra)
    write_text(folder / "report.md", markdown)
    write_text(folder / "report.html", report_html(markdown, folder))


def write_outputs(folder: Path, info: IdaInfo, rows: list[dict[str, Any]], files: FigureFiles = PNG_ONLY
                  ) -> dict[str, dict[str, Fit]]:
    """Tables, fragility, figures (as ``files`` says) and report of a study folder from its data."""
    spec = IdaSpec.model_validate(info.config)
    write_tables(folder, rows)
    fits = fragilities(rows, spec)
    table = fragility_rows(fits, spec)
    write_text(folder / "fragility.csv", table_csv(tuple(table[0]), table))
    margins = collapse_margins(fits, spec, rows)
    if margins:
        write_text(folder / "collapse.csv", table_csv(tuple(margins[0]), margins))
    write_report(folder, info, spec, rows, fits, files)
    return fits
