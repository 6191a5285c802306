"""Model forms, fit data and the objective of Eq. (5), in the paper's units (mm, mm/s, N).

Hyperbolic: F = c0 v + k0 x + alpha sinh(beta x) + F0 (Eq. 3-4); S = [c0, k0, alpha, beta].
Bouc-Wen:   F = k x + c v + alpha y + F0, y from Eq. (2) (components.physics.bouc_wen_core, with
            delta fixed at 1/mm); S = [k, c, alpha, beta, gamma, n].
In both, F0 is the mean measured force over the fit window, as the paper states.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from components.identification.bouc_wen_native import path_states
from components.identification.paper_tables import Condition
from components.identification.testdata import ShakeRecord, TestDataError, hyperbolic_force_mm

HYPERBOLIC_PARAMS: tuple[str, ...] = ("c0", "k0", "alpha", "beta")
BOUC_WEN_PARAMS: tuple[str, ...] = ("k", "c", "alpha", "beta", "gamma", "n")
BW_DELTA_MM = 1.0  # delta fixed at 1 per mm (see components.physics.bouc_wen_core)
# Sub-step control of the Bouc-Wen integrator in identification (see bouc_wen_core.substeps):
# at most 0.2 mm and 2/Lam per sub-step, at most 4 sub-steps per sample. Coarser than the
# FMU's defaults to keep FFOA affordable; the scheme stays stable, and for the parameters
# FFOA ends at the state error is below 1 % of the envelope (tests/physics/test_bouc_wen.py).
BW_DX_MAX_MM = 0.2
BW_LAM_DX_MAX = 2.0
BW_CAP = 4


@dataclass(frozen=True, eq=False)
class FitData:
    """The data of one test condition that an identifier sees, paper units.

    Per repeat r: the full history from the record start up to the end of the fit window
    (``x_hist``, used to integrate the Bouc-Wen state from y = 0 at t[0]) and the fit
    window itself (``x``, ``v``, ``F`` = samples ``start[r]:`` of the history).
    """

    condition: Condition
    sources: tuple[str, ...]
    x_hist: tuple[np.ndarray, ...]
    v_hist: tuple[np.ndarray, ...]
    F_hist: tuple[np.ndarray, ...]
    start: tuple[int, ...]
    clean_hist: tuple[np.ndarray, ...] | None = None
    synthetic: bool = False
    truth: dict[str, float] = field(default_factory=dict)

    def _win(self, arrays: Sequence[np.ndarray]) -> np.ndarray:
        return np.concatenate([a[s:] for a, s in zip(arrays, self.start, strict=True)])

    @property
    def x(self) -> np.ndarray:
        return self._win(self.x_hist)

    @property
    def v(self) -> np.ndarray:
        return self._win(self.v_hist)

    @property
    def F(self) -> np.ndarray:
        return self._win(self.F_hist)

    @property
    def F0(self) -> float:
        """Force offset: mean measured force over the fit window [N]."""
        return float(np.mean(self.F))

    @property
    def noise_rms(self) -> float | None:
        """RMS of (measured - clean) force over the fit window; synthetic data only."""
        if self.clean_hist is None:
            return None
        return float(np.sqrt(np.mean((self.F - self._win(self.clean_hist)) ** 2)))

    def shared_path(self) -> bool:
        """True if every repeat has the same displacement and velocity history and window start
        (synthetic data without displacement noise): model forces are then the same in every
        repeat and are computed for one repeat only, which gives the same numbers."""
        return len(set(self.start)) == 1 and all(
            np.array_equal(self.x_hist[0], x) and np.array_equal(self.v_hist[0], v)
            for x, v in zip(self.x_hist[1:], self.v_hist[1:], strict=True)
        )

    @property
    def force_rms(self) -> float:
        """RMS of the force about its mean over the fit window [N]."""
        F = self.F
        return float(np.sqrt(np.mean((F - F.mean()) ** 2)))


def fit_data(records: Sequence[ShakeRecord], first_cycle: int = 1, cycles: int = 1) -> FitData:
    """Fit data of one condition from its repeats: cycles first_cycle .. +cycles-1 of each run."""
    if not records:
        raise ValueError("no records")
    cond = records[0].condition
    for r in records:
        if r.condition != cond:
            raise TestDataError(f"{r.source}: condition {r.condition} mixed with {cond}")
    windows = [r.cycle_window(first_cycle, cycles) for r in records]
    for r, w in zip(records, windows, strict=True):
        if w.stop - w.start < 8:
            raise TestDataError(f"{r.source}: fit window holds only {w.stop - w.start} samples")
    clean = None
    if all(r.F_clean is not None for r in records):
        clean = tuple(r.F_clean[: w.stop] for r, w in zip(records, windows, strict=True))
    truth = {k.removeprefix("true_"): float(v) for k, v in records[0].meta.items() if k.startswith("true_")}
    return FitData(
        condition=cond,
        sources=tuple(r.source for r in records),
        x_hist=tuple(r.x[: w.stop] for r, w in zip(records, windows, strict=True)),
        v_hist=tuple(r.v[: w.stop] for r, w in zip(records, windows, strict=True)),
        F_hist=tuple(r.F[: w.stop] for r, w in zip(records, windows, strict=True)),
        start=tuple(w.start for w in windows),
        clean_hist=clean,
        synthetic=all(r.synthetic for r in records),
        truth=truth,
    )


def rms(residual: np.ndarray, axis: int = -1) -> np.ndarray:
    """Root mean square along ``axis``."""
    return np.sqrt(np.mean(residual**2, axis=axis))


# ------------------------------------------------------------------- hyperbolic


def hyperbolic_predict(data: FitData, params: dict[str, float]) -> np.ndarray:
    """Hyperbolic force over the fit window [N] for named parameters (paper units, F0 incl.)."""
    return hyperbolic_force_mm(
        data.x, data.v, params["c0"], params["k0"], params["alpha"], params["beta"], params.get("F0", data.F0)
    )


def _repeat(pred: np.ndarray, repeats: int) -> np.ndarray:
    """A model force of one repeat's window, laid out over the concatenated windows."""
    return np.tile(pred, repeats) if repeats > 1 else pred


def _objective_window(data: FitData) -> tuple[np.ndarray, np.ndarray, Callable[[np.ndarray], np.ndarray]]:
    """(x, v, error): the samples a model force is computed on, and the RMS error [N] over
    the fit window of every repeat for a batch of such forces (P, samples) -> (P,).

    If the repeats share their path (:meth:`FitData.shared_path`), the force is computed
    for one repeat's window only and, with Fbar the mean measured force over the repeats,
    sum_r (F_r - f)^2 = R sum (f - Fbar)^2 + sum_r (F_r - Fbar)^2. This equals the direct sum
    up to rounding (relative differences of order 1e-16) and costs 1/R of it.
    """
    F = data.F
    repeats = len(data.x_hist)
    if repeats == 1 or not data.shared_path():
        return data.x, data.v, lambda pred: rms(F - pred)
    s = data.start[0]
    per_repeat = F.reshape(repeats, -1)
    F_mean = per_repeat.mean(axis=0)
    spread = float(np.sum((per_repeat - F_mean) ** 2))

    def error(pred: np.ndarray) -> np.ndarray:
        d = pred - F_mean
        return np.sqrt((repeats * np.sum(d * d, axis=-1) + spread) / F.size)

    return data.x_hist[0][s:], data.v_hist[0][s:], error


def hyperbolic_objective(data: FitData):
    """Eq. (5) for a batch S (n_pop, 4) = [c0, k0, alpha, beta]; F0 = mean force.

    The whole population is evaluated at once: returns (n_pop,) RMS errors [N].
    """
    F0 = data.F0
    x, v, error = _objective_window(data)

    def objective(S: np.ndarray) -> np.ndarray:
        c0, k0, alpha, beta = (S[:, j, None] for j in range(4))
        with np.errstate(over="ignore", invalid="ignore"):
            return error(hyperbolic_force_mm(x, v, c0, k0, alpha, beta, F0))

    return objective


# ------------------------------------------------------------------- Bouc-Wen


def bouc_wen_window_states(  # noqa: PLR0913 - the law's parameter arrays and integrator limits; per objective call
    data: FitData,
    beta,
    gamma,
    n,
    dx_max: float = BW_DX_MAX_MM,
    lam_dx_max: float = BW_LAM_DX_MAX,
    cap: int = BW_CAP,
    use: str | None = None,
    one_repeat: bool = False,
) -> np.ndarray:
    """Bouc-Wen state [1] over the fit window, concatenated over repeats; parameters (P,) or scalars.

    Result (P, samples) or (samples,), from y = 0 at the first sample of every repeat.
    Repeats of equal history length are integrated as one batch (one sub-step count per
    sample for all of them, as in ``bouc_wen_core.bouc_wen_states``); repeats that share
    their path (:meth:`FitData.shared_path`) are integrated once, which gives the same
    numbers. ``one_repeat``: then return the window of one repeat only. ``use``: backend
    of :func:`bouc_wen_native.path_states` ("c", "numpy", None = C when available).
    """
    kw = {"dx_max": dx_max, "lam_dx_max": lam_dx_max, "cap": cap, "use": use}
    if data.shared_path():
        s = data.start[0]
        y = path_states(data.x_hist[0], beta, gamma, BW_DELTA_MM, n, **kw)[..., s:]
        return y if one_repeat else _repeat(y, len(data.x_hist))
    if len({a.size for a in data.x_hist}) == 1 and len(set(data.start)) == 1:
        y = path_states(np.stack(data.x_hist), beta, gamma, BW_DELTA_MM, n, **kw)
        return y[..., data.start[0] :].reshape(*y.shape[:-2], -1)
    parts = [
        path_states(xh, beta, gamma, BW_DELTA_MM, n, **kw)[..., s:]
        for xh, s in zip(data.x_hist, data.start, strict=True)
    ]
    return np.concatenate(parts, axis=-1)


def bouc_wen_predict(data: FitData, params: dict[str, float]) -> np.ndarray:
    """Bouc-Wen force over the fit window [N] for named parameters (paper units)."""
    y = bouc_wen_window_states(data, params["beta"], params["gamma"], params["n"])
    return params["k"] * data.x + params["c"] * data.v + params["alpha"] * y + params.get("F0", data.F0)


def bouc_wen_objective(data: FitData, dx_max: float = BW_DX_MAX_MM, use: str | None = None):
    """Eq. (5) with the Bouc-Wen force for a batch S (n_pop, 6) = [k, c, alpha, beta, gamma, n].

    The whole population is evaluated at once (one pass over the samples for all flies,
    see :func:`bouc_wen_native.path_states`): returns (n_pop,) RMS errors [N].
    """
    F0 = data.F0
    x, v, error = _objective_window(data)
    one_repeat = x.size < data.F.size

    def objective(S: np.ndarray) -> np.ndarray:
        k, c, alpha, beta, gamma, n = (S[:, j, None] for j in range(6))
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            y = bouc_wen_window_states(data, beta[:, 0], gamma[:, 0], n[:, 0], dx_max, use=use,
                                       one_repeat=one_repeat)
            return error(k * x + c * v + alpha * y + F0)

    return objective
