"""Signal analysis of simulated and measured whiskers (numpy/scipy on arrays, SI units): the
resonance protocol's drive and read-out, ring-down fits (per-mode f and ζ), the linear
chain's damped modes. Imports only the model; protocols and the diagnosis build on it."""
