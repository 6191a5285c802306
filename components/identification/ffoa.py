"""Fruit fly optimization algorithm (FFOA) as in the paper, section 3.3, Steps 1-7, Eq. (7)-(12).

Every parameter p has its own swarm coordinate pair (X_p, Y_p). One iteration:

* Eq. (7)-(8): each of the N_pop flies draws x_i = X + random_value, y_i = Y + random_value
  (independent draws per fly, per parameter and per axis);
* Eq. (9)-(10): dist_i = sqrt(x_i^2 + y_i^2), candidate S_i = 1/dist_i (so S_i > 0: the
  positivity constraints of Eq. (6) hold by construction);
* Eq. (11)-(12): smell_i = Obj(S_i); the best fly of the iteration is found;
* Steps 6-7: if it beats the record, the record (smell and coordinates) is replaced and the
  swarm (X, Y) flies to that fly's coordinates; otherwise the record and the swarm stay.
  This is Pan's (2012) reference implementation, which the paper cites.

Choices the paper leaves open (documented in docs/identification.md):

* scale: parameter p has a distance scale D_p = 1 / s_p from a typical magnitude s_p;
  the initial swarm location is X_p, Y_p ~ U(0, D_p) (Pan's X_axis = rand, scaled), and
  random_value ~ U(-rho, rho) * D_p with rho = ``step`` (default 0.1). The record starts
  from the best fly of an initial swarm evaluated around the initial location.
* stopping: always N_iter iterations (paper); convergence is judged afterwards
  (:func:`judge_convergence`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

Objective = Callable[[np.ndarray], np.ndarray]  # (n_pop, n_params) -> (n_pop,)


@dataclass(frozen=True)
class FFOASettings:
    """Algorithm parameters: population, iterations, relative step rho of random_value."""

    n_pop: int = 50
    n_iter: int = 300
    step: float = 0.1

    def __post_init__(self) -> None:
        if int(self.n_pop) != self.n_pop or self.n_pop < 2:
            raise ValueError(f"ffoa.n_pop must be an integer >= 2, got {self.n_pop!r}")
        if int(self.n_iter) != self.n_iter or self.n_iter < 1:
            raise ValueError(f"ffoa.n_iter must be an integer >= 1, got {self.n_iter!r}")
        if not (0 < self.step < np.inf):
            raise ValueError(f"ffoa.step must be > 0, got {self.step!r}")


@dataclass(frozen=True)
class FFOAResult:
    """Outcome of one FFOA run.

    best: parameter vector S of the record; best_smell: its objective;
    history: record smell after each iteration (n_iter,), the convergence curve (Fig. 6b);
    path: swarm location (X, Y) per parameter before the first and after every iteration,
    shape (n_iter + 1, n_params, 2), the flight path (Fig. 6a);
    evaluations: objective evaluations (flies) in total.
    """

    best: np.ndarray
    best_smell: float
    history: np.ndarray
    path: np.ndarray
    evaluations: int


def candidates(X: np.ndarray, Y: np.ndarray, rng: np.random.Generator, n_pop: int, radius: np.ndarray):
    """Eq. (7)-(10): fly coordinates around (X, Y) and the candidates S = 1/dist.

    X, Y, radius: (n_params,); returns xi, yi, S, each (n_pop, n_params).
    """
    xi = X + radius * rng.uniform(-1.0, 1.0, size=(n_pop, X.size))
    yi = Y + radius * rng.uniform(-1.0, 1.0, size=(n_pop, X.size))
    dist = np.hypot(xi, yi)
    with np.errstate(divide="ignore"):
        S = 1.0 / dist
    return xi, yi, S


def ffoa_minimize(
    objective: Objective,
    typical: Sequence[float],
    rng: np.random.Generator,
    settings: FFOASettings | None = None,
) -> FFOAResult:
    """Minimise ``objective`` over positive parameters with FFOA (Steps 1-7 of the paper).

    typical: a typical magnitude s_p per parameter (sets D_p = 1/s_p, see module doc).
    """
    settings = settings or FFOASettings()
    scale = 1.0 / np.asarray(typical, dtype=float)
    if np.any(~np.isfinite(scale)) or np.any(scale <= 0):
        raise ValueError("typical magnitudes must be finite and > 0")
    radius = settings.step * scale

    def smell_of(S: np.ndarray) -> np.ndarray:
        smell = np.asarray(objective(S), dtype=float)
        return np.where(np.isfinite(smell), smell, np.inf)

    # Step 2: initial swarm location; a first swarm around it sets the record (Pan 2012).
    X = rng.uniform(0.0, 1.0, scale.size) * scale
    Y = rng.uniform(0.0, 1.0, scale.size) * scale
    xi, yi, S = candidates(X, Y, rng, settings.n_pop, radius)
    smell = smell_of(S)
    k = int(np.argmin(smell))
    best_smell, best = float(smell[k]), S[k].copy()
    X, Y = xi[k].copy(), yi[k].copy()
    path = np.empty((settings.n_iter + 1, scale.size, 2))
    path[0, :, 0], path[0, :, 1] = X, Y
    history = np.empty(settings.n_iter)
    for it in range(settings.n_iter):
        xi, yi, S = candidates(X, Y, rng, settings.n_pop, radius)  # Step 3-4
        smell = smell_of(S)  # Step 5, Eq. (11)
        k = int(np.argmin(smell))  # Eq. (12)
        if smell[k] < best_smell:  # Steps 6-7
            best_smell, best = float(smell[k]), S[k].copy()
            X, Y = xi[k].copy(), yi[k].copy()
        history[it] = best_smell
        path[it + 1, :, 0], path[it + 1, :, 1] = X, Y
    return FFOAResult(best, best_smell, history, path, settings.n_pop * (settings.n_iter + 1))


def judge_convergence(history: np.ndarray, window: int, rel_tol: float) -> tuple[bool, str]:
    """Did the record settle? True if it improved by less than ``rel_tol`` (relative) over
    the last ``window`` iterations and is finite; returns (ok, reason)."""
    if history.size == 0 or not np.isfinite(history[-1]):
        return False, "no finite objective value was found"
    w = min(window, history.size - 1)
    if w <= 0:
        return True, ""
    before, after = history[-w - 1], history[-1]
    change = (before - after) / max(abs(after), 1e-300)
    if change > rel_tol:
        return False, f"still improving: objective fell by {100 * change:.2g} % over the last {w} iterations"
    return True, ""
