"""A model script (tests only) whose transient analysis genuinely fails to converge once storey 1 yields.

The Dyke building of scenarios/structures/dyke_linear.py (Table 3 of the paper, on its 98.3 kg base floor),
except storey 1: two springs in series through a massless hinge node. An elastic spring of stiffness
1.5 k_1 and a Steel01 spring with E0 = 3 k_1 (together k_1, the Dyke storey while both are elastic),
Fy = FY_1 and a negative post-yield ratio b = -0.6, so after yield the Steel01 spring softens with the
tangent b E0 = -1.8 k_1, steeper than the elastic spring's 1.5 k_1. The hinge node then has a negative
stiffness and no mass or damping: the storey snaps back (its force-drift curve turns back on itself), so
near the drift the floors impose there is no equilibrium of the hinge, and OpenSees' Newton iterations
cannot meet their tolerance (CTestNormDispIncr: "failed to converge after: 25 iterations"). The storey's
dashpot c_1 acts between the base and floor 1, beside the springs, not on the hinge.

Read by tests/interop/test_opensees_building.py; a model that fails on purpose, not a shipped scenario.
"""

import openseespy.opensees as ops

MASSES = (98.3, 98.3, 98.3, 98.3)  # kg: base floor, floors 1..3
STIFFNESSES = (516e3, 684e3, 684e3)  # N/m, storeys 1..3
DAMPINGS = (125.0, 50.0, 50.0)  # N*s/m, storeys 1..3
FY_1 = 400.0  # N: storey 1's Steel01 yield force (its linear peak shear on El Centro x 0.5, SOSM: 784 N)
SOFTENING = -0.6  # Steel01 post-yield stiffness ratio b (negative: the spring loses strength)

GROUND = 0
BASE_NODE = 1
FLOOR_NODES = [2, 3, 4]
HINGE = 9  # massless node inside storey 1

ops.model("basic", "-ndm", 1, "-ndf", 1)
ops.node(GROUND, 0.0)
ops.fix(GROUND, 1)
for tag, m in zip([BASE_NODE, *FLOOR_NODES], MASSES, strict=True):
    ops.node(tag, 0.0)
    ops.mass(tag, m)
ops.node(HINGE, 0.0)
levels = [BASE_NODE, *FLOOR_NODES]
k1 = STIFFNESSES[0]
ops.uniaxialMaterial("Elastic", 101, 1.5 * k1)
ops.uniaxialMaterial("Steel01", 102, FY_1, 3.0 * k1, SOFTENING)
ops.uniaxialMaterial("Elastic", 103, 0.0, DAMPINGS[0])
ops.element("zeroLength", 101, BASE_NODE, HINGE, "-mat", 101, "-dir", 1)
ops.element("zeroLength", 102, HINGE, FLOOR_NODES[0], "-mat", 102, "-dir", 1)
ops.element("zeroLength", 103, BASE_NODE, FLOOR_NODES[0], "-mat", 103, "-dir", 1)
for j in (2, 3):
    ops.uniaxialMaterial("Elastic", j, STIFFNESSES[j - 1], DAMPINGS[j - 1])
    ops.element("zeroLength", j, levels[j - 1], levels[j], "-mat", j, "-dir", 1)
