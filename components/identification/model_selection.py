"""Model selection among current-dependent isolator models (docs/identification.md, "Model selection").

For each candidate (a form and its coefficients, paper units):

* RMS of the model on every condition's fit data relative to that condition's noise RMS (synthetic data);
* peak force against Table 1 under the sinusoidal drive: x = A sin(2 pi f t) at the 36 test conditions,
  the peak |F| per device over the last of three cycles (Bouc-Wen from y = 0) against the peak of that
  condition's own Table 1 fit (Eq. 3-4, the paper's identification);
* F(14.9 mm) / F(8 mm) at 1 Hz and 3 A (the same drive): how the model goes on past the tested stroke;
* parameter count k and AIC = 2k - 2 ln L, BIC = k ln N - 2 ln L under two stated likelihoods:
  - ``sample``: every fit-window sample an independent Gaussian error with one unknown variance per
    condition (profiled out): ln L = -sum_c N_c / 2 (ln(2 pi RSS_c / N_c) + 1), N = sum_c N_c;
  - ``condition``: each condition's normalised RMS error e_c = RMS_c / force RMS_c one independent Gaussian
    draw with one unknown variance: ln L = -C / 2 (ln(2 pi sum_c e_c^2 / C) + 1), N = C = 36. Within a
    condition the error of a wrong model form is systematic (the same in every repeat and cycle), so the
    sample likelihood counts one piece of evidence thousands of times; the condition likelihood does not.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from components.identification.bouc_wen_joint import JOINT_DX_MAX_MM
from components.identification.bouc_wen_native import path_states
from components.identification.joint_fits import FORMS, JointForm, current_values
from components.identification.models import FitData, bouc_wen_window_states
from components.identification.paper_tables import TABLE1, TEST_MATRIX, Condition

PEAK_CYCLES = 3
PEAK_SAMPLES_PER_CYCLE = 2000
PEAK_DX_MAX_MM = 0.02  # the BoucWenIsolator FMU's sub-step (and its lam_dx_max 0.5, cap 64)
STROKE_CHECK = (1.0, 14.9, 8.0, 3.0)  # frequency Hz, amplitude mm, reference amplitude mm, current A


def _hyperbolic(q: Mapping[str, float], x: np.ndarray, v: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore", invalid="ignore"):
        return q["c0"] * v + q["k0"] * x + q["alpha"] * np.sinh(q["beta"] * x)


def table1_peak(f: float, a_mm: float, i: float) -> float:
    """Peak |F| [N] of one device under x = A sin(2 pi f t) with that condition's Table 1 parameters."""
    t = np.linspace(0.0, 1.0 / f, 20001)
    w = 2 * np.pi * f
    return float(np.max(np.abs(_hyperbolic(TABLE1[(f, a_mm, i)], a_mm * np.sin(w * t), a_mm * w * np.cos(w * t)))))


def sine_peak(form: JointForm, coefficients: Mapping[str, float], f: float, a_mm: float, i: float) -> float:
    """Peak |F| [N] of one device over the last of PEAK_CYCLES cycles of x = A sin(2 pi f t), paper units."""
    q = current_values(form, coefficients, i)
    n = PEAK_CYCLES * PEAK_SAMPLES_PER_CYCLE
    t = np.linspace(0.0, PEAK_CYCLES / f, n + 1)
    w = 2 * np.pi * f
    x, v = a_mm * np.sin(w * t), a_mm * w * np.cos(w * t)
    if form.model == "hyperbolic":
        F = _hyperbolic(q, x, v)
    else:
        y = path_states(x, q["beta"], q["gamma"], q.get("delta", 1.0), q["n"], dx_max=PEAK_DX_MAX_MM)
        F = q["k"] * x + q["c"] * v + q["alpha"] * y
    return float(np.max(np.abs(F[-PEAK_SAMPLES_PER_CYCLE - 1:])))


def peak_errors(form: JointForm, coefficients: Mapping[str, float]) -> dict[Condition, float]:
    """(model peak / Table 1 peak) - 1 at every test condition."""
    return {c: sine_peak(form, coefficients, *c) / table1_peak(*c) - 1.0 for c in TEST_MATRIX}


def stroke_ratio(form: JointForm, coefficients: Mapping[str, float]) -> float:
    """F(14.9 mm) / F(8 mm) at 1 Hz, 3 A (peaks under the sinusoidal drive)."""
    f, a, a_ref, i = STROKE_CHECK
    return sine_peak(form, coefficients, f, a, i) / sine_peak(form, coefficients, f, a_ref, i)


def window_prediction(form: JointForm, coefficients: Mapping[str, float], d: FitData) -> np.ndarray:
    """The model force [N] over one condition's fit window (F0 = the mean measured force)."""
    q = current_values(form, coefficients, d.condition[2])
    if form.model == "hyperbolic":
        return _hyperbolic(q, d.x, d.v) + d.F0
    y = bouc_wen_window_states(d, q["beta"], q["gamma"], q["n"], dx_max=JOINT_DX_MAX_MM, lam_dx_max=np.inf)
    return q["k"] * d.x + q["c"] * d.v + q["alpha"] * y + d.F0


@dataclass(frozen=True)
class Candidate:
    """One row of the model-selection table."""

    name: str
    form: str
    coefficients: dict[str, float]
    fitted: bool = True  # False: coefficients not fitted to these data (the paper's Table 2)


@dataclass(frozen=True)
class Selection:
    """The measured row of one candidate."""

    name: str
    parameters: int
    rms_over_noise: dict[Condition, float]
    peak_error: dict[Condition, float]
    stroke_ratio: float
    aic: dict[str, float]
    bic: dict[str, float]

    def summary(self) -> dict[str, float]:
        r = np.array(list(self.rms_over_noise.values()))
        e = np.abs(np.array(list(self.peak_error.values())))
        return {"rms_noise_median": float(np.median(r)), "rms_noise_max": float(r.max()),
                "peak_error_median": float(np.median(e)), "peak_error_max": float(e.max()),
                "stroke_ratio": self.stroke_ratio}


def evaluate(candidate: Candidate, data: Mapping[Condition, FitData]) -> Selection:
    """Every measure of the table for one candidate on the fit data ``data`` (synthetic: noise RMS known)."""
    form = FORMS[candidate.form]
    k = form.size
    rss, n_c, e2, rel = [], [], [], {}
    for c, d in data.items():
        r = window_prediction(form, candidate.coefficients, d) - d.F
        s = float(np.sum(r * r))
        rss.append(s)
        n_c.append(r.size)
        e2.append(s / r.size / d.force_rms**2)
        noise = d.noise_rms
        rel[c] = math.sqrt(s / r.size) / noise if noise else math.nan
    n_c_arr, rss_arr = np.array(n_c, dtype=float), np.array(rss)
    loglik = {"sample": float(-np.sum(n_c_arr / 2 * (np.log(2 * np.pi * rss_arr / n_c_arr) + 1))),
              "condition": float(-len(e2) / 2 * (math.log(2 * math.pi * sum(e2) / len(e2)) + 1))}
    counts = {"sample": float(n_c_arr.sum()), "condition": float(len(e2))}
    aic = {key: 2 * k - 2 * ll for key, ll in loglik.items()}
    bic = {key: k * math.log(counts[key]) - 2 * ll for key, ll in loglik.items()}
    return Selection(candidate.name, k, rel, peak_errors(form, candidate.coefficients),
                     stroke_ratio(form, candidate.coefficients), aic, bic)
