"""Case 2 of the paper: a rigid body in an ideal fluid (Kirchhoff's equations), (5.1), and its lam-deformation.

With M = P = Omega = Gamma = 0 and no k-dependence, V^1 = V, both readings coincide and the Lax
equation is exactly dU/dt = [V, U]. The component equations (3.9) at fixed lam give (docs/lax.md, special cases)::

    dp/dt = p x omega + lam^4 m x gamma,      dm/dt = m x omega + p x gamma

(lam = 0: Kirchhoff's equations (5.1a,b), with (5.1b)'s d/ds read as d/dt, misprint 14), with
``omega = dh/dm`` and ``gamma = dh/dp`` where h(m, p) is the Legendre transform of the kinetic
energy h(omega, gamma) of (3.10c,d) (misprint 15). Here h is the general quadratic
``h = m.Am/2 + m.Bp + p.Cp/2`` given by the symmetric 6x6 matrix H = [[A, B], [B^T, C]].

Invariants for every lam: the energy h and the so(4) Casimirs ``p.p + lam^4 m.m`` and ``p.m``
(tr U^2 = 2 lam^2 (p.p + lam^4 m.m), tr U^4 - (tr U^2)^2/4 = lam^4 |p + lam^2 m|^2 |p - lam^2 m|^2).
"""
from __future__ import annotations

import numpy as np

from dnarod.physics.lax.cases._ode import SixStateODE
from dnarod.core.errors import DnarodError
from dnarod.physics.lax._checks import as_lambda

__all__ = ["KirchhoffBody"]


class KirchhoffBody(SixStateODE):
    """Rigid body in an ideal fluid, (5.1), deformed by the spectral parameter lam.

    Parameters
    ----------
    H : array_like, shape (6, 6)
        Symmetric matrix of the Hamiltonian h(m, p) = [m; p].H.[m; p]/2 (inverse mass-inertia
        matrix including added mass; order m then p).
    lam : float
        Spectral parameter (0 for the physical Kirchhoff equations).
    """

    STATE = "(p, m)"
    NAME = "Kirchhoff body"

    def __init__(self, H, lam=0.0):
        H = np.asarray(H, dtype=float)
        if H.shape != (6, 6) or not np.isfinite(H).all():
            raise DnarodError(f"H: expected a finite 6x6 matrix, got shape {H.shape}")
        if np.abs(H - H.T).max() > 1e-12 * max(np.abs(H).max(), 1.0):
            raise DnarodError("H: must be symmetric")
        self.H = H
        self.lam = as_lambda(lam)

    def velocities(self, y):
        """(gamma, omega) = (dh/dp, dh/dm), each shape (..., 3)."""
        p, m = self._split(y)
        sig = np.einsum("ij,...j->...i", self.H, np.concatenate([m, p], axis=-1))
        return sig[..., 3:], sig[..., :3]

    def rhs(self, t, y):
        """d/dt (p, m), state y = (p, m) shape (6,)."""
        p1, p2, p3, m1, m2, m3 = y
        w1, w2, w3, g1, g2, g3 = self.H @ np.array([m1, m2, m3, p1, p2, p3])
        l4 = self.lam ** 4
        # scalar cross products: np.cross costs more than the whole right-hand side here
        return np.array([p2 * w3 - p3 * w2 + l4 * (m2 * g3 - m3 * g2),
                         p3 * w1 - p1 * w3 + l4 * (m3 * g1 - m1 * g3),
                         p1 * w2 - p2 * w1 + l4 * (m1 * g2 - m2 * g1),
                         m2 * w3 - m3 * w2 + p2 * g3 - p3 * g2,
                         m3 * w1 - m1 * w3 + p3 * g1 - p1 * g3,
                         m1 * w2 - m2 * w1 + p1 * g2 - p2 * g1])

    def energy(self, y):
        """h(m, p), shape (...)."""
        p, m = self._split(y)
        x = np.concatenate([m, p], axis=-1)
        return 0.5 * np.einsum("...i,ij,...j", x, self.H, x)

    def casimirs(self, y):
        """(p.p + lam^4 m.m, p.m), shape (..., 2)."""
        p, m = self._split(y)
        return np.stack([np.einsum("...i,...i", p, p) + self.lam ** 4 * np.einsum("...i,...i", m, m),
                         np.einsum("...i,...i", p, m)], axis=-1)
