"""The paper's Lax pair: 4x4 complex (U~, V~) of (3.3)-(3.7), the 8x8 (X~, Y~) of Appendix A, residuals.

Field conventions (all arrays shape (n_nodes, 3), body-frame components, one row per node k):

* U-fields (node k only): ``Gamma`` (shear/extension, dimensionless), ``Omega`` (bend/twist, 1/nm),
  ``p`` (linear momentum density), ``m`` (angular momentum density);
* V-fields (nodes k and k+1): ``gamma`` (linear velocity, nm/ps), ``omega`` (angular velocity,
  1/ps), ``P`` (force), ``M`` (moment).

The Lax pair (paper (3.3)-(3.7), checked in docs/lax.md; no misprint in the matrices)::

    U = -(Omega.J + lam^2 Gamma.K) - i lam (p.J + lam^2 m.K),     U~ = 1 + ds U
    V = -(omega.J + lam^2 gamma.K) - i lam (P.J + lam^2 M.K),     V~ = V

and the exact identity ``dU~/dt - (V~^1 U~ - U~ V~) = ds Res`` with
``Res = dU/dt - (V^1 - V)/ds - (V^1 U - U V)``, whose symmetric part is ``-1/2 {V^1 - V, U}``.
The superscript 1 means node k+1: it wraps around for ``periodic=True``; for ``periodic=False`` the
field at node N (beyond the last node) is taken as zero.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.core.docs import fill_doc
from dnarod.physics.lax._checks import LAM_DOC, LAM_DS_DOC, as_ds, as_fields, as_lambda, shift_next
from dnarod.physics.lax.generators import D_FLIP, so4_coefficients, so4_matrix

__all__ = [
    "U_matrix", "V_matrix", "lax_pair", "lax_residual", "symmetric_obstruction", "so4_to_fields",
    "realify", "complexify", "appendix_pair", "appendix_to_paper", "appendix_residual",
    "U_NAMES", "V_NAMES",
]

U_NAMES = ("Gamma", "Omega", "p", "m")
V_NAMES = ("gamma", "omega", "P", "M")


def _pair_matrix(lin, rot, mom_lin, mom_rot, lam):
    # -(rot.J + lam^2 lin.K) - i lam (mom_lin.J + lam^2 mom_rot.K), for U: (Gamma, Omega, p, m)
    j = -(rot + 1j * lam * mom_lin)
    k = -lam ** 2 * (lin + 1j * lam * mom_rot)
    return so4_matrix(j, k)


#: The spectral parameter and the result of :func:`U_matrix` and :func:`V_matrix`.
_LAM_MATRIX_DOC = LAM_DOC + """

Returns
-------
ndarray, shape (n, 4, 4), complex"""


def _checked_pair_matrix(names, fields, lam):
    return _pair_matrix(*as_fields(names, fields), as_lambda(lam))


@fill_doc(lam_matrix=_LAM_MATRIX_DOC)
def U_matrix(Gamma, Omega, p, m, lam):
    """U = -(Omega.J + lam^2 Gamma.K) - i lam (p.J + lam^2 m.K), paper (3.3c), (3.4), (3.5).

    Parameters
    ----------
    Gamma, Omega, p, m : array_like, shape (n, 3)
        U-fields per node (Gamma dimensionless, Omega 1/nm, momenta per unit length).
    %(lam_matrix)s
    """
    return _checked_pair_matrix(U_NAMES, (Gamma, Omega, p, m), lam)


@fill_doc(lam_matrix=_LAM_MATRIX_DOC)
def V_matrix(gamma, omega, P, M, lam):
    """V = -(omega.J + lam^2 gamma.K) - i lam (P.J + lam^2 M.K), paper (3.3d), (3.6), (3.7).

    Parameters
    ----------
    gamma, omega, P, M : array_like, shape (n, 3)
        V-fields per node (velocities nm/ps and 1/ps, force and moment).
    %(lam_matrix)s
    """
    return _checked_pair_matrix(V_NAMES, (gamma, omega, P, M), lam)


@fill_doc(lam_ds=LAM_DS_DOC)
def lax_pair(Gamma, Omega, p, m, gamma, omega, P, M, lam, ds):
    """The 4x4 complex Lax pair U~ = 1 + ds U and V~ = V of (3.3a,b).

    Parameters
    ----------
    Gamma, Omega, p, m, gamma, omega, P, M : array_like, shape (n, 3)
        The 24 fields per node (see the module docstring).
    %(lam_ds)s

    Returns
    -------
    Ut, Vt : ndarray, shape (n, 4, 4), complex
    """
    fields = as_fields(U_NAMES + V_NAMES, (Gamma, Omega, p, m, gamma, omega, P, M))
    ds = as_ds(ds)
    lam = as_lambda(lam)
    U = _pair_matrix(*fields[:4], lam)
    V = _pair_matrix(*fields[4:], lam)
    return np.eye(4) + ds * U, V


def lax_residual(Gamma, Omega, p, m, gamma, omega, P, M, dGamma, dOmega, dp, dm, lam, ds, periodic=True):
    """Exact residual of the Lax equation (3.8): ``dU~/dt - (V~^1 U~ - U~ V~)`` per node.

    Parameters
    ----------
    Gamma, Omega, p, m, gamma, omega, P, M : array_like, shape (n, 3)
        The 24 fields per node.
    dGamma, dOmega, dp, dm : array_like, shape (n, 3)
        Time derivatives of the U-fields (per ps).
    lam : float
        Real spectral parameter.
    ds : float
        Step length (nm), > 0.
    periodic : bool
        If True node n-1 couples to node 0; else V~ at node n is taken as zero.

    Returns
    -------
    ndarray, shape (n, 4, 4), complex
        Zero iff (3.8) holds exactly. Equals ``ds * Res`` (docs/lax.md).
    """
    names = U_NAMES + V_NAMES + ("dGamma", "dOmega", "dp", "dm")
    f = as_fields(names, (Gamma, Omega, p, m, gamma, omega, P, M, dGamma, dOmega, dp, dm))
    ds = as_ds(ds)
    lam = as_lambda(lam)
    Ut = np.eye(4) + ds * _pair_matrix(*f[:4], lam)
    V = _pair_matrix(*f[4:8], lam)
    dUt = ds * _pair_matrix(*f[8:], lam)
    V1 = shift_next(V, periodic)
    return dUt - (V1 @ Ut - Ut @ V)


def symmetric_obstruction(Gamma, Omega, p, m, gamma, omega, P, M, lam, ds, periodic=True):
    """The anticommutator ``{V_{k+1} - V_k, U_k}`` (complex symmetric; docs/lax.md).

    The symmetric part of the Lax residual is ``-(ds/2)`` times this, whatever the time derivatives;
    (3.8) therefore needs it to vanish in addition to the 12 component equations (3.9).

    Parameters
    ----------
    Gamma, Omega, p, m, gamma, omega, P, M : array_like, shape (n, 3)
    lam : float
    ds : float
        Step length (nm); only checked here (the obstruction does not depend on it).
    periodic : bool

    Returns
    -------
    ndarray, shape (n, 4, 4), complex, symmetric in the last two axes.
    """
    f = as_fields(U_NAMES + V_NAMES, (Gamma, Omega, p, m, gamma, omega, P, M))
    as_ds(ds)
    lam = as_lambda(lam)
    U = _pair_matrix(*f[:4], lam)
    V = _pair_matrix(*f[4:], lam)
    dV = shift_next(V, periodic) - V
    return dV @ U + U @ dV


def so4_to_fields(X, lam):
    """Invert the U (or V) ansatz: the four real fields whose matrix is the so(4, C) part of X.

    For ``X = U_matrix(Gamma, Omega, p, m, lam)`` this returns ``(Gamma, Omega, p, m)``. Applied to
    the residual ``Res`` it gives the residuals of the 12 component equations (J_a projection ->
    Omega (real) and p (imaginary / lam); K_a projection -> Gamma (real / lam^2) and m
    (imaginary / lam^3)).

    Parameters
    ----------
    X : array_like, shape (..., 4, 4), complex
    lam : float, nonzero

    Returns
    -------
    Gamma, Omega, p, m : ndarray, shape (..., 3), real
    """
    lam = as_lambda(lam)
    if lam == 0.0:
        raise DnarodError("lam: must be nonzero to separate p, Gamma and m from the so(4) projection")
    j, k = so4_coefficients(np.asarray(X, dtype=complex))
    Omega = -np.real(j)
    p = -np.imag(j) / lam
    Gamma = -np.real(k) / lam ** 2
    m = -np.imag(k) / lam ** 3
    return Gamma, Omega, p, m


# ---------------------------------------------------------------- Appendix A (8x8 real pair)

def realify(Z):
    """Real 2n x 2n form ``[[Re Z, -Im Z], [Im Z, Re Z]]`` of a complex n x n matrix (vectorised)."""
    Z = np.asarray(Z, dtype=complex)
    top = np.concatenate([Z.real, -Z.imag], axis=-1)
    bot = np.concatenate([Z.imag, Z.real], axis=-1)
    return np.concatenate([top, bot], axis=-2)


def complexify(X):
    """Inverse of :func:`realify` on matrices of block form [[A, -B], [B, A]]: returns ``A + iB``.

    Uses the average of the two copies of each block, so it is the exact inverse on that form.
    """
    X = np.asarray(X)
    n = X.shape[-1] // 2
    A = 0.5 * (X[..., :n, :n] + X[..., n:, n:])
    B = 0.5 * (X[..., n:, :n] - X[..., :n, n:])
    return A + 1j * B


def _appendix_blocks(lin, rot, mom_lin, mom_rot, zeta):
    # (A.2e,f) / (A.2g,h): A = -rot.J + zeta^2 lin.K,  B = zeta(-mom_lin.J + zeta^2 mom_rot.K)
    A = so4_matrix(-rot + 0j * zeta, zeta ** 2 * lin)
    B = so4_matrix(-zeta * mom_lin, zeta ** 3 * mom_rot)
    top = np.concatenate([A, -B], axis=-1)
    bot = np.concatenate([B, A], axis=-1)
    out = np.concatenate([top, bot], axis=-2)
    if not np.iscomplexobj(zeta):
        out = np.real(out)
    return out


def appendix_pair(Gamma, Omega, p, m, gamma, omega, P, M, zeta, ds):
    """The 8x8 Lax pair of Appendix A: X~ = 1 + ds X, Y~ = Y with X = [[A, -B], [B, A]] (A.2).

    For real ``zeta`` both are real. With ``zeta = lam`` they are the real form of the 4x4 pair
    conjugated by diag(1,1,1,-1) (docs/lax.md): ``X~ = realify(D U~ D)``; see :func:`appendix_to_paper`.
    A complex ``zeta`` is accepted (complex 8x8 result), e.g. to show that ``zeta = i lam`` does not
    reproduce (3.9) (misprint 12).

    Parameters
    ----------
    Gamma, Omega, p, m, gamma, omega, P, M : array_like, shape (n, 3)
    zeta : float or complex
    ds : float
        Step length (nm), > 0.

    Returns
    -------
    Xt, Yt : ndarray, shape (n, 8, 8)
    """
    f = as_fields(U_NAMES + V_NAMES, (Gamma, Omega, p, m, gamma, omega, P, M))
    ds = as_ds(ds)
    zeta = as_lambda(zeta, "zeta", allow_complex=True)
    X = _appendix_blocks(*f[:4], zeta)
    Y = _appendix_blocks(*f[4:], zeta)
    return np.eye(8) + ds * X, Y


def appendix_to_paper(X8):
    """Map an 8x8 Appendix-A matrix (real zeta) to the 4x4 complex matrix of Section III.

    ``appendix_to_paper(X~(zeta=lam)) == U~(lam)`` and likewise for Y~ -> V~: the complex form
    ``A + iB`` conjugated by diag(1,1,1,-1).

    Parameters
    ----------
    X8 : array_like, shape (..., 8, 8), real

    Returns
    -------
    ndarray, shape (..., 4, 4), complex
    """
    Z = complexify(np.asarray(X8, dtype=float))
    return D_FLIP @ Z @ D_FLIP


def appendix_residual(Gamma, Omega, p, m, gamma, omega, P, M, dGamma, dOmega, dp, dm, zeta, ds, periodic=True):
    """Residual of (A.3): ``dX~/dt - (Y~^1 X~ - X~ Y~)`` per node, shape (n, 8, 8).

    Parameters are as for :func:`lax_residual`, with ``zeta`` (real or complex) in place of ``lam``.
    """
    names = U_NAMES + V_NAMES + ("dGamma", "dOmega", "dp", "dm")
    f = as_fields(names, (Gamma, Omega, p, m, gamma, omega, P, M, dGamma, dOmega, dp, dm))
    ds = as_ds(ds)
    zeta = as_lambda(zeta, "zeta", allow_complex=True)
    Xt = np.eye(8) + ds * _appendix_blocks(*f[:4], zeta)
    Y = _appendix_blocks(*f[4:8], zeta)
    dXt = ds * _appendix_blocks(*f[8:], zeta)
    Y1 = shift_next(Y, periodic)
    return dXt - (Y1 @ Xt - Xt @ Y)
