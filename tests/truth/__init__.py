"""An independent truth for testing ``pipeline diagnose``: a planar, geometrically exact
discrete elastic rod (Bergou et al. 2008, reduced to the plane) that shares no code with
``pipeline.model``, ``pipeline.engines`` or ``pipeline.diagnosis``.

Modules: :mod:`.whisker` (geometry, material, hidden effects → nodal masses and spring
constants), :mod:`.rod` (exact nonlinear dynamics and statics of the nodal rod),
:mod:`.drives` (prescribed base rotations), :mod:`.record` (tracking at the camera rate and
the measured time-series file), :mod:`.cases` (random hidden-effect cases for tests and the
benchmark). Frames and units as docs/model.md: SI, whisker rest frame (origin at the base
point, x along the base tangent, y toward the concave side); the rod moves in the x–y plane.
"""

from .cases import Case, draw_case
from .record import simulate_measurement
from .rod import Rod
from .whisker import Effects, TruthWhisker

__all__ = ["Case", "Effects", "Rod", "TruthWhisker", "draw_case", "simulate_measurement"]
