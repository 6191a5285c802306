"""Figures of an identification run (matplotlib, Agg), numbered as in the paper (Fig. 6-12)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from components.identification.models import bouc_wen_predict, hyperbolic_predict
from orchestration.master.figure_files import PNG_ONLY, FigureFiles, save_figure

IDENT_DPI = 110  # [dots per inch] the PNGs' resolution unless --dpi asks for another

if TYPE_CHECKING:
    from components.identification.identifiers import IdentResult
    from components.identification.models import FitData
    from orchestration.identification.ident_config import IdentificationConfig
    from orchestration.identification.ident_result import RunResult


def _save(fig, path: Path, synthetic: bool, files: FigureFiles) -> None:
    if synthetic:
        fig.text(
            0.5,
            0.005,
            "SYNTHETIC DATA - not measured",
            ha="center",
            va="bottom",
            color="firebrick",
            fontsize=8,
        )
    try:
        save_figure(fig, path, files, IDENT_DPI, tight=False)
    finally:
        plt.close(fig)


def _first_window(d: FitData, values: np.ndarray) -> np.ndarray:
    n = d.x_hist[0].size - d.start[0]
    return values[:n]


def _prediction(d: FitData, r: IdentResult) -> np.ndarray:
    return hyperbolic_predict(d, r.params) if r.model == "hyperbolic" else bouc_wen_predict(d, r.params)


def _best_hyperbolic(rr: RunResult) -> str | None:
    for name in ("hyperbolic-structured", "hyperbolic-ffoa"):
        if name in rr.results:
            return name
    return None


def _loops(axes, rr: RunResult, name: str, conds, label) -> bool:
    drawn = False
    for cond in conds:
        if cond not in rr.data or cond not in rr.results[name]:
            continue
        d, r = rr.data[cond], rr.results[name][cond]
        x, v, F = (_first_window(d, a) for a in (d.x, d.v, d.F))
        lines = axes[0].plot(x, F, ".", ms=2, label=f"{label(cond)} measured")
        axes[1].plot(v, F, ".", ms=2, color=lines[0].get_color())
        if np.all(np.isfinite(list(r.params.values()))):
            p = _first_window(d, _prediction(d, r))
            tag = "" if r.converged else " (not converged)"
            axes[0].plot(x, p, "-", color=lines[0].get_color(), lw=1, label=f"{label(cond)} {name}{tag}")
            axes[1].plot(v, p, "-", color=lines[0].get_color(), lw=1)
        drawn = True
    axes[0].set(xlabel="displacement [mm]", ylabel="force [N]")
    axes[1].set(xlabel="velocity [mm/s]", ylabel="force [N]")
    if drawn:
        axes[0].legend(fontsize=6)
    return drawn


def fig6(out: Path, rr: RunResult, files: FigureFiles = PNG_ONLY) -> None:
    """FFOA flight path of k0 and convergence (paper: 4 Hz, 2 mm; 1 A gives k0 = 16.38)."""
    per = rr.results.get("hyperbolic-ffoa")
    if not per:
        return
    cond = (4.0, 2.0, 1.0) if (4.0, 2.0, 1.0) in per else next(iter(per))
    r = per[cond]
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    ax[0].plot(r.path[:, 1, 0], r.path[:, 1, 1], "-o", ms=2)
    ax[0].set(
        xlabel="X (k0)", ylabel="Y (k0)", title=f"(a) flight path of k0, final k0 = {r.params['k0']:.4g} N/mm"
    )
    ax[1].semilogy(np.arange(1, r.history.size + 1), r.history)
    ax[1].set(xlabel="iteration", ylabel="best RMS error [N]", title="(b) convergence")
    fig.suptitle(f"Fig. 6: FFOA, hyperbolic model, {cond[0]:g} Hz {cond[1]:g} mm {cond[2]:g} A")
    _save(fig, out / "fig6_ffoa_convergence.png", rr.synthetic, files)


def fig7_8_9(out: Path, rr: RunResult, files: FigureFiles = PNG_ONLY) -> None:
    """Measured vs predicted loops: Fig. 7 (2 mm, 1 A), Fig. 8 (2 Hz 4 mm; 1 Hz 3 A), Fig. 9 (Bouc-Wen)."""
    name = _best_hyperbolic(rr)
    sets = []
    if name:
        sets += [
            (
                "fig7_loops_2mm_1A.png",
                "Fig. 7: 2 mm, 1 A, frequencies",
                name,
                [(f, 2.0, 1.0) for f in (1.0, 2.0, 4.0)],
                lambda c: f"{c[0]:g} Hz",
            ),
            (
                "fig8a_loops_2Hz_4mm.png",
                "Fig. 8(a): 2 Hz, 4 mm, currents",
                name,
                [(2.0, 4.0, i) for i in (0.0, 1.0, 2.0, 3.0)],
                lambda c: f"{c[2]:g} A",
            ),
            (
                "fig8b_loops_1Hz_3A.png",
                "Fig. 8(b): 1 Hz, 3 A, amplitudes",
                name,
                [(1.0, a, 3.0) for a in (2.0, 4.0, 8.0)],
                lambda c: f"{c[1]:g} mm",
            ),
        ]
    if "bouc_wen-ffoa" in rr.results:
        sets.append(
            (
                "fig9_bouc_wen_4Hz_3A.png",
                "Fig. 9: Bouc-Wen, 4 Hz, 3 A",
                "bouc_wen-ffoa",
                [(4.0, a, 3.0) for a in (2.0, 4.0, 8.0)],
                lambda c: f"{c[1]:g} mm",
            )
        )
    for fname, title, ident, conds, label in sets:
        fig, ax = plt.subplots(1, 2, figsize=(10, 4))
        if _loops(ax, rr, ident, conds, label):
            fig.suptitle(f"{title} ({ident})")
            _save(fig, out / fname, rr.synthetic, files)
        else:
            plt.close(fig)


def fig10_11(out: Path, rr: RunResult, files: FigureFiles = PNG_ONLY) -> None:
    """RMS error (Fig. 10) and run time (Fig. 11) per condition, every identifier side by side."""
    conds = list(rr.data)
    labels = [f"{c[0]:g}Hz {c[1]:g}mm {c[2]:g}A" for c in conds]
    names = list(rr.results)
    width = 0.8 / len(names)
    for fname, attr, ylabel, log in (
        ("fig10_rms_error.png", "rms", "RMS error [N]", False),
        ("fig11_run_time.png", "seconds", "run time [s]", True),
    ):
        fig, ax = plt.subplots(figsize=(max(8, 0.35 * len(conds)), 4.5))
        pos = np.arange(len(conds))
        for k, n in enumerate(names):
            ax.bar(pos + k * width, [getattr(rr.results[n][c], attr) for c in conds], width, label=n)
        if attr == "rms" and all(d.noise_rms is not None for d in rr.data.values()):
            ax.plot(
                pos + 0.4 - width / 2, [rr.data[c].noise_rms for c in conds], "k_", ms=8, label="noise RMS"
            )
        ax.set_xticks(pos + 0.4 - width / 2, labels, rotation=90, fontsize=6)
        ax.set_ylabel(ylabel)
        if log:
            ax.set_yscale("log")
        ax.legend(fontsize=7)
        fig.suptitle(
            "Fig. 10: RMS error per condition" if attr == "rms" else "Fig. 11: run time per condition"
        )
        fig.tight_layout()
        _save(fig, out / fname, rr.synthetic, files)


def fig12(out: Path, rr: RunResult, files: FigureFiles = PNG_ONLY) -> None:
    """Per-current parameter means and the fitted lines of Eq. (13)-(16)."""
    fits = {n: f for n, f in rr.generalized.items() if f.model == "hyperbolic" and f.means}  # joint fits: no means
    if not fits:
        return
    fig, axes = plt.subplots(2, 2, figsize=(9, 7))
    for ax, p in zip(axes.ravel(), ("k0", "c0", "alpha", "beta"), strict=True):
        for n, fit in fits.items():
            i = np.array(sorted(fit.means))
            line = ax.plot(i, [fit.means[c][p] for c in i], "o", label=f"{n} means")
            grid = np.linspace(0, max(i.max(), 3), 20)
            ax.plot(
                grid,
                fit.coefficients[f"{p}_0"] * grid + fit.coefficients[f"{p}_1"],
                "-",
                color=line[0].get_color(),
                label=f"{n} LS line",
            )
        ax.set(xlabel="current [A]", ylabel=p)
    axes[0, 0].legend(fontsize=6)
    fig.suptitle("Fig. 12: parameters vs current with linear fits")
    fig.tight_layout()
    _save(fig, out / "fig12_params_vs_current.png", rr.synthetic, files)


def write_all(out: Path, rr: RunResult, cfg: IdentificationConfig, files: FigureFiles = PNG_ONLY) -> None:
    """Write every figure that the run's identifiers and conditions allow (each a PNG and ``files.formats``)."""
    out.mkdir(parents=True, exist_ok=True)
    fig6(out, rr, files)
    fig7_8_9(out, rr, files)
    fig10_11(out, rr, files)
    fig12(out, rr, files)
