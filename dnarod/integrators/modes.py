"""Normal modes of a rod pose from finite differences of the analytic loads.

The generalised coordinates of node k are its lab displacement ``dr_k`` (nm) and lab rotation
``dtheta_k`` (rad, ``L -> exp(hat(dtheta)) L``). The Hessian is the central difference of
``-(F, tau)`` from :func:`dnarod.energy.loads`; the mass matrix holds the node masses and
the lab inertia tensors ``L J L^T``. At a stress-free pose the Hessian is symmetric and its
spectrum in ``M^-1 H`` gives the normal-mode frequencies (design A4, A5 ii).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg

from ..energy import loads
from ..rotations import rotation_about_axis


def _perturbed(positions, frames, dof, eps):
    pos, frm = positions.copy(), frames.copy()
    k, a = divmod(dof, 6)
    if a < 3:
        pos[k, a] += eps
    else:
        axis = np.zeros(3)
        axis[a - 3] = 1.0
        frm[k] = rotation_about_axis(axis, eps) @ frm[k]
    return pos, frm


def hessian(model, positions=None, frames=None, eps=1e-5):
    """Potential Hessian (6n, 6n) in lab translations and rotations, kJ/mol per nm^2 / nm rad / rad^2.

    Central differences of the analytic loads with step ``eps`` (nm or rad); symmetrised.
    """
    pos = model.positions if positions is None else np.asarray(positions, float)
    frm = model.frames if frames is None else np.asarray(frames, float)
    n = pos.shape[0]
    H = np.empty((6 * n, 6 * n))
    for dof in range(6 * n):
        cols = []
        for s in (eps, -eps):
            p, f = _perturbed(pos, frm, dof, s)
            _, F, tau = loads(p, f, model.params, model.ds, model.closure)
            cols.append(-np.concatenate([F, tau], axis=1).ravel())
        H[:, dof] = (cols[0] - cols[1]) / (2 * eps)
    return 0.5 * (H + H.T)


def mass_matrix(model, frames=None):
    """Block-diagonal mass matrix (6n, 6n): ``m_k I`` and ``L_k diag(J_k) L_k^T``."""
    frm = model.frames if frames is None else np.asarray(frames, float)
    n = frm.shape[0]
    Mm = np.zeros((6 * n, 6 * n))
    for k in range(n):
        Mm[6 * k:6 * k + 3, 6 * k:6 * k + 3] = model.mass[k] * np.eye(3)
        Mm[6 * k + 3:6 * k + 6, 6 * k + 3:6 * k + 6] = frm[k] @ np.diag(model.inertia[k]) @ frm[k].T
    return Mm


def normal_modes(model, positions=None, frames=None, eps=1e-5):
    """Normal-mode angular frequencies (6n,) rad/ps (sorted; negative eigenvalues give -sqrt|.|)
    and mode shapes (6n, 6n), columns M-orthonormal, in (dr, dtheta) per node."""
    H = hessian(model, positions, frames, eps)
    Mm = mass_matrix(model, frames)
    w2, vecs = scipy.linalg.eigh(H, Mm)
    return np.sign(w2) * np.sqrt(np.abs(w2)), vecs
