"""The SMK elastic energy and its exact forces and torques (docs/formulation.md §3-4).

``E = sum_k ds H(Omega_k, Gamma_k)`` with ``H = 1/2 dOm^T A dOm + 1/2 dGa^T C dGa + dOm^T B dGa``.
Stresses ``M = dH/dOmega = A dOm + B dGa`` and ``P = dH/dGamma = B^T dOm + C dGa``.

Loads are lab-frame: forces ``F = -dE/dr`` (kJ/mol/nm), torques ``tau = -dE/dtheta``
(kJ/mol/rad) for lab virtual rotations ``dL = hat(dtheta) L``. Each step k contributes::

    n_k  = L_k P_k
    mu_k = L_k (M + w x M / 2 + w (w.M) / 4),  w = ds Omega_k
    F_k += n_k,  F_{k+1} -= n_k,  tau_k += mu_k + e_k x n_k,  tau_{k+1} -= mu_k

For a circular chain the loads on the image of node 0 are mapped back with ``Q^T``.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.strains import step_geometry, strains
from dnarod.core.errors import ParameterError
from dnarod.core.docs import POSE, fill_doc


def stresses(Omega, Gamma, params):
    """Stresses and energy density of every step.

    Parameters
    ----------
    Omega, Gamma : ndarray, shape (n_steps, 3)
        Strains (1/nm, dimensionless).
    params : StepParameters
        Per-step stiffness and intrinsic strains.

    Returns
    -------
    M : ndarray, shape (n_steps, 3)
        Moment stress dH/dOmega, kJ/mol (body frame).
    P : ndarray, shape (n_steps, 3)
        Force stress dH/dGamma, kJ/mol/nm (body frame).
    H : ndarray, shape (n_steps,)
        Energy per unit length, kJ/mol/nm.
    """
    dxi = np.concatenate([Omega, Gamma], axis=1) - params.intrinsic
    sigma = np.einsum("kij,kj->ki", params.stiffness, dxi)
    H = 0.5 * np.einsum("ki,ki->k", dxi, sigma)
    return sigma[:, :3], sigma[:, 3:], H


#: The chain and parameters the energy functions take.
_CHAIN_DOC = POSE + """
params : StepParameters
    With ``n_nodes - 1`` steps (open) or ``n_nodes`` steps (circular).
ds : float
    Arc length per step, nm.
closure : Closure or None
    Screw closure of a circular chain."""


def step_energies(positions, frames, params, ds, closure=None):
    """Energy of every step, ``ds * H_k``, kJ/mol; shape (n_steps,)."""
    Omega, Gamma = strains(positions, frames, ds, closure)
    _check_counts(Omega, params)
    return ds * stresses(Omega, Gamma, params)[2]


@fill_doc(chain=_CHAIN_DOC)
def energy(positions, frames, params, ds, closure=None):
    """Total elastic energy, kJ/mol.

    Parameters
    ----------
    %(chain)s

    Returns
    -------
    float
    """
    return float(step_energies(positions, frames, params, ds, closure).sum())


def _check_counts(Omega, params):
    if Omega.shape[0] != params.n_steps:
        raise ParameterError(
            f"the chain has {Omega.shape[0]} steps but the parameters have {params.n_steps}; "
            f"an open chain of N nodes needs N-1 steps, a circular one N"
        )


@fill_doc(chain=_CHAIN_DOC)
def loads(positions, frames, params, ds, closure=None):
    """Energy, forces and torques on every node (docs/formulation.md §4), vectorised over steps.

    Parameters
    ----------
    %(chain)s

    Returns
    -------
    E : float
        Total energy, kJ/mol.
    F : ndarray, shape (n_nodes, 3)
        Lab forces, kJ/mol/nm.
    tau : ndarray, shape (n_nodes, 3)
        Lab torques, kJ/mol (per radian).
    """
    positions = np.asarray(positions, dtype=float)
    frames = np.asarray(frames, dtype=float)
    n = positions.shape[0]
    Omega, Gamma = strains(positions, frames, ds, closure)
    _check_counts(Omega, params)
    M, P, H = stresses(Omega, Gamma, params)
    _, e = step_geometry(positions, frames, closure)
    L0 = frames if closure is not None else frames[:-1]
    w = ds * Omega
    body_mu = M + 0.5 * np.cross(w, M) + 0.25 * w * np.einsum("ki,ki->k", w, M)[:, None]
    n_lab = np.einsum("kij,kj->ki", L0, P)
    mu_lab = np.einsum("kij,kj->ki", L0, body_mu)
    m = Omega.shape[0]
    F = np.zeros((n, 3))
    tau = np.zeros((n, 3))
    left = np.arange(m)
    F[left] += n_lab
    tau[left] += mu_lab + np.cross(e, n_lab)
    if closure is None:
        F[1:] -= n_lab
        tau[1:] -= mu_lab
    else:
        F[1:] -= n_lab[:-1]
        tau[1:] -= mu_lab[:-1]
        # Image node N = S g_0: its loads act on node 0 through Q^T (docs/formulation.md §4).
        QT = closure.Q.T
        F[0] -= QT @ n_lab[-1]
        tau[0] -= QT @ mu_lab[-1]
    return float(ds * H.sum()), F, tau
