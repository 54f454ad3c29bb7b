"""Fitting the whisker model to measured data and finding what it gets wrong (docs/measurements.md).

- ``linear``, ``drives``, ``fastsim``: the fast simulator (linearised 3D chain, exact in time);
  ``engine``: the same interface on a physics engine, for checks and refinement.
- ``parameters``: named fit parameters and the model spec they define; ``objective``: what a
  fit minimises; ``features``: the paper's tip features and MSA; ``fitting``: optimiser, grid,
  uncertainties, engine refinement; ``threads``: single-threaded BLAS for small matrices.
- ``calibrate``, ``diagnose`` (+ ``candidates``, ``residuals``, ``report``), ``table_diagnosis``,
  ``synth`` (+ ``scenarios``), ``commands``: what the ``pipeline`` commands call.
"""
