"""Internal units of the Bullet engine: millimetre, milligram, second.

Whisker tip links have inertias near 10⁻¹⁸ kg·m² in SI, below Bullet's epsilon (the joint
silently freezes), and its collision margins and contact thresholds assume metre-sized
bodies. In mm–mg–s the same whiskers have inertias of 10⁻⁶–10⁻¹ mg·mm², radii of
0.002–0.08 mm and Bullet's default tolerances (0.02–0.04 units) become tens of micrometres.
"""

LENGTH = 1e3                     # m → mm
MASS = 1e6                       # kg → mg
INERTIA = MASS * LENGTH ** 2     # kg·m² → mg·mm²
FORCE = MASS * LENGTH            # N → mg·mm/s²
TORQUE = MASS * LENGTH ** 2      # N·m → mg·mm²/s² (also stiffness N·m/rad, damping N·m·s/rad)
