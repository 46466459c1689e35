"""Subcase 1.2 of the paper: the static Kirchhoff rod (4.5) read as the heavy top.

With Gamma = chi fixed (no shear or extension) and M = A (Omega - Omega0), the continuum limit of
(4.5a,b), with s read as time, is the Euler-Poisson system (docs/lax.md, special cases)::

    M' = M x Omega + P x chi,      P' = P x Omega,      Omega = A^{-1} M + Omega0

(angular momentum L = M, Poisson vector P, centre-of-mass vector chi). Invariants: the Casimirs
|P|^2 and M.P and the energy E = M.A^{-1}M/2 + M.Omega0 + P.chi. Integrable cases (Omega0 = 0,
chi = (0, 0, c)):

* Lagrange, A11 = A22: extra integral M3;
* Kowalewski, A33 = A11 = 2 A22 (the paper's condition is right: the equal pair is (1, 3), the
  symmetry axis 2 is perpendicular to chi; it is Kowalewski's I1 = I2 = 2 I3 with our axes
  (1, 2, 3) = standard (2, 3, 1)). Extra integral
  ``K = |(Omega3 + i Omega1)^2 - (c / A22) (P3 + i P1)|^2``.

The time-discrete top is the static-rod map (4.5a,b) with Gamma = chi (:meth:`HeavyTop.discrete_step`).
"""
from __future__ import annotations

import numpy as np

from dnarod.physics.lax.cases._ode import SixStateODE
from dnarod.core.errors import DnarodError
from dnarod.physics.lax._checks import as_ds, as_reading
from dnarod.physics.lax.cases.static import static_stress_step

__all__ = ["HeavyTop"]


class HeavyTop(SixStateODE):
    """The heavy top of (4.5) (continuum in s, read as time) with its integrals.

    Parameters
    ----------
    A : array_like, shape (3, 3)
        Symmetric positive definite bending/twisting modulus (inertia tensor of the top).
    chi : array_like, shape (3,)
        Fixed Gamma (the centre-of-mass vector times the weight); default (0, 0, 1).
    Omega0 : array_like, shape (3,)
        Intrinsic strain; default 0.
    """

    STATE = "(M, P)"
    NAME = "heavy top"

    def __init__(self, A, chi=(0.0, 0.0, 1.0), Omega0=(0.0, 0.0, 0.0)):
        A = np.asarray(A, dtype=float)
        if A.shape != (3, 3) or not np.isfinite(A).all():
            raise DnarodError(f"A: expected a finite 3x3 matrix, got shape {A.shape}")
        if np.abs(A - A.T).max() > 1e-12 * np.abs(A).max() or np.linalg.eigvalsh(A)[0] <= 0:
            raise DnarodError("A: must be symmetric positive definite")
        self.A = A
        self.Ainv = np.linalg.inv(A)
        self.chi = np.asarray(chi, dtype=float)
        self.Omega0 = np.asarray(Omega0, dtype=float)
        for name, v in (("chi", self.chi), ("Omega0", self.Omega0)):
            if v.shape != (3,) or not np.isfinite(v).all():
                raise DnarodError(f"{name}: expected a finite 3-vector, got {v!r}")

    @classmethod
    def lagrange(cls, A11, A33, c=1.0):
        """Lagrange top: A = diag(A11, A11, A33), chi = (0, 0, c)."""
        return cls(np.diag([A11, A11, A33]), chi=(0.0, 0.0, c))

    @classmethod
    def kowalewski(cls, A22, c=1.0):
        """Kowalewski top in the paper's labels: A = diag(2 A22, A22, 2 A22), chi = (0, 0, c)."""
        return cls(np.diag([2.0 * A22, A22, 2.0 * A22]), chi=(0.0, 0.0, c))

    def omega(self, M):
        """Omega = A^{-1} M + Omega0, shape (..., 3)."""
        return np.einsum("ij,...j->...i", self.Ainv, M) + self.Omega0

    def rhs(self, s, y):
        """d/ds (M, P) for scipy; y shape (6,)."""
        M1, M2, M3, P1, P2, P3 = y
        O1, O2, O3 = self.Ainv @ y[:3] + self.Omega0
        c1, c2, c3 = self.chi
        # scalar cross products: np.cross costs more than the whole right-hand side here
        return np.array([M2 * O3 - M3 * O2 + P2 * c3 - P3 * c2,
                         M3 * O1 - M1 * O3 + P3 * c1 - P1 * c3,
                         M1 * O2 - M2 * O1 + P1 * c2 - P2 * c1,
                         P2 * O3 - P3 * O2, P3 * O1 - P1 * O3, P1 * O2 - P2 * O1])

    def energy(self, y):
        """E = M.A^{-1}M/2 + M.Omega0 + P.chi, shape (...)."""
        M, P = self._split(y)
        return (0.5 * np.einsum("...i,ij,...j", M, self.Ainv, M) + M @ self.Omega0 + P @ self.chi)

    def casimirs(self, y):
        """(|P|^2, M.P), shape (..., 2)."""
        M, P = self._split(y)
        return np.stack([np.einsum("...i,...i", P, P), np.einsum("...i,...i", M, P)], axis=-1)

    def _require_axisymmetric_chi(self, what):
        if np.abs(self.chi[:2]).max() > 0 or np.abs(self.Omega0).max() > 0:
            raise DnarodError(f"{what}: needs chi = (0, 0, c) and Omega0 = 0")

    def lagrange_integral(self, y):
        """M3, conserved when A11 = A22, chi = (0, 0, c), Omega0 = 0."""
        self._require_axisymmetric_chi("lagrange_integral")
        A = self.A
        if abs(A[0, 0] - A[1, 1]) > 1e-12 * abs(A[0, 0]) or np.abs(A - np.diag(np.diag(A))).max() > 0:
            raise DnarodError("lagrange_integral: needs diagonal A with A11 = A22")
        return self._split(y)[0][..., 2]

    def kowalewski_integral(self, y):
        """|(Omega3 + i Omega1)^2 - (c/A22)(P3 + i P1)|^2, conserved when A33 = A11 = 2 A22."""
        self._require_axisymmetric_chi("kowalewski_integral")
        A = self.A
        a = A[1, 1]
        if (np.abs(A - np.diag(np.diag(A))).max() > 0 or abs(A[0, 0] - 2 * a) > 1e-12 * a
                or abs(A[2, 2] - 2 * a) > 1e-12 * a):
            raise DnarodError("kowalewski_integral: needs A = diag(2a, a, 2a)")
        M, P = self._split(y)
        Om = self.omega(M)
        z = (Om[..., 2] + 1j * Om[..., 0]) ** 2 - (self.chi[2] / a) * (P[..., 2] + 1j * P[..., 0])
        return np.abs(z) ** 2

    def discrete_step(self, M, P, ds, reading="R1"):
        """One step of the s-discrete top (4.5a,b): (M, P) at k -> (M1, P1) at k+1."""
        ds = as_ds(ds)
        reading = as_reading(reading)
        M = np.asarray(M, dtype=float)
        Om = self.omega(M)
        return static_stress_step(Om, self.chi, M, P, ds, reading)
