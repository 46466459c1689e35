"""Exact thermal equilibrium of the free open chain (design A5 iii).

The configuration measure is Haar on SE(3)^N, so steps are independent with density
``p(Omega, Gamma) ~ exp(-ds H / kT) (1 + ds^2 |Omega|^2 / 4)^-2``. Integrating Gamma out
leaves a Gaussian in ``w = ds Omega`` of covariance ``kT ds S^-1`` (``S = A - B C^-1 B^T``)
times the Haar factor ``(1 + |w|^2/4)^-2``. Expectations over that 3D density are computed
here by tensor Gauss-Hermite quadrature about the Gaussian (exact up to quadrature error,
which the tests bound against Monte Carlo and a finer rule).

Units: kT in kJ/mol, lengths in nm.
"""
from __future__ import annotations

import numpy as np

from .parameters import StepParameters
from .rotations import cayley
from .units import BOLTZMANN



def kT(temperature):
    """Thermal energy at ``temperature`` (K), kJ/mol."""
    return BOLTZMANN * float(temperature)


def node_kinetic_energy(mass, inertia, velocities, angular_velocities):
    """Kinetic energy of rigid nodes, kJ/mol: ``sum m v^2/2 + sum J_a w_a^2/2``.

    Parameters
    ----------
    mass : (n,) amu;  inertia : (n, 3) amu nm^2
    velocities : (..., n, 3) nm/ps (lab);  angular_velocities : (..., n, 3) rad/ps (body frame)

    Returns
    -------
    float or ndarray, shape (...)
    """
    v = np.asarray(velocities, float)
    w = np.asarray(angular_velocities, float)
    return 0.5 * (np.einsum("k,...ki,...ki->...", mass, v, v) + np.einsum("ki,...ki,...ki->...", inertia, w, w))


def kinetic_temperature(kinetic_energy, n_dof):
    """Temperature (K) of ``n_dof`` degrees of freedom holding ``kinetic_energy`` (kJ/mol); 0 if none."""
    return 2.0 * np.asarray(kinetic_energy) / (n_dof * BOLTZMANN) if n_dof > 0 else 0.0 * np.asarray(kinetic_energy)


def bend_twist_schur(stiffness):
    """Rotational stiffness with translations relaxed, ``S = A - B C^-1 B^T``; shape (..., 3, 3)."""
    K = np.asarray(stiffness, float)
    A, B, C = K[..., :3, :3], K[..., :3, 3:], K[..., 3:, 3:]
    return A - B @ np.linalg.solve(C, np.swapaxes(B, -1, -2))


def _quadrature(S, w0, ds, kt, order):
    """Nodes (q, 3) and normalised weights (q,) of the exact Cayley-vector density of one step."""
    x, wts = np.polynomial.hermite.hermgauss(order)
    cov = kt * ds * np.linalg.inv(S)
    L = np.linalg.cholesky(0.5 * (cov + cov.T))
    g = np.stack(np.meshgrid(x, x, x, indexing="ij"), axis=-1).reshape(-1, 3)
    W = (wts[:, None, None] * wts[None, :, None] * wts[None, None, :]).reshape(-1)
    w = w0 + np.sqrt(2.0) * g @ L.T
    W = W * (1.0 + 0.25 * np.einsum("qi,qi->q", w, w)) ** -2
    return w, W / W.sum()


def mean_rotation(params: StepParameters, ds, kt, order=24):
    """Exact thermal mean of each step's relative rotation, ``<R_k>``.

    Parameters
    ----------
    params : StepParameters
    ds : float
        nm.
    kt : float
        Thermal energy, kJ/mol.
    order : int
        Gauss-Hermite points per axis.

    Returns
    -------
    ndarray, shape (n_steps, 3, 3)
    """
    S = bend_twist_schur(params.stiffness)
    out = np.empty((params.n_steps, 3, 3))
    cache = {}
    for k in range(params.n_steps):
        key = (S[k].tobytes(), params.Omega0[k].tobytes())
        if key not in cache:
            w, W = _quadrature(S[k], ds * params.Omega0[k], ds, kt, order)
            cache[key] = np.einsum("q,qij->ij", W, cayley(w))
        out[k] = cache[key]
    return out


def tangent_correlation(params: StepParameters, ds, kt, n_max, order=24):
    """Exact ``<d3(0) . d3(n)>`` for n = 0..n_max along an open chain starting at step 0.

    Returns
    -------
    ndarray, shape (n_max + 1,)
    """
    Rm = mean_rotation(params, ds, kt, order)
    out = np.empty(n_max + 1)
    P = np.eye(3)
    out[0] = 1.0
    for n in range(1, n_max + 1):
        P = P @ Rm[(n - 1) % params.n_steps]
        out[n] = P[2, 2]
    return out


def persistence_length(params: StepParameters, ds, kt, order=24):
    """Bending persistence length of the discrete model, nm: ``-ds / ln c`` (design A5 iii).

    For a uniform axisymmetric step ``c = <R_33>`` and this is exact. For a sequence the
    tangent correlation is averaged per step over one period of the parameter list:
    ``c = ((prod_k <R_k>)_33)^(1/n_steps)``.
    """
    Rm = mean_rotation(params, ds, kt, order)
    if params.n_steps == 1:
        c = Rm[0, 2, 2]
    else:
        P = np.eye(3)
        for R in Rm:
            P = P @ R
        c = P[2, 2] ** (1.0 / params.n_steps)
    return -ds / np.log(c)


def reweighted_covariance_expected(params: StepParameters, ds, kt):
    """The exact identity ``<dxi dxi^T W>/<W> = kT (ds K)^-1`` (design A5 iii); shape (n_steps, 6, 6)."""
    return kt * np.linalg.inv(ds * params.stiffness)
