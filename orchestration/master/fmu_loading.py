"""Loading an FMU's library: the archive extracted (within limits) and opened with fmpy."""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path
from typing import Any

from orchestration.master.errors import SimulationError
from orchestration.master.fmu_description import model_identifier, open_fmu
from orchestration.master.safe_archive import safe_extract


def load_slave(slave_class: Any, path: Path, md: Any, name: str, start_time: float,
               interface: str = "co-simulation") -> tuple[str, Any]:
    """Extract an FMU and load the library of its ``interface`` as fmpy's ``slave_class`` (FMU2Slave, FMU2Model or
    FMU3Slave)."""
    directory = None
    try:
        directory = tempfile.mkdtemp(prefix="cosim_fmu_")
        with open_fmu(Path(path)) as z:
            safe_extract(z, directory, path)
        slave = slave_class(guid=md.guid, unzipDirectory=directory,
                            modelIdentifier=model_identifier(md, interface), instanceName=name)
    except Exception as exc:
        if directory is not None:
            shutil.rmtree(directory, ignore_errors=True)
        raise SimulationError(f"cannot load FMU {path}: {exc}", unit=name, time=start_time) from exc
    return directory, slave
