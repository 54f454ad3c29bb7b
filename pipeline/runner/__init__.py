"""Simulation runs: the trials of a dataset on this process or a dask cluster, sharded or
resumed, streamed to the dataset writer (built on :mod:`pipeline.protocols.whisking`)."""
