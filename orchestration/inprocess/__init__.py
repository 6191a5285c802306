"""In-process units over the physics cores, stepped by the engine's own coupling algorithm.

The fast path for tuning, base sensitivity and any study that evaluates the isolated building
many times: :func:`simulate_coupled` runs the system of a
:class:`~components.physics.monolithic.SystemSetup` with
:class:`~orchestration.master.algorithm.CouplingAlgorithm`, the algorithm a scenario run uses
for its FMUs, with the physics cores behind the engine's :class:`~orchestration.master.unit.Unit`
interface (:mod:`orchestration.inprocess.units`).

Layer: imports the engine (``orchestration.master``) and ``components.physics``; the engine
never imports it.
"""

from orchestration.inprocess.isolated_building import CONNECTIONS, build_units, simulate_coupled
from orchestration.inprocess.units import GroundMotionUnit, MreIsolatorUnit, ShearBuildingUnit, SosmControllerUnit

__all__ = ["CONNECTIONS", "GroundMotionUnit", "MreIsolatorUnit", "ShearBuildingUnit", "SosmControllerUnit",
           "build_units", "simulate_coupled"]
