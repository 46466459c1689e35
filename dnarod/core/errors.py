"""Exceptions raised by dnarod.

Every error names the bad value (the entry, the node or the step) and says what to do.
All derive from :class:`DnarodError`, itself a :class:`ValueError`, so callers can catch
one type.
"""


class DnarodError(ValueError):
    """Base class of dnarod's errors about bad input or a failed run."""


class ParameterError(DnarodError):
    """A parameter set (force field file, stiffness matrix, sequence) is invalid."""


class GeometryError(DnarodError):
    """Positions or frames are invalid (non-orthonormal, left-handed, rotation at or beyond pi)."""


class SimulationError(DnarodError):
    """A run failed: NaN, blow-up or an unstable time step. Carries the step, node and term."""

    def __init__(self, message, step=None, node=None, term=None):
        super().__init__(message)
        self.step = step
        self.node = node
        self.term = term


class StructureError(DnarodError):
    """An input structure (PDB, mmCIF, trajectory) cannot be read or has no usable DNA."""


class RunWarning(UserWarning):
    """A warning about a long run that has just begun (it will be slow or inefficient, not wrong).

    The command line prints it when it is raised; other warnings wait until the command ends.
    """
