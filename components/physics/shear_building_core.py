"""Physics of an n-storey shear building on a base floor, Eq. (18)-(23) of the paper.

Coordinates are relative to the ground: x = [x_0 (base), x_1, ..., x_n] [m]. The
isolator force F [N] is the isolator's restoring force (positive along x_0) and acts on
the base floor against it (f_b = -F), the ground acceleration ag [m/s^2] loads every
mass with -m_j ag:

    M x'' + C x' + K x = -e_0 F - M 1 ag

K and C are tridiagonal; k_0 and c_0 couple the base floor to the ground (the paper's
k_b and c_b, zero by default: the isolators carry the base alone).

The structure is linear, so :class:`ShearBuilding` integrates it exactly between
communication points for inputs held constant over the step (zero-order hold):
q_{k+1} = Phi q_k + Gamma u_k with q = [x, x'] and u = [ag, F].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

# Dyke et al. (1996) three-storey model, Table 3 of the paper (SI units).
DYKE_MASSES = (98.3, 98.3, 98.3)  # kg, floors 1..3
DYKE_STIFFNESSES = (516e3, 684e3, 684e3)  # N/m, storeys 1..3
DYKE_DAMPINGS = (125.0, 50.0, 50.0)  # N*s/m, storeys 1..3
# Assumption (the paper gives no base floor): a base slab like a floor, no spring or
# dashpot to the ground besides the isolators.
BASE_MASS = 98.3  # kg
BASE_STIFFNESS = 0.0  # N/m
BASE_DAMPING = 0.0  # N*s/m


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
        if min(self.m) <= 0:
            raise ValueError(f"masses must be positive, got {self.m}")
        if min(self.k) < 0 or min(self.c) < 0:
            raise ValueError("stiffnesses and dampings must not be negative")

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


def natural_frequencies(p: BuildingParams) -> np.ndarray:
    """Undamped natural circular frequencies [rad/s], ascending (eigenvalues of M^-1 K).

    With k_0 = 0 the first one is the zero of the free base (rigid-body mode).
    """
    M, _, K = matrices(p)
    lam = np.linalg.eigvals(np.linalg.solve(M, K))
    return np.sqrt(np.clip(np.sort(lam.real), 0.0, None))


class ShearBuilding:
    """Exact-ZOH time stepping of the shear building.

    ``step(ag, F, h)`` advances the state by h [s] with ag [m/s^2] and F [N] held.
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
        self._fused(h).dot(self._state_and_inputs(ag, F), out=following[: self._nq])
        self._z, self._z_next = following, z
        self.steps += 1

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
