"""Sampled-data reference of the isolated building under a digital current controller.

Independent of the engine's coupling code: it uses the physics cores (building matrices,
Eq. 17 of the isolator, the record playback, the controller cores) and integrates the
continuous plant itself, as the system it models would run:

* **Controller**: sampled every ``period`` H [s]. At t_k it reads the plant (x, v, absolute and
  relative accelerations, the isolator force F, the ground acceleration) and returns a current.
* **Latency** (``latency``, in recorded steps of H / ``record_every``): the current computed from the
  samples at t_k acts from t_k + latency on. The default, 0, is the co-simulation's timing whatever its
  plant step (docs/master.md, "Multi-rate stepping"): the controller unit steps from t_k to t_{k+1} with
  its inputs sampled at t_k (delayed connections), its output is its value at t_{k+1} (one of its own
  steps, the FMI rule), and the isolator, stepping after it in Gauss-Seidel, applies that current over
  [t_k, t_{k+1}]: a zero-order hold with no computation delay. A one-period delay (``latency`` =
  ``record_every``) is what a scenario gets by making the current's connection ``delayed``. The
  measurements at t_k are taken with the current acting just before t_k.
* **Hold**: the current is constant between two actions (zero-order hold).
* **Plant**: building (Eq. 18-23) + isolators (Eq. 17 at the held current) + ground acceleration
  (the record's linear interpolation, zero outside it), integrated by classic fourth-order
  Runge-Kutta with N sub-steps per interval (``native/sampled_plant.c``), N >= ``substeps`` and
  large enough that omega * h_sub <= ``omega_h``, with omega the largest of the building's
  frequencies and the isolators' tangent frequency sqrt(K_t / m_0) + C / m_0 at the interval's
  current and at |x_0| + 2 |v_0| H (the sinh spring stiffens fast). Record breakpoints fall on
  sub-step boundaries when the record's sample times are multiples of h_sub; the right-hand side
  is smooth inside every sub-step otherwise.

Outputs are recorded every H / ``record_every`` (the value at t_k after the switch, like the
co-simulation's values at its communication points). :func:`converged` runs it twice (the
sub-step halved) and says how much the peaks moved.

Units: SI throughout (m, m/s, m/s^2, N, A, s).
"""

from __future__ import annotations

import ctypes
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from components.physics.ground_motion_core import G, GroundMotion
from components.physics.monolithic import Trajectory
from components.physics.mre_isolator_core import TABLE2, GeneralizedCoefficients, isolator_force, isolator_stiffness
from components.physics.shear_building_core import BuildingParams, state_space
from mre_common import c_compile

SOURCE = Path(__file__).resolve().parent / "native" / "sampled_plant.c"
CFLAGS = ("-shared", "-fPIC", "-O2", "-ffp-contract=off", "-std=c99", "-Wall", "-Wextra")
MAX_SUBSTEPS = 1 << 16  # sub-steps per interval beyond which the reference gives up (stiffness runaway)
_LIB: list[Any] = []


def _kernel() -> Any:
    if not _LIB:
        lib = ctypes.CDLL(str(c_compile.compile_cached(SOURCE, CFLAGS, ("-lm",), name="sampled_plant")))
        p, i32, f64 = ctypes.c_void_p, ctypes.c_int, ctypes.c_double
        lib.plant_interval.argtypes = [i32, p, p, p, p, p, i32, f64, i32, p, p]
        lib.plant_interval.restype = i32
        _LIB.append(lib)
    return _LIB[0]


Motion = Callable[[np.ndarray], np.ndarray]
"""Ground acceleration [m/s^2] at an array of times [s]."""


def record_motion(gm: GroundMotion) -> Motion:
    """The record playback of :class:`GroundMotion` (linear interpolation, 0 outside), vectorised."""
    t = np.asarray(gm.record.time, dtype=float) * gm.time_scale
    a = np.asarray(gm.record.accel_g, dtype=float) * (G * gm.scale)
    return lambda times: np.interp(times, t, a, left=0.0, right=0.0)


@dataclass(frozen=True)
class Plant:
    """The continuous plant: ground motion, building, isolator coefficients and device count."""

    motion: Motion
    building: BuildingParams = field(default_factory=BuildingParams.dyke)
    coeffs: GeneralizedCoefficients = TABLE2
    n_isolators: int = 2

    def force(self, x0: float, v0: float, i: float) -> float:
        """Restoring force of the isolators together [N] (Eq. 17)."""
        return isolator_force(x0, v0, i, self.coeffs, 0.0, self.n_isolators)


@dataclass(frozen=True)
class Measurements:
    """What the controller samples at t [s]: per level x, v, absolute a, relative arel; F [N]; ag."""

    t: float
    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    arel: np.ndarray
    F: float
    ag: float


class SampledController(Protocol):
    """A digital current controller: its output before the first sample, then one output per sample [A]."""

    def initial(self, m: Measurements) -> float: ...

    def sample(self, m: Measurements) -> float: ...


@dataclass
class SampledRun:
    """The reference's time histories (every H / record_every), peaks and how it went."""

    trajectory: Trajectory
    period: float
    record_every: int
    max_substeps: int  # most sub-steps any interval took
    stopped: str = ""  # why the run ended early ("" = it reached the end)
    as_recorded: Trajectory | None = None  # F, accelerations and i as the co-simulation records them (see peaks)

    def peaks(self, stride: int = 1, limit: str = "left") -> dict[str, float]:
        """Peak |value| of x_0, drifts, absolute accelerations and the isolator force F (SI), over every
        ``stride``-th recorded point (stride = record_every: the controller's sample instants only).

        Where the current jumps, F and the accelerations jump with it. ``limit="left"`` (the default) takes the
        values at t with the current applied over the step that ends at t, as the co-simulation records them
        (its recorded values are the units' outputs at the end of each step), so peaks compare like with like;
        ``"right"`` takes them with the current from t on (:attr:`trajectory`); ``"both"`` the larger of the
        two, the peak of the continuous-time signal on the recorded grid."""
        if limit == "both":
            a, b = self.peaks(stride, "left"), self.peaks(stride, "right")
            return {k: max(a[k], b[k]) for k in a}
        tr = self.trajectory if limit == "right" or self.as_recorded is None else self.as_recorded
        sub = Trajectory(*(getattr(tr, f)[::stride] for f in ("t", "x", "v", "a", "arel", "F", "i", "ag")))
        out = sub.peaks()
        out["F"] = float(np.max(np.abs(sub.F)))
        return out


def simulate_sampled(plant: Plant, controller: SampledController, period: float, n_samples: int, *,
                     record_every: int = 1, latency: int | None = None, substeps: int = 8, omega_h: float = 0.05,
                     x_limit: float = 0.1) -> SampledRun:
    """Run the sampled-data loop for n_samples periods H = ``period`` [s] (see the module docstring).

    ``record_every``: recorded points per period (recorded step H / record_every); ``latency``: recorded steps
    from a sample to the action of the current computed from it, 0..record_every (default 0: at once, the
    co-simulation's timing); ``substeps``, ``omega_h``: the integrator's resolution per period. The run stops
    (``stopped`` says why) when |x_0| exceeds ``x_limit`` [m], the state stops being finite or a period would
    need more than :data:`MAX_SUBSTEPS` sub-steps.
    """
    R = int(record_every)
    d = 0 if latency is None else int(latency)
    if R < 1 or not 0 <= d <= R:
        raise ValueError(f"record_every must be >= 1 and latency in [0, record_every], got {record_every}, {latency}")
    if substeps < 1 or not omega_h > 0:
        raise ValueError("substeps must be >= 1 and omega_h > 0")
    lib = _kernel()
    A, B = state_space(plant.building)
    n = A.shape[0]
    m = n // 2
    A_c = np.ascontiguousarray(A)
    b_ag, b_F = np.ascontiguousarray(B[:, 0]), np.ascontiguousarray(B[:, 1])
    omega_building = float(np.max(np.abs(np.linalg.eigvals(A))))
    m0 = plant.building.m[0]
    c = plant.coeffs
    n_iso = plant.n_isolators
    H = float(period)
    h_rec = H / R

    rows = n_samples * R + 1
    q_rec = np.zeros((rows, n))
    F_rec = np.zeros(rows)
    i_rec = np.zeros(rows)
    t_rec = np.arange(rows) * h_rec
    q = np.zeros(n)
    p = np.zeros(4)
    out = np.zeros((MAX_SUBSTEPS + 1) * (n + 1))
    ptr = {name: arr.ctypes.data for name, arr in (("A", A_c), ("b_ag", b_ag), ("b_F", b_F), ("p", p), ("q", q),
                                                     ("out", out))}

    def measure(t: float, i: float) -> Measurements:
        ag = float(plant.motion(np.array([t]))[0])
        F = plant.force(q[0], q[m], i)
        arel = A[m:] @ q + B[m:, 0] * ag + B[m:, 1] * F
        return Measurements(t, q[:m].copy(), q[m:].copy(), arel + ag, arel, F, ag)

    def omega(i: float) -> float:
        """Largest frequency of the plant in this period at current i [rad/s] (bound, see module docstring)."""
        k_t = isolator_stiffness(abs(q[0]) + 2.0 * abs(q[m]) * H, i, c, n_iso)
        c_t = n_iso * (c.c0_0 * i + c.c0_1)
        return max(omega_building, math.sqrt(max(k_t, 0.0) / m0) + abs(c_t) / m0)

    def integrate(first: int, last: int, i: float, M: int, t0: float) -> bool:
        """Recorded steps first..last-1 of this period at current i, M sub-steps each; False if not finite."""
        N = (last - first) * M
        h = h_rec / M
        ag = np.ascontiguousarray(plant.motion(t0 + first * h_rec + 0.5 * h * np.arange(2 * N + 1)))
        hp = c.at_current(i)
        p[:] = (n_iso * hp.c0, n_iso * hp.k0, n_iso * hp.alpha, hp.beta)
        if lib.plant_interval(n, ptr["A"], ptr["b_ag"], ptr["b_F"], ptr["p"], ag.ctypes.data, N, h, M,
                              ptr["q"], ptr["out"]) != 0:
            return False
        block = out[: (last - first) * (n + 1)].reshape(last - first, n + 1)
        rows_ = slice(r0 + first + 1, r0 + last + 1)
        q_rec[rows_], F_rec[rows_], i_rec[rows_] = block[:, :n], block[:, n], i
        return True

    i_prev = float(controller.initial(measure(0.0, 0.0)))
    stopped = ""
    most = 0
    last = 0
    r0 = 0
    for k in range(n_samples):
        t0 = k * H
        r0 = k * R
        i_new = float(controller.sample(measure(t0, i_prev)))  # measured with the current acting at t_k
        acting = i_new if d == 0 else i_prev
        q_rec[r0], F_rec[r0], i_rec[r0] = q, plant.force(q[0], q[m], acting), acting
        last = r0
        if not (math.isfinite(i_new) and math.isfinite(F_rec[r0])):
            stopped = f"non-finite current or force at t = {t0:.6g} s"
            break
        pieces = [(a, b, i) for a, b, i in ((0, d, i_prev), (d, R, i_new)) if b > a]
        M = max(math.ceil(substeps / R), math.ceil(max(omega(i) for _, _, i in pieces) * h_rec / omega_h))
        if not M * R <= MAX_SUBSTEPS:
            stopped = f"stiffness runaway at t = {t0:.6g} s: {M * R} sub-steps needed (x_0 = {q[0]:.4g} m)"
            break
        most = max(most, M * R)
        if not all(integrate(a, b, i, M, t0) for a, b, i in pieces):
            stopped = f"the state stopped being finite in [{t0:.6g}, {t0 + H:.6g}] s"
            break
        if 0 < d < R:  # the switching point inside the period carries the new current (values after the switch)
            j = r0 + d
            F_rec[j], i_rec[j] = plant.force(q_rec[j, 0], q_rec[j, m], i_new), i_new
        last = r0 + R
        i_prev = i_new
        if abs(q[0]) > x_limit:
            stopped = f"|x_0| = {abs(q[0]):.4g} m beyond {x_limit} m at t = {t0 + H:.6g} s"
            break
    else:  # the last point carries the current that acts from there on (the co-simulation's last values)
        F_rec[last], i_rec[last] = plant.force(q[0], q[m], i_prev), i_prev
    sl = slice(0, last + 1)
    t, qs, F, i = t_rec[sl], q_rec[sl], F_rec[sl], i_rec[sl]
    ag = plant.motion(t)
    arel = qs @ A[m:].T + np.outer(ag, B[m:, 0]) + np.outer(F, B[m:, 1])
    traj = Trajectory(t, qs[:, :m], qs[:, m:], arel + ag[:, None], arel, F, i, ag)
    i_left = np.concatenate((i[:1], i[:-1]))  # the current over the step that ends at each recorded point
    F_left = np.array([plant.force(x0, v0, c) for x0, v0, c in zip(qs[:, 0], qs[:, m], i_left, strict=True)])
    arel_left = qs @ A[m:].T + np.outer(ag, B[m:, 0]) + np.outer(F_left, B[m:, 1])
    left = Trajectory(t, qs[:, :m], qs[:, m:], arel_left + ag[:, None], arel_left, F_left, i_left, ag)
    return SampledRun(traj, H, R, most, stopped, left)


def converged(run: Callable[[int, float], SampledRun], substeps: int = 8, omega_h: float = 0.05
              ) -> tuple[SampledRun, float]:
    """``run(substeps, omega_h)`` at this resolution and at half the sub-step; (finer run, largest
    relative change of any peak between the two)."""
    coarse, fine = run(substeps, omega_h), run(2 * substeps, omega_h / 2)
    a, b = coarse.peaks(), fine.peaks()
    change = max(abs(a[k] - b[k]) / abs(b[k]) for k in b if b[k] != 0.0)
    return fine, change


# -- the shipped controllers, driven from their cores ------------------------------------------------------


class ConstantCurrent:
    """A constant current [A] (the passive strategies)."""

    def __init__(self, current: float) -> None:
        self.current = float(current)

    def initial(self, m: Measurements) -> float:
        return self.current

    def sample(self, m: Measurements) -> float:
        return self.current


class SosmCurrent:
    """The SOSM core (Eq. 27-39): the current integrated over each period at the sampled rate."""

    def __init__(self, gains: Any, period: float, i_start: float = 0.0) -> None:
        from components.physics.sosm_controller_core import IsolatorModel, SosmController

        self.core = SosmController(gains, IsolatorModel(), i0=i_start)
        self.period = period

    def initial(self, m: Measurements) -> float:
        return self.core.i

    def sample(self, m: Measurements) -> float:
        return self.core.update(float(m.x[0]), float(m.v[0]), float(m.arel[0]), self.period)


class SwitchingCurrent:
    """The on-off (switching-stiffness) law."""

    def __init__(self, i_high: float, i_low: float, i_max: float) -> None:
        from components.physics.switching_controller_core import SwitchingLaw

        self.law = SwitchingLaw(i_high, i_low, i_max)

    def initial(self, m: Measurements) -> float:
        return self.law.current(float(m.x[0]), float(m.v[0]))

    def sample(self, m: Measurements) -> float:
        return self.law.current(float(m.x[0]), float(m.v[0]))


class EstimatedCurrent:
    """Clipped-optimal or Lyapunov: the core's controller fed with x_0, v_0, the absolute accelerations and F."""

    def __init__(self, kind: str, values: dict[str, Any], period: float) -> None:
        from components.physics import clipped_optimal_core, lqg_plant_core, lyapunov_controller_core

        module = {"clipped-optimal": clipped_optimal_core, "lyapunov": lyapunov_controller_core}[kind]
        cls = module.ClippedOptimalController if kind == "clipped-optimal" else module.LyapunovController
        params = {**lqg_plant_core.building_defaults(4), **values}
        self.core = cls(*module.controller_parts(params, 4))
        self.kind = kind
        self.period = period

    def initial(self, m: Measurements) -> float:
        c = self.core
        x, v = float(m.x[0]), float(m.v[0])
        if self.kind == "clipped-optimal":
            return c.current(c.desired_force(c.estimator.z), x, v, m.F)
        return c.current(c.estimator.z, x, v)

    def sample(self, m: Measurements) -> float:
        return self.core.update(float(m.x[0]), float(m.v[0]), np.asarray(m.a, dtype=float), m.F, self.period)


class FrequencyCurrent:
    """Frequency control: the core fed with the sampled ground acceleration."""

    def __init__(self, values: dict[str, Any], period: float) -> None:
        from components.physics import frequency_controller_core as core
        from components.physics import lqg_plant_core

        self.core = core.FrequencyController(*core.controller_parts({**lqg_plant_core.building_defaults(4),
                                                                       **values}, 4))
        self.period = period

    def initial(self, m: Measurements) -> float:
        return self.core.i

    def sample(self, m: Measurements) -> float:
        return self.core.update(m.ag, self.period)
