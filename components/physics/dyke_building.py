"""The paper's case-study building: the Dyke et al. (1996) three-storey model (Table 3 of the paper) on a base floor.

The one place of these numbers in the product: the building unit (``shear_building_core``), the controllers'
model of the building (``lqg_plant_core``) and the isolator's stop (``mre_isolator_core``: the isolated mass)
import them. Constants only, no dependency: the pure-Python isolator FMU carries this module too.

Source: Dyke, Spencer, Sain and Carlson (1996), "Modeling and control of magnetorheological dampers for seismic
response reduction", Smart Mater. Struct. 5, 565-575. SI units.
"""

from __future__ import annotations

DYKE_MASSES = (98.3, 98.3, 98.3)  # kg, floors 1..3
DYKE_STIFFNESSES = (516e3, 684e3, 684e3)  # N/m, storeys 1..3
DYKE_DAMPINGS = (125.0, 50.0, 50.0)  # N*s/m, storeys 1..3
# Assumption (the paper gives no base floor, docs/assumptions.md): a base slab like a floor, no spring or
# dashpot to the ground besides the isolators.
BASE_MASS = 98.3  # kg
BASE_STIFFNESS = 0.0  # N/m
BASE_DAMPING = 0.0  # N*s/m

# This module's source as loaded: several FMUs carry it and share one interpreter (the copy loaded first serves
# them all), and the FMU folder it came from may be gone when another FMU compares it with its own copy.
with open(__file__, "rb") as _source:
    LOADED_SOURCE = _source.read()
