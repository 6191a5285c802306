"""The controllers' model of the isolated building, and the designs on it.

Shared by the model-based semi-active current controllers (clipped-optimal, Lyapunov and
frequency control): each of their FMUs carries this module beside its own law.

Plant (the paper's Eq. 18-23, relative coordinates, levels 0 = base .. n = roof):

    M x'' + C x' + K x = -e_0 F - M 1 ag

F [N] is the restoring force of the isolators (positive along x_0), ag [m/s^2] the ground
acceleration; z = [x, x'] is the state. The isolator law is Eq. 17 (Table 2 by default), per
device F_d = c0(i) v + k0(i) x + alpha(i) sinh(beta(i) x): its functions and coefficients come
from ``mre_isolator_core``, the building's defaults (Table 3) from ``dyke_building``; both travel
in every FMU that carries this module.

Linearisation of the isolators at a current i (used by the LQR, the Lyapunov matrix and
the natural frequencies): the damping c0(i) is linear already and kept exactly; the spring
k0(i) x + alpha(i) sinh(beta(i) x) becomes its **secant through the origin at the
amplitude x_lin**, k_lin(i) = k0(i) + alpha(i) sinh(beta(i) x_lin) / x_lin (the stiffness
that gives the law's force at +-x_lin); x_lin = 0 is the tangent at x = 0,
k0(i) + alpha(i) beta(i). Both times n_isolators devices in parallel.

Estimator: a steady-state Kalman filter on the building alone with the *measured*
isolator force F as a known input (the isolated building linearised at any current with
its linearised force moved into the control force u = F_lin - F is the same model, so
nothing about the isolator is approximated in it). Measurements y = [x_0, a_0 .. a_n]:
base displacement and absolute floor accelerations (a = x'' + ag = -M^-1 (K x + C x'
+ e_0 F), free of ag). The process noise is the ground acceleration, white with intensity
S_g [m^2/s^3], plus an error of the measured isolator force, white with intensity S_F
[N^2 s] (without it the flexible modes, which a uniform ground acceleration on a free
base does not excite, would get no filter gain and be estimated only as fast as the
structure's own damping forgets them). The sensors have white noise of intensities
R_x [m^2 s] (displacement) and R_a [m^2/s^3] (each accelerometer). The gain L = P C^T R^-1 comes from the filter's
continuous algebraic Riccati equation (scipy.linalg.solve_continuous_are). It is
discretised at the communication step h by holding the innovation over the step:

    z^_{k+1} = Phi z^_k + Gamma_F F_k + Gamma_L (y_k - C z^_k - D F_k)

with Phi = e^{A h}, Gamma_F, Gamma_L the zero-order-hold integrals of the plant's input
columns and of L (exact for the plant with F held; the error of a noiseless run obeys
e_{k+1} = (Phi - Gamma_L C) e_k). This is the predictor form: z^_k uses the measurements up
to t_{k-1}.

Sources: the LQG/clipped-optimal setting of Dyke, Spencer, Sain and Carlson (1996),
"Modeling and control of magnetorheological dampers for seismic response reduction",
Smart Mater. Struct. 5, 565-575; the Lyapunov function of Jansen and Dyke (2000),
"Semiactive control strategies for MR dampers: comparative study", J. Eng. Mech. 126(8),
795-803. All quantities SI.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np
from scipy.linalg import eigh, expm, solve_continuous_are, solve_continuous_lyapunov

try:  # a package module here, bare modules in an FMU
    from . import dyke_building as dyke
    from . import mre_isolator_core as isolator_core
except ImportError:
    import dyke_building as dyke
    import mre_isolator_core as isolator_core

_TABLE2 = isolator_core.TABLE2

# Table 3 of the paper (Dyke et al. 1996 three-storey model) on the assumed base floor, per level 0 (base) .. 3:
# masses [kg], stiffnesses [N/m] and dampings [N*s/m] (k_0, c_0 tie the base to the ground).
LEVEL_MASSES = (dyke.BASE_MASS, *dyke.DYKE_MASSES)
LEVEL_STIFFNESSES = (dyke.BASE_STIFFNESS, *dyke.DYKE_STIFFNESSES)
LEVEL_DAMPINGS = (dyke.BASE_DAMPING, *dyke.DYKE_DAMPINGS)


class ParameterError(ValueError):
    """A design parameter out of its domain; ``parameter`` is its FMU parameter name (e.g. ``q_x``, ``m_1``)."""

    def __init__(self, parameter: str, message: str) -> None:
        self.parameter = parameter
        super().__init__(message)


class EstimatorDiverged(ArithmeticError):
    """The state estimate is no longer finite (NaN or inf)."""


def _clipped_sinh(z: np.ndarray) -> np.ndarray:
    """numpy's sinh with its argument clipped at +-700 (finite, ~5e303): changes nothing below |x| ~ 0.9 m."""
    return np.sinh(np.clip(z, -700, 700))


@dataclass(frozen=True)
class IsolatorLaw:
    """Eq. 17 of the paper for ``n_isolators`` identical devices, SI coefficients (Table 2 by default).

    k0_0 [N/(m A)], k0_1 [N/m], c0_0 [N s/(m A)], c0_1 [N s/m], alpha_0 [N/A], alpha_1 [N],
    beta_0 [1/(m A)], beta_1 [1/m]: the controller's model of the isolator (FMU parameters of their own, which
    may differ from the plant's); the law itself is ``mre_isolator_core``'s.
    """

    k0_0: float = _TABLE2.k0_0
    k0_1: float = _TABLE2.k0_1
    c0_0: float = _TABLE2.c0_0
    c0_1: float = _TABLE2.c0_1
    alpha_0: float = _TABLE2.alpha_0
    alpha_1: float = _TABLE2.alpha_1
    beta_0: float = _TABLE2.beta_0
    beta_1: float = _TABLE2.beta_1
    n_isolators: int = 2

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not math.isfinite(value):
                raise ParameterError(f.name, f"isolator model {f.name} must be finite, got {value}")
        if self.n_isolators < 1:
            raise ParameterError("n_isolators", f"n_isolators must be >= 1, got {self.n_isolators}")

    def force(self, x: float, v: float, i: float) -> float:
        """Total restoring force [N] at displacement x [m], velocity v [m/s], current i [A] (Eq. 17)."""
        return isolator_core.force_with(x, v, i, self, self.n_isolators)

    def forces(self, x: float, v: float, currents: np.ndarray) -> np.ndarray:
        """:meth:`force` on an array of currents [A] (numpy, for grid searches; sinh's argument clipped at +-700)."""
        return isolator_core.force_with(x, v, np.asarray(currents, dtype=float), self, self.n_isolators,
                                        _clipped_sinh)

    def dforce_di(self, x: float, v: float, i: float) -> float:
        """dF/di [N/A] at x [m], v [m/s], i [A]: the paper's Eq. 34 bracket times n_isolators."""
        return isolator_core.current_sensitivity(x, v, i, self, self.n_isolators)

    def damping(self, i: float) -> float:
        """Linear damping of all devices [N s/m] at current i [A]."""
        return isolator_core.isolator_damping(i, self, self.n_isolators)

    def stiffness(self, i: float, x_lin: float) -> float:
        """Linearised stiffness of all devices [N/m] at i [A]: secant at amplitude x_lin [m] (0: tangent at 0)."""
        return isolator_core.secant_stiffness(x_lin, i, self, self.n_isolators)


@dataclass(frozen=True)
class BuildingModel:
    """Masses [kg], stiffnesses [N/m], dampings [N s/m] per level, index 0 = base floor.

    k[0]/c[0] tie the base to the ground besides the isolators (0 by default); k[j]/c[j]
    (j >= 1) is storey j. Defaults: Table 3 of the paper (Dyke et al. 1996) on a 98.3 kg base.
    """

    m: tuple[float, ...] = LEVEL_MASSES
    k: tuple[float, ...] = LEVEL_STIFFNESSES
    c: tuple[float, ...] = LEVEL_DAMPINGS

    def __post_init__(self) -> None:
        if not (len(self.m) == len(self.k) == len(self.c)) or len(self.m) < 1:
            raise ParameterError("m_0", "building model: m, k and c need one entry per level")
        for name in ("m", "k", "c"):
            for j, value in enumerate(getattr(self, name)):
                if not math.isfinite(value) or value < 0 or (name == "m" and value == 0):
                    kind = "positive" if name == "m" else ">= 0"
                    raise ParameterError(f"{name}_{j}",
                                         f"building model {name}_{j} must be {kind} and finite, got {value}")

    @property
    def n_levels(self) -> int:
        return len(self.m)


def _chain(springs: np.ndarray) -> np.ndarray:
    """Tridiagonal matrix of a chain; element 0 ties level 0 to the ground."""
    n = len(springs)
    out = np.zeros((n, n))
    for j in range(n):
        out[j, j] += springs[j]
        if j + 1 < n:
            out[j, j] += springs[j + 1]
            out[j, j + 1] = out[j + 1, j] = -springs[j + 1]
    return out


def mck(building: BuildingModel, k_iso: float = 0.0, c_iso: float = 0.0) -> tuple[np.ndarray, ...]:
    """M, C, K [kg, N s/m, N/m] with a linear isolator (k_iso, c_iso) added between base and ground."""
    k = np.array(building.k, dtype=float)
    c = np.array(building.c, dtype=float)
    k[0] += k_iso
    c[0] += c_iso
    return np.diag(np.asarray(building.m, dtype=float)), _chain(c), _chain(k)


@dataclass(frozen=True)
class LinearPlant:
    """z' = A z + b u + e ag; u [N] a force on the base along x_0, ag [m/s^2] the ground acceleration.

    ``acc_rows``, ``acc_u``: absolute accelerations a = acc_rows z + acc_u u [m/s^2].
    """

    A: np.ndarray
    b: np.ndarray
    e: np.ndarray
    acc_rows: np.ndarray
    acc_u: np.ndarray

    @property
    def n_levels(self) -> int:
        return self.A.shape[0] // 2


def linear_plant(building: BuildingModel, k_iso: float = 0.0, c_iso: float = 0.0) -> LinearPlant:
    """The building with a linear isolator (k_iso [N/m], c_iso [N s/m]) and a force input on the base."""
    _, C, K = mck(building, k_iso, c_iso)
    n = building.n_levels
    minv = 1.0 / np.asarray(building.m, dtype=float)
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -minv[:, None] * K
    A[n:, n:] = -minv[:, None] * C
    b = np.zeros(2 * n)
    b[n] = minv[0]
    e = np.zeros(2 * n)
    e[n:] = -1.0
    acc_u = np.zeros(n)
    acc_u[0] = minv[0]
    return LinearPlant(A, b, e, A[n:].copy(), acc_u)


def linearised_plant(building: BuildingModel, law: IsolatorLaw, i: float, x_lin: float) -> LinearPlant:
    """The isolated building with the isolators linearised at current i [A] (secant at x_lin [m])."""
    return linear_plant(building, law.stiffness(i, x_lin), law.damping(i))


@dataclass(frozen=True)
class Weights:
    """Weights of the regulated responses (the H2 cost J = integral of the weighted squares).

    q_x [1/m^2] base displacement, q_v [s^2/m^2] base velocity, q_drift [1/m^2] each
    inter-storey drift, q_acc [s^4/m^2] each absolute floor acceleration (levels 0..n),
    r [1/N^2] the control force.
    """

    q_x: float = 1.0 / 0.008**2  # 8 mm (the isolator's identified range) costs 1
    q_v: float = 0.0
    q_drift: float = 1.0 / 0.002**2  # 2 mm of drift costs 1
    q_acc: float = 1.0 / 5.0**2  # 5 m/s^2 on each floor costs 1
    r: float = 1.0 / 500.0**2  # 500 N of control force costs 1

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not (math.isfinite(value) and value >= 0):
                raise ParameterError(f.name, f"weight {f.name} must be >= 0 and finite, got {value}")


def regulated_cost(plant: LinearPlant, w: Weights) -> tuple[np.ndarray, np.ndarray, float]:
    """(Q, N, R) of J = integral of z'Qz + 2 z'N u + R u^2 for the weighted responses."""
    n = plant.n_levels
    nz = 2 * n
    rows, cross, weights = [], [], []
    eye = np.eye(nz)
    rows.append(eye[0]), cross.append(0.0), weights.append(w.q_x)
    rows.append(eye[n]), cross.append(0.0), weights.append(w.q_v)
    for j in range(1, n):
        rows.append(eye[j] - eye[j - 1]), cross.append(0.0), weights.append(w.q_drift)
    for j in range(n):
        rows.append(plant.acc_rows[j]), cross.append(plant.acc_u[j]), weights.append(w.q_acc)
    Cr, Dr, W = np.array(rows), np.array(cross), np.array(weights)
    Q = Cr.T @ (W[:, None] * Cr)
    N = Cr.T @ (W * Dr)
    R = w.r + float(Dr @ (W * Dr))
    return 0.5 * (Q + Q.T), N, R


def lqr_gain(A: np.ndarray, b: np.ndarray, Q: np.ndarray, R: float, N: np.ndarray | None = None) -> np.ndarray:
    """Gain K of u = -K z minimising integral of z'Qz + 2 z'N u + R u^2 (scipy.linalg.solve_continuous_are)."""
    if not R > 0:
        raise ValueError(f"the control weight must be positive (r > 0 or q_acc > 0), got R = {R}")
    B = b.reshape(-1, 1)
    S = np.zeros_like(B) if N is None else N.reshape(-1, 1)
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(Q)) and np.all(np.isfinite(S)) and math.isfinite(R)):
        raise ValueError("the LQR design has non-finite matrices (a weight or a model parameter too large)")
    P = solve_continuous_are(A, B, Q, np.array([[R]]), s=S)
    K = ((B.T @ P + S.T) / R).ravel()
    if not np.all(np.isfinite(K)):
        raise ValueError("the LQR design failed (non-finite gain)")
    return K


@dataclass(frozen=True)
class NoiseIntensities:
    """White-noise intensities of the Kalman filter.

    s_ground [m^2/s^3] ground acceleration and s_force [N^2 s] isolator-force error (process
    noise), r_x [m^2 s] displacement sensor, r_acc [m^2/s^3] each accelerometer. Only their
    ratios shape the gain. (White noise of intensity S sampled at a step h has variance S/h.)
    """

    s_ground: float = 1.0e-2  # 3.2 m/s^2 RMS at a 1 kHz sampling rate
    s_force: float = 0.1  # 10 N RMS at a 1 kHz sampling rate
    r_x: float = 1.0e-10  # 0.32 mm RMS at a 1 kHz sampling rate
    r_acc: float = 1.0e-5  # 0.1 m/s^2 RMS at a 1 kHz sampling rate

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not (math.isfinite(value) and value >= 0):
                raise ParameterError(f.name, f"noise intensity {f.name} must be >= 0 and finite, got {value}")
        if self.r_x <= 0 or self.r_acc <= 0:
            raise ParameterError("r_x" if self.r_x <= 0 else "r_acc",
                                 "sensor noise intensities r_x and r_acc must be positive (the filter divides by them)")


def _zoh(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """(e^{A h}, integral_0^h e^{A s} ds B) by the block exponential."""
    n, m = B.shape
    aug = np.zeros((n + m, n + m))
    aug[:n, :n] = A
    aug[:n, n:] = B
    e = expm(aug * h)
    return e[:n, :n], e[:n, n:]


class StateEstimator:
    """Steady-state Kalman filter of the building state from y = [x_0, a_0 .. a_n] and the measured F.

    Continuous design (solve_continuous_are), discretised at the step h by holding the
    innovation over the step (module docstring). ``z`` is the estimate [x, x'] at the
    present communication point.
    """

    def __init__(self, building: BuildingModel, noise: NoiseIntensities | None = None) -> None:
        self.noise = noise if noise is not None else NoiseIntensities()
        plant = linear_plant(building)
        n = plant.n_levels
        self.n_levels = n
        self.A = plant.A
        self.bF = -plant.b  # the isolator force acts on the base against x_0
        self.C = np.vstack([np.eye(2 * n)[0], plant.acc_rows])
        self.D = np.concatenate([[0.0], -plant.acc_u])
        R = np.diag([self.noise.r_x] + [self.noise.r_acc] * n)
        G = self.noise.s_ground * np.outer(plant.e, plant.e) + self.noise.s_force * np.outer(plant.b, plant.b)
        if not (np.all(np.isfinite(self.A)) and np.all(np.isfinite(G))):
            raise ValueError("the Kalman filter design has non-finite matrices (a noise intensity or a model "
                             "parameter too large)")
        P = solve_continuous_are(self.A.T, self.C.T, G, R)
        self.L = P @ self.C.T @ np.linalg.inv(R)
        if not np.all(np.isfinite(self.L)):
            raise ValueError("the Kalman filter design failed (non-finite gain)")
        self.z = np.zeros(2 * n)
        self._h: float | None = None
        self._Phi = self._GF = self._GL = self._step = self._zFy = np.zeros(0)
        self._cache: dict[float, tuple[np.ndarray, ...]] = {}

    def discretize(self, h: float) -> None:
        """Set up the step h [s]; ValueError if the discrete filter is unstable at this step.

        Kept per step size (a master's steps may differ in their last bits: t_{k+1} - t_k).
        """
        if h == self._h:
            return
        cached = self._cache.get(h)
        if cached is not None:
            self._h, self._Phi, self._GF, self._GL, self._step = h, *cached
            return
        if not (math.isfinite(h) and h > 0):
            raise ValueError(f"communication step must be positive, got {h}")
        Phi, G = _zoh(self.A, np.column_stack([self.bF, self.L]), h)
        GF, GL = G[:, 0], G[:, 1:]
        radius = max(abs(np.linalg.eigvals(Phi - GL @ self.C)))
        if not radius < 1.0:
            raise ValueError(f"the discretised Kalman filter is unstable at the step h = {h:g} s (spectral radius "
                             f"{radius:.4g}): lower the sensor noise ratio or the step")
        self._h, self._Phi, self._GF, self._GL = h, Phi, GF, GL
        # one product per step: z_next = step_matrix @ [z, F, y]
        self._step = np.hstack([Phi - GL @ self.C, (GF - GL @ self.D)[:, None], GL])
        self._zFy = np.zeros(self._step.shape[1])
        if len(self._cache) >= 16:
            self._cache.clear()
        self._cache[h] = (Phi, GF, GL, self._step)

    def error_matrix(self, h: float) -> np.ndarray:
        """Phi - Gamma_L C: the estimation error's one-step matrix at the step h."""
        self.discretize(h)
        return self._Phi - self._GL @ self.C

    def update(self, y: np.ndarray, F: float, h: float) -> np.ndarray:
        """Advance the estimate over h [s] with y = [x_0, a_0..a_n] and F [N] held; EstimatorDiverged if not finite."""
        if h != self._h:
            self.discretize(h)
        zFy = self._zFy
        nz = len(self.z)
        zFy[:nz] = self.z
        zFy[nz] = F
        zFy[nz + 1 :] = y
        with np.errstate(over="ignore", invalid="ignore"):  # a non-finite estimate is reported below
            z_next = self._step.dot(zFy)
        if not math.isfinite(float(z_next.sum())):  # NaN or inf anywhere (or an overflowing sum: divergence too)
            raise EstimatorDiverged("the state estimate is not finite (the Kalman filter diverged)")
        self.z = z_next
        return z_next


def lyapunov_matrix(A: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """P of A'P + PA = -Q (scipy.linalg.solve_continuous_lyapunov); ValueError unless A is stable."""
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(Q))):
        raise ValueError("the Lyapunov design has non-finite matrices (a weight or a model parameter too large)")
    eig = np.linalg.eigvals(A)
    if not np.all(eig.real < 0):
        raise ValueError(f"the passive system is not asymptotically stable (max Re eig = {max(eig.real):.3g} 1/s)")
    P = solve_continuous_lyapunov(A.T, -Q)
    if not np.all(np.isfinite(P)):
        raise ValueError("the Lyapunov design failed (non-finite P)")
    return 0.5 * (P + P.T)


def first_natural_frequency(building: BuildingModel, k_iso: float) -> float:
    """First undamped natural frequency [Hz] with a linear isolator k_iso [N/m] (scipy.linalg.eigh of K, M)."""
    M, _, K = mck(building, k_iso)
    lam = eigh(K, M, eigvals_only=True)
    return math.sqrt(max(float(lam[0]), 0.0)) / (2.0 * math.pi)


# FMU parameter tables of the controllers' models (name -> (unit, description)); the shells
# register them and rebuild the dataclasses from their values with the functions below.
ISOLATOR_DOCS: dict[str, tuple[str, str]] = {
    "k0_0": ("N/(m.A)", "controller's isolator model: stiffness k0 slope per ampere (Table 2 k0^0)"),
    "k0_1": ("N/m", "controller's isolator model: stiffness k0 at 0 A (Table 2 k0^1)"),
    "c0_0": ("N.s/(m.A)", "controller's isolator model: damping c0 slope per ampere (Table 2 c0^0)"),
    "c0_1": ("N.s/m", "controller's isolator model: damping c0 at 0 A (Table 2 c0^1)"),
    "alpha_0": ("N/A", "controller's isolator model: alpha slope per ampere (Table 2 alpha^0)"),
    "alpha_1": ("N", "controller's isolator model: alpha at 0 A (Table 2 alpha^1)"),
    "beta_0": ("1/(m.A)", "controller's isolator model: beta slope per ampere (Table 2 beta^0)"),
    "beta_1": ("1/m", "controller's isolator model: beta at 0 A (Table 2 beta^1)"),
}
WEIGHT_DOCS: dict[str, tuple[str, str]] = {
    "q_x": ("1/m2", "weight of the squared base displacement"),
    "q_v": ("s2/m2", "weight of the squared base velocity"),
    "q_drift": ("1/m2", "weight of each squared inter-storey drift"),
    "q_acc": ("s4/m2", "weight of each squared absolute floor acceleration"),
    "r": ("1/N2", "weight of the squared control force"),
}
NOISE_DOCS: dict[str, tuple[str, str]] = {
    "s_ground": ("m2/s3", "Kalman filter: intensity of the ground acceleration (process noise)"),
    "s_force": ("N2.s", "Kalman filter: intensity of the isolator-force error (process noise)"),
    "r_x": ("m2.s", "Kalman filter: intensity of the base displacement sensor noise"),
    "r_acc": ("m2/s3", "Kalman filter: intensity of each accelerometer's noise"),
}


def building_docs(n_levels: int) -> dict[str, tuple[str, str]]:
    """FMU parameters m_j, k_j, c_j (j = 0 base .. n_levels - 1) of the controller's building model."""
    docs: dict[str, tuple[str, str]] = {}
    for j in range(n_levels):
        where = "base floor" if j == 0 else f"level {j}"
        tie = "base to ground besides the isolators" if j == 0 else f"storey {j}"
        docs[f"m_{j}"] = ("kg", f"controller's building model: mass of the {where}")
        docs[f"k_{j}"] = ("N/m", f"controller's building model: stiffness of {tie}")
        docs[f"c_{j}"] = ("N.s/m", f"controller's building model: damping of {tie}")
    return docs


def building_defaults(n_levels: int) -> dict[str, float]:
    """Default values of :func:`building_docs` (the Dyke model for four levels, its upper storey repeated else)."""
    out = {}
    for j in range(n_levels):
        src = min(j, len(LEVEL_MASSES) - 1)
        out[f"m_{j}"], out[f"k_{j}"], out[f"c_{j}"] = LEVEL_MASSES[src], LEVEL_STIFFNESSES[src], LEVEL_DAMPINGS[src]
    return out


def building_from(values: dict[str, float], n_levels: int) -> BuildingModel:
    """The building model from the FMU parameter values m_j, k_j, c_j."""
    return BuildingModel(m=tuple(float(values[f"m_{j}"]) for j in range(n_levels)),
                         k=tuple(float(values[f"k_{j}"]) for j in range(n_levels)),
                         c=tuple(float(values[f"c_{j}"]) for j in range(n_levels)))


# This module's source as loaded: the FMU folder it came from may be gone by the time another FMU asks
# (an importer removes an FMU's unpacked folder when it frees the instance; the module stays loaded).
_LOADED_SOURCE = Path(__file__).read_bytes()


def module_copy_problem(module_file: str, loaded_source: bytes, resources: str | None) -> str:
    """A text if the module at ``module_file`` (source ``loaded_source`` as loaded) is not the calling FMU's own
    copy in ``resources`` (its folder) but another FMU's with other code, else ""."""
    if not resources:
        return ""
    loaded = Path(module_file)
    own = Path(resources) / loaded.name
    if not own.is_file() or own.resolve() == loaded.resolve() or own.read_bytes() == loaded_source:
        return ""
    return (f"another FMU in this process loaded a different version of the module {loaded.stem} "
            f"(from {loaded.parent}); use FMUs built from the same project version")


def foreign_copy_problem(resources: str | None) -> str:
    """A text if this module was loaded from another FMU's resources with other code, else "".

    Several FMUs of the project carry this module, and pythonfmu FMUs share one interpreter:
    the first one loaded is the one every FMU uses. ``resources`` is the calling FMU's folder.
    """
    return module_copy_problem(__file__, _LOADED_SOURCE, resources)


def design_from(cls: type, values: Mapping[str, Any], **fixed: Any) -> Any:
    """An instance of the design dataclass ``cls`` from FMU parameter values by field name.

    Absent names take the field's default; each value is cast to its default's type (float, int,
    str), as the shells cast their attributes; ``fixed`` overrides. Out-of-domain values raise
    :class:`ParameterError` naming the parameter (the dataclass's own check).
    """
    default = cls()
    kwargs = {f.name: type(getattr(default, f.name))(values.get(f.name, getattr(default, f.name)))
              for f in fields(cls) if f.name not in fixed}
    return cls(**kwargs, **fixed)


def first_parameter_problem(parts: Callable[[Mapping[str, Any], int], Any], values: Mapping[str, Any],
                            n_levels: int) -> tuple[str, str] | None:
    """(parameter, message) for the first FMU parameter out of its domain, or None: ``parts`` (a core's
    ``controller_parts``) builds the design objects from the values (a check before any run)."""
    try:
        parts(values, n_levels)
    except ParameterError as exc:
        return exc.parameter, str(exc)
    return None


def estimator_parts(design_class: type, values: Mapping[str, Any], n_levels: int, **fixed_weights: Any) -> tuple[
        Any, Weights, NoiseIntensities, BuildingModel, IsolatorLaw]:
    """(design, weights, noise, building, isolator) of a controller fed by the Kalman estimate, from its FMU
    parameter values by name; ``fixed_weights`` overrides weights (Lyapunov: r = 0). :class:`ParameterError`
    names the first one out of its domain."""
    return (design_from(design_class, values), design_from(Weights, values, **fixed_weights),
            design_from(NoiseIntensities, values), building_from(values, n_levels), design_from(IsolatorLaw, values))


class EstimatedStateController:
    """Base of the current controllers that act on the Kalman estimate of the building state (clipped-optimal,
    Lyapunov): the design objects (defaults where None), the gains of the subclass's design and the shared
    :class:`StateEstimator`, and the step: decide the current from the estimate at this communication point,
    then advance the estimate with the measurements.

    A subclass sets ``design_class``, may override :meth:`default_weights`, and implements
    :meth:`_design` (its gains, from ``self.design``, ``self.weights``, ``self.building``, ``self.isolator``)
    and :meth:`decide`.
    """

    design_class: type

    def __init__(self, design: Any = None, weights: Weights | None = None, noise: NoiseIntensities | None = None,
                 building: BuildingModel | None = None, isolator: IsolatorLaw | None = None) -> None:
        self.design = design if design is not None else self.design_class()
        self.weights = weights if weights is not None else self.default_weights()
        self.building = building if building is not None else BuildingModel()
        self.isolator = isolator if isolator is not None else IsolatorLaw()
        with np.errstate(all="ignore"):  # out-of-range parameters end in a ValueError, not in warnings
            self._design()
            self.estimator = StateEstimator(self.building, noise)
        self.i = 0.0

    @staticmethod
    def default_weights() -> Weights:
        """The weights when none are given."""
        return Weights()

    def _design(self) -> None:
        raise NotImplementedError

    def decide(self, x: float, v: float, F: float) -> float:
        """The current [A] from the estimate ``self.estimator.z`` and the measured x [m], v [m/s], F [N]."""
        raise NotImplementedError

    def update(self, x: float, v: float, acc: np.ndarray, F: float, h: float) -> float:
        """Decide the current from the measurements at this communication point, then advance the estimate.

        x [m], v [m/s] base displacement and velocity, acc [m/s^2] absolute accelerations of
        levels 0..n, F [N] isolator force, h [s] the step. Returns i [A], held over the step.
        EstimatorDiverged if the estimate stops being finite.
        """
        self.i = self.decide(x, v, F)
        self.estimator.update(np.concatenate(([x], acc)), F, h)
        return self.i


def design_problem(controller_class: type, parts: Callable[[Mapping[str, Any], int], Any],
                   values: Mapping[str, Any], n_levels: int) -> tuple[str, str] | None:
    """(parameter, message) if the controller's design cannot be made from these values, or None: every
    parameter in its domain (:func:`first_parameter_problem`), process noise that is not all zero, a
    positive control weight and a finite, stabilizing gain (the design the unit makes when it initializes,
    made before any run; each set of values once per process: a study plans every run)."""
    try:
        key = (controller_class.__qualname__, n_levels, tuple(sorted(values.items())))
        hash(key)
    except TypeError:
        key = None
    if key is not None and key in _DESIGN_CHECKED:
        return _DESIGN_CHECKED[key]
    found = _design_problem(controller_class, parts, values, n_levels)
    if key is not None:
        _DESIGN_CHECKED[key] = found
    return found


_DESIGN_CHECKED: dict[Any, tuple[str, str] | None] = {}


def _design_problem(controller_class: type, parts: Callable[[Mapping[str, Any], int], Any],
                    values: Mapping[str, Any], n_levels: int) -> tuple[str, str] | None:
    found = first_parameter_problem(parts, values, n_levels)
    if found is not None:
        return found
    design, weights, noise, building, isolator = parts(values, n_levels)
    if noise.s_ground <= 0 and noise.s_force <= 0:
        return ("s_ground", "process noise intensities s_ground and s_force are both 0: the Kalman filter would "
                            "trust its model alone (zero gain, every sensor ignored); give at least one a positive "
                            "value")
    try:
        controller = controller_class(design, weights, noise, building, isolator)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        text = str(exc)
        parameter = ("r" if "control weight" in text else "s_ground" if "Kalman" in text
                     else "c_0" if "passive system" in text else "i_nom")
        return parameter, f"the controller's design fails with these parameters: {text}"
    gain = getattr(controller, "K_u", None)
    if gain is not None:
        plant = linearised_plant(building, isolator, getattr(design, "i_nom", 0.0), getattr(design, "x_lin", 0.0))
        poles = np.linalg.eigvals(plant.A - np.outer(plant.b, gain))
        if not np.all(np.real(poles) < 0):
            return ("i_nom", f"the design is not stabilizing (closed-loop pole {poles[np.argmax(poles.real)]:.3g}): "
                             "the linearised plant is not stabilizable with these weights and model parameters")
    return None
