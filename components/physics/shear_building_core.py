"""Physics of an n-storey shear building on a base floor, Eq. (18)-(23) of the paper.

Coordinates are relative to the ground: x = [x_0 (base), x_1, ..., x_n] [m]. The
isolator force F [N] is the isolator's restoring force (positive along x_0) and acts on
the base floor against it (f_b = -F), the ground acceleration ag [m/s^2] loads every
mass with -m_j ag:

    M x'' + C x' + K x = -e_0 F - M 1 ag

K and C are tridiagonal; k_0 and c_0 couple the base floor to the ground (the paper's
k_b and c_b, zero by default: the isolators carry the base alone).

The linear structure (``hysteresis = 'linear'``) is integrated exactly by :class:`ShearBuilding`
between communication points for inputs held constant over the step (zero-order hold):
q_{k+1} = Phi q_k + Gamma u_k with q = [x, x'] and u = [ag, F].

Yielding storeys (docs/structures.md): :class:`Steel01` (OpenSees' bilinear law) and
:class:`BoucWen` (Wen 1976) replace k_j x drift_j; :class:`HystereticShearBuilding` steps them
with Newmark's average-acceleration scheme and Newton iterations (plus an exact elastic path
for bilinear storeys); :func:`make_building` picks the model for a :class:`StoreyLaws`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

# Dyke et al. (1996) three-storey model, Table 3 of the paper, on the assumed base floor (SI units): its one
# place is dyke_building, re-exported here.
try:  # a package module here, a bare module in an FMU
    from .dyke_building import (
        BASE_DAMPING,
        BASE_MASS,
        BASE_STIFFNESS,
        DYKE_DAMPINGS,
        DYKE_MASSES,
        DYKE_STIFFNESSES,
    )
except ImportError:
    from dyke_building import BASE_DAMPING, BASE_MASS, BASE_STIFFNESS, DYKE_DAMPINGS, DYKE_MASSES, DYKE_STIFFNESSES


@dataclass(frozen=True)
class BuildingParams:
    """Masses [kg], stiffnesses [N/m] and dampings [N*s/m] per level, index 0 = base.

    ``k[0]``/``c[0]`` tie the base to the ground; ``k[j]``/``c[j]`` (j >= 1) is storey j,
    between levels j-1 and j.
    """

    m: tuple[float, ...]
    k: tuple[float, ...]
    c: tuple[float, ...]

    def __post_init__(self) -> None:
        if not (len(self.m) == len(self.k) == len(self.c)) or len(self.m) < 2:
            raise ValueError("m, k and c need one entry per level (base + at least one storey)")
        for j, m in enumerate(self.m):
            if not m > 0:  # NaN too
                raise ParameterError(f"m_{j}", f"masses must be positive, got {self.m}")
        for name, values in (("k", self.k), ("c", self.c)):
            for j, value in enumerate(values):
                if value < 0:
                    raise ParameterError(f"{name}_{j}", "stiffnesses and dampings must not be negative")

    @property
    def n_storeys(self) -> int:
        return len(self.m) - 1

    @classmethod
    def dyke(cls) -> BuildingParams:
        """The paper's case-study building: Dyke three-storey model on a 98.3 kg base."""
        return cls(
            m=(BASE_MASS, *DYKE_MASSES),
            k=(BASE_STIFFNESS, *DYKE_STIFFNESSES),
            c=(BASE_DAMPING, *DYKE_DAMPINGS),
        )

    @classmethod
    def uniform(cls, n_storeys: int) -> BuildingParams:
        """n storeys with the properties of the Dyke model's upper storeys (for scaling studies)."""
        return cls(
            m=(BASE_MASS,) + (DYKE_MASSES[-1],) * n_storeys,
            k=(BASE_STIFFNESS,) + (DYKE_STIFFNESSES[-1],) * n_storeys,
            c=(BASE_DAMPING,) + (DYKE_DAMPINGS[-1],) * n_storeys,
        )


def tridiagonal(springs: tuple[float, ...] | np.ndarray) -> np.ndarray:
    """Stiffness (or damping) matrix of a chain: element 0 ties level 0 to the ground."""
    s = np.asarray(springs, dtype=float)
    n = len(s)
    out = np.zeros((n, n))
    for j in range(n):
        out[j, j] += s[j]
        if j + 1 < n:
            out[j, j] += s[j + 1]
            out[j, j + 1] = out[j + 1, j] = -s[j + 1]
    return out


def matrices(p: BuildingParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """M, C, K of Eq. (23) [kg, N*s/m, N/m]."""
    return np.diag(p.m), tridiagonal(p.c), tridiagonal(p.k)


def state_space(p: BuildingParams) -> tuple[np.ndarray, np.ndarray]:
    """A (2N x 2N) and B (2N x 2) of q' = A q + B [ag, F], q = [x, x'], N = n + 1 levels."""
    _, C, K = matrices(p)
    n = len(p.m)
    Minv = np.diag(1.0 / np.asarray(p.m))
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -Minv @ K
    A[n:, n:] = -Minv @ C
    B = np.zeros((2 * n, 2))
    B[n:, 0] = -1.0
    B[n, 1] = -1.0 / p.m[0]
    return A, B


def zoh_discretize(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretization for inputs held over a step h [s]: (Phi, Gamma)."""
    n, m = B.shape
    aug = np.zeros((n + m, n + m))
    aug[:n, :n] = A
    aug[:n, n:] = B
    e = expm(aug * h)
    return e[:n, :n], e[:n, n:]


def zoh_quadratic_integral(A: np.ndarray, B: np.ndarray, Q: np.ndarray, h: float) -> np.ndarray:
    """W with integral_0^h z(t)' Q z(t) dt = z(0)' W z(0) for z = [q, u], q' = A q + B u, u held over h [s].

    Van Loan's block exponential (C. F. Van Loan, "Computing integrals involving the matrix
    exponential", IEEE Trans. Autom. Control 23(3), 1978, Theorem 1): with Z = [[A, B], [0, 0]],
    expm([[-Z', Q], [0, Z]] h) = [[., F12], [0, F22]] and W = F22' F12. ``Q`` is (n+m) x (n+m).
    """
    n, m = B.shape
    nz = n + m
    Z = np.zeros((nz, nz))
    Z[:n, :n] = A
    Z[:n, n:] = B
    big = np.zeros((2 * nz, 2 * nz))
    big[:nz, :nz] = -Z.T
    big[:nz, nz:] = Q
    big[nz:, nz:] = Z
    e = expm(big * h)
    W = e[nz:, nz:].T @ e[:nz, nz:]
    return 0.5 * (W + W.T)


def natural_frequencies(p: BuildingParams) -> np.ndarray:
    """Undamped natural circular frequencies [rad/s], ascending (eigenvalues of M^-1 K).

    With k_0 = 0 the first one is the zero of the free base (rigid-body mode).
    """
    M, _, K = matrices(p)
    lam = np.linalg.eigvals(np.linalg.solve(M, K))
    return np.sqrt(np.clip(np.sort(lam.real), 0.0, None))


ENERGY_NAMES = ("E_input", "E_isolator", "E_damping", "E_strain", "E_hysteretic", "E_kinetic")
"""The building's energy outputs [J], in the order of ``energies()`` (docs/running.md, "Validity"):
relative input energy -integral ag sum_j m_j v_j dt (Uang & Bertero 1990), the work the building
gave the isolators (integral F v_0 dt with the force it integrated), storey (and base) damping,
recoverable strain energy now, storey hysteretic work so far, relative kinetic energy now."""


class ShearBuilding:
    """Exact-ZOH time stepping of the shear building.

    ``step(ag, F, h)`` advances the state by h [s] with ag [m/s^2] and F [N] held. Each step also
    adds its exact work integrals (the inputs are held, so they follow from the state at both ends
    and Van Loan's integral of the damping power): ``energies()`` (:data:`ENERGY_NAMES`).
    """

    def __init__(self, params: BuildingParams) -> None:
        self.params = params
        self.n_levels = len(params.m)
        self.A, self.B = state_space(params)
        self.steps = 0  # number of steps taken: changes whenever the state does
        self._cache: dict[float, np.ndarray] = {}  # step -> [Phi, Gamma]
        # The state lives in z = [q, ag, F] (everything the building computes is linear in z),
        # so an evaluation only writes the two inputs; step() writes the next state into a
        # second buffer and swaps the two.
        self._nq = 2 * self.n_levels
        self._z = np.zeros(self._nq + 2)
        self._z_next = np.zeros(self._nq + 2)
        n = self.n_levels
        # rows of [q, ag, F] -> relative accelerations, and storey shear gains
        self._acc_rows = np.hstack([self.A[n:], self.B[n:]])
        self._shear_k = np.asarray(params.k[1:], dtype=float)
        self._shear_c = np.asarray(params.c[1:], dtype=float)
        self._output_rows = self._output_matrix()
        self._energy_rows: dict[float, np.ndarray] = {}  # step -> the three work integrals as quadratic forms
        self.work = np.zeros(3)  # [E_input, E_isolator, E_damping] so far [J]
        self._steppers: dict[float, np.ndarray] = {}
        nz = self._nq + 2
        self._scratch = np.zeros(self._nq + 3 * nz)  # the next state, then Q_k z of each work form
        _, C, K = matrices(params)
        self._K = K
        self._m = np.asarray(params.m, dtype=float)
        self._C = C

    def _work_forms(self, h: float) -> np.ndarray:
        """(3 * nz, nz) rows Q_k with the step's work k = z' Q_k z, z = [q, ag, F] at the step start."""
        rows = self._energy_rows.get(h)
        if rows is None:
            n, nq = self.n_levels, self._nq
            nz = nq + 2
            PG = self._fused(h)
            dx = PG[:n].copy()  # x(t + h) - x(t) as rows over z
            dx[:, :n] -= np.eye(n)
            q_in = np.zeros((nz, nz))
            q_in[nq] = -self._m @ dx  # -ag sum_j m_j dx_j
            q_iso = np.zeros((nz, nz))
            q_iso[nq + 1] = dx[0]  # F dx_0
            Q = np.zeros((nz, nz))
            Q[n:nq, n:nq] = self._C  # damping power v' C v
            q_damp = zoh_quadratic_integral(self.A, self.B, Q, h)
            if len(self._energy_rows) > 16:
                self._energy_rows.clear()
            rows = self._energy_rows[h] = np.vstack([q_in, q_iso, q_damp])
        return rows

    def energies(self) -> np.ndarray:
        """[E_input, E_isolator, E_damping, E_strain, E_hysteretic, E_kinetic] [J] (:data:`ENERGY_NAMES`):
        the work integrals so far, then the strain (1/2 x' K x) and kinetic (1/2 v' M v) energy now;
        linear storeys dissipate no hysteretic work."""
        x, v = self.x, self.v
        return np.array([*self.work, 0.5 * x.dot(self._K.dot(x)), 0.0, 0.5 * self._m.dot(v * v)])

    def discretization(self, h: float) -> tuple[np.ndarray, np.ndarray]:
        """(Phi, Gamma) for step h, cached per step size."""
        PG = self._fused(h)
        n = self._nq
        return PG[:, :n], PG[:, n:]

    def _fused(self, h: float) -> np.ndarray:
        PG = self._cache.get(h)
        if PG is None:
            if len(self._cache) > 16:
                self._cache.clear()
            PG = self._cache[h] = np.hstack(zoh_discretize(self.A, self.B, h))
        return PG

    def step(self, ag: float, F: float, h: float) -> None:
        """Advance the state by h [s], inputs held."""
        # ndarray.dot, not @: the same BLAS product (the same numbers) at half the call overhead,
        # which is most of the cost for matrices this small.
        z, following = self._z, self._z_next
        stepper = self._steppers.get(h)
        if stepper is None:
            stepper = self._stepper(h)
        scratch = self._scratch
        stepper.dot(self._state_and_inputs(ag, F), out=scratch)  # the next state and the work forms' rows at once
        following[: self._nq] = scratch[: self._nq]
        self.work += scratch[self._nq:].reshape(3, -1).dot(z)  # z' Q_k z (no stored view: FMU states deep-copy)
        self._z, self._z_next = following, z
        self.steps += 1

    def _stepper(self, h: float) -> np.ndarray:
        """[Phi, Gamma] over the rows Q_k of the work forms, for step h (cached)."""
        if len(self._steppers) > 16:
            self._steppers.clear()
        stepper = self._steppers[h] = np.vstack([self._fused(h), self._work_forms(h)])
        return stepper

    @property
    def q(self) -> np.ndarray:
        """State [x, x'] (a view of the present state, like x and v: writing into it sets the state;
        copy it to keep it, since the buffer it views is reused two steps later)."""
        return self._z[: self._nq]

    @q.setter
    def q(self, value: np.ndarray) -> None:
        self._z[: self._nq] = value

    @property
    def x(self) -> np.ndarray:
        """Relative displacements per level [m]."""
        return self._z[: self.n_levels]

    @property
    def v(self) -> np.ndarray:
        """Relative velocities per level [m/s]."""
        return self._z[self.n_levels : self._nq]

    def _state_and_inputs(self, ag: float, F: float) -> np.ndarray:
        """z = [q, ag, F]: the state buffer with the inputs written after it."""
        z = self._z
        z[self._nq] = ag
        z[self._nq + 1] = F
        return z

    def relative_acceleration(self, ag: float, F: float) -> np.ndarray:
        """Relative accelerations per level [m/s^2] for the current state and inputs."""
        return self._acc_rows.dot(self._state_and_inputs(ag, F))

    def _output_matrix(self) -> np.ndarray:
        """All outputs are linear in z = [q, ag, F]: the rows of output_vector, built once."""
        n = self.n_levels
        m = 2 * n + 2
        eye = np.eye(m)
        x, v = eye[:n], eye[n : 2 * n]
        ground = eye[2 * n]
        arel = self._acc_rows
        dx, dv = np.diff(x, axis=0), np.diff(v, axis=0)
        shear = self._shear_k[:, None] * dx + self._shear_c[:, None] * dv
        return np.vstack((x, v, arel + ground, arel, dx, shear))

    def output_vector(self, ag: float, F: float) -> np.ndarray:
        """[x (N), v (N), a absolute (N), a relative (N), drift (N-1), shear (N-1)] for the inputs."""
        return self._output_rows.dot(self._state_and_inputs(ag, F))

    def absolute_acceleration(self, ag: float, F: float) -> np.ndarray:
        """Absolute accelerations per level [m/s^2] (relative + ground)."""
        return self.relative_acceleration(ag, F) + ag

    def drifts(self) -> np.ndarray:
        """Inter-storey drifts x_j - x_{j-1}, j = 1..n [m]."""
        n = self.n_levels
        return self.output_vector(0.0, 0.0)[4 * n : 5 * n - 1]

    def storey_shears(self) -> np.ndarray:
        """Shear force in storey j = 1..n [N]: k_j drift_j + c_j (v_j - v_{j-1})."""
        n = self.n_levels
        return self.output_vector(0.0, 0.0)[5 * n - 1 :]


# ---------------------------------------------------------------------------------------------
# Yielding storeys: the hysteresis laws and the implicit integrator for them
# ---------------------------------------------------------------------------------------------

HYSTERESIS_LAWS = ("linear", "bilinear", "bouc-wen")
GRAVITY = 9.80665  # m/s^2, standard gravity (P-Delta loads)
DBL_EPSILON = 2.220446049250313e-16  # C's DBL_EPSILON, as Steel01.cpp uses it


class ParameterError(ValueError):
    """A storey parameter is out of its range; ``parameter`` is its FMU name (e.g. ``fy_2``)."""

    def __init__(self, parameter: str, message: str) -> None:
        self.parameter = parameter
        super().__init__(f"{parameter}: {message}")


def _c_div(a: float, b: float) -> float:
    """a / b with C's IEEE semantics (x / 0 = +-inf, 0 / 0 = NaN) instead of Python's ZeroDivisionError."""
    if b != 0.0:
        return a / b
    if a == 0.0 or math.isnan(a):
        return math.nan
    return math.copysign(math.inf, a) * math.copysign(1.0, b)


class Steel01:
    """OpenSees' ``Steel01`` uniaxial law, here force [N] against drift [m] of one storey.

    Source: OpenSees, SRC/material/uniaxial/Steel01.cpp (Filippou, Fenves, McKenna),
    ``setTrialStrain`` and ``determineTrialState`` transcribed line for line, including the
    ``DBL_EPSILON`` test on the strain increment and on the elastic tangent. ``E0`` is the
    storey stiffness k_j [N/m], ``fy`` the yield shear [N], ``b`` the post-yield stiffness
    ratio. a1..a4 are the isotropic-hardening parameters with OpenSees' defaults
    (0, 1, 0, 1): no isotropic hardening (shifts stay 1). Four literal zeros would make
    ``pow(x / 0, 0.8) * 0`` = NaN shifts, as in OpenSees itself.
    """

    __slots__ = (
        "E0",
        "a1",
        "a2",
        "a3",
        "a4",
        "b",
        "c_loading",
        "c_max",
        "c_min",
        "c_shift_n",
        "c_shift_p",
        "c_strain",
        "c_stress",
        "c_tangent",
        "fy",
        "t_loading",
        "t_max",
        "t_min",
        "t_shift_n",
        "t_shift_p",
        "t_strain",
        "t_stress",
        "t_tangent",
    )

    def __init__(self, fy: float, E0: float, b: float, a1: float = 0.0, a2: float = 1.0, a3: float = 0.0,
                 a4: float = 1.0) -> None:
        self.fy, self.E0, self.b, self.a1, self.a2, self.a3, self.a4 = fy, E0, b, a1, a2, a3, a4
        self.c_min = self.c_max = 0.0
        self.c_shift_p = self.c_shift_n = 1.0
        self.c_loading = 0
        self.c_strain = self.c_stress = 0.0
        self.c_tangent = E0
        self._reset_trial()

    def _reset_trial(self) -> None:
        self.t_min, self.t_max = self.c_min, self.c_max
        self.t_shift_p, self.t_shift_n, self.t_loading = self.c_shift_p, self.c_shift_n, self.c_loading
        self.t_strain, self.t_stress, self.t_tangent = self.c_strain, self.c_stress, self.c_tangent

    def trial(self, strain: float) -> tuple[float, float]:
        """Force [N] and tangent [N/m] at a trial drift [m], from the last committed state."""
        self._reset_trial()
        d_strain = strain - self.c_strain
        if math.fabs(d_strain) > DBL_EPSILON:
            self.t_strain = strain
            self._determine_trial_state(d_strain)
        return self.t_stress, self.t_tangent

    def _determine_trial_state(self, d_strain: float) -> None:
        fy, E0, b = self.fy, self.E0, self.b
        fy_one_minus_b = fy * (1.0 - b)
        esh = b * E0
        epsy = fy / E0
        c1 = esh * self.t_strain
        c2 = self.t_shift_n * fy_one_minus_b
        c3 = self.t_shift_p * fy_one_minus_b
        c = self.c_stress + E0 * d_strain
        c1c3 = c1 + c3
        stress = c1c3 if c1c3 < c else c
        c1c2 = c1 - c2
        if c1c2 > stress:
            stress = c1c2
        self.t_stress = stress
        self.t_tangent = E0 if math.fabs(stress - c) < DBL_EPSILON else esh
        if self.t_loading == 0 and d_strain != 0.0:
            self.t_loading = 1 if d_strain > 0.0 else -1
        if self.t_loading == 1 and d_strain < 0.0:
            self.t_loading = -1
            if self.c_strain > self.t_max:
                self.t_max = self.c_strain
            self.t_shift_n = 1 + self.a1 * _c_div(self.t_max - self.t_min, 2.0 * self.a2 * epsy) ** 0.8
        if self.t_loading == -1 and d_strain > 0.0:
            self.t_loading = 1
            if self.c_strain < self.t_min:
                self.t_min = self.c_strain
            self.t_shift_p = 1 + self.a3 * _c_div(self.t_max - self.t_min, 2.0 * self.a4 * epsy) ** 0.8

    def elastic_band(self) -> tuple[float, float]:
        """(fy (1 - b) shift_n, fy (1 - b) shift_p): a trial force c with c1 - lower <= c <= c1 + upper,
        c1 = b E0 d, stays on the elastic branch (``determineTrialState``'s bounds, same arithmetic)."""
        fy_one_minus_b = self.fy * (1.0 - self.b)
        return self.c_shift_n * fy_one_minus_b, self.c_shift_p * fy_one_minus_b

    def commit_elastic(self, strain: float) -> float:
        """``trial(strain)`` then ``commit()`` for a trial known to stay elastic (the caller checked the
        band); the same state, without the return mapping. Returns the force [N]."""
        d_strain = strain - self.c_strain
        if math.fabs(d_strain) > DBL_EPSILON:
            # determineTrialState with Tstress = c, Ttangent = E0, then commitState
            loading = self.c_loading
            if loading == 0:
                loading = 1 if d_strain > 0.0 else -1
            if loading == 1 and d_strain < 0.0:
                loading = -1
                if self.c_strain > self.c_max:
                    self.c_max = self.c_strain
                epsy = self.fy / self.E0
                self.c_shift_n = 1 + self.a1 * _c_div(self.c_max - self.c_min, 2.0 * self.a2 * epsy) ** 0.8
            if loading == -1 and d_strain > 0.0:
                loading = 1
                if self.c_strain < self.c_min:
                    self.c_min = self.c_strain
                epsy = self.fy / self.E0
                self.c_shift_p = 1 + self.a3 * _c_div(self.c_max - self.c_min, 2.0 * self.a4 * epsy) ** 0.8
            self.c_loading = loading
            self.c_stress = self.c_stress + self.E0 * d_strain
            self.c_strain = strain
            self.c_tangent = self.E0
        return self.c_stress

    def commit(self) -> None:
        """Accept the last trial state (OpenSees' ``commitState``)."""
        self.c_min, self.c_max = self.t_min, self.t_max
        self.c_shift_p, self.c_shift_n, self.c_loading = self.t_shift_p, self.t_shift_n, self.t_loading
        self.c_strain, self.c_stress, self.c_tangent = self.t_strain, self.t_stress, self.t_tangent

    @property
    def force(self) -> float:
        """Committed force [N]."""
        return self.c_stress


class BoucWen:
    """Bouc-Wen storey law (Wen 1976, J. Eng. Mech. Div. ASCE 102(2):249-263), force [N] against drift d [m].

        f = b k d + (1 - b) fy z,    dz/dd = (1/dy) (1 - |z|^n (beta sgn(dd z) + gamma)),  dy = fy / k

    (Wen's A = 1, z made dimensionless with the yield drift dy, so z -> 1 and f -> b k d + (1 - b) fy
    under monotonic loading when beta + gamma = 1; beta = gamma = 0.5 unloads at k). The law is
    rate-independent: z is integrated against the drift with the trapezoidal rule over the
    step's drift increment (second order, as the Newmark scheme around it), solved by Newton;
    ``trial`` returns the consistent tangent df/dd.
    """

    __slots__ = ("b", "beta", "c_d", "c_z", "dy", "fy", "gamma", "k", "n", "t_d", "t_z")

    def __init__(self, fy: float, k: float, b: float, n: float, beta: float = 0.5, gamma: float = 0.5) -> None:
        self.k, self.fy, self.b, self.n, self.beta, self.gamma = k, fy, b, n, beta, gamma
        self.dy = fy / k
        self.c_d = self.c_z = self.t_d = self.t_z = 0.0

    def _phi(self, z: float, s: float) -> tuple[float, float]:
        """dz/dd * dy and its derivative in z, for a drift increment of sign s."""
        az = abs(z)
        if az == 0.0:
            return 1.0, 0.0
        sz = math.copysign(1.0, z)
        w = self.beta * (1.0 if s * z > 0.0 else -1.0) + self.gamma
        p = az ** (self.n - 1.0)
        return 1.0 - p * az * w, -self.n * p * sz * w

    def trial(self, d: float) -> tuple[float, float]:
        """Force [N] and consistent tangent [N/m] at a trial drift [m], from the committed state."""
        dd = d - self.c_d
        s = 1.0 if dd >= 0.0 else -1.0
        phi_c, _ = self._phi(self.c_z, s)
        r = dd / self.dy
        z = self.c_z + r * phi_c  # explicit predictor
        for _ in range(50):
            phi, dphi = self._phi(z, s)
            g = z - self.c_z - 0.5 * r * (phi_c + phi)
            dg = 1.0 - 0.5 * r * dphi
            step = g / dg
            z -= step
            if abs(step) <= 1e-15 * max(1.0, abs(z)):
                break
        phi, dphi = self._phi(z, s)
        dz_dd = 0.5 * (phi_c + phi) / self.dy / (1.0 - 0.5 * r * dphi)
        self.t_d, self.t_z = d, z
        return self.b * self.k * d + (1.0 - self.b) * self.fy * z, self.b * self.k + (1.0 - self.b) * self.fy * dz_dd

    def commit(self) -> None:
        self.c_d, self.c_z = self.t_d, self.t_z

    @property
    def force(self) -> float:
        """Committed force [N]."""
        return self.b * self.k * self.c_d + (1.0 - self.b) * self.fy * self.c_z


@dataclass(frozen=True)
class StoreyLaws:
    """Hysteresis of the storeys j = 1..n: one law for all, per-storey parameters.

    ``hysteresis``: 'linear' (today's model), 'bilinear' (OpenSees Steel01 without isotropic
    hardening) or 'bouc-wen'. ``fy[j-1]`` yield shear [N] > 0, ``b[j-1]`` post-yield stiffness
    ratio in [0, 1), ``n[j-1]`` Bouc-Wen exponent >= 1; ``bw_beta``, ``bw_gamma`` one pair for all
    storeys (beta > 0, |gamma| <= beta); ``substeps`` Newmark sub-steps per ``step`` call.
    ``p_delta``: add the linearised P-Delta stiffness -P_j / h_j of every storey, P_j = g times the
    masses of the floors j..n above it, h[j-1] the storey height [m] > 0 (any law, linear too).
    """

    hysteresis: str = "linear"
    fy: tuple[float, ...] = ()
    b: tuple[float, ...] = ()
    n: tuple[float, ...] = ()
    bw_beta: float = 0.5
    bw_gamma: float = 0.5
    substeps: int = 4
    p_delta: bool = False
    h: tuple[float, ...] = ()

    def geometric_stiffness(self, params: BuildingParams) -> tuple[float, ...]:
        """-P_j / h_j per storey j = 1..n [N/m] (zeros without P-Delta); P_j = g * (m_j + ... + m_n)."""
        n = params.n_storeys
        if not self.p_delta:
            return (0.0,) * n
        return tuple(-GRAVITY * sum(params.m[j:]) / self.h[j - 1] for j in range(1, n + 1))

    def check(self, params: BuildingParams) -> None:
        """Raise :class:`ParameterError` naming the first parameter out of range."""
        if self.hysteresis not in HYSTERESIS_LAWS:
            raise ParameterError("hysteresis", f"{self.hysteresis!r} is not one of "
                                 f"{', '.join(repr(h) for h in HYSTERESIS_LAWS)}")
        if self.p_delta:
            self._check_p_delta(params)
        if self.hysteresis != "linear":
            self._check_yielding(params)

    def _check_p_delta(self, params: BuildingParams) -> None:
        """The storey heights, and each storey stiffer than the weight above it over its height."""
        n = params.n_storeys
        if len(self.h) != n:
            raise ParameterError("h_1", f"P-Delta needs one storey height per storey ({n}), got {len(self.h)}")
        for j in range(1, n + 1):
            if not (math.isfinite(self.h[j - 1]) and self.h[j - 1] > 0.0):
                raise ParameterError(f"h_{j}", f"storey height {self.h[j - 1]!r} m must be > 0 for P-Delta")
        for j, kg in enumerate(self.geometric_stiffness(params), start=1):
            if not params.k[j] + kg > 0.0:
                raise ParameterError(f"h_{j}", f"P-Delta: the weight above storey {j} over its height "
                                     f"({-kg:.4g} N/m) is not below its stiffness k_{j} = {params.k[j]:.4g} N/m")

    def _check_yielding(self, params: BuildingParams) -> None:
        """The storey laws' parameters (hysteresis 'bilinear' or 'bouc-wen') and the sub-steps."""
        n = params.n_storeys
        for name, values in (("fy", self.fy), ("b", self.b)) + ((("n", self.n),) if self.hysteresis == "bouc-wen"
                                                                  else ()):
            if len(values) != n:
                raise ParameterError(f"{name}_1", f"needs one value per storey ({n}), got {len(values)}")
        for j in range(1, n + 1):
            fy, b, k = self.fy[j - 1], self.b[j - 1], params.k[j]
            if not (math.isfinite(fy) and fy > 0.0):
                raise ParameterError(f"fy_{j}", f"yield shear {fy!r} N must be a finite number > 0")
            if not (0.0 <= b < 1.0):
                raise ParameterError(f"b_{j}", f"post-yield stiffness ratio {b!r} must be in [0, 1)")
            if not (math.isfinite(k) and k > 0.0):
                raise ParameterError(f"k_{j}", f"a yielding storey needs a stiffness > 0 N/m, got {k!r}")
            if self.hysteresis == "bouc-wen" and not (math.isfinite(self.n[j - 1]) and self.n[j - 1] >= 1.0):
                raise ParameterError(f"n_{j}", f"Bouc-Wen exponent {self.n[j - 1]!r} must be >= 1")
        if self.hysteresis == "bouc-wen" and not (self.bw_beta > 0.0 and abs(self.bw_gamma) <= self.bw_beta):
            raise ParameterError("bw_beta", f"Bouc-Wen needs beta > 0 and |gamma| <= beta, got beta = "
                                 f"{self.bw_beta!r}, gamma = {self.bw_gamma!r}")
        if not (isinstance(self.substeps, int) and 1 <= self.substeps <= 1000):
            raise ParameterError("substeps", f"{self.substeps!r} must be an integer in [1, 1000]")

    def storeys(self, params: BuildingParams) -> list[Steel01] | list[BoucWen]:
        """Fresh (virgin) storey laws."""
        js = range(1, params.n_storeys + 1)
        if self.hysteresis == "bilinear":
            return [Steel01(self.fy[j - 1], params.k[j], self.b[j - 1]) for j in js]
        return [BoucWen(self.fy[j - 1], params.k[j], self.b[j - 1], self.n[j - 1], self.bw_beta, self.bw_gamma)
                for j in js]


NEWTON_MAX_ITERATIONS = 50


class ConvergenceError(RuntimeError):
    """Newton's iterations of a step did not converge."""


class HystereticShearBuilding:
    """The shear building with yielding storeys, same interface as :class:`ShearBuilding`.

    Integration (why: docs/structures.md). Newmark's average-acceleration scheme (the
    trapezoidal rule; Newmark 1959), implicit and unconditionally stable, with full
    Newton-Raphson iterations on the consistent tangent of every storey law, the way
    OpenSees' transient analysis advances a Steel01 model. Each ``step`` is divided into
    ``laws.substeps`` Newmark sub-steps. Inputs ag, F are held over the step (zero-order hold,
    as in the linear model): the acceleration at the start of a step is re-evaluated with the
    new inputs. Steel01 is a return-mapping law on drift increments (not an ODE), so it is
    stepped the way OpenSees steps it, not by an explicit ODE solver.

    Bilinear storeys add an exact elastic path (``exact_elastic``): while every storey stays
    on its elastic branch, the building is linear with the plastic offsets as constant loads,
    so the step is taken exactly (zero-order hold, as :class:`ShearBuilding`); if a storey's
    trial force leaves the yield band at the end of the step, the step is taken again from
    its start with the Newmark sub-steps. A bilinear building that never yields follows the
    linear one to round-off; only yielding steps pay for Newton. (A storey that yields and
    returns inside one elastic 1 ms step would be missed: its drift would have to reverse
    within the step.)
    """

    def __init__(self, params: BuildingParams, laws: StoreyLaws, exact_elastic: bool = True) -> None:
        laws.check(params)
        if laws.hysteresis == "linear":
            raise ValueError("use ShearBuilding for linear storeys (exact ZOH)")
        self.params = params
        self.laws = laws
        self.n_levels = n = len(params.m)
        ns = n - 1
        self.steps = 0
        self.m = [float(v) for v in params.m]
        self.k0 = float(params.k[0])
        self.c0 = float(params.c[0])
        self.cs = [float(v) for v in params.c[1:]]
        self.ks = [float(v) for v in params.k[1:]]
        self.storey_laws = laws.storeys(params)
        self.kg = list(laws.geometric_stiffness(params))  # P-Delta stiffness per storey [N/m] (0: none)
        self._x = [0.0] * n
        self._v = [0.0] * n
        self._f = [0.0] * ns  # committed storey spring forces [N]: the law's plus kg * drift
        self.newton_iterations = 0  # total, for diagnostics
        self.newmark_steps = 0  # communication steps taken with Newmark (the rest: exact elastic)
        # Everything the building outputs is linear in w = [x, v, ag, F, f]: one matrix, as ShearBuilding.
        m_arr = np.asarray(params.m, dtype=float)
        # the linear part of the building: storey stiffness k_j + kg_j (the law's elastic k_j and P-Delta)
        linear = BuildingParams(params.m, (params.k[0], *(k + g for k, g in zip(params.k[1:], self.kg, strict=True))),
                                params.c)
        A, B = state_space(linear)
        G = np.zeros((n, ns))  # level loads of storey forces f (f_s pulls level s up, level s+1 back)
        for s_ in range(ns):
            G[s_, s_] = 1.0
            G[s_ + 1, s_] = -1.0
        K0 = np.zeros((n, n))
        K0[0, 0] = self.k0
        _, C, _ = matrices(params)
        minv = 1.0 / m_arr[:, None]
        acc = np.hstack([-minv * K0, -minv * C, -np.ones((n, 1)), B[n:, 1:2], minv * G])  # rows of x'' in w
        eye = np.eye(2 * n + 2 + ns)
        x_rows, v_rows, ground, f_rows = eye[:n], eye[n:2 * n], eye[2 * n], eye[2 * n + 2:]
        shear = f_rows + np.asarray(self.cs)[:, None] * np.diff(v_rows, axis=0)
        self._out_rows = np.vstack((x_rows, v_rows, acc + ground, acc, np.diff(x_rows, axis=0), shear))
        self._w = np.zeros(2 * n + 2 + ns)  # [x, v, ag, F, f] (elastic steps: f replaced by the offsets)
        self._exact = exact_elastic and laws.hysteresis == "bilinear"
        if self._exact:
            # f_s = k_s (d_s - p_s): the plastic offsets p_s load the linear building like inputs
            Gp = np.zeros((n, ns))
            for s_, k in enumerate(self.ks):
                Gp[s_ + 1, s_] = k
                Gp[s_, s_] = -k
            self._B_ext = np.hstack([B, np.vstack([np.zeros((n, ns)), Gp / m_arr[:, None]])])
            self._A = A
            self._cache: dict[float, np.ndarray] = {}
            self._damping_forms: dict[float, np.ndarray] = {}
            self._bands = [law.elastic_band() for law in self.storey_laws]
            self._C_full = C
        self.work = [0.0] * 4  # [E_input, E_isolator, E_damping, E_restoring (storey springs, k_0, P-Delta)] [J]

    # -- state -----------------------------------------------------------------------------------
    @property
    def x(self) -> np.ndarray:
        """Relative displacements per level [m] (a copy)."""
        return np.array(self._x)

    @property
    def v(self) -> np.ndarray:
        """Relative velocities per level [m/s] (a copy)."""
        return np.array(self._v)

    def _accelerations(self, x: list[float], v: list[float], f: list[float], ag: float, F: float) -> list[float]:
        """Relative accelerations [m/s^2]: M x'' = -C v - R(x) - e_0 F - M 1 ag."""
        n, m, cs = self.n_levels, self.m, self.cs
        out = [0.0] * n
        for i in range(n):
            load = -m[i] * ag
            if i == 0:
                load -= F + self.k0 * x[0] + self.c0 * v[0]
            if i > 0:  # storey i (index i-1) below level i
                load -= f[i - 1] + cs[i - 1] * (v[i] - v[i - 1])
            if i < n - 1:  # storey i+1 (index i) above level i
                load += f[i] + cs[i] * (v[i + 1] - v[i])
            out[i] = load / m[i]
        return out

    def _inputs(self, ag: float, F: float) -> np.ndarray:
        """w = [x, v, ag, F, f] for the present state and these inputs."""
        n = self.n_levels
        w = self._w
        w[: 2 * n] = self._x + self._v
        w[2 * n] = ag
        w[2 * n + 1] = F
        w[2 * n + 2:] = self._f
        return w

    def relative_acceleration(self, ag: float, F: float) -> np.ndarray:
        """Relative accelerations per level [m/s^2] for the current state and inputs."""
        n = self.n_levels
        return self._out_rows[3 * n: 4 * n].dot(self._inputs(ag, F))

    def absolute_acceleration(self, ag: float, F: float) -> np.ndarray:
        return self.relative_acceleration(ag, F) + ag

    # -- stepping --------------------------------------------------------------------------------
    def step(self, ag: float, F: float, h: float) -> None:
        """Advance by h [s] with ag [m/s^2] and F [N] held."""
        if not (self._exact and self._elastic_step(ag, F, h)):
            hs = h / self.laws.substeps
            for _ in range(self.laws.substeps):
                self._newmark(ag, F, hs)
            self.newmark_steps += 1
            if self._exact:
                self._bands = [law.elastic_band() for law in self.storey_laws]
        self.steps += 1

    def _elastic_step(self, ag: float, F: float, h: float) -> bool:
        """The exact step if every storey stays elastic (then committed, True); else nothing changes."""
        PG = self._cache.get(h)
        if PG is None:
            if len(self._cache) > 16:
                self._cache.clear()
            PG = self._cache[h] = np.hstack(zoh_discretize(self._A, self._B_ext, h))
        n = self.n_levels
        laws = self.storey_laws
        w = self._inputs(ag, F)
        w[2 * n + 2:] = [law.c_strain - law.c_stress / law.E0 for law in laws]  # plastic offsets
        xv = PG.dot(w).tolist()
        drifts = []
        for s, law in enumerate(laws):
            d = xv[s + 1] - xv[s]
            # Steel01's trial force and its bounds (determineTrialState, same arithmetic)
            c = law.c_stress + law.E0 * (d - law.c_strain)
            c1 = law.b * law.E0 * d
            lower, upper = self._bands[s]
            if c1 + upper < c or c1 - lower > c:
                return False
            drifts.append(d)
        x0, work = self._x, self.work
        W = self._damping_forms.get(h)
        if W is None:
            nz = len(w)
            Q = np.zeros((nz, nz))
            Q[n:2 * n, n:2 * n] = self._C_full  # damping power v' C v, exact for the held inputs and offsets
            if len(self._damping_forms) > 16:
                self._damping_forms.clear()
            W = self._damping_forms[h] = zoh_quadratic_integral(self._A, self._B_ext, Q, h)
        work[2] += float(w.dot(W.dot(w)))
        f, kg = self._f, self.kg
        spring = 0.0
        for s, law in enumerate(laws):
            d0, p = x0[s + 1] - x0[s], law.c_strain - law.c_stress / law.E0
            spring += 0.5 * law.E0 * ((drifts[s] - p) ** 2 - (d0 - p) ** 2) + 0.5 * kg[s] * (drifts[s] ** 2 - d0 ** 2)
            f[s] = law.commit_elastic(drifts[s]) + kg[s] * drifts[s]
        self._x, self._v = xv[:n], xv[n:]
        self._add_work(x0, ag, F, spring)
        return True

    def _add_work(self, x0: list[float], ag: float, F: float, spring: float) -> None:
        """Add a step's input and isolator work (inputs held: exact from the displacements at both ends) and
        the storey springs' work ``spring`` [J], with k_0's."""
        x1, m, work = self._x, self.m, self.work
        work[0] -= ag * sum(m[i] * (x1[i] - x0[i]) for i in range(self.n_levels))
        work[1] += F * (x1[0] - x0[0])
        work[3] += spring + 0.5 * self.k0 * (x1[0] ** 2 - x0[0] ** 2)

    def energies(self) -> np.ndarray:
        """[E_input, E_isolator, E_damping, E_strain, E_hysteretic, E_kinetic] [J] (:data:`ENERGY_NAMES`).

        The work integrals are those of the scheme: exact on the elastic path; on Newmark's sub-steps
        the trapezoidal rule, with which the average-acceleration scheme balances energy exactly
        (to Newton's tolerance). The strain energy is the recoverable one now: 1/2 k_0 x_0^2, per storey
        f^2 / (2 E0) (Steel01, unloading along E0) or 1/2 b k d^2 + 1/2 (1 - b) k (dy z)^2 (Bouc-Wen's
        elastic and hysteretic springs), plus 1/2 kg d^2 (P-Delta); the hysteretic work is what the
        storey springs took beyond it."""
        x, v, m = self._x, self._v, self.m
        strain = 0.5 * self.k0 * x[0] ** 2
        for s, law in enumerate(self.storey_laws):
            d = x[s + 1] - x[s]
            if isinstance(law, Steel01):
                strain += 0.5 * law.c_stress ** 2 / law.E0
            else:
                strain += 0.5 * law.b * law.k * d * d + 0.5 * (1.0 - law.b) * law.k * (law.dy * law.c_z) ** 2
            strain += 0.5 * self.kg[s] * d * d
        kinetic = 0.5 * sum(m[i] * v[i] * v[i] for i in range(self.n_levels))
        e_in, e_iso, e_damp, e_spring = self.work
        return np.array([e_in, e_iso, e_damp, strain, e_spring - strain, kinetic])

    def _newmark(self, ag: float, F: float, h: float) -> None:
        """One Newmark (gamma = 1/2, beta = 1/4) sub-step of h [s] with Newton iterations."""
        n, m, cs, laws, kg = self.n_levels, self.m, self.cs, self.storey_laws, self.kg
        ns = n - 1
        x0, v0 = self._x, self._v
        a0 = self._accelerations(x0, v0, self._f, ag, F)
        g4, g2 = 4.0 / (h * h), 2.0 / h
        # unknown D = x1 - x0;  v1 = 2/h D - v0;  a1 = 4/h^2 (D - h v0) - a0
        D = [h * v0[i] + 0.25 * h * h * a0[i] for i in range(n)]
        scale = max(max(abs(d) for d in D), 1e-12)
        f, kt = [0.0] * ns, [0.0] * ns
        r = [0.0] * n
        for _ in range(NEWTON_MAX_ITERATIONS):
            x1 = [x0[i] + D[i] for i in range(n)]
            v1 = [g2 * D[i] - v0[i] for i in range(n)]
            for s in range(ns):
                d = x1[s + 1] - x1[s]
                f[s], kt[s] = laws[s].trial(d)
                f[s] += kg[s] * d
                kt[s] += kg[s]
            # residual r = M a1 + C v1 + R(x1) - p  (p = -M 1 ag - e_0 F)
            for i in range(n):
                ri = m[i] * (g4 * (D[i] - h * v0[i]) - a0[i] + ag)
                if i == 0:
                    ri += F + self.k0 * x1[0] + self.c0 * v1[0]
                if i > 0:
                    ri += f[i - 1] + cs[i - 1] * (v1[i] - v1[i - 1])
                if i < n - 1:
                    ri -= f[i] + cs[i] * (v1[i + 1] - v1[i])
                r[i] = ri
            # tridiagonal Jacobian: diag and the off-diagonal (i, i+1) = -(kt_i + 2/h c_i)
            diag = [m[i] * g4 for i in range(n)]
            diag[0] += self.k0 + g2 * self.c0
            off = [0.0] * ns
            for s in range(ns):
                e = kt[s] + g2 * cs[s]
                diag[s] += e
                diag[s + 1] += e
                off[s] = -e
            delta = _thomas(diag, off, r)
            worst = 0.0
            for i in range(n):
                D[i] -= delta[i]
                worst = max(worst, abs(delta[i]))
            self.newton_iterations += 1
            if worst <= 1e-12 * scale + 1e-16:
                break
        else:
            raise ConvergenceError(f"Newton did not converge in {NEWTON_MAX_ITERATIONS} iterations")
        x1 = [x0[i] + D[i] for i in range(n)]
        f0 = self._f
        spring = 0.0
        for s in range(ns):
            d = x1[s + 1] - x1[s]
            f[s] = laws[s].trial(d)[0] + kg[s] * d
            laws[s].commit()
            spring += 0.5 * (f0[s] + f[s]) * (d - (x0[s + 1] - x0[s]))  # trapezoidal work of the storey spring
        self._x = x1
        self._v = v1 = [g2 * D[i] - v0[i] for i in range(n)]
        self._f = f
        # damping work sum dx' C (v0 + v1) / 2 (the trapezoidal rule, as the scheme integrates)
        vm = [0.5 * (v0[i] + v1[i]) for i in range(n)]
        damping = self.c0 * D[0] * vm[0] + sum(cs[s] * (D[s + 1] - D[s]) * (vm[s + 1] - vm[s]) for s in range(ns))
        self.work[2] += damping
        self._add_work(x0, ag, F, spring)

    # -- outputs ---------------------------------------------------------------------------------
    def output_vector(self, ag: float, F: float) -> np.ndarray:
        """[x (N), v (N), a absolute (N), a relative (N), drift (N-1), shear (N-1)], as ShearBuilding."""
        return self._out_rows.dot(self._inputs(ag, F))

    def drifts(self) -> np.ndarray:
        """Inter-storey drifts x_j - x_{j-1}, j = 1..n [m]."""
        return np.diff(self._x)

    def storey_shears(self) -> np.ndarray:
        """Storey shear j = 1..n [N]: spring force (the law's, plus -P_j/h_j drift_j with P-Delta) plus
        c_j (v_j - v_{j-1}): the net shear the floors above feel."""
        v = self._v
        return np.array([self._f[s] + self.cs[s] * (v[s + 1] - v[s]) for s in range(self.n_levels - 1)])

    def restoring_forces(self) -> np.ndarray:
        """Hysteretic (spring) part of the storey shears [N], without P-Delta."""
        return np.array(self._f) - np.array(self.kg) * self.drifts()

    def residual_drifts(self) -> np.ndarray:
        """Residual drift per storey [m]: drift_j - f_j / k_j, the drift left when the storey is unloaded
        to zero restoring force along its elastic stiffness k_j (the plastic offset). At rest (end of a
        record, motion decayed) it equals the drift itself; while the building moves it removes the
        elastic part, so its value at the end of a run is the permanent set even if some sway remains."""
        return self.drifts() - self.restoring_forces() / np.array(self.ks)


def _thomas(diag: list[float], off: list[float], rhs: list[float]) -> list[float]:
    """Solve a symmetric tridiagonal system (diagonal ``diag``, off-diagonal ``off``) by the Thomas algorithm."""
    n = len(diag)
    c = [0.0] * n
    d = [0.0] * n
    b0 = diag[0]
    c[0] = off[0] / b0 if n > 1 else 0.0
    d[0] = rhs[0] / b0
    for i in range(1, n):
        denom = diag[i] - off[i - 1] * c[i - 1]
        c[i] = off[i] / denom if i < n - 1 else 0.0
        d[i] = (rhs[i] - off[i - 1] * d[i - 1]) / denom
    for i in range(n - 2, -1, -1):
        d[i] -= c[i] * d[i + 1]
    return d


def make_building(params: BuildingParams, laws: StoreyLaws | None = None) -> ShearBuilding | HystereticShearBuilding:
    """The building model for a law: linear (exact ZOH, :class:`ShearBuilding`) or hysteretic.

    Linear storeys with P-Delta are the linear building with k_j - P_j / h_j (its storey shears are
    then the net shears the floors above feel)."""
    if laws is None or laws.hysteresis == "linear":
        if laws is not None:
            laws.check(params)
            if laws.p_delta:
                kg = laws.geometric_stiffness(params)
                params = BuildingParams(params.m, (params.k[0], *(k + g for k, g in zip(params.k[1:], kg,
                                                                                         strict=True))), params.c)
        return ShearBuilding(params)
    return HystereticShearBuilding(params, laws)


def parameter_problem(values: dict[str, float | int | str]) -> tuple[str, str] | None:
    """(parameter, message) for the first out-of-range building parameter, or None.

    ``values`` holds the FMU's parameters by name (``m_j``, ``k_j``, ``c_j``, ``hysteresis``,
    ``fy_j``, ``b_j``, ``n_j``, ``bw_beta``, ``bw_gamma``, ``substeps``, ``p_delta``, ``h_j``), e.g. the model
    description's start values overridden by a scenario's: for a check before anything runs.
    """
    n_levels = sum(1 for name in values if name.startswith("m_") and name[2:].isdigit())
    try:
        params = BuildingParams(*(tuple(float(values[f"{p}_{j}"]) for j in range(n_levels)) for p in "mkc"))
    except ParameterError as exc:
        return exc.parameter, str(exc)
    except (KeyError, ValueError, TypeError) as exc:
        return "m_j, k_j, c_j", str(exc)
    storeys = range(1, n_levels)

    def each(p: str) -> tuple[float, ...]:
        return tuple(float(values.get(f"{p}_{j}", math.nan)) for j in storeys)

    laws = StoreyLaws(str(values.get("hysteresis", "linear")), each("fy"), each("b"), each("n"),
                      float(values.get("bw_beta", 0.5)), float(values.get("bw_gamma", 0.5)),
                      int(values.get("substeps", 4)), bool(values.get("p_delta", False)), each("h"))
    try:
        laws.check(params)
    except ParameterError as exc:
        return exc.parameter, str(exc)
    return None
