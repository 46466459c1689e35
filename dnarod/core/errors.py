"""Exceptions raised by dnarod.

Every error names the bad value (the entry, the node or the step) and says what to do.
All derive from :class:`DnarodError`, itself a :class:`ValueError`, so callers can catch
one type.
"""
import math


def base_pair(k):
    """How a message names node ``k`` (0-based index): ``"base pair k+1"`` -- numbered from 1, as `dnarod steps`
    and `dnarod pairs` number them (one node per base pair)."""
    return f"base pair {int(k) + 1}"


def step_name(k, n_nodes=None):
    """How a message names step ``k`` (0-based index, between nodes k and k+1): ``"step k+1 (base pairs k+1-k+2)"``,
    numbered from 1 as `dnarod steps` numbers them; the closing step of a ring of ``n_nodes`` joins the last base
    pair to the first."""
    k = int(k)
    nxt = (k + 1) % n_nodes if n_nodes else k + 1
    return f"step {k + 1} (base pairs {k + 1}-{nxt + 1})"


def positive_number(value):
    """``value`` as a float if it is a finite number > 0, else None (not a number, NaN, infinite or <= 0): the
    check behind the options that take a positive quantity (a temperature, a timeout)."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) and x > 0 else None


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
