"""The identifiers compared by the tool, with one result type.

* ``hyperbolic-ffoa``: hyperbolic model (Eq. 3-4) by FFOA on Eq. (5), as in the paper;
* ``bouc_wen-ffoa``: Bouc-Wen model (Eq. 1-2) by FFOA on Eq. (5), as in the paper;
* ``hyperbolic-structured``: hyperbolic model by variable projection
  (:mod:`components.identification.structured`), beyond the paper.

An identification is *converged* when its optimiser settled (FFOA: the record stopped
improving, see :func:`ffoa.judge_convergence`; structured: beta is an interior optimum)
and the fit explains the data: RMS error <= ``max_nrmse`` times the force RMS. A result
that is not converged carries the reason, and the tool writes no parameters for it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from components.identification.ffoa import FFOASettings, ffoa_minimize, judge_convergence
from components.identification.models import (
    BOUC_WEN_PARAMS,
    BW_DELTA_MM,
    HYPERBOLIC_PARAMS,
    FitData,
    bouc_wen_objective,
    bouc_wen_predict,
    hyperbolic_objective,
    hyperbolic_predict,
)
from components.identification.paper_tables import Condition
from components.identification.structured import structured_fit

IDENTIFIERS: tuple[str, ...] = ("hyperbolic-ffoa", "bouc_wen-ffoa", "hyperbolic-structured")

# Typical magnitudes (paper units) that scale the FFOA search, see ffoa module doc.
HYPERBOLIC_TYPICAL = {"c0": 1.0, "k0": 10.0, "alpha": 10.0, "beta": 0.5}
BOUC_WEN_TYPICAL = {"k": 10.0, "c": 1.0, "alpha": 20.0, "beta": 0.5, "gamma": 0.5, "n": 1.5}


@dataclass(frozen=True)
class Acceptance:
    """Convergence rules: FFOA record change over ``window`` iterations < ``rel_tol``;
    fit RMS <= ``max_nrmse`` x force RMS."""

    window: int = 50
    rel_tol: float = 1e-3
    max_nrmse: float = 0.3


@dataclass(frozen=True, eq=False)
class IdentResult:
    """One identification of one condition. params in paper units (F0 included)."""

    identifier: str
    condition: Condition
    params: dict[str, float]
    rms: float
    nrmse: float
    seconds: float
    converged: bool
    reason: str = ""
    history: np.ndarray | None = None
    path: np.ndarray | None = None
    noise_rms: float | None = None
    extra: dict[str, float] = field(default_factory=dict)

    @property
    def model(self) -> str:
        return self.identifier.split("-")[0]


@dataclass(frozen=True)
class _Run:
    """How an identifier's optimisation went: its time [s], whether it settled (and why not), its trace."""

    seconds: float
    settled: tuple[bool, str]
    history: np.ndarray | None = None
    path: np.ndarray | None = None
    extra: dict[str, float] | None = None


def _finish(identifier: str, data: FitData, params: dict[str, float], pred: np.ndarray, run: _Run,
            acceptance: Acceptance) -> IdentResult:
    err = float(np.sqrt(np.mean((data.F - pred) ** 2)))
    nrmse = err / data.force_rms if data.force_rms > 0 else float("inf")
    ok, reason = run.settled
    if ok and not (np.isfinite(err) and nrmse <= acceptance.max_nrmse):
        ok, reason = (
            False,
            (
                f"poor fit: RMS error {err:.4g} N is {nrmse:.3g} of the force RMS "
                f"(limit {acceptance.max_nrmse:g})"
            ),
        )
    return IdentResult(
        identifier,
        data.condition,
        params,
        err,
        nrmse,
        run.seconds,
        ok,
        reason,
        run.history,
        run.path,
        data.noise_rms,
        dict(run.extra or {}),
    )


def _run_ffoa(objective, typical: list[float], rng: np.random.Generator, settings: FFOASettings | None,
              acceptance: Acceptance):
    """(FFOA result, how the run went: optimisation seconds, (settled, reason), trace) for one objective."""
    t0 = time.perf_counter()
    res = ffoa_minimize(objective, typical, rng, settings)
    seconds = time.perf_counter() - t0
    settled = judge_convergence(res.history, acceptance.window, acceptance.rel_tol)
    return res, _Run(seconds, settled, res.history, res.path)


def identify_hyperbolic_ffoa(
    data: FitData,
    rng: np.random.Generator,
    settings: FFOASettings | None = None,
    acceptance: Acceptance | None = None,
) -> IdentResult:
    """Hyperbolic model by FFOA (paper). Run time includes only the optimisation."""
    acceptance = acceptance or Acceptance()
    res, run = _run_ffoa(hyperbolic_objective(data), [HYPERBOLIC_TYPICAL[p] for p in HYPERBOLIC_PARAMS],
                         rng, settings, acceptance)
    params = {**dict(zip(HYPERBOLIC_PARAMS, map(float, res.best), strict=True)), "F0": data.F0}
    return _finish("hyperbolic-ffoa", data, params, hyperbolic_predict(data, params), run, acceptance)


def identify_bouc_wen_ffoa(
    data: FitData,
    rng: np.random.Generator,
    settings: FFOASettings | None = None,
    acceptance: Acceptance | None = None,
) -> IdentResult:
    """Bouc-Wen model (delta = 1/mm) by FFOA (paper)."""
    acceptance = acceptance or Acceptance()
    res, run = _run_ffoa(bouc_wen_objective(data), [BOUC_WEN_TYPICAL[p] for p in BOUC_WEN_PARAMS],
                         rng, settings, acceptance)
    params = {
        **dict(zip(BOUC_WEN_PARAMS, map(float, res.best), strict=True)),
        "delta": BW_DELTA_MM,
        "F0": data.F0,
    }
    pred = bouc_wen_predict(data, params) if np.all(np.isfinite(res.best)) else np.full_like(data.F, np.nan)
    return _finish("bouc_wen-ffoa", data, params, pred, run, acceptance)


def identify_structured(data: FitData, acceptance: Acceptance | None = None, **kwargs) -> IdentResult:
    """Hyperbolic model by variable projection (see structured.py)."""
    acceptance = acceptance or Acceptance()
    t0 = time.perf_counter()
    fit = structured_fit(data.x, data.v, data.F, **kwargs)
    seconds = time.perf_counter() - t0
    params = fit.params
    return _finish(
        "hyperbolic-structured",
        data,
        params,
        hyperbolic_predict(data, params),
        _Run(seconds, (fit.ok, fit.reason), extra={"evaluations": float(fit.evaluations)}),
        acceptance,
    )
