"""FMI 2.0 co-simulation shell of the measurement channels (sensor noise and delay), sensor_channels_core.

Channels by quantity, each an input ``u_<q>_<k>`` and an output ``y_<q>_<k>`` in the SI unit of
its quantity, and a parameter ``rms_<q>_<k>``: the noise RMS in that unit (0: none). Quantities:
``disp`` [m] (2 channels), ``vel`` [m/s] (2), ``acc`` [m/s2] (6), ``force`` [N] (2). Parameters
``delay`` [communication steps] and ``seed``. Every output depends directly on its own input
(delay 0: y = u + noise at the same instant); with delay >= 1 the output is the sample the
unit was stepped from ``delay`` steps before, so connect its inputs ``delayed: true`` then.
"""

from __future__ import annotations

import copy
import math
import sys

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status

try:
    from sensor_channels_core import SensorChannels as ChannelsCore
except ImportError as exc:  # the host's Python lacks numpy: say so (the build's logging shim shows it)
    raise ImportError(f"the SensorChannels unit needs the Python package numpy in the host's interpreter "
                      f"({sys.executable}): {exc}") from exc

FMU_CORE_MODULES = ("sensor_channels_core",)
FMU_REQUIREMENTS: tuple[str, ...] = ("numpy",)  # besides Python >= 3.11
FMU_FAILED_STEP_STATUS = "error"  # a do_step that returns False (an error it logged) is fmi2Error

UNIT = "SensorChannels"
QUANTITIES = (("disp", "m", 2, "displacement"), ("vel", "m/s", 2, "velocity"), ("acc", "m/s2", 6, "acceleration"),
              ("force", "N", 2, "force"))
CHANNELS = tuple(f"{q}_{k}" for q, _, n, _ in QUANTITIES for k in range(1, n + 1))


class SensorChannels(Fmi2Slave):
    """Pass-through measurement channels with seeded Gaussian noise of stated RMS and a delay in steps."""

    description = "Measurement channels: seeded Gaussian sensor noise of stated RMS and a delay in communication steps"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._slave_attrs = frozenset(vars(self)) | {"_slave_attrs"}
        self.delay = 0
        self.seed = 0
        self._core: object | None = None
        self._failed = ""
        self._started = False
        self.fmi_units = {}
        self.fmi_dependencies = {}
        inp = {"causality": Fmi2Causality.input, "variability": Fmi2Variability.continuous}
        par = {"causality": Fmi2Causality.parameter, "variability": Fmi2Variability.fixed}
        out = {"causality": Fmi2Causality.output, "variability": Fmi2Variability.continuous}
        self.register_variable(Integer("delay", description="measurement delay in communication steps (>= 0)", **par))
        self.register_variable(Integer("seed", description="seed of the noise (0 ... 2^31 - 1)", **par))
        for k, name in enumerate(CHANNELS):
            q = name.rsplit("_", 1)[0]
            unit, what = next((u, w) for qq, u, _, w in QUANTITIES if qq == q)
            setattr(self, f"u_{name}", 0.0)
            setattr(self, f"rms_{name}", 0.0)
            self.register_variable(Real(f"u_{name}", description=f"measured {what}, channel {name}", **inp))
            self.register_variable(Real(f"rms_{name}", description=f"noise RMS of channel {name} (0: none)", **par))
            self.register_variable(Real(f"y_{name}", description=f"{what} as the controller reads it, channel {name}",
                                        getter=lambda k=k: self._output(k), **out))
            self.fmi_units.update({f"u_{name}": unit, f"rms_{name}": unit, f"y_{name}": unit})
            self.fmi_dependencies[f"y_{name}"] = (f"u_{name}",)

    def _inputs(self) -> list[float]:
        return [getattr(self, f"u_{name}") for name in CHANNELS]

    def _output(self, k: int) -> float:
        if self._core is None:
            return getattr(self, f"u_{CHANNELS[k]}") if not self._failed else math.nan
        return float(self._core.outputs(self._inputs())[k])

    def exit_initialization_mode(self):
        # Problems are logged and fail the first step: an exception here would be fmi2Fatal.
        try:
            self._core = ChannelsCore([getattr(self, f"rms_{n}") for n in CHANNELS], self.delay, self.seed)
            self._core.start(self._inputs())
        except ValueError as exc:
            self._core = None
            self._failed = f"{UNIT}: invalid parameter: {exc}"
            self.log(self._failed, Fmi2Status.error)

    def do_step(self, current_time: float, step_size: float) -> bool:
        if self._failed:
            self.log(self._failed, Fmi2Status.error)
            return False
        u = self._inputs()
        if not all(math.isfinite(x) for x in u):
            bad = next(n for n, x in zip(CHANNELS, u, strict=True) if not math.isfinite(x))
            self.log(f"{UNIT}: input u_{bad} is not finite at t = {current_time:.6g} s", Fmi2Status.error)
            return False
        self._core.step(u)
        return True

    # FMU state (fmi2GetFMUstate/fmi2SetFMUstate): every instance attribute the shell added.
    def _get_fmu_state(self) -> dict:
        return {k: copy.deepcopy(v) for k, v in vars(self).items() if k not in self._slave_attrs}

    def _set_fmu_state(self, state: dict) -> None:
        vars(self).update(copy.deepcopy(state))
