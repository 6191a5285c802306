"""Current-dependent models fitted jointly to every test condition, and their uncertainty (beyond the paper).

The paper fits each condition alone (Table 1) and then lines through the per-current means (Table 2).
Here a current-dependent form is fitted directly to the data of all conditions at once by nonlinear
least squares (``scipy.optimize.least_squares``, trust-region reflective, bounds), with the residual
weighting of :mod:`bouc_wen_joint`: per condition (predicted - measured force) / (force RMS *
sqrt(samples)), so every condition weighs the same whatever its force level; F0 per condition = its
mean measured force. Forms (:data:`FORMS`), paper units (mm, N):

* ``hyperbolic``: Eq. (13)-(17), c0, k0, alpha, beta linear in the current (8 coefficients);
* ``bouc_wen``: Eq. (1)-(2), k, c, alpha, beta, gamma linear in the current, n constant, delta = 1/mm
  (11 coefficients; the model of :mod:`bouc_wen_joint`, which the pipeline fits);
* ``bouc_wen-quadratic``: the same with every current-dependent parameter quadratic in the current
  (16 coefficients): room for a field dependence that saturates (magnetic saturation of the MR effect;
  Table 1's per-current means of c0 rise by 0.77, 0.65 and 0.28 N s/mm per ampere).

Unknowns are each parameter's values at the current nodes (0 and i_ref, or 0, i_ref/2 and i_ref, with
i_ref the largest current of the data), bounded below as in :mod:`bouc_wen_joint`, so the coefficients
follow by a fixed linear map. Coefficients: ``<p>_1`` value at 0 A, ``<p>_0`` slope per ampere,
``<p>_2`` (quadratic form only) the coefficient of i^2.

Uncertainty (:func:`bootstrap`): the fit repeated on B data sets, each with a fresh noise realisation
(a new seed of the synthetic generator, or the same data when they are measured) and the conditions
drawn with replacement (a condition drawn twice weighs twice): a spread over the test matrix as well
as over the noise, which the Jacobian covariance (:attr:`JointFormFit.covariance`, also given) misses
when, as here, the residual is model-form error rather than noise.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from components.identification.bouc_wen_joint import JOINT_DX_MAX_MM
from components.identification.models import FitData, bouc_wen_window_states
from components.identification.paper_tables import Condition


@dataclass(frozen=True)
class JointForm:
    """A current-dependent model form: which parameters depend on the current, and how."""

    name: str
    model: str  # "hyperbolic" | "bouc_wen" (the force law)
    current_params: tuple[str, ...]
    constant: tuple[str, ...]
    rule: str  # "linear" | "quadratic"
    floor: Mapping[str, float]
    constant_bounds: Mapping[str, tuple[float, float]]

    @property
    def nodes(self) -> int:
        return 2 if self.rule == "linear" else 3

    @property
    def size(self) -> int:
        """Number of fitted coefficients (the parameter count of the model-selection table)."""
        return self.nodes * len(self.current_params) + len(self.constant)

    def coefficient_names(self) -> list[str]:
        suffixes = ("_0", "_1") if self.rule == "linear" else ("_0", "_1", "_2")
        return [p + s for p in self.current_params for s in suffixes] + list(self.constant)


_BW_FLOOR = {"k": 1e-3, "c": 1e-4, "alpha": 1e-3, "beta": 1e-4, "gamma": 0.0}
FORMS: dict[str, JointForm] = {
    "hyperbolic": JointForm("hyperbolic", "hyperbolic", ("k0", "c0", "alpha", "beta"), (), "linear",
                            {"k0": 0.0, "c0": 0.0, "alpha": 0.0, "beta": 1e-4}, {}),
    "bouc_wen": JointForm("bouc_wen", "bouc_wen", ("k", "c", "alpha", "beta", "gamma"), ("n",), "linear",
                          _BW_FLOOR, {"n": (0.5, 4.0)}),
    "bouc_wen-quadratic": JointForm("bouc_wen-quadratic", "bouc_wen", ("k", "c", "alpha", "beta", "gamma"), ("n",),
                                    "quadratic", _BW_FLOOR, {"n": (0.5, 4.0)}),
}


def current_values(form: JointForm, coefficients: Mapping[str, float], i: float) -> dict[str, float]:
    """The form's parameters at current i [A] from its coefficients (paper units)."""
    out = {}
    for p in form.current_params:
        value = coefficients[f"{p}_0"] * i + coefficients[f"{p}_1"]
        if form.rule == "quadratic":
            value += coefficients[f"{p}_2"] * i * i
        out[p] = value
    out.update({p: coefficients[p] for p in form.constant})
    if form.model == "bouc_wen":
        out.setdefault("delta", 1.0)
    return out


def _node_currents(form: JointForm, i_ref: float) -> np.ndarray:
    return np.linspace(0.0, i_ref, form.nodes)


def _params(form: JointForm, theta: np.ndarray, i: float, i_ref: float) -> dict[str, np.ndarray]:
    """Parameters at current i for a batch theta (P, size) (Lagrange interpolation through the node values)."""
    nodes = _node_currents(form, i_ref)
    weights = [np.prod([(i - nodes[m]) / (nodes[k] - nodes[m]) for m in range(len(nodes)) if m != k])
               for k in range(len(nodes))]
    out = {}
    for j, p in enumerate(form.current_params):
        vals = theta[:, j * form.nodes:(j + 1) * form.nodes]
        out[p] = sum(w * vals[:, k] for k, w in enumerate(weights))
    base = form.nodes * len(form.current_params)
    for j, p in enumerate(form.constant):
        out[p] = theta[:, base + j]
    return out


def to_coefficients(form: JointForm, theta: np.ndarray, i_ref: float) -> dict[str, float]:
    """Node values -> coefficients ``<p>_0``, ``<p>_1`` (``<p>_2``) and the constants (paper units)."""
    out: dict[str, float] = {}
    h = i_ref / 2.0
    for j, p in enumerate(form.current_params):
        v = theta[j * form.nodes:(j + 1) * form.nodes]
        if form.rule == "linear":
            out[f"{p}_1"], out[f"{p}_0"] = float(v[0]), float((v[1] - v[0]) / i_ref)
        else:
            c = (v[0] - 2.0 * v[1] + v[2]) / (2.0 * h * h)
            out[f"{p}_1"], out[f"{p}_0"], out[f"{p}_2"] = float(v[0]), float((v[1] - v[0]) / h - c * h), float(c)
    base = form.nodes * len(form.current_params)
    out.update({p: float(theta[base + j]) for j, p in enumerate(form.constant)})
    if form.model == "bouc_wen":
        out["delta"] = 1.0
    return out


def coefficient_map(form: JointForm, i_ref: float) -> np.ndarray:
    """The linear map theta -> coefficients (rows in :meth:`JointForm.coefficient_names` order)."""
    names = form.coefficient_names()
    base = to_coefficients(form, np.zeros(form.size), i_ref)
    cols = []
    for k in range(form.size):
        e = np.zeros(form.size)
        e[k] = 1.0
        co = to_coefficients(form, e, i_ref)
        cols.append([co[n] - base[n] for n in names])
    return np.array(cols).T


def to_theta(form: JointForm, coefficients: Mapping[str, float], i_ref: float) -> np.ndarray:
    """Coefficients -> node values (the inverse of :func:`to_coefficients`)."""
    nodes = _node_currents(form, i_ref)
    theta = [current_values(form, coefficients, float(i))[p] for p in form.current_params for i in nodes]
    return np.array(theta + [coefficients[p] for p in form.constant], dtype=float)


def predict(form: JointForm, theta: np.ndarray, d: FitData, i_ref: float) -> np.ndarray:
    """Model force [N] over the fit window of one condition for a batch theta (P, size) -> (P, samples)."""
    q = _params(form, np.atleast_2d(theta), d.condition[2], i_ref)
    col = {k: v[:, None] for k, v in q.items()}
    if form.model == "hyperbolic":
        with np.errstate(over="ignore", invalid="ignore"):
            return col["c0"] * d.v + col["k0"] * d.x + col["alpha"] * np.sinh(col["beta"] * d.x) + d.F0
    y = bouc_wen_window_states(d, q["beta"], q["gamma"], q["n"], dx_max=JOINT_DX_MAX_MM, lam_dx_max=np.inf)
    return col["k"] * d.x + col["c"] * d.v + col["alpha"] * y + d.F0


def _residuals(form: JointForm, theta: np.ndarray, items: Sequence[FitData], weights: Sequence[float],
               i_ref: float) -> np.ndarray:
    parts = [np.sqrt(w) * (predict(form, theta, d, i_ref) - d.F) / (d.force_rms * np.sqrt(d.F.size))
             for d, w in zip(items, weights, strict=True) if w > 0]
    return np.concatenate(parts, axis=1)


@dataclass(frozen=True)
class JointFormFit:
    """A joint fit: coefficients (paper units), per-condition RMS [N], and the Jacobian covariance.

    ``covariance``: s^2 (J^T J)^-1 of the coefficients (rows/columns ``names``), with s^2 the weighted
    residual sum of squares over (residuals - coefficients): the noise-only (local) uncertainty.
    """

    form: str
    coefficients: dict[str, float]
    theta: np.ndarray
    i_ref: float
    rms_per_condition: dict[Condition, float]
    cost: float
    seconds: float
    success: bool
    message: str
    names: tuple[str, ...]
    covariance: np.ndarray


def fit_joint(form: JointForm | str, data: Mapping[Condition, FitData], start: Mapping[str, float],
              max_nfev: int = 100, weights: Mapping[Condition, float] | None = None,
              i_ref: float | None = None) -> JointFormFit:
    """Fit ``form`` jointly to every condition of ``data`` from ``start`` (coefficients, paper units)."""
    form = FORMS[form] if isinstance(form, str) else form
    items = list(data.values())
    w = [1.0 if weights is None else float(weights.get(d.condition, 0.0)) for d in items]
    currents = {d.condition[2] for d, wk in zip(items, w, strict=True) if wk > 0}
    i_ref = max(d.condition[2] for d in items) if i_ref is None else i_ref
    if i_ref <= 0 or len(currents) < form.nodes:
        raise ValueError(f"the joint {form.name} fit needs data at {form.nodes} or more currents")
    lower = np.array([form.floor[p] for p in form.current_params for _ in range(form.nodes)]
                     + [form.constant_bounds[p][0] for p in form.constant])
    upper = np.array([np.inf] * (form.nodes * len(form.current_params))
                     + [form.constant_bounds[p][1] for p in form.constant])
    x0 = np.clip(to_theta(form, start, i_ref), lower + 1e-3 * np.maximum(np.abs(lower), 1e-2), upper)

    def fun(th: np.ndarray) -> np.ndarray:
        return _residuals(form, th[None, :], items, w, i_ref)[0]

    def jac(th: np.ndarray) -> np.ndarray:
        h = 1e-6 * np.maximum(np.abs(th), 1e-2)
        r = _residuals(form, np.vstack([th, th + np.diag(h)]), items, w, i_ref)
        return ((r[1:] - r[0]) / h[:, None]).T

    t0 = time.perf_counter()
    res = least_squares(fun, x0, jac=jac, bounds=(lower, upper), method="trf", max_nfev=max_nfev, x_scale="jac")
    seconds = time.perf_counter() - t0
    J = jac(res.x)
    dof = max(J.shape[0] - J.shape[1], 1)
    s2 = 2.0 * float(res.cost) / dof
    cov_theta = s2 * np.linalg.pinv(J.T @ J)
    A = coefficient_map(form, i_ref)
    per = {d.condition: float(np.sqrt(np.mean((predict(form, res.x, d, i_ref)[0] - d.F) ** 2))) for d in items}
    return JointFormFit(form.name, to_coefficients(form, res.x, i_ref), res.x, i_ref, per, float(res.cost), seconds,
                        bool(res.success), str(res.message), tuple(form.coefficient_names()), A @ cov_theta @ A.T)


@dataclass(frozen=True)
class Bootstrap:
    """Coefficients of B refits (rows, ``names`` order, paper units) and what they were fitted to."""

    form: str
    names: tuple[str, ...]
    samples: np.ndarray
    seeds: tuple[int, ...]
    draws: tuple[dict[Condition, int], ...]
    seconds: float

    def covariance(self) -> np.ndarray:
        return np.cov(self.samples, rowvar=False)

    def correlation(self) -> np.ndarray:
        return np.corrcoef(self.samples, rowvar=False)

    def principal_axes(self) -> tuple[np.ndarray, np.ndarray]:
        """Eigenvalues (descending) and unit eigenvectors (columns) of the correlation matrix: the principal
        axes of the standardised coefficients (each coefficient divided by its bootstrap standard deviation)."""
        values, vectors = np.linalg.eigh(self.correlation())
        order = np.argsort(values)[::-1]
        return values[order], vectors[:, order]


def bootstrap(form: JointForm | str, make_data: Callable[[int], Mapping[Condition, FitData]],
              start: Mapping[str, float], samples: int, seed: int, max_nfev: int = 100) -> Bootstrap:
    """``samples`` refits of ``form``, each on ``make_data(noise_seed)`` with the conditions drawn with
    replacement (``numpy.random.default_rng(seed)``); every refit starts from ``start``."""
    form = FORMS[form] if isinstance(form, str) else form
    rng = np.random.default_rng(seed)
    rows, seeds, draws = [], [], []
    t0 = time.perf_counter()
    for _ in range(samples):
        noise_seed = int(rng.integers(2**31 - 1))
        data = make_data(noise_seed)
        conditions = list(data)
        picks = rng.integers(len(conditions), size=len(conditions))
        counts = {c: 0 for c in conditions}
        for k in picks:
            counts[conditions[k]] += 1
        fit = fit_joint(form, data, start, max_nfev, weights=counts, i_ref=max(c[2] for c in conditions))
        rows.append([fit.coefficients[n] for n in fit.names])
        seeds.append(noise_seed)
        draws.append(counts)
    return Bootstrap(form.name, tuple(form.coefficient_names()), np.array(rows), tuple(seeds), tuple(draws),
                     time.perf_counter() - t0)
