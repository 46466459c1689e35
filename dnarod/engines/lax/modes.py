"""Normal modes of a rod pose (compatibility layer over :mod:`dnarod.physics.modes`, the one home of the Hessian).

The generalised coordinates of node k are its lab displacement ``dr_k`` (nm) and lab rotation
``dtheta_k`` (rad, ``L -> exp(hat(dtheta)) L``); the mass matrix holds the node masses and the lab
inertia tensors ``L J L^T`` (design A4, A5 ii).
"""
from __future__ import annotations

from dnarod.physics import modes as _modes


def hessian(model, positions=None, frames=None, eps=1e-5, loads=()):
    """Dense potential Hessian (6n, 6n) in lab translations and rotations, kJ/mol per nm^2 / nm rad / rad^2.

    See :func:`dnarod.physics.modes.hessian` (the sparse original); ``eps`` is the relative step.
    """
    return _modes.hessian(model, loads, positions, frames, rel_step=eps).toarray()


def mass_matrix(model, frames=None):
    """Dense block-diagonal mass matrix (6n, 6n): ``m_k I`` and ``L_k diag(J_k) L_k^T``."""
    return _modes.mass_matrix(model, frames).toarray()


def normal_modes(model, positions=None, frames=None, eps=1e-5, loads=()):
    """Normal-mode angular frequencies (6n,) rad/ps (sorted; negative eigenvalues give -sqrt|.|)
    and mode shapes (6n, 6n), columns M-orthonormal, in (dr, dtheta) per node (clamped nodes removed
    from the frequencies; see :func:`dnarod.physics.modes.normal_modes`)."""
    w, modes = _modes.normal_modes(model, loads, positions=positions, frames=frames)
    return w, modes.reshape(modes.shape[0], -1).T
