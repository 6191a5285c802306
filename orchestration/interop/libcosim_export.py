"""Running an exported SSP package in the Open Simulation Platform's libcosim (PyPI ``libcosimpy``).

libcosim's fixed-step algorithm, per communication step from t to t + h:

1. every simulator, on its own worker thread, sets the input values it holds, calls
   ``fmi2DoStep(t, h)`` and reads its outputs;
2. then the outputs are copied to the connected inputs, which the units see at their next step.

So an output read after a step is computed from the inputs of t: a direct-feedthrough
output (the isolator force ``F`` from ``x``, ``v``, ``i``; the building's accelerations from
``ag`` and ``F``) carries the state at t + h but the inputs at t. Our master's Jacobi
scheme instead re-evaluates feedthrough outputs with the inputs at t + h after the step
(feedthrough propagation), so the two differ by design, at first order in h.

Our master reproduces libcosim's scheme exactly when every connection is ``delayed``
(nothing is propagated within a communication point) and the algorithm is Jacobi:
:func:`libcosim_scheme`. That is what the cross-check compares, to 1e-9.

pythonfmu units in libcosim's worker threads: every FMI call of a pythonfmu FMU takes the
GIL (``PyGILState_Ensure``) and libcosimpy calls libcosim through ``ctypes.CDLL``, which
releases the GIL, so the Python units step one at a time and do not deadlock.
"""

from __future__ import annotations

import contextlib
import copy
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from orchestration.master.graph import Port
from orchestration.master.scenario import LoadedScenario

NANOSECONDS = 1_000_000_000


def libcosim_scheme(loaded: LoadedScenario) -> LoadedScenario:
    """The same scenario coupled the way libcosim's fixed-step algorithm couples it: Jacobi, all connections delayed."""
    sc = loaded.scenario
    connections = [c.model_copy(update={"delayed": True}) for c in sc.connections]
    update: dict[str, object] = {"algorithm": "jacobi", "order": None}
    if "inputs" in type(sc.simulation).model_fields:  # hold the latest value (delayed links do anyway)
        update["inputs"] = "hold"
    simulation = sc.simulation.model_copy(update=update)
    derived = copy.copy(loaded)  # same class and files (a LoadedSsp keeps its extracted package)
    derived.scenario = sc.model_copy(update={"connections": connections, "simulation": simulation})
    derived.parent = loaded  # keeps the original, and so an extracted package, alive
    return derived


def libcosim_available() -> str | None:
    """None if libcosimpy imports and loads its library, else the reason it does not."""
    try:
        from libcosimpy._internal import libcosimc

        libcosimc()
    except Exception as exc:  # ImportError, OSError from the shared library
        return f"libcosimpy is not usable: {type(exc).__name__}: {exc}"
    return None


@dataclass
class LibcosimRun:
    """Time series recorded by libcosim: one row per communication point (the initial one too).

    A unit with its own step (``osp:StepSizeHint``) is sampled by libcosim at its own steps only;
    its values are held over the base steps in between (the value of its last step).
    """

    times: np.ndarray
    names: list[str]
    data: np.ndarray

    def column(self, name: str) -> np.ndarray:
        """Samples of ``unit.variable``."""
        return self.data[:, self.names.index(name)]


def _samples(observer, slave: int, ref: int, first: int, count: int) -> tuple[list[int], list[int], list[float]]:
    times, steps, values = observer.time_series_real_samples(slave, ref, from_step=first, sample_count=count)
    return list(times), list(steps), list(values)


def run_libcosim(
    package: Path, workdir: Path, ports: list[Port], step: float, stop_time: float, start_time: float = 0.0
) -> LibcosimRun:
    """Run an ``.ssp`` in libcosim (its own SSP loader reads the SSD and the .ssv parameter sets).

    The package is extracted into ``workdir`` and libcosim runs with that folder as the
    working directory, so the package-relative data files the parameter sets name
    (``resources/<record>``) resolve. ``ports`` are the Real outputs to record. The start
    time is the package's (DefaultExperiment); ``start_time`` must agree with it.
    """
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    workdir = Path(workdir)
    with zipfile.ZipFile(package) as z:
        z.extractall(workdir)
    step_ns = round(step * NANOSECONDS)
    if abs(step_ns / NANOSECONDS - step) > 1e-15 * step:
        raise ValueError(f"step {step} s is not a whole number of nanoseconds (libcosim's time unit)")
    n_steps = round((stop_time - start_time) / step)
    log_output_level(CosimLogLevel.ERROR)
    with contextlib.chdir(workdir):
        execution = CosimExecution.from_ssp_file(str(workdir / "SystemStructure.ssd"), step_size=step_ns)
        slaves = {info.name.decode(): info.index for info in execution.slave_infos()}
        refs = {}
        for unit, index in slaves.items():
            for var in execution.slave_variables(index):
                refs[(unit, var.name.decode())] = var.reference
        observer = CosimObserver.create_time_series(buffer_size=n_steps + 16)
        execution.add_observer(observer)
        for port in ports:
            if not observer.start_time_series(slaves[port[0]], refs[port], CosimVariableType.REAL):
                raise RuntimeError(f"libcosim cannot observe {port[0]}.{port[1]}")
        if not execution.simulate_until(round(start_time * NANOSECONDS) + n_steps * step_ns):
            from libcosimpy._internal import get_last_error_message

            raise RuntimeError(f"libcosim simulation failed: {get_last_error_message()}")
    data = np.empty((n_steps + 1, len(ports)))
    times = None
    for k, port in enumerate(ports):
        slave, ref = slaves[port[0]], refs[port]
        # libcosimpy trims its sample arrays by counting step numbers equal to 0, which drops
        # the last real sample whenever step 0 is among them: read steps 0..n-1, then step n.
        t, steps, values = _samples(observer, slave, ref, 0, n_steps + 1)
        t_last, steps_last, values_last = _samples(observer, slave, ref, n_steps, 1)
        t, steps, values = t + t_last, steps + steps_last, values + values_last
        stride = steps[1] - steps[0] if len(steps) > 1 else 1
        if stride < 1 or steps != list(range(0, n_steps + 1, stride)):
            raise RuntimeError(f"libcosim returned steps {steps[:3]}...{steps[-3:]} for {port}, expected 0..{n_steps}")
        # a unit with its own step (decimation factor) is sampled at its own steps: held in between
        data[:, k] = np.repeat(values, stride)[: n_steps + 1]
        if stride == 1:
            times = np.asarray(t, dtype=np.int64)
    return LibcosimRun(times / NANOSECONDS, [f"{u}.{v}" for u, v in ports], data)
