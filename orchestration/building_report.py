"""The isolated building's report: its roles in a scenario's ``report:`` section, its limits, its summary and figures.

The engine (:mod:`orchestration.master.report`) knows recorded variables only; this module
is the application's :class:`~orchestration.master.report.ReportHook` (:data:`REPORT`, given
to the engine by :mod:`orchestration.engine_hooks`). A scenario names which recorded variable
plays which role (base displacement, inter-storey drifts, floor accelerations, isolator
current and force, ground acceleration) and may name the displacement limits drawn on the
hysteresis plot; from them come the peaks engineers read (``summary.json``) and four figures:
top-floor acceleration with the ground, drifts, current and the isolator's hysteresis.
Time histories show the strong-motion window large and the whole record below it;
displacements and drifts are drawn in mm, as engineers read them.
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
from pydantic import ConfigDict, Field, field_validator, model_validator

from components.physics.building_periods import (
    REFERENCE_DISPLACEMENT_M,
    fixed_base_periods,
    isolated_period,
    isolator_secant_stiffness,
)
from components.physics.ground_motion_core import G as STANDARD_GRAVITY
from components.physics.mre_isolator_core import DEVICE_LIMIT_M, IDENTIFIED_RANGE_M
from components.physics.shear_building_core import ENERGY_NAMES
from orchestration.building_studies.isolated_structure import NotMonolithic, structure_setup
from orchestration.master.recorder import Recorder
from orchestration.master.report import Figures, ReportHook, RunDescription, peak, sample_interval
from orchestration.master.scenario import Number, ReportSpec, VariableRef, variable_refs

__all__ = ["DEFAULT_ENERGY_TOLERANCE", "DEFAULT_STEP_TOLERANCE", "DEVICE_LIMIT_M", "IDENTIFIED_RANGE_M", "REPORT",
           "BuildingReport", "displacement_limits", "energy_section", "periods_section", "physical_outcome", "plot",
           "step_changes", "strong_motion_window", "summarize"]
# IDENTIFIED_RANGE_M, DEVICE_LIMIT_M: the limits drawn when a scenario names none: the isolator
# model was identified on +-8 mm and the device allows 15 mm (paper, section 2).
DEFAULT_ENERGY_TOLERANCE = 0.01
"""Largest energy residual and coupling energy error of a valid run, as a fraction of the input energy:
the 1 % the reports call a tie (and the 1 % the coupling is checked to against Radau, docs/master.md).
A run whose energy books are off by more cannot rank strategies 1 % apart. The building's own balance
closes to round-off (linear storeys) or Newton's tolerance (yielding ones): only a coupling that went
wrong or an integrator that failed comes near it."""
DEFAULT_STEP_TOLERANCE = 0.01
"""Largest change of a peak when the plant's step is halved (``--verify-step``) for a run that converged in
the step: the same 1 % (a verdict closer than the change is a tie anyway)."""


class BuildingReport(ReportSpec):
    """Roles of recorded variables of the isolated building (all optional), besides the caption and labels.

    Declared in the order the variables are added to a run's recording when ``outputs`` lists
    fewer (base displacement, current, isolator force, ground acceleration, drifts, floors).
    """

    model_config = ConfigDict(extra="forbid")

    base_displacement: VariableRef | None = None
    current: VariableRef | None = None  # the commanded current
    device_current: VariableRef | None = None  # the current reaching the device (after a coil lag), drawn with it
    isolator_force: VariableRef | None = None
    ground_acceleration: VariableRef | None = None
    drifts: list[VariableRef] = Field(default_factory=list)
    floor_accelerations: list[VariableRef] = Field(default_factory=list)
    displacement_limits: dict[str, Number | str] = Field(
        default_factory=dict, description="named limits [m] drawn on the hysteresis plot: a value or 'unit.param'")
    energy_tolerance: Number = Field(
        DEFAULT_ENERGY_TOLERANCE, description="largest energy residual and coupling energy error of a valid run, "
                                              "as a fraction of the input energy")
    step_tolerance: Number = Field(
        DEFAULT_STEP_TOLERANCE, description="largest change of a peak with the plant's step halved (--verify-step) "
                                            "of a run converged in the step, as a fraction")
    acceleration_unit: Literal["m/s2", "g"] = Field(
        "m/s2", description="the figures' acceleration axis: m/s2, or g (standard gravity 9.80665 m/s2)")
    drift_unit: Literal["mm", "ratio"] = Field(
        "mm", description="the figures' drift axis: mm, or the drift ratio drift_j / h_j in % (needs storey_heights)")
    storey_heights: list[Number] | None = Field(
        None, description="h_j [m] of storeys 1..n, in the order of drifts (for drift_unit: ratio)")

    @field_validator("energy_tolerance", "step_tolerance")
    @classmethod
    def _tolerance(cls, value: float) -> float:
        if isinstance(value, bool) or not (math.isfinite(value) and value > 0):
            raise ValueError(f"must be a finite positive number (a fraction, e.g. 0.01), got {value!r}")
        return value

    @field_validator("storey_heights")
    @classmethod
    def _heights(cls, value: list[float] | None) -> list[float] | None:
        if value is not None and not all(not isinstance(h, bool) and math.isfinite(h) and h > 0 for h in value):
            raise ValueError(f"storey heights must be finite positive lengths [m], got {value}")
        return value

    @model_validator(mode="after")
    def _ratio_needs_heights(self) -> BuildingReport:
        if self.drift_unit == "ratio":
            if not self.storey_heights:
                raise ValueError("drift_unit: ratio needs report.storey_heights [m], one per storey (drift_j / h_j)")
            if self.drifts and len(self.storey_heights) != len(self.drifts):
                raise ValueError(f"storey_heights gives {len(self.storey_heights)} heights for {len(self.drifts)} "
                                 "drifts: one per storey, in the order of report.drifts")
        return self

    @field_validator("displacement_limits")
    @classmethod
    def _limit_refs(cls, value: dict[str, Number | str]) -> dict[str, Number | str]:
        for label, ref in value.items():
            if isinstance(ref, str):
                VariableRef.parse(ref)
            elif not ref > 0:
                raise ValueError(f"displacement limit {label!r} must be positive, got {ref}")
        return value

    @field_validator("base_displacement", "current", "device_current", "isolator_force", "ground_acceleration",
                     "drifts", "floor_accelerations", mode="before")
    @classmethod
    def _refs(cls, value: Any) -> Any:
        return variable_refs(value)

    def optional_variables(self) -> list[VariableRef]:
        """The building's energy integrals (:data:`ENERGY_NAMES`), from the unit of the base displacement, where
        that unit has them (the OpenSees unit does not: its energy section says "not checked")."""
        if self.base_displacement is None:
            return []
        return [VariableRef(unit=self.base_displacement.unit, name=name) for name in ENERGY_NAMES]

    def templates(self) -> list[tuple[tuple[str, ...], str]]:
        """The caption and labels, and each displacement limit given as ``unit.param``."""
        return super().templates() + [(("displacement_limits", label), "{" + ref + "}")
                                      for label, ref in self.displacement_limits.items() if isinstance(ref, str)]


def summarize(spec: BuildingReport, rec: Recorder, run: RunDescription) -> dict[str, Any]:
    """Peaks per role (SI units), time beyond the isolator's identified range and device limit, strong motion."""
    out: dict[str, Any] = {}
    if spec.base_displacement is not None:
        x = rec.column(str(spec.base_displacement))
        out["peak_base_displacement_m"] = peak(x)
        out["time_beyond_identified_range_s"] = float(np.sum(np.abs(x) > IDENTIFIED_RANGE_M) * sample_interval(rec))
        out["time_beyond_device_limit_s"] = float(np.sum(np.abs(x) > DEVICE_LIMIT_M) * sample_interval(rec))
    if spec.drifts:
        out["peak_drift_m"] = {str(r): peak(rec.column(str(r))) for r in spec.drifts}
    if spec.floor_accelerations:
        out["peak_abs_acceleration_m_s2"] = {str(r): peak(rec.column(str(r))) for r in spec.floor_accelerations}
    if spec.current is not None:
        i = rec.column(str(spec.current))
        out["peak_current_A"] = float(np.max(i)) if len(i) else None
        out["mean_current_A"] = float(np.mean(i)) if len(i) else None
    if spec.isolator_force is not None:
        out["peak_isolator_force_N"] = peak(rec.column(str(spec.isolator_force)))
    if spec.ground_acceleration is not None:
        ag = rec.column(str(spec.ground_acceleration))
        out["peak_ground_acceleration_m_s2"] = peak(ag)
        window = strong_motion_window(rec.times, ag)
        if window is not None:
            out["strong_motion_window_s"] = list(window)
    physical = physical_outcome(spec, rec, run)
    if physical:
        out["physical"] = physical
    if spec.base_displacement is not None:
        out["periods"] = periods_section(run)
    energy, reasons = energy_section(spec, rec, run)
    if energy is not None:
        out["energy"] = energy
    out["invalid_reasons"] = reasons  # the engine adds its own (non-finite values) and sets ``valid``
    return out


def periods_section(run: RunDescription, displacement: float = REFERENCE_DISPLACEMENT_M) -> dict[str, Any]:
    """The building's periods [s]: fixed base (the storeys above the base floor, every mode, longest first) and
    the isolated first mode at 0 A and at the run's i_max, with the isolators' secant stiffness at
    ``displacement`` [m]; ``{"note": why}`` for a system the in-process model does not represent."""
    try:
        s = structure_setup(run.model_names, run.set_values)
        iso = {current: (isolator_secant_stiffness(s.coeffs, s.n_isolators, current, displacement),
                         isolated_period(s.building, s.coeffs, s.n_isolators, current, displacement))
               for current in (0.0, s.i_max)}
        fixed = fixed_base_periods(s.building)
    except (NotMonolithic, ValueError, ArithmeticError) as exc:
        return {"note": f"not computed: {exc}"}
    return {"fixed_base_s": fixed, "isolated_0A_s": iso[0.0][1], "isolated_i_max_s": iso[s.i_max][1],
            "i_max_A": s.i_max, "reference_displacement_m": displacement,
            "isolator_secant_stiffness_0A_N_m": iso[0.0][0], "isolator_secant_stiffness_i_max_N_m": iso[s.i_max][0],
            "note": "fixed base: the storeys above the base floor with the base floor held, every mode, longest "
                    "first; isolated: the first mode of the whole building with the isolators as a linear spring "
                    "of their secant stiffness at the reference displacement"}


def strong_motion_window(t: np.ndarray, ag: np.ndarray) -> tuple[float, float] | None:
    """Time window [s] holding the strong motion and the response right after it.

    The significant duration D5-95 (Trifunac & Brady 1975: from 5 % to 95 % of the Arias
    intensity, the cumulative integral of ag²), widened by a quarter of D before and half of D
    after (the structure keeps moving after the ground calms down). None without motion.
    """
    if len(t) < 3:
        return None
    energy = np.cumsum(np.asarray(ag, dtype=float) ** 2)
    if not np.isfinite(energy[-1]) or energy[-1] <= 0:
        return None
    energy /= energy[-1]
    t5 = float(t[np.searchsorted(energy, 0.05)])
    t95 = float(t[min(np.searchsorted(energy, 0.95), len(t) - 1)])
    d = max(t95 - t5, float(t[1] - t[0]))
    return max(float(t[0]), t5 - 0.25 * d), min(float(t[-1]), t95 + 0.5 * d)


def displacement_limits(spec: BuildingReport, run: RunDescription) -> dict[str, float]:
    """Named displacement limits [m] for the hysteresis plot (values or ``unit.param`` references)."""
    if not spec.displacement_limits:
        return {"identified range": IDENTIFIED_RANGE_M, "device limit": DEVICE_LIMIT_M}
    out = {}
    for label, ref in spec.displacement_limits.items():
        value = ref if isinstance(ref, int | float) else run.value(*str(ref).split(".", 1))
        if isinstance(value, int | float) and not isinstance(value, bool) and value > 0:
            out[label] = float(value)
    return out


def named(run: RunDescription, ref: str, role: str) -> str:
    """A variable's name in a figure: the scenario's label for it, else its role in words with the variable
    (``base displacement (building.x_0)``), so an axis never shows a bare variable name."""
    label = run.label(ref)
    return label if label != ref else f"{role} ({ref})"


def plot(spec: BuildingReport, rec: Recorder, run: RunDescription, figures: Figures) -> None:
    """PNG figures for the roles present: top-floor acceleration with the ground, drifts, current, hysteresis.

    With the ground acceleration named, time histories show its strong-motion window
    (:func:`strong_motion_window`) large, unless the window covers nearly the whole record.
    """
    t = rec.times
    window, note = None, ""
    if spec.ground_acceleration is not None:
        window = strong_motion_window(t, rec.column(str(spec.ground_acceleration)))
        if window is not None and window[1] - window[0] > 0.8 * (t[-1] - t[0]):
            window = None  # the record is nearly all strong motion: one panel
        if window is not None:
            note = f"strong motion {window[0]:.1f}-{window[1]:.1f} s (Arias 5-95 %, widened)"

    def time_figure(title: str, ylabel: str, lines: list[tuple[np.ndarray, str, dict[str, Any]]]) -> Any:
        return figures.time_figure(t, title, ylabel, lines, window, note)

    if spec.floor_accelerations:
        top = str(spec.floor_accelerations[-1])
        lines = []
        if spec.ground_acceleration is not None:
            ground = str(spec.ground_acceleration)
            lines.append((rec.column(ground), named(run, ground, "ground acceleration"), {"color": "0.6", "lw": 0.6}))
        lines.append((rec.column(top), named(run, top, "top floor"), {"color": "C0"}))
        if spec.acceleration_unit == "g":
            lines = [(y / STANDARD_GRAVITY, label, style) for y, label, style in lines]
        figures.save(time_figure(f"absolute acceleration: {named(run, top, 'top floor')}",
                                 "acceleration [g]" if spec.acceleration_unit == "g" else "acceleration [m/s²]",
                                 lines),
                     "top_floor_acceleration.png")
    if spec.drifts:
        if spec.drift_unit == "ratio":
            heights = [float(h) for h in spec.storey_heights or ()]
            lines = [(100.0 * rec.column(str(r)) / h, named(run, str(r), f"storey {k}"), {})
                     for k, (r, h) in enumerate(zip(spec.drifts, heights, strict=True), start=1)]
            figures.save(time_figure("inter-storey drift ratios", "drift ratio [%]", lines), "drifts.png")
        else:
            lines = [(1e3 * rec.column(str(r)), named(run, str(r), f"storey {k}"), {})
                     for k, r in enumerate(spec.drifts, start=1)]
            figures.save(time_figure("inter-storey drifts", "drift [mm]", lines), "drifts.png")
    if spec.current is not None:
        ref = str(spec.current)
        lines = [(rec.column(ref), named(run, ref, "current command"), {})]
        if spec.device_current is not None:
            dev = str(spec.device_current)
            lines.append((rec.column(dev), named(run, dev, "device current"), {"ls": "--"}))
        title = "current: commanded and in the device" if len(lines) > 1 else \
            f"command: {named(run, ref, 'current command')}"
        figures.save(time_figure(title, "current [A]", lines), "current.png")
    if spec.isolator_force is not None and spec.base_displacement is not None:
        fig, ax = figures.plt.subplots(figsize=(6, 4.6))
        x_ref, f_ref = str(spec.base_displacement), str(spec.isolator_force)
        ax.plot(1e3 * rec.column(x_ref), rec.column(f_ref), lw=0.4)
        styles = iter([("0.5", "--"), ("C3", ":"), ("C2", "-.")])
        for label, edge in displacement_limits(spec, run).items():
            color, ls = next(styles, ("0.3", ":"))
            for sign in (1, -1):
                ax.axvline(sign * 1e3 * edge, color=color, ls=ls, lw=0.9, label=f"{label} ±{1e3 * edge:g} mm"
                           if sign == 1 else None)
        ax.set(xlabel=f"{named(run, x_ref, 'base displacement')} [mm]",
               ylabel=f"{named(run, f_ref, 'isolator force')} [N]",
               title=f"{figures.head}\nhysteresis")
        ax.legend(fontsize=7, loc="upper left")
        ax.grid(alpha=0.3)
        figures.save(fig, "isolator_hysteresis.png")


def _isolator_limits(spec: BuildingReport, run: RunDescription) -> tuple[float, float]:
    """The isolator's identified range and device limit [m]: its parameters in the run, else the paper's."""
    unit = spec.isolator_force.unit if spec.isolator_force is not None else None
    out = []
    for name, default in (("x_identified", IDENTIFIED_RANGE_M), ("x_limit", DEVICE_LIMIT_M)):
        value = run.value(unit, name) if unit is not None else None
        ok = isinstance(value, int | float) and not isinstance(value, bool) and value > 0
        out.append(float(value) if ok else default)
    return out[0], out[1]


def physical_outcome(spec: BuildingReport, rec: Recorder, run: RunDescription) -> dict[str, Any]:
    """The run's physical outcome, a result and not a defect: the base's time beyond the isolator's identified
    range and at or beyond its device limit (the run's ``x_identified``, ``x_limit``), the peak force, and the
    law beyond the range (``beyond_range``: 'stop' is a stop at the limit)."""
    out: dict[str, Any] = {}
    dt = sample_interval(rec)
    if spec.base_displacement is not None:
        x = np.abs(rec.column(str(spec.base_displacement)))
        identified, limit = _isolator_limits(spec, run)
        out.update(peak_base_displacement_m=peak(x), identified_range_m=identified,
                   time_beyond_identified_range_s=float(np.sum(x > identified) * dt), device_limit_m=limit,
                   time_at_device_limit_s=float(np.sum(x >= limit) * dt))
    if spec.isolator_force is not None:
        out["peak_isolator_force_N"] = peak(rec.column(str(spec.isolator_force)))
        law = run.value(spec.isolator_force.unit, "beyond_range")
        if isinstance(law, str):
            out["beyond_range"] = law
    return out


def _cumulative_work(force: np.ndarray, x: np.ndarray, held: np.ndarray | None = None) -> np.ndarray:
    """integral F dx over the samples (trapezoidal rule), from 0 at the first sample [J].

    ``held``: the piecewise-constant input the force depends on (the device current, when the master holds it:
    a discrete output or one of a unit with its own step), recorded like the force,
    as the value applied over the step that ends at each sample. Where it changes at t_k, F jumps there and the
    recorded F(t_k) is the value before the jump; the step from t_k then starts from F(t_k+), estimated by the
    line back from the step's two following samples when the input stays constant over both (second order, as
    the trapezoid), else by the step's end value."""
    start = force[:-1].copy()
    if held is not None and len(force) > 2:
        jump = np.flatnonzero(held[1:] != held[:-1])  # step k (t_k -> t_k+1) runs at another input than step k-1
        jump = jump[jump > 0]
        line = jump[jump + 2 < len(force)]
        line = line[held[line + 2] == held[line + 1]]
        start[jump] = force[jump + 1]
        start[line] = 2.0 * force[line + 1] - force[line + 2]
    return np.concatenate([[0.0], np.cumsum(0.5 * (force[1:] + start) * np.diff(x))])


def _fraction(value: float, of: float) -> float | None:
    return float(value / of) if of > 0 and math.isfinite(value / of) else None


def energy_section(spec: BuildingReport, rec: Recorder, run: RunDescription
                   ) -> tuple[dict[str, Any] | None, list[str]]:
    """The run's energy balance [J] from what the units exchanged, and the reasons it makes the run invalid.

    From the building's integrals (:data:`ENERGY_NAMES`, what it integrated with the inputs it held):
    the relative input energy E_in (Uang & Bertero 1990), damping, strain and kinetic energy at the end,
    hysteretic work, and the isolators' work twice: with the force the building integrated
    (``isolator_J``) and with the isolator's own force over the displacement it was given
    (``isolator_own_J``: the trapezoid of its output F over the recorded base displacement, each step after a jump
    of the device current starting from the force after the jump, see :func:`_cumulative_work`). Their
    difference is the coupling's energy error; ``residual_J`` = E_in - (kinetic + strain + damping +
    hysteretic + isolators') closes the building's own books. Fractions are of the input energy at the end;
    the ``max_*_fraction`` of the largest |value| over the run against the largest |E_in| so far, which is
    what :attr:`BuildingReport.energy_tolerance` bounds. A building without these integrals (the OpenSees
    unit): ``{"checked": false, ...}``, no reason.
    """
    if spec.base_displacement is None:
        return None, []
    unit = spec.base_displacement.unit
    names = [f"{unit}.{name}" for name in ENERGY_NAMES]
    if not all(name in rec.names for name in names) or rec.count < 1:
        return {"checked": False, "note": f"not checked: {unit} ({run.model_names.get(unit, '?')}) gives no energy "
                                          f"integrals ({', '.join(ENERGY_NAMES)}): its internal energy cannot be "
                                          "known from its outputs"}, []
    e_in, e_iso, e_damp, e_strain, e_hyst, e_kin = (np.asarray(rec.column(n), dtype=float) for n in names)
    residual = e_in - (e_kin + e_strain + e_damp + e_hyst + e_iso)
    scale = float(np.max(np.abs(e_in)))
    tol = float(spec.energy_tolerance)
    out: dict[str, Any] = {
        "checked": True, "input_J": float(e_in[-1]), "damping_J": float(e_damp[-1]), "strain_J": float(e_strain[-1]),
        "kinetic_J": float(e_kin[-1]), "hysteretic_J": float(e_hyst[-1]), "isolator_J": float(e_iso[-1]),
        "isolator_share": _fraction(float(e_iso[-1]), float(e_in[-1])),
        "residual_J": float(residual[-1]), "residual_fraction": _fraction(float(residual[-1]), float(e_in[-1])),
        "max_residual_fraction": _fraction(float(np.max(np.abs(residual))), scale), "tolerance": tol}
    reasons = []
    worst = out["max_residual_fraction"]
    if worst is not None and worst > tol:
        at = float(rec.times[int(np.argmax(np.abs(residual)))])
        reasons.append(f"energy balance does not close: residual up to {100 * worst:.3g} % of the input energy "
                       f"(at t = {at:.6g} s; tolerance {100 * tol:g} %, report.energy_tolerance)")
    if spec.isolator_force is not None:
        device = spec.device_current or spec.current
        held = np.asarray(rec.column(str(device)), dtype=float) \
            if device is not None and str(device) in run.held and str(device) in rec.names else None
        own = _cumulative_work(np.asarray(rec.column(str(spec.isolator_force)), dtype=float),
                               np.asarray(rec.column(str(spec.base_displacement)), dtype=float), held)
        error = e_iso - own
        out.update(isolator_own_J=float(own[-1]), coupling_error_J=float(error[-1]),
                   coupling_error_fraction=_fraction(float(error[-1]), float(e_in[-1])),
                   max_coupling_error_fraction=_fraction(float(np.max(np.abs(error))), scale))
        worst = out["max_coupling_error_fraction"]
        if worst is not None and worst > tol:
            at = float(rec.times[int(np.argmax(np.abs(error)))])
            reasons.append(f"coupling energy error: the force {unit} integrated did {e_iso[-1]:.4g} J of work on the "
                           f"isolators, their own force {own[-1]:.4g} J; the difference reaches {100 * worst:.3g} % "
                           f"of the input energy (at t = {at:.6g} s; tolerance {100 * tol:g} %, "
                           "report.energy_tolerance)")
    else:
        out["coupling_error_J"] = None
        out["coupling_note"] = "not checked: the report names no isolator_force"
    if not math.isfinite(scale) or not np.all(np.isfinite(residual)):
        reasons.append("energy balance not finite")
    return out, reasons


def step_changes(coarse: dict[str, Any], fine: dict[str, Any]) -> dict[str, float]:
    """Relative change of each peak of a run's summary (the hook's roles) in the run with the plant's step halved:
    fine / coarse - 1 per ``name`` (a role) or ``name[variable]`` (roles with several variables)."""
    out: dict[str, float] = {}
    for key in ("peak_base_displacement_m", "peak_drift_m", "peak_abs_acceleration_m_s2", "peak_isolator_force_N"):
        a, b = coarse.get(key), fine.get(key)
        pairs = [(key, a, b)] if not isinstance(a, dict) else [
            (f"{key}[{name}]", a[name], (b or {}).get(name)) for name in a]
        for name, x, y in pairs:
            if isinstance(x, int | float) and isinstance(y, int | float) and x:
                out[name] = float(y / x - 1)
            else:
                out[name] = math.nan
    return out


REPORT = ReportHook(BuildingReport, summarize, plot)
"""The isolated building's report hook (see the module docstring)."""
