"""whisker-pipeline: natural tactile statistics of the rat whisker array.

Stages (each a ``pipeline`` subcommand and a Python function): scan cleaning into
collision meshes, head-pose sampling, whisking trials on a physics engine, versioned
HDF5 datasets with rerun recordings, and comparison with measured data.
All public quantities are SI (m, kg, s, N, N·m, rad) unless a name says otherwise.
"""

__version__ = "0.1.0"
