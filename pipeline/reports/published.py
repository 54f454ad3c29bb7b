"""The published numbers the validation compares with (docs/model.md §5–6), each with its source.

"the paper" is the WHISKiT Physics paper (Zweifel et al., ../shared/seed/whiskit_physics_paper.txt).
The measured α and B1 resonances (f1, δ, ζ with standard deviations) are the measurement
library's table ``paper_alpha_b1`` (:func:`pipeline.diagnosis.material_fit.paper_table_1`);
this module adds the rest of Table 1 and the figures' numbers.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Published:
    """A published value (a number, a (low, high) range or a statement), its ± sd and source."""

    value: Any
    sd: float | None = None
    source: str = ""


TABLE_1 = "the paper, Table 1"

# Table 1, "Simulation" column: the paper's own model (θ_E = 5.0 GPa, θ_ζ = 0.33).
TABLE_1_SIMULATED = {
    "alpha": {"f1_hz": Published(64.87, 1.12, TABLE_1), "log_decrement": Published(0.50, 0.4, TABLE_1),
              "damping_ratio": Published(0.08, 0.06, TABLE_1)},
    "B1": {"f1_hz": Published(58.96, 0.68, TABLE_1), "log_decrement": Published(0.23, 0.08, TABLE_1),
           "damping_ratio": Published(0.04, 0.01, TABLE_1)},
}
YOUNGS_MODULUS_GPA = Published((1.3, 7.8), None, "reported range, the paper §2.1 (refs 33–37)")
DAMPING_RATIO = Published((0.05, 0.28), None, "reported range, the paper §2.1 (refs 33, 34, 38)")
PAPER_FIT = {"youngs_modulus_gpa": Published(5.0, None, "the paper §2.1 (its joints use S, not S/N)"),
             "damping_ratio": Published(0.33, None, "the paper §2.1")}

# Figure 2: f1 against arc length S (mm) over three measured datasets.
FIG2_SOURCE = "the paper §2.2, Fig. 2B"
F1_FIT = {"coefficient": 8963.0, "exponent": -1.4, "offset": -3.8}   # f = 8963·S^−1.4 − 3.8 (Hz)
F1_FIT_R2 = Published(0.91, None, FIG2_SOURCE)
OUTSIDE_SHORTER_THAN_MM = Published(15.0, None, "the paper §2.2, Fig. 2C: only whiskers < 15 mm fall "
                                                "outside the prediction interval")

# Figure 3: collisions with an edge.
FIG3_SOURCE = "the paper §2.3, Fig. 3"
CONTACT_LINK = Published(19, None, "the paper §2.3: link 19 (95 % of S) hits the edge")
DMZ_PEAK_DELAY_MS = Published(3.0, None, "the paper §2.3, Fig. 3A: first negative peak ≈ 3 ms after contact")
PEAK_VS_SPEED_ADJ_R2 = Published(0.92, None, "the paper §2.3, Fig. 3B (straight and curved)")
SLOPES_DIFFER_P = Published("< 0.001", None, "the paper §2.3, Fig. 3B: straight vs curved slopes")
CURVED_PEAK_SMALLER = Published("smaller", None, "the paper §2.3: Ṁz,max decreases with curvature")
QS_BENDING_MOMENT_R2 = Published(0.307, None, "the paper §2.3, Fig. 3C: M_b falls with curvature")
QS_TRANSVERSE_FORCE_R2 = Published(0.467, None, "the paper §2.3, Fig. 3C: F_t falls with curvature")
FRONT_SPEED_COLUMN1_M_S = Published(5.5, None, "the paper §2.3, Fig. 3D (first 4 rows, first column)")
FRONT_SPEED_ANALYTIC_M_S = 5.6       # Boubenec et al. 2012, as quoted by the paper
FRONT_SPEED_MEASURED_M_S = 5.02      # Boubenec et al. 2012, as quoted by the paper
FRONT_R2_COLUMN1 = Published(0.90, None, "the paper §2.3, Fig. 3D")
FRONT_SPEED_GREEK_M_S = Published(4.3, None, "the paper §2.3 (Greek column)")
FRONT_R2_GREEK = Published(0.97, None, "the paper §2.3 (Greek column)")

# Figure 4: rigid vs compliant follicle after a release (B1 whisker).
FIG4_SOURCE = "the paper §2.4, Fig. 4"
RIGID_OVER_IN_VIVO_TIP = Published(10.0, None, "the paper §2.4, Fig. 4A: rigid-follicle deflections "
                                               "'nearly an order of magnitude larger' than in vivo")
COMPLIANT_REDUCES_BASE = Published(10.0, None, "the paper §2.4, Fig. 4C: the compliant follicle reduces "
                                               "F_z and M_y 'by more than an order of magnitude'")
TIP_CORRELATION_R = Published(0.63, 0.15, "the paper §2.4, Fig. 4B (5 whiskers, 11 animals)")

# Figure 5: the right array against a passive peg, active pegs and a natural scene.
FIG5_SOURCE = "the paper §2.5, Fig. 5"
SLIP_OFF = Published("POC rises at the end of each contact", None,
                     "the paper §2.5, Fig. 5D (passive peg): slip-off of each whisker tip")
ROSTRAL_FIRST = Published("rostral first", None, "the paper §2.5: the moving peg first collides with the "
                                                 "most rostral whiskers")
M_POC_INVERSE = Published("inverse", None, "the paper §2.5: M and POC tend to be inversely related")
CAUDAL_LARGER_M = Published("caudal larger", None, "the paper §2.5: caudal whiskers undergo larger M")
LESS_SLIP_ON_SURFACE = Published("less than pegs", None, "the paper §2.5: slip-off less likely on an "
                                                         "extended surface (drainpipe) than on pegs")
