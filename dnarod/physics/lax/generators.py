"""The SO(4) generators J_a, K_a of the paper's (3.1), their algebra and projections.

The printed matrices (3.1a,b) are correct as printed (docs/lax.md); closed forms:

* ``(J_a)_jk = -eps_ajk`` for ``j, k <= 3`` (zero in row/column 4), so ``(Omega . J) v = Omega x v``
  on the first three components, i.e. ``Omega . J`` is ``hat(Omega)`` padded to 4x4;
* ``K_a = E_4a - E_a4`` (entry (4, a) is +1, entry (a, 4) is -1).

They satisfy ``[J_a, J_b] = eps_abc J_c``, ``[J_a, K_b] = eps_abc K_c``, ``[K_a, K_b] = eps_abc J_c``
(3.1c) and ``tr(J_a J_b) = tr(K_a K_b) = -2 delta_ab``, ``tr(J_a K_b) = 0``. Indices here are
0-based (a = 0, 1, 2 stands for the paper's 1, 2, 3).
"""
from __future__ import annotations

import numpy as np

from dnarod.core.rotations import axial, hat

__all__ = [
    "J", "K", "LEVI_CIVITA", "XPLUS", "XMINUS", "D_FLIP", "commutator",
    "so4_matrix", "so4_coefficients", "xpm_coefficients", "antisymmetric_part", "symmetric_part",
]


def _levi_civita():
    eps = np.zeros((3, 3, 3))
    for a, b, c in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        eps[a, b, c] = 1.0
        eps[a, c, b] = -1.0
    return eps


#: Levi-Civita symbol, shape (3, 3, 3).
LEVI_CIVITA = _levi_civita()


def _generators():
    Jm = np.zeros((3, 4, 4))
    Km = np.zeros((3, 4, 4))
    for a in range(3):
        Jm[a, :3, :3] = -LEVI_CIVITA[a]
        Km[a, 3, a] = 1.0
        Km[a, a, 3] = -1.0
    return Jm, Km


#: J_a of (3.1a), shape (3, 4, 4), real.
#: K_a of (3.1b), shape (3, 4, 4), real.
J, K = _generators()
J.setflags(write=False)
K.setflags(write=False)

#: X^+_a = (J_a + K_a)/2 and X^-_a = (J_a - K_a)/2: two commuting copies of so(3), shape (3, 4, 4).
XPLUS = 0.5 * (J + K)
XMINUS = 0.5 * (J - K)
XPLUS.setflags(write=False)
XMINUS.setflags(write=False)

#: diag(1, 1, 1, -1): conjugation by it fixes J_a and sends K_a to -K_a (docs/lax.md).
D_FLIP = np.diag([1.0, 1.0, 1.0, -1.0])
D_FLIP.setflags(write=False)


def commutator(X, Y):
    """Matrix commutator ``X Y - Y X`` (vectorised over leading axes).

    Parameters
    ----------
    X, Y : array_like, shape (..., n, n)

    Returns
    -------
    ndarray, shape (..., n, n)
    """
    X = np.asarray(X)
    Y = np.asarray(Y)
    return X @ Y - Y @ X


def so4_matrix(j, k):
    """The so(4) (or so(4, C)) matrix ``j_a J_a + k_a K_a``.

    Parameters
    ----------
    j, k : array_like, shape (..., 3), real or complex
        Coefficients of J_a and of K_a.

    Returns
    -------
    ndarray, shape (..., 4, 4)
        Real if both inputs are real, complex otherwise.
    """
    j = np.asarray(j)
    k = np.asarray(k)
    dtype = np.result_type(j, k, float)
    shape = np.broadcast_shapes(j.shape, k.shape)[:-1]
    out = np.zeros(shape + (4, 4), dtype=dtype)
    if np.iscomplexobj(out):
        out[..., :3, :3] = hat(np.real(j)) + 1j * hat(np.imag(j))
    else:
        out[..., :3, :3] = hat(j)
    out[..., 3, :3] = k
    out[..., :3, 3] = -k
    return out


def xpm_coefficients(j, k):
    """Split ``j.J + k.K`` into the two commuting so(3) copies: ``(j + k).X^+ + (j - k).X^-``.

    Parameters
    ----------
    j, k : array_like, shape (..., 3), real or complex

    Returns
    -------
    plus, minus : ndarray, shape (..., 3)
        Coefficients of X^+_a and X^-_a.
    """
    j = np.asarray(j)
    k = np.asarray(k)
    return j + k, j - k


def antisymmetric_part(X):
    """``(X - X^T)/2`` over the last two axes (plain transpose, no conjugation)."""
    X = np.asarray(X)
    return 0.5 * (X - np.swapaxes(X, -1, -2))


def symmetric_part(X):
    """``(X + X^T)/2`` over the last two axes (plain transpose, no conjugation)."""
    X = np.asarray(X)
    return 0.5 * (X + np.swapaxes(X, -1, -2))


def so4_coefficients(X):
    """Coefficients (j, k) of the antisymmetric part of X on the basis J_a, K_a.

    Equal to the trace form ``j_a = -tr(J_a X)/2``, ``k_a = -tr(K_a X)/2``: the symmetric part of X
    is orthogonal to so(4) in this form and does not contribute.

    Parameters
    ----------
    X : array_like, shape (..., 4, 4), real or complex

    Returns
    -------
    j, k : ndarray, shape (..., 3)
    """
    A = antisymmetric_part(X)
    if np.iscomplexobj(A):
        j = axial(np.real(A[..., :3, :3])) + 1j * axial(np.imag(A[..., :3, :3]))
    else:
        j = axial(A[..., :3, :3])
    k = A[..., 3, :3]
    return j, np.array(k)
