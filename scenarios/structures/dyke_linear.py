"""OpenSees model of the paper's building, linear: the Dyke et al. (1996) three-storey model
(Table 3 of the paper) on a 98.3 kg base floor, as the ShearBuilding unit has it
(components/physics/shear_building_core.py, BuildingParams.dyke()).

A model script for the OpenSeesBuilding unit (convention: components/physics/opensees_building_core.py,
docs/structures.md "OpenSees unit"). SI units. One DOF per node (horizontal); node 0 is the ground,
node 1 the base floor (carried by the isolators alone: no spring or dashpot to the ground),
nodes 2-4 floors 1-3. Storey j is a zeroLength element between levels j-1 and j with an Elastic
material of stiffness k_j [N/m] and damping coefficient eta = c_j [N*s/m] (its stress is
k_j * drift + c_j * drift rate, the shear building's storey force).
"""

import openseespy.opensees as ops

MASSES = (98.3, 98.3, 98.3, 98.3)  # kg: base floor, floors 1..3
STIFFNESSES = (516e3, 684e3, 684e3)  # N/m, storeys 1..3
DAMPINGS = (125.0, 50.0, 50.0)  # N*s/m, storeys 1..3

GROUND = 0
BASE_NODE = 1
FLOOR_NODES = [2, 3, 4]
LINEAR = True

ops.model("basic", "-ndm", 1, "-ndf", 1)
ops.node(GROUND, 0.0)
ops.fix(GROUND, 1)
for tag, m in zip([BASE_NODE, *FLOOR_NODES], MASSES, strict=True):
    ops.node(tag, 0.0)
    ops.mass(tag, m)
levels = [BASE_NODE, *FLOOR_NODES]
for j, (k, c) in enumerate(zip(STIFFNESSES, DAMPINGS, strict=True), start=1):
    ops.uniaxialMaterial("Elastic", j, k, c)
    ops.element("zeroLength", j, levels[j - 1], levels[j], "-mat", j, "-dir", 1)
