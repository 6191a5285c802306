"""Model forms, fit data and the objective of Eq. (5), in the paper's units (mm, mm/s, N).

Hyperbolic: F = c0 v + k0 x + alpha sinh(beta x) + F0 (Eq. 3-4); S = [c0, k0, alpha, beta].
Bouc-Wen:   F = k x + c v + alpha y + F0, y from Eq. (2) (components.physics.bouc_wen_core, with
            delta fixed at 1/mm); S = [k, c, alpha, beta, gamma, n].
In both, F0 is the mean measured force over the fit window, as the paper states.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from components.identification.paper_tables import Condition
from components.identification.testdata import ShakeRecord, TestDataError, hyperbolic_force_mm
from components.physics.bouc_wen_core import bouc_wen_states

HYPERBOLIC_PARAMS: tuple[str, ...] = ("c0", "k0", "alpha", "beta")
BOUC_WEN_PARAMS: tuple[str, ...] = ("k", "c", "alpha", "beta", "gamma", "n")
BW_DELTA_MM = 1.0  # delta fixed at 1 per mm (see components.physics.bouc_wen_core)
# Sub-step control of the Bouc-Wen integrator in identification (see bouc_wen_core.substeps):
# at most 0.2 mm and 2/Lam per sub-step, at most 4 sub-steps per sample. Coarser than the
# FMU's defaults to keep FFOA affordable; the scheme stays stable, and for the parameters
# FFOA ends at the state error is below 1 % of the envelope (tests/test_bouc_wen.py).
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


def hyperbolic_objective(data: FitData):
    """Eq. (5) for a batch S (n_pop, 4) = [c0, k0, alpha, beta]; F0 = mean force."""
    x, v, F, F0 = data.x, data.v, data.F, data.F0

    def objective(S: np.ndarray) -> np.ndarray:
        c0, k0, alpha, beta = (S[:, j, None] for j in range(4))
        with np.errstate(over="ignore", invalid="ignore"):
            return rms(F - hyperbolic_force_mm(x, v, c0, k0, alpha, beta, F0))

    return objective


# ------------------------------------------------------------------- Bouc-Wen


def bouc_wen_window_states(
    data: FitData,
    beta,
    gamma,
    n,
    dx_max: float = BW_DX_MAX_MM,
    lam_dx_max: float = BW_LAM_DX_MAX,
    cap: int = BW_CAP,
) -> np.ndarray:
    """Bouc-Wen state over the fit window, concatenated over repeats; parameters (P, 1) or scalars.

    Repeats of equal history length are integrated together (one batch).
    """
    lengths = {a.size for a in data.x_hist}
    if len(lengths) == 1 and len(set(data.start)) == 1:
        y = bouc_wen_states(
            np.stack(data.x_hist),
            np.asarray(beta)[..., None],
            np.asarray(gamma)[..., None],
            BW_DELTA_MM,
            np.asarray(n)[..., None],
            dx_max,
            lam_dx_max=lam_dx_max,
            cap=cap,
        )
        return y[..., data.start[0] :].reshape(*y.shape[:-2], -1)
    parts = [
        bouc_wen_states(xh, beta, gamma, BW_DELTA_MM, n, dx_max, lam_dx_max=lam_dx_max, cap=cap)[..., s:]
        for xh, s in zip(data.x_hist, data.start, strict=True)
    ]
    return np.concatenate(parts, axis=-1)


def bouc_wen_predict(data: FitData, params: dict[str, float]) -> np.ndarray:
    """Bouc-Wen force over the fit window [N] for named parameters (paper units)."""
    y = bouc_wen_window_states(data, params["beta"], params["gamma"], params["n"])
    return params["k"] * data.x + params["c"] * data.v + params["alpha"] * y + params.get("F0", data.F0)


def bouc_wen_objective(data: FitData, dx_max: float = BW_DX_MAX_MM):
    """Eq. (5) with the Bouc-Wen force for a batch S (n_pop, 6) = [k, c, alpha, beta, gamma, n]."""
    x, v, F, F0 = data.x, data.v, data.F, data.F0

    def objective(S: np.ndarray) -> np.ndarray:
        k, c, alpha, beta, gamma, n = (S[:, j, None] for j in range(6))
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            y = bouc_wen_window_states(data, beta[:, 0], gamma[:, 0], n[:, 0], dx_max)
            return rms(F - (k * x + c * v + alpha * y + F0))

    return objective
