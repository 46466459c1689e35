"""Monodromy T(lam) = U~_{N-1} ... U~_0 of a periodic chain and its spectral invariants tr T^n (docs/lax.md, monodromy).

If every U~_k obeys the Lax equation dU~_k/dt = V~_{k+1} U~_k - U~_k V~_k exactly, with periodic V
(V~_N = V~_0), then dT/dt = [V~_0, T] and tr T^n is constant, whatever V is. Fields that solve
the 12 component equations (3.9) (either reading) do not satisfy (3.8) exactly: the symmetric
obstruction {V_{k+1} - V_k, U_k} remains, and tr T^n drifts at O(ds) for smooth fields.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.core.docs import fill_doc
from dnarod.physics.lax._checks import LAM_DS_DOC, as_ds, as_fields, as_lambda
from dnarod.physics.lax.pair import U_NAMES, _pair_matrix

__all__ = ["monodromy", "monodromy_from_matrices", "spectral_invariants"]


def monodromy_from_matrices(Ut):
    """Ordered product ``Ut[n-1] @ ... @ Ut[0]``.

    Parameters
    ----------
    Ut : array_like, shape (n, d, d)
        Step matrices (node k -> node k+1), real or complex.

    Returns
    -------
    ndarray, shape (d, d)
    """
    Ut = np.asarray(Ut)
    if Ut.ndim != 3 or Ut.shape[1] != Ut.shape[2] or Ut.shape[0] == 0:
        raise DnarodError(f"Ut: expected shape (n_steps, d, d) with n_steps >= 1, got {Ut.shape}")
    if not np.all(np.isfinite(Ut)):
        raise DnarodError("Ut: contains non-finite entries; fix the step matrices")
    T = np.eye(Ut.shape[1], dtype=Ut.dtype)
    for U in Ut:
        T = U @ T
    return T


@fill_doc(lam_ds=LAM_DS_DOC)
def monodromy(Gamma, Omega, p, m, lam, ds):
    """Monodromy T(lam) = U~_{N-1} ... U~_0 with U~_k = 1 + ds U_k of (3.3a).

    Parameters
    ----------
    Gamma, Omega, p, m : array_like, shape (n, 3)
        U-fields per node of a periodic chain (n steps; node n is node 0).
    %(lam_ds)s

    Returns
    -------
    ndarray, shape (4, 4), complex
    """
    f = as_fields(U_NAMES, (Gamma, Omega, p, m))
    ds = as_ds(ds)
    lam = as_lambda(lam)
    return monodromy_from_matrices(np.eye(4) + ds * _pair_matrix(*f, lam))


def spectral_invariants(T, nmax=4):
    """Traces tr T^n for n = 1..nmax.

    Parameters
    ----------
    T : array_like, shape (d, d)
    nmax : int, >= 1

    Returns
    -------
    ndarray, shape (nmax,), complex (real input gives a real-valued complex array)
    """
    T = np.asarray(T, dtype=complex)
    if T.ndim != 2 or T.shape[0] != T.shape[1]:
        raise DnarodError(f"T: expected a square matrix, got shape {T.shape}")
    if int(nmax) != nmax or nmax < 1:
        raise DnarodError(f"nmax: expected an integer >= 1, got {nmax!r}")
    out = np.empty(int(nmax), dtype=complex)
    Tn = np.eye(T.shape[0], dtype=complex)
    for i in range(int(nmax)):
        Tn = Tn @ T
        out[i] = np.trace(Tn)
    return out
