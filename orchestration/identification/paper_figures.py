"""Fig. 3(b) and Fig. 13 of the paper, from the identified models (no measured data ships).

* **Fig. 3(b)**, effective stiffness against current: the slope of the force-displacement
  loop, (F_max - F_min) / (x_max - x_min), under 2 Hz, 8 mm harmonic motion, from the
  per-condition fits of Table 1 (2 Hz, 8 mm, 0-3 A) and from the generalized model of
  Table 2, with a straight line fitted to each (the paper reports a linear relation).
* **Fig. 13**, the generalized model under random excitation (4 mm peak, 1 A): the
  paper compares it with measurements we do not have. Here the motion is SYNTHETIC
  (band-limited random, seeded) and the generalized model is compared with the three
  Table 1 fits at 1 A and 4 mm (1, 2, 4 Hz), each identified on harmonic tests only.

Everything per device, SI inside (m, m/s, N); figures in mm and N as the paper draws them.
Run: ``python -m orchestration.identification.paper_figures OUT_DIR``.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from components.identification.paper_tables import CURRENTS_A, TABLE1
from components.physics.mre_isolator_core import MM, TABLE2, GeneralizedCoefficients, HyperbolicParams, device_force

SYNTHETIC = "SYNTHETIC random excitation (not measured)"


def loop_force(p: HyperbolicParams, x: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Force of one device [N] (Eq. 3-4) along a motion x [m], v [m/s]."""
    return device_force(x, v, p, np.sinh)


def effective_stiffness(p: HyperbolicParams, amplitude_m: float, frequency_hz: float, samples: int = 4001) -> float:
    """(F_max - F_min) / (2 A) [N/m] over one cycle of x = A sin(2 pi f t)."""
    w = 2 * np.pi * frequency_hz
    t = np.linspace(0.0, 1.0 / frequency_hz, samples)
    f = loop_force(p, amplitude_m * np.sin(w * t), amplitude_m * w * np.cos(w * t))
    return float((f.max() - f.min()) / (2 * amplitude_m))


def table1_params(frequency_hz: float, amplitude_mm: float, current_a: float) -> HyperbolicParams:
    """A Table 1 fit in SI."""
    row = TABLE1[(frequency_hz, amplitude_mm, current_a)]
    return HyperbolicParams.from_paper_units(row["c0"], row["k0"], row["alpha"], row["beta"])


@dataclass(frozen=True)
class StiffnessLine:
    """K_eff(i) = intercept + slope i [N/m, N/(m A)] fitted by least squares, with R^2."""

    currents: tuple[float, ...]
    stiffness: tuple[float, ...]
    slope: float
    intercept: float
    r2: float


def _line(currents: np.ndarray, k: np.ndarray) -> StiffnessLine:
    slope, intercept = np.polyfit(currents, k, 1)
    resid = k - (intercept + slope * currents)
    r2 = 1 - float(np.sum(resid**2) / np.sum((k - k.mean()) ** 2))
    return StiffnessLine(tuple(map(float, currents)), tuple(map(float, k)), float(slope), float(intercept), r2)


def fig3b(coeffs: GeneralizedCoefficients = TABLE2, frequency_hz: float = 2.0,
          amplitude_mm: float = 8.0) -> dict[str, StiffnessLine]:
    """Effective stiffness against current: Table 1 fits at (f, A) and the generalized model."""
    currents = np.asarray(CURRENTS_A)
    a = amplitude_mm * MM
    per_condition = np.array([effective_stiffness(table1_params(frequency_hz, amplitude_mm, i), a, frequency_hz)
                              for i in CURRENTS_A])
    generalized = np.array([effective_stiffness(coeffs.at_current(i), a, frequency_hz) for i in currents])
    return {"Table 1 fits": _line(currents, per_condition), "generalized model (Table 2)": _line(currents, generalized)}


def random_motion(seed: int = 13, duration_s: float = 4.0, peak_mm: float = 4.0,
                  band_hz: tuple[float, float] = (0.5, 5.0),
                  dt: float = 1e-3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """SYNTHETIC band-limited random displacement: t [s], x [m] (peak ``peak_mm``), v [m/s].

    A sum of 40 sines with frequencies uniform in ``band_hz`` and random phases, equal
    amplitudes, scaled to the peak; v is its exact derivative.
    """
    rng = np.random.default_rng(seed)
    freqs = rng.uniform(*band_hz, 40)
    phases = rng.uniform(0, 2 * np.pi, 40)
    t = np.arange(0.0, duration_s + dt / 2, dt)
    arg = 2 * np.pi * np.outer(t, freqs) + phases
    x = np.sin(arg).sum(axis=1)
    v = (np.cos(arg) * (2 * np.pi * freqs)).sum(axis=1)
    k = peak_mm * MM / np.max(np.abs(x))
    return t, k * x, k * v


def fig13(coeffs: GeneralizedCoefficients = TABLE2, current_a: float = 1.0, seed: int = 13) -> dict[str, object]:
    """Forces [N] of the generalized model and the Table 1 fits at 1 A, 4 mm under the synthetic motion.

    Returns the motion, each model's force, and the RMS difference of each fit from the
    generalized model relative to the generalized model's RMS force.
    """
    t, x, v = random_motion(seed)
    forces = {"generalized model (Table 2)": loop_force(coeffs.at_current(current_a), x, v)}
    for f in (1.0, 2.0, 4.0):
        forces[f"Table 1 fit, {f:g} Hz, 4 mm"] = loop_force(table1_params(f, 4.0, current_a), x, v)
    ref = forces["generalized model (Table 2)"]
    rms_ref = float(np.sqrt(np.mean(ref**2)))
    diff = {name: float(np.sqrt(np.mean((fo - ref) ** 2)) / rms_ref) for name, fo in forces.items()
            if fo is not ref}
    return {"t": t, "x": x, "v": v, "forces": forces, "relative_rms_difference": diff}


def write_figures(out: Path) -> dict[str, object]:
    """fig3b_effective_stiffness.png, fig13_random_excitation.png and paper_figures.json in ``out``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    lines = fig3b()
    fig, ax = plt.subplots(figsize=(5.5, 3.8))
    for (name, line), marker in zip(lines.items(), ("o", "s"), strict=True):
        i = np.asarray(line.currents)
        ax.plot(i, 1e-3 * np.asarray(line.stiffness), marker, label=f"{name}: R² = {line.r2:.3f}")
        ax.plot(i, 1e-3 * (line.intercept + line.slope * i), "--", color=ax.lines[-1].get_color(), lw=0.8)
    ax.set(xlabel="current [A]", ylabel="effective stiffness [N/mm]",
           title="Fig. 3(b): effective stiffness, 2 Hz, 8 mm, one device\n(from the identified models)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "fig3b_effective_stiffness.png", dpi=110)
    plt.close(fig)

    r = fig13()
    fig, axes = plt.subplots(1, 3, figsize=(14, 3.8))
    axes[0].plot(r["t"], r["x"] / MM, lw=0.7)
    axes[0].set(xlabel="time [s]", ylabel="displacement [mm]", title=SYNTHETIC)
    axes[1].plot(r["t"], r["v"] / MM, lw=0.7)
    axes[1].set(xlabel="time [s]", ylabel="velocity [mm/s]", title="its velocity")
    for name, f in r["forces"].items():
        axes[2].plot(r["x"] / MM, f, lw=0.8 if "generalized" in name else 0.5, label=name)
    axes[2].set(xlabel="displacement [mm]", ylabel="force [N]", title="Fig. 13: 1 A, 4 mm peak, one device")
    axes[2].legend(fontsize=7)
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "fig13_random_excitation.png", dpi=110)
    plt.close(fig)

    summary = {"fig3b": {name: {"slope_N_per_mm_A": 1e-3 * ln.slope, "intercept_N_per_mm": 1e-3 * ln.intercept,
                                "r2": ln.r2, "stiffness_N_per_mm": [1e-3 * k for k in ln.stiffness],
                                "currents_A": list(ln.currents)} for name, ln in lines.items()},
               "fig13": {"note": SYNTHETIC, "relative_rms_difference": r["relative_rms_difference"]}}
    (out / "paper_figures.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m orchestration.identification.paper_figures",
                                     description="Draw Fig. 3(b) and Fig. 13 of the paper from the identified models.")
    parser.add_argument("out", type=Path, help="folder for the PNGs and paper_figures.json")
    args = parser.parse_args(argv)
    summary = write_figures(args.out)
    print(json.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
