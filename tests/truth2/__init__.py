"""Second independent truth generator (issue 25): a 3-D finite-element Euler–Bernoulli frame of
the tapered curved whisker that shares no code or conventions with ``pipeline.model``,
``pipeline.diagnosis`` or ``tests.truth`` (only the documented file format).

Modules: :mod:`.beam` (elements, assembly, damping laws, Newmark time stepping, exact
kinematics of the tracked points), :mod:`.draws` (random whiskers with zero, one or two hidden
effects or another damping law; whisks, releases, two-camera tracking; the measurement file).
"""
