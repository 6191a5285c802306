"""A minimal fmpy driver for per-FMU tests (independent of the project's master)."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave


class Driven:
    """One FMU instance driven through fmpy's FMU2Slave: parameters, init, set/get/step by name."""

    def __init__(self, path: Path, name: str, parameters: dict[str, Any] | None = None, start: float = 0.0):
        self.md = read_model_description(str(path))
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.dir = extract(str(path))
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate(loggingOn=True)
        self.closed = False
        try:
            for key, value in (parameters or {}).items():
                self.set_any(key, value)
            self.fmu.setupExperiment(startTime=start)
            self.fmu.enterInitializationMode()
            self.fmu.exitInitializationMode()
        except Exception:
            self.close(terminate=False)
            raise

    def set_any(self, name: str, value: Any) -> None:
        var = self.vars[name]
        setter = {"Real": self.fmu.setReal, "Integer": self.fmu.setInteger,
                  "Boolean": self.fmu.setBoolean, "String": self.fmu.setString}[var.type]
        setter([var.valueReference], [value])

    def set(self, **values: float) -> None:
        self.fmu.setReal([self.vars[k].valueReference for k in values], list(values.values()))

    def get(self, *names: str) -> list[float]:
        return self.fmu.getReal([self.vars[k].valueReference for k in names])

    def step(self, t: float, h: float) -> None:
        self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)

    def outputs(self) -> list[str]:
        return [v.name for v in self.md.modelVariables if v.causality == "output"]

    def close(self, terminate: bool = True) -> None:
        if self.closed:
            return
        self.closed = True
        try:
            if terminate:
                self.fmu.terminate()
        finally:
            self.fmu.freeInstance()
            shutil.rmtree(self.dir, ignore_errors=True)
