"""OpenSees model of the paper's building with yielding storeys: the Dyke et al. (1996)
three-storey model (Table 3 of the paper) on a 98.3 kg base floor, each storey a Steel01
force-drift law (OpenSees' bilinear kinematic-hardening material, Filippou et al. 1983)
with E0 = k_j, Fy = fy_j and b = b_j, in parallel with its dashpot c_j.

A model script for the OpenSeesBuilding unit (convention: components/physics/opensees_building_core.py,
docs/structures.md "OpenSees unit"). SI units. Steel01 is given without its isotropic-hardening
parameters a1..a4, so their defaults (0, 1, 0, 1: no isotropic hardening) apply; four literal
zeros would give a2 = a4 = 0, which is not "off" and silently changes the forces.

Yield shears fy_j = 500, 380, 200 N: about 2/3 of the linear building's peak storey shears on
El Centro x 0.5 under SOSM control (784, 568, 297 N), so that the storeys yield on the paper's
records (measured peak drift / yield drift: 3.6, 1.1, 1.4 on El Centro x 0.5; 10.7, 6.8, 6.0 on
Kobe x 0.25); post-yield stiffness ratio b_j = 0.05. They are module-level values (read by the tests
that compare this model with ShearBuilding's bilinear storeys): copy the file to change them.
"""

import openseespy.opensees as ops

MASSES = (98.3, 98.3, 98.3, 98.3)  # kg: base floor, floors 1..3
STIFFNESSES = (516e3, 684e3, 684e3)  # N/m, storeys 1..3 (Steel01 E0)
DAMPINGS = (125.0, 50.0, 50.0)  # N*s/m, storeys 1..3
YIELD_SHEARS = (500.0, 380.0, 200.0)  # N, storeys 1..3 (Steel01 Fy)
HARDENING = (0.05, 0.05, 0.05)  # post-yield stiffness ratio b, storeys 1..3

GROUND = 0
BASE_NODE = 1
FLOOR_NODES = [2, 3, 4]

ops.model("basic", "-ndm", 1, "-ndf", 1)
ops.node(GROUND, 0.0)
ops.fix(GROUND, 1)
for tag, m in zip([BASE_NODE, *FLOOR_NODES], MASSES, strict=True):
    ops.node(tag, 0.0)
    ops.mass(tag, m)
levels = [BASE_NODE, *FLOOR_NODES]
for j, (k, c, fy, b) in enumerate(zip(STIFFNESSES, DAMPINGS, YIELD_SHEARS, HARDENING, strict=True), start=1):
    ops.uniaxialMaterial("Steel01", 10 + j, fy, k, b)  # a1..a4 left out: defaults 0, 1, 0, 1
    ops.uniaxialMaterial("Elastic", 20 + j, 0.0, c)  # the storey's dashpot
    ops.element("zeroLength", j, levels[j - 1], levels[j], "-mat", 10 + j, 20 + j, "-dir", 1, 1)
