"""Exact force-extension of the discrete rod by transfer matrix (uniform axisymmetric steps; node 0 free or held).

A free open chain of n nodes pulled by ``+F z`` on its last node and ``-F z`` on node 0 has the partition function
``Z(F) = < exp(beta F (r_{n-1} - r_0) . z) >`` over the free chain, whose steps are independent in their body
frames (docs/formulation.md §8). With ``u_k = L_k^T z`` (the force axis seen from node k) the step adds
``ds u_k . Gamma_k`` to the extension and turns u by ``u_{k+1} = R_k^T u_k``. Integrating ``Gamma`` out (Gaussian
given ``Omega``: mean ``Gamma0 - C^-1 B^T (Omega - Omega0)``, covariance ``kT (ds C)^-1``) leaves, for a step whose
stiffness is invariant under turns about d3 and whose mean shear vanishes, a weight that depends on u only through
``c = u_3`` (the cosine of the angle between d3 and the force). The backward functions ``h_k(c) = <exp(beta F
sum_{j>=k} ds u_j . Gamma_j) | u_k>`` then stay functions of c, and by the addition theorem of Legendre polynomials
(the average over the azimuth of ``P_l(u . v)`` is ``P_l(c) P_l(v_3)``) one step acts on Legendre coefficients as::

    h_k(c) = sum_l a_l P_l(c) G_l(c),   G_l(c) = < g(c, w) P_l(R_33(w)) >_w

with g the Gaussian Gamma integral and ``<>_w`` the exact Cayley-vector density of the step (the quadrature of
:func:`dnarod.physics.thermal.mean_rotation`). Node 0's orientation is uniform (Haar) for a free chain, so
``Z = a_0`` of ``h_0``; a chain whose node 0 is held (clamped, as on a tweezers surface) with its d3 at cosine
``c0`` to the force has ``Z = h_0(c0) = sum_l a_l P_l(c0)``. The extension is ``kT d ln Z / dF`` (central
difference in F). Truncation: Legendre degree ``l_max``, ``n_c``
Gauss-Legendre nodes in c and ``order`` Gauss-Hermite points per axis in w; the defaults change the relative
extension by less than 1e-6 at 0.1-10 pN (tests).
"""
from __future__ import annotations

import numpy as np
from numpy.polynomial import legendre as npleg

from dnarod.core.errors import ParameterError


def _legendre_table(x, lmax):
    """P_l(x) for l = 0..lmax, shape (len(x), lmax + 1) (three-term recurrence)."""
    x = np.asarray(x, float)
    P = np.empty((x.size, lmax + 1))
    P[:, 0] = 1.0
    if lmax >= 1:
        P[:, 1] = x
    for l in range(1, lmax):
        P[:, l + 1] = ((2 * l + 1) * x * P[:, l] - l * P[:, l - 1]) / (l + 1)
    return P


def _check_axisymmetric(K, xi0):
    if np.ptp(K, axis=0).max() > 1e-9 * np.abs(K).max() or np.ptp(xi0, axis=0).max() > 1e-12:
        raise ParameterError("the transfer-matrix force-extension needs a uniform chain (one stiffness and intrinsic "
                             "strain for every step)")
    k, x = K[0], xi0[0]
    if np.abs(x[[0, 1, 3, 4]]).max() > 1e-12:
        raise ParameterError("the transfer-matrix force-extension needs zero intrinsic bend and shear")
    tol = 1e-9 * np.abs(k).max()
    zero = [(i, j) for i in (0, 1, 3, 4) for j in (2, 5)] + [(0, 1), (3, 4), (0, 4), (1, 3), (0, 3), (1, 4)]
    if any(abs(k[i, j]) > tol or abs(k[j, i]) > tol for i, j in zero) or abs(k[0, 0] - k[1, 1]) > tol \
            or abs(k[3, 3] - k[4, 4]) > tol:
        raise ParameterError("the transfer-matrix force-extension needs a stiffness invariant under turns about d3 "
                             "with no bend-shear coupling")


def _step_tables(params, ds, kt, order):
    """Quadrature nodes (q, 3) of w = ds Omega with normalised weights, and the per-node Gamma-mean slope."""
    from dnarod.physics.thermal import _quadrature, bend_twist_schur

    K = params.stiffness[0]
    S = bend_twist_schur(K[None])[0]
    w, W = _quadrature(S, ds * params.Omega0[0], ds, kt, order)
    C = K[3:, 3:]
    Binv = np.linalg.solve(C, K[:3, 3:].T)  # C^-1 B^T, (3, 3)
    dOm = w / ds - params.Omega0[0]
    mu3 = params.Gamma0[0, 2] - dOm @ Binv[2]
    Cinv = np.linalg.inv(C)
    return w, W, mu3, Cinv


def log_partition(params, ds, kt, n_nodes, force, lmax=60, n_c=120, order=16, tables=None, start_cos=None):
    """``ln Z(F)`` of the chain of ``n_nodes`` nodes pulled by ``force`` (kJ/mol/nm) on its last node and the
    opposite force on node 0 (module docstring); ``start_cos``: node 0 held with its d3 at that cosine to the force
    (None: node 0 free)."""
    from dnarod.core.rotations import cayley

    w, W, mu3, Cinv = tables if tables is not None else _step_tables(params, ds, kt, order)
    beta = 1.0 / kt
    c, wc = npleg.leggauss(n_c)
    R33 = cayley(w)[:, 2, 2]
    Pq = _legendre_table(R33, lmax)                        # (q, L)
    Pc = _legendre_table(c, lmax)                          # (n_c, L)
    var = (1.0 - c * c) * Cinv[0, 0] + c * c * Cinv[2, 2]  # u^T C^-1 u (axisymmetric C)
    f = float(force)
    lng = beta * f * ds * c[:, None] * mu3[None, :] + 0.5 * (beta * f) ** 2 * ds * kt * var[:, None]
    g = np.exp(lng)                                        # (n_c, q)
    G = (g * W[None, :]) @ Pq                              # (n_c, L): G_l(c_i)
    T = ((2 * np.arange(lmax + 1) + 1) / 2.0)[:, None] * ((Pc * wc[:, None]).T @ (Pc * G))  # a_new = T a
    a = np.zeros(lmax + 1)
    a[0] = 1.0
    logz = 0.0
    for _ in range(n_nodes - 1):
        a = T @ a
        s = a[0]
        logz += np.log(s)
        a /= s
    if start_cos is not None:
        logz += float(np.log(_legendre_table(np.array([float(start_cos)]), lmax)[0] @ a))
    return float(logz)


def force_extension(params, ds, temperature, n_nodes, force_pN, lmax=60, n_c=120, order=16, rel_step=1e-4,
                    start_cos=None):
    """Exact mean extension ``<(r_{n-1} - r_0) · z>`` (nm) of the discrete chain pulled at both ends (node 0 free),
    or pulled at its last node with node 0 held (``start_cos``).

    Parameters
    ----------
    params : StepParameters
        Uniform, axisymmetric steps (``dna-default``); otherwise :class:`ParameterError`.
    ds : float
        nm.
    temperature : float
        K.
    n_nodes : int
    force_pN : float or array_like
        pN (> 0).
    lmax, n_c, order : int
        Legendre degree, Gauss-Legendre nodes in cos(theta), Gauss-Hermite points per axis.
    rel_step : float
        Relative step of the central difference in F.
    start_cos : float, optional
        Node 0 held (position and orientation, e.g. :class:`~dnarod.physics.loads.Clamp`) with its d3 at this
        cosine to the force (1: along it); None: node 0 free.

    Returns
    -------
    ndarray
        Extension, nm, one per force.
    """
    from dnarod.core.units import kT
    from dnarod.core.units import PN

    _check_axisymmetric(params.stiffness, params.intrinsic)
    kt = kT(temperature)
    tables = _step_tables(params, ds, kt, order)
    out = []
    for F in np.atleast_1d(np.asarray(force_pN, float)):
        if not F > 0:
            raise ParameterError(f"force {F} pN: give a pulling force > 0")
        f = F * PN
        h = rel_step * f
        lp = log_partition(params, ds, kt, n_nodes, f + h, lmax, n_c, order, tables, start_cos)
        lm = log_partition(params, ds, kt, n_nodes, f - h, lmax, n_c, order, tables, start_cos)
        out.append(kt * (lp - lm) / (2.0 * h))
    return np.asarray(out)
