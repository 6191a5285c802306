"""Generalized current-dependent model, section 3.5: Eq. (13)-(16) by least squares.

Identified parameters are grouped by current, averaged over the conditions of each
current, and every parameter is fitted as p(i) = p^0 * i + p^1 (``numpy.polyfit``,
degree 1, ordinary least squares on the per-current means, as the paper does).
The result is written as a parameter file (YAML, SI) that a scenario hands to the
isolator FMU (MreIsolator for the hyperbolic model, BoucWenIsolator for Bouc-Wen).
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from components.identification.paper_tables import CURRENTS_A, PARAMS, TABLE1
from components.physics.bouc_wen_core import BoucWenCurrentModel
from components.physics.bouc_wen_core import device_problem as bouc_wen_device_problem
from components.physics.mre_isolator_core import GeneralizedCoefficients, ParameterError
from components.physics.mre_isolator_core import device_problem as hyperbolic_device_problem
from mre_common.atomic_files import atomic_write_text

LINEAR_IN_CURRENT = {
    "hyperbolic": ("k0", "c0", "alpha", "beta"),
    "bouc_wen": ("k", "c", "alpha", "beta", "gamma"),
}
CONSTANT = {"hyperbolic": (), "bouc_wen": ("n", "delta")}
FMU_OF_MODEL = {"hyperbolic": "MreIsolator", "bouc_wen": "BoucWenIsolator"}
SI_UNITS_OF = {
    "k0_0": "N/(m.A)",
    "k0_1": "N/m",
    "c0_0": "N.s/(m.A)",
    "c0_1": "N.s/m",
    "alpha_0": "N/A",
    "alpha_1": "N",
    "beta_0": "1/(m.A)",
    "beta_1": "1/m",
    "k_0": "N/(m.A)",
    "k_1": "N/m",
    "c_0": "N.s/(m.A)",
    "c_1": "N.s/m",
    "gamma_0": "1/(m.A)",
    "gamma_1": "1/m",
    "delta": "1/m",
    "n": "1",
}


class GeneralizationError(ValueError):
    """The generalized model cannot be fitted (e.g. fewer than two currents)."""


@dataclass(frozen=True)
class GeneralizedFit:
    """Per-current means and the Eq. (13)-(16) coefficients, paper units.

    coefficients: ``<param>_0`` slope per A, ``<param>_1`` value at 0 A (Table 2 layout),
    plus constant parameters (Bouc-Wen n, delta) by their own name.
    """

    model: str
    means: dict[float, dict[str, float]]
    counts: dict[float, int]
    coefficients: dict[str, float]


def group_means(rows: Iterable[tuple[float, Mapping[str, float]]], names: Sequence[str]):
    """(current, params) rows -> ({current: {name: mean}}, {current: count})."""
    groups: dict[float, list[Mapping[str, float]]] = {}
    for current, params in rows:
        groups.setdefault(float(current), []).append(params)
    means = {i: {p: float(np.mean([g[p] for g in grp])) for p in names} for i, grp in sorted(groups.items())}
    return means, {i: len(grp) for i, grp in sorted(groups.items())}


def fit_generalized(
    rows: Iterable[tuple[float, Mapping[str, float]]], model: str = "hyperbolic"
) -> GeneralizedFit:
    """Least-squares lines through the per-current means of the identified parameters."""
    linear, constant = LINEAR_IN_CURRENT[model], CONSTANT[model]
    means, counts = group_means(rows, (*linear, *constant))
    if len(means) < 2:
        raise GeneralizationError(
            f"need converged identifications at two or more currents, have {sorted(means) or 'none'}"
        )
    currents = np.array(sorted(means))
    coeffs: dict[str, float] = {}
    for p in linear:
        slope, intercept = np.polyfit(currents, [means[i][p] for i in currents], 1)
        coeffs[f"{p}_0"], coeffs[f"{p}_1"] = float(slope), float(intercept)
    for p in constant:
        coeffs[p] = float(np.mean([means[i][p] for i in currents]))
    return GeneralizedFit(model, means, counts, coeffs)


def generalized_rms(fit_model: str, coefficients: Mapping[str, float], data: Mapping) -> dict:
    """RMS error [N] of a generalized model (paper-unit coefficients) on every condition's fit data."""
    from components.identification.models import bouc_wen_predict, hyperbolic_predict

    out = {}
    for cond, d in data.items():
        i = cond[2]
        p = {q: coefficients[f"{q}_0"] * i + coefficients[f"{q}_1"] for q in LINEAR_IN_CURRENT[fit_model]}
        for q in CONSTANT[fit_model]:
            p[q] = coefficients[q]
        with np.errstate(all="ignore"):
            pred = hyperbolic_predict(d, p) if fit_model == "hyperbolic" else bouc_wen_predict(d, p)
            out[cond] = float(np.sqrt(np.mean((pred - d.F) ** 2)))
    return out


def table2_from_table1() -> GeneralizedFit:
    """Eq. (13)-(16) fitted to the means of the paper's Table 1 (to compare with Table 2)."""
    rows = [(i, TABLE1[(f, a, i)]) for (f, a, i) in TABLE1]
    fit = fit_generalized(rows, "hyperbolic")
    assert set(fit.means) == set(CURRENTS_A) and all(set(m) == set(PARAMS) for m in fit.means.values())
    return fit


def si_coefficients(fit: GeneralizedFit) -> GeneralizedCoefficients | BoucWenCurrentModel:
    """The fitted coefficients converted once to SI through the core classes."""
    if fit.model == "hyperbolic":
        return GeneralizedCoefficients.from_paper_units(**fit.coefficients)
    return BoucWenCurrentModel.from_paper_units(**fit.coefficients)


ROUNDOFF_REL = 1e-9
"""Relative size below which a fitted value counts as zero (see :func:`roundoff_tolerance`)."""


def roundoff_tolerance(fit: GeneralizedFit, param: str, i_max: float) -> float:
    """Absolute tolerance for comparing the fitted line of ``param`` with zero on [0, i_max] A.

    The lines come from ``np.polyfit`` (least squares through BLAS/LAPACK) on per-current
    means of order 1-40 in paper units. A value that is zero in exact arithmetic comes out
    as +-1e-16..1e-15 with a sign that depends on the BLAS build and the CPU (e.g. k0(0 A)
    = -3.966e-16 on AMD EPYC, +2e-16 elsewhere); double precision leaves ~1e-16 relative
    to the magnitudes involved, amplified by the (small) condition number of the fit. So a
    value counts as zero within ROUNDOFF_REL = 1e-9 times the largest magnitude involved
    (|line| at 0 A and i_max, and the means it was fitted to): 10^6 above round-off, yet
    far below any physically meaningful parameter (a real -1e-9 relative stiffness is zero
    for every purpose of the model).
    """
    line = [abs(fit.coefficients[f"{param}_0"] * i + fit.coefficients[f"{param}_1"]) for i in (0.0, i_max)]
    data = [abs(m[param]) for m in fit.means.values() if param in m]
    return ROUNDOFF_REL * max([*line, *data, 0.0])


def physical_problems(fit: GeneralizedFit, i_max: float) -> list[str]:
    """Why the fitted lines are not a usable device model on [0, i_max] A (empty if usable).

    Every linear parameter must be >= 0 at 0 A and at i_max (Eq. 6; lines, so then on the
    whole range); for Bouc-Wen also beta + gamma > 0 (else there is no hysteresis envelope).
    Values within round-off of zero (:func:`roundoff_tolerance`) count as zero: a parameter
    of -4e-16 is accepted as 0, a beta + gamma of +4e-16 is refused as 0.
    """
    linear = LINEAR_IN_CURRENT[fit.model]
    tol = {p: roundoff_tolerance(fit, p, i_max) for p in linear}
    out = []
    for i in (0.0, i_max):
        values = {p: fit.coefficients[f"{p}_0"] * i + fit.coefficients[f"{p}_1"] for p in linear}
        out += [f"{p}({i:g} A) = {v:.4g} < 0" for p, v in values.items() if v < -tol[p]]
        if fit.model == "bouc_wen":
            total = values["beta"] + values["gamma"]
            if total <= tol["beta"] + tol["gamma"]:
                out.append(f"beta + gamma = {total:.4g} <= 0 at {i:g} A")
    return out


def write_parameter_file(path: str | os.PathLike, fit: GeneralizedFit, note: str, synthetic: bool) -> None:
    """YAML parameter file: ``fmu``, ``parameters`` (SI, FMU variable names), units, provenance."""
    si = si_coefficients(fit).as_dict()
    for name, value in si.items():
        if not math.isfinite(value):
            raise GeneralizationError(f"coefficient {name} = {value} is not finite")
    doc = {
        "fmu": FMU_OF_MODEL[fit.model],
        "model": fit.model,
        "synthetic": bool(synthetic),
        "note": note,
        "parameters": {k: float(v) for k, v in si.items()},
        "units": {k: SI_UNITS_OF[k] for k in si},
        "paper_units": {k: float(v) for k, v in fit.coefficients.items()},
        "per_current_means_paper_units": {float(i): dict(m) for i, m in fit.means.items()},
        "conditions_per_current": {float(i): int(c) for i, c in fit.counts.items()},
    }
    head = "# SYNTHETIC DATA - not measured. " if synthetic else "# "
    text = head + "Generalized isolator coefficients (Eq. 13-16), SI units.\n"
    atomic_write_text(path, text + yaml.safe_dump(doc, sort_keys=False))


def load_parameter_file(path: str | os.PathLike, i_max: float = 3.0) -> GeneralizedCoefficients | BoucWenCurrentModel:
    """Read a file written by :func:`write_parameter_file` back into the SI core class.

    GeneralizationError naming the file and the coefficient when the law is no device on [0, i_max] A up to
    the device limit (the force does not rise with displacement somewhere; Bouc-Wen: beta + gamma <= 0):
    the cores' ``device_problem``.
    """
    doc = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    if not isinstance(doc, dict) or "parameters" not in doc or doc.get("model") not in LINEAR_IN_CURRENT:
        raise GeneralizationError(f"{path}: not a generalized coefficient file")
    cls = GeneralizedCoefficients if doc["model"] == "hyperbolic" else BoucWenCurrentModel
    try:
        model = cls(**{k: float(v) for k, v in doc["parameters"].items()})
    except (TypeError, ValueError) as exc:
        raise GeneralizationError(f"{path}: {exc}") from None
    check = hyperbolic_device_problem if doc["model"] == "hyperbolic" else bouc_wen_device_problem
    try:
        check(model, i_max, beyond_range="extrapolate")
    except ParameterError as exc:
        raise GeneralizationError(f"{path}: coefficient {exc.parameter}: {exc}") from None
    return model
