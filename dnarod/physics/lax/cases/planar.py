"""Case 4 of the paper: the rod moving in a plane, (7.1a-f).

Only Omega3, Gamma1, Gamma2, omega3, gamma1, gamma2, M3, P1, P2, m3, p1, p2 are nonzero; the
six discarded components of (3.13) then vanish identically (both readings). R1 (docs/lax.md, special cases)::

    dOmega3 = (omega3^1 - omega3)/ds                                         (7.1a)
    dGamma1 = (gamma1^1 - gamma1)/ds + Gamma2 omega3^1 - gamma2 Omega3           (7.1b)
    dGamma2 = (gamma2^1 - gamma2)/ds - Gamma1 omega3^1 + gamma1 Omega3           (7.1c)
    dm3     = (M3^1 - M3)/ds + p1 gamma2 - p2 gamma1 + Gamma1 P2^1 - Gamma2 P1^1  (7.1d)
    dp1     = (P1^1 - P1)/ds + p2 omega3^1 - P2 Omega3                          (7.1e)
    dp2     = (P2^1 - P2)/ds - omega3 p1 + Omega3 P1^1                          (7.1f, corrected)

The printed (7.1f) has ``+ p1 omega3^1 - P1 Omega3`` on the left, i.e. dp2 = ... - p1 omega3^1 + P1
Omega3 (misprint 19, an O(ds) difference); ``reading="printed"`` evaluates it for comparison.
The midpoint reading replaces the k/k+1 placement by averages xbar = (x_k + x_{k+1})/2.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.physics.lax._checks import as_ds, shift_next

__all__ = ["PLANAR_U", "PLANAR_V", "planar_rhs", "planar_embed"]

#: Planar U-fields, in the column order of the (n, 6) arrays used here.
PLANAR_U = ("Omega3", "Gamma1", "Gamma2", "m3", "p1", "p2")
#: Planar V-fields, column order.
PLANAR_V = ("omega3", "gamma1", "gamma2", "M3", "P1", "P2")


def _as_planar(name, x):
    x = np.asarray(x, dtype=float)
    if x.ndim != 2 or x.shape[1] != 6 or x.shape[0] == 0:
        raise DnarodError(f"{name}: expected shape (n_nodes, 6) with columns {PLANAR_U if name == 'u' else PLANAR_V}, "
                          f"got {x.shape}")
    if not np.isfinite(x).all():
        raise DnarodError(f"{name}: contains non-finite values")
    return x


def planar_embed(u, v):
    """The 24 fields (Gamma, Omega, p, m, gamma, omega, P, M), each (n, 3), of planar data.

    Parameters
    ----------
    u : array_like, shape (n, 6)
        Columns (Omega3, Gamma1, Gamma2, m3, p1, p2).
    v : array_like, shape (n, 6)
        Columns (omega3, gamma1, gamma2, M3, P1, P2).
    """
    u = _as_planar("u", u)
    v = _as_planar("v", v)
    if u.shape != v.shape:
        raise DnarodError(f"v: has {v.shape[0]} nodes but u has {u.shape[0]}")
    n = u.shape[0]
    z = np.zeros((8, n, 3))
    Gamma, Omega, p, m, gamma, omega, P, M = z
    Omega[:, 2], Gamma[:, 0], Gamma[:, 1], m[:, 2], p[:, 0], p[:, 1] = u.T
    omega[:, 2], gamma[:, 0], gamma[:, 1], M[:, 2], P[:, 0], P[:, 1] = v.T
    return Gamma, Omega, p, m, gamma, omega, P, M


def planar_rhs(u, v, ds, reading="R1", periodic=True):
    """Time derivatives of the six planar U-fields, (7.1a-f).

    Parameters
    ----------
    u : array_like, shape (n, 6)
        (Omega3, Gamma1, Gamma2, m3, p1, p2) per node.
    v : array_like, shape (n, 6)
        (omega3, gamma1, gamma2, M3, P1, P2) per node.
    ds : float
        Step length (nm), > 0.
    reading : {"R1", "midpoint", "printed"}
        "printed" is R1 with (7.1f) as printed (misprint 19).
    periodic : bool
        As for :func:`dnarod.physics.lax.smk_rhs` (k+1 fields past the last node are zero if False).

    Returns
    -------
    ndarray, shape (n, 6): d/dt of (Omega3, Gamma1, Gamma2, m3, p1, p2).
    """
    u = _as_planar("u", u)
    v = _as_planar("v", v)
    if u.shape != v.shape:
        raise DnarodError(f"v: has {v.shape[0]} nodes but u has {u.shape[0]}")
    ds = as_ds(ds)
    if reading not in ("R1", "midpoint", "printed"):
        raise DnarodError(f"reading: expected 'R1', 'midpoint' or 'printed', got {reading!r}")
    O3, G1, G2, m3, p1, p2 = u.T
    w3, g1, g2, M3, P1, P2 = v.T
    w3n, g1n, g2n, M3n, P1n, P2n = shift_next(v, periodic).T
    out = np.empty_like(u)
    out[:, 0] = (w3n - w3) / ds
    if reading == "midpoint":
        wb, g1b, g2b = 0.5 * (w3 + w3n), 0.5 * (g1 + g1n), 0.5 * (g2 + g2n)
        P1b, P2b = 0.5 * (P1 + P1n), 0.5 * (P2 + P2n)
        out[:, 1] = (g1n - g1) / ds + G2 * wb - O3 * g2b
        out[:, 2] = (g2n - g2) / ds - G1 * wb + O3 * g1b
        out[:, 3] = (M3n - M3) / ds + p1 * g2b - p2 * g1b + G1 * P2b - G2 * P1b
        out[:, 4] = (P1n - P1) / ds + p2 * wb - O3 * P2b
        out[:, 5] = (P2n - P2) / ds - p1 * wb + O3 * P1b
        return out
    out[:, 1] = (g1n - g1) / ds + G2 * w3n - g2 * O3
    out[:, 2] = (g2n - g2) / ds - G1 * w3n + g1 * O3
    out[:, 3] = (M3n - M3) / ds + p1 * g2 - p2 * g1 + G1 * P2n - G2 * P1n
    out[:, 4] = (P1n - P1) / ds + p2 * w3n - P2 * O3
    if reading == "R1":
        out[:, 5] = (P2n - P2) / ds - w3 * p1 + O3 * P1n
    else:
        out[:, 5] = (P2n - P2) / ds - p1 * w3n + P1 * O3
    return out
