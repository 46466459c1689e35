"""Case 5 of the paper: the moving discrete space curve, (8.1)-(8.3), with the corrected signs.

Tetrad rows (d1, d2, d3, rhat) with rhat = lam^2 r (misprint 24: the paper writes lam^-2 r) obey
the corrected (8.1a,b) (misprints 21-22)::

    [d(k+1); rhat(k+1)] = (1 + ds (-Omega.J + lam^2 Gamma.K)) [d(k); rhat(k)]
    d/dt [d; rhat]      = (-omega.J + lam^2 gamma.K) [d; rhat]

whose 3x3 block has rows (0, O3, -O2), (-O3, 0, O1), (O2, -O1, 0) (antisymmetric; the printed
(8.1a) has the wrong sign at entries (2,3), (3,1), (3,2)). This is U~ of (3.3a) at p = m = 0
conjugated by diag(1,1,1,-1) (a harmless convention, docs/lax.md, special cases: Case 5).

Curvature and torsion (misprint 23): for the right-handed frame d3 = t, d2 = n, d1 = n x t = -b
(with Omega2 = Gamma1 = Gamma2 = 0)::

    kappa = -Omega1 / Gamma3,      tau = +Omega3 / Gamma3

The printed (8.2a,b) (d1 = b, kappa = Omega1/Gamma3, tau = -Omega3/Gamma3) is the left-handed
frame (b, n, t) with det = -1. With these, the corrected (8.1a) in the basis (b, n, t, rhat) is the
discrete Serret-Frenet matrix (8.3a) (correct as printed), with step ds~ = Gamma3 ds.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.physics.lax._checks import as_ds, as_fields, as_lambda
from dnarod.physics.lax.generators import so4_matrix

__all__ = ["arclength", "curvature_torsion", "tetrad_step_matrix", "tetrad_velocity_matrix",
           "printed_tetrad_step_matrix",
           "frenet_step_matrix"]


def curvature_torsion(Omega, Gamma):
    """Curvature and torsion of the discrete curve from strains, right-handed frame (-b, n, t).

    Parameters
    ----------
    Omega : array_like, shape (n, 3)
        Bend/twist strains (1/nm), Omega2 = 0 for a Frenet-adapted frame.
    Gamma : array_like, shape (n, 3)
        Shear/extension, Gamma1 = Gamma2 = 0 (unshearable), Gamma3 > 0.

    Returns
    -------
    kappa, tau : ndarray, shape (n,), 1/nm per unit arc length of the deformed curve.
    """
    Omega, Gamma = as_fields(("Omega", "Gamma"), (Omega, Gamma))
    if np.any(Gamma[:, 2] <= 0):
        k = int(np.argmax(Gamma[:, 2] <= 0))
        raise DnarodError(f"Gamma: Gamma3 must be positive (the tangent d3 = t), node {k} has {Gamma[k, 2]:g}")
    return -Omega[:, 0] / Gamma[:, 2], Omega[:, 2] / Gamma[:, 2]


def arclength(Gamma, ds):
    """Current arc length at the nodes, s~(k) = ds sum_{n=0}^{k-1} |Gamma(n)| (misprint 2: the paper sums n = 1..k).

    Parameters
    ----------
    Gamma : array_like, shape (n, 3)
        Shear/extension strain of each step (frame k).
    ds : float
        Step length (nm), > 0.

    Returns
    -------
    ndarray, shape (n + 1,), nm; s~(0) = 0. Exact for the chord lengths |r_{k+1} - r_k| = ds |Gamma_k| (2.6).
    """
    (Gamma,) = as_fields(("Gamma",), (Gamma,))
    ds = as_ds(ds)
    return np.concatenate([[0.0], ds * np.cumsum(np.linalg.norm(Gamma, axis=1))])


def tetrad_step_matrix(Omega, Gamma, lam, ds):
    """Corrected (8.1a): 1 + ds(-Omega.J + lam^2 Gamma.K), shape (n, 4, 4), acting on rows (d1, d2, d3, rhat)."""
    Omega, Gamma = as_fields(("Omega", "Gamma"), (Omega, Gamma))
    lam = as_lambda(lam)
    return np.eye(4) + as_ds(ds) * so4_matrix(-Omega, lam ** 2 * Gamma)


def tetrad_velocity_matrix(omega, gamma, lam):
    """Corrected (8.1b): -omega.J + lam^2 gamma.K, shape (n, 4, 4)."""
    omega, gamma = as_fields(("omega", "gamma"), (omega, gamma))
    lam = as_lambda(lam)
    return so4_matrix(-omega, lam ** 2 * gamma)


def printed_tetrad_step_matrix(Omega, Gamma, lam, ds):
    """(8.1a) exactly as printed (for comparison; its 3x3 block is not antisymmetric), shape (n, 4, 4)."""
    Omega, Gamma = as_fields(("Omega", "Gamma"), (Omega, Gamma))
    lam = as_lambda(lam)
    ds = as_ds(ds)
    O1, O2, O3 = Omega.T
    n = Omega.shape[0]
    X = np.zeros((n, 4, 4))
    X[:, 0, 1], X[:, 0, 2] = O3, -O2
    X[:, 1, 0], X[:, 1, 2] = -O3, -O1
    X[:, 2, 0], X[:, 2, 1] = -O2, O1
    X[:, :3, 3] = -lam ** 2 * Gamma
    X[:, 3, :3] = lam ** 2 * Gamma
    return np.eye(4) + ds * X


def frenet_step_matrix(kappa, tau, lam, ds_tilde):
    """(8.3a), correct as printed: step matrix on rows (b, n, t, rhat), shape (n, 4, 4).

    Parameters
    ----------
    kappa, tau : array_like, shape (n,)
        Curvature and torsion per node (1/nm).
    lam : float
    ds_tilde : array_like, shape (n,) or float
        Arc-length step Gamma3 ds (nm), > 0.
    """
    kappa = np.atleast_1d(np.asarray(kappa, dtype=float))
    tau = np.atleast_1d(np.asarray(tau, dtype=float))
    dst = np.broadcast_to(np.asarray(ds_tilde, dtype=float), kappa.shape)
    if kappa.shape != tau.shape or kappa.ndim != 1:
        raise DnarodError(f"kappa, tau: expected equal shapes (n,), got {kappa.shape} and {tau.shape}")
    if not (np.isfinite(kappa).all() and np.isfinite(tau).all()):
        raise DnarodError("kappa, tau: contain non-finite values")
    if not np.all(dst > 0) or not np.isfinite(dst).all():
        raise DnarodError(f"ds_tilde: must be positive and finite, got {ds_tilde!r}")
    lam = as_lambda(lam)
    n = kappa.shape[0]
    X = np.zeros((n, 4, 4))
    X[:, 0, 1], X[:, 1, 0] = -tau, tau
    X[:, 1, 2], X[:, 2, 1] = -kappa, kappa
    X[:, 2, 3], X[:, 3, 2] = -lam ** 2, lam ** 2
    return np.eye(4) + dst[:, None, None] * X
