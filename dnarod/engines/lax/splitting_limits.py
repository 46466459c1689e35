"""Blow-up thresholds shared by the numpy and numba paths of the splitting integrator."""

#: A node whose linear (amu nm/ps) or body angular (amu nm^2/ps) momentum exceeds this has blown
#: up: thermal values at 300 K are ~40 and ~20, and 1e15 means a kinetic energy of ~1e27 kJ/mol.
MOMENTUM_LIMIT = 1e15
