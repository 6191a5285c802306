"""The smart base-isolated benchmark's criteria J1...J9 and the control effort, from a run's recorded series.

Source: S. Narasimhan, S. Nagarajaiah, E. A. Johnson, H. P. Gavin, "Smart base-isolated benchmark
building. Part I: problem definition", *Struct. Control Health Monit.* 13 (2006) 573-588. Each
criterion there is the controlled value over the uncontrolled one; here the baseline is a strategy
of the study (passive-off by default, passive-on as a second table). Adapted to this building (a base
floor, level 0, and storeys 1...n; masses m_j [kg]); every quantity in SI, t the recorded times [s],
T = t_end - t_0, integrals by the trapezoidal rule over the recorded samples:

| criterion | raw value (:func:`raw_criteria`) |
|---|---|
| J1 peak base shear | max_t abs(V_b), V_b = sum_{j=0..n} m_j a_j: inertia forces of every level, base included [N] |
| J2 peak first-storey shear | max_t abs(shear_1): the structural shear above the base floor [N] |
| J3 peak base displacement | max_t abs(x_0), relative to the ground [m] |
| J4 peak inter-storey drift | max_j max_t abs(drift_j), j = 1..n [m] (not divided by storey heights) |
| J5 peak absolute floor acceleration | max_j max_t abs(a_j), j = 1..n, floors above the base [m/s^2] |
| J6 peak controllable force | max_t abs(F - F_off), the isolators together, F_off the force at 0 A along |
|  | the same motion (the isolator's output ``F_off``; NaN for an isolator without it) [N] |
| J7 RMS base displacement | sqrt((1/T) integral x_0^2 dt) [m] |
| J8 RMS absolute floor acceleration | max_j sqrt((1/T) integral a_j^2 dt), j = 1..n [m/s^2] |
| J9 energy share | E_d / E_in [-], E_d = integral F v_0 dt (work of the isolators, dissipated plus stored at T), |
|  | E_in = -integral ag sum_{j=0..n} m_j v_j dt (relative input energy, Uang & Bertero 1990) [J], |
|  | both from the run's energy section (summary.json ``energy``: what the building integrated, exact for |
|  | the inputs it held over each step; not a trapezoid of sampled F v_0, which misses the force inside a |
|  | step); NaN where the building's energy is not checked (the OpenSees unit) |

Differences from the benchmark paper: J4 uses the drift in metres (the ratio is the same as the paper's
drift ratio for a storey of any height, but the storey that is largest may differ with unequal heights);
the paper's J6 divides the peak device force by the controlled run's own peak base shear. With nothing but
the isolators between the base and the ground that ratio is 1 to rounding (V_b = -F), so here J6 is the peak
force the current controls, over passive-on's (:data:`J6_REFERENCE`: passive-off's is zero): the share of the
device's controllable force a strategy uses. J9 is the energy share over the baseline's share.

Control effort: mean current (1/T) integral i dt [A], coil heat per ohm integral i^2 dt [A^2 s] and
mean rate (1/T) sum abs(delta i) = mean abs(di/dt) [A/s].
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

CRITERIA = ("J1", "J2", "J3", "J4", "J5", "J6", "J7", "J8", "J9")
J6_REFERENCE = "passive-on"  # the default of a benchmark's j6_reference: J6 is over this strategy's peak controllable
# force on the same record
FORCE_OFF = "isolator.F_off"  # the isolator's force at 0 A along the run's motion (J6), as the runs record it
EFFORT = ("mean_current_A", "joule_A2s", "switching_rate_A_s")
NAMES = {"J1": "peak base shear", "J2": "peak first-storey shear", "J3": "peak base displacement",
         "J4": "peak inter-storey drift", "J5": "peak absolute floor acceleration", "J6": "peak controllable force",
         "J7": "RMS base displacement", "J8": "RMS absolute floor acceleration",
         "J9": "energy the devices take / energy the ground puts in"}
Series = Mapping[str, np.ndarray]


def j6_reference(config: Mapping[str, Any]) -> str:
    """The strategy J6 is over in a study (its config's ``benchmark.j6_reference``; :data:`J6_REFERENCE` by
    default, and for a study written before the key existed)."""
    return (config.get("benchmark") or {}).get("j6_reference") or J6_REFERENCE


def integral(t: np.ndarray, y: np.ndarray) -> float:
    """Trapezoidal integral of y over the samples t."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t))) if len(t) > 1 else 0.0


def rms(t: np.ndarray, y: np.ndarray) -> float:
    """Root mean square over the record: sqrt((1/T) integral y^2 dt)."""
    span = float(t[-1] - t[0]) if len(t) > 1 else 0.0
    return math.sqrt(integral(t, np.asarray(y, float) ** 2) / span) if span > 0 else math.nan


def peak(y: np.ndarray) -> float:
    """max abs(y)."""
    return float(np.max(np.abs(y))) if len(y) else math.nan


def _levels(series: Series, prefix: str) -> list[int]:
    return sorted(int(k.rsplit("_", 1)[1]) for k in series if k.startswith(prefix) and k.rsplit("_", 1)[1].isdigit())


def raw_criteria(series: Series, masses: Sequence[float], energy: Mapping[str, Any] | None = None
                 ) -> dict[str, float]:
    """The raw values of J1...J9 (see the module's table) of one run's series, SI; J9 from its ``energy``
    section (:func:`energy_share`)."""
    t = np.asarray(series["time"], float)
    floors = [j for j in _levels(series, "building.a_") if j > 0]
    storeys = _levels(series, "building.drift_")
    acc = {j: np.asarray(series[f"building.a_{j}"], float) for j in [0, *floors]}
    if len(masses) != len(acc):
        raise ValueError(f"{len(masses)} masses for {len(acc)} levels")
    base_shear = sum(m * acc[j] for j, m in enumerate(masses))
    out = {
        "J1": peak(base_shear),
        "J2": peak(series["building.shear_1"]),
        "J3": peak(series["building.x_0"]),
        "J4": max(peak(series[f"building.drift_{j}"]) for j in storeys),
        "J5": max(peak(acc[j]) for j in floors),
        "J6": controllable_force(series),
        "J7": rms(t, series["building.x_0"]),
        "J8": max(rms(t, acc[j]) for j in floors),
    }
    out["J9"] = energy_share(energy)
    return out


def controllable_force(series: Series) -> float:
    """max_t abs(F - F_off) [N]: the peak force the current adds to the device's force at 0 A; NaN without
    ``isolator.F_off`` in the series (an isolator FMU that does not give it)."""
    if FORCE_OFF not in series:
        return math.nan
    return peak(np.asarray(series["isolator.F"], float) - np.asarray(series[FORCE_OFF], float))


def energy_share(energy: Mapping[str, Any] | None) -> float:
    """E_d / E_in: the isolators' work (with the force the building integrated) over the relative input energy,
    from a run's energy section; NaN where it was not checked."""
    if not energy or not energy.get("checked"):
        return math.nan
    e_d, e_in = energy.get("isolator_J"), energy.get("input_J")
    if not isinstance(e_d, int | float) or not isinstance(e_in, int | float) or e_in == 0:
        return math.nan
    return float(e_d / e_in)


def effort(t: np.ndarray, i: np.ndarray) -> dict[str, float]:
    """Mean current [A], integral of i^2 [A^2 s] and mean abs(di/dt) [A/s] over the record."""
    t, i = np.asarray(t, float), np.asarray(i, float)
    span = float(t[-1] - t[0]) if len(t) > 1 else 0.0
    if span <= 0:
        return dict.fromkeys(EFFORT, math.nan)
    return {"mean_current_A": integral(t, i) / span, "joule_A2s": integral(t, i ** 2),
            "switching_rate_A_s": float(np.sum(np.abs(np.diff(i)))) / span}


def normalised(raw: Mapping[str, float], baseline: Mapping[str, float],
               j6_reference: Mapping[str, float] | None = None) -> dict[str, float]:
    """J1...J9: each raw value over the baseline's, J6 over ``j6_reference``'s (:data:`J6_REFERENCE`'s run on
    the same record; NaN where the divisor is 0 or missing)."""
    out = {}
    for k in CRITERIA:
        a = raw.get(k, math.nan)
        b = (j6_reference or {}).get(k, math.nan) if k == "J6" else baseline.get(k, math.nan)
        out[k] = a / b if (math.isfinite(a) and math.isfinite(b) and b != 0) else math.nan
    return out
