"""Case 1 of the paper: the static discrete rod (4.1) with linear constitutive law (4.2)/(4.3).

With omega = gamma = m = p = 0 and no t-dependence, (3.13a,b) vanish and (3.13c,d) become the
difference equations (docs/lax.md, special cases: Case 1)::

    R1 (printed (4.1a,b), correct):   (M1-M)/ds + Gamma x P1 + Omega x M = 0
                                      (P1-P)_a/ds - (P_{a+1} Omega_{a+2} - Omega_{a+1} P1_{a+2}) = 0
    midpoint:                          (M1-M)/ds + Gamma x Pbar + Omega x Mbar = 0
                                       (P1-P)/ds + Omega x Pbar = 0

(4.1a) = -(3.13d) and (4.1b) = -(3.13c). Both are linear in the stresses at k+1, so the
equilibrium is a shooting map k -> k+1: solve for (M1, P1), then invert the constitutive law
``[M; P] = K [Omega - Omega0; Gamma - Gamma0]`` for (Omega1, Gamma1). The constitutive law uses
the full stiffness K = [[A, B], [B^T, C]] (dnarod.core.energy.stresses); the printed (4.3c,d) is right
only for symmetric A, B, C (misprint 13).

The midpoint map conserves |P|^2 and M.P exactly (P1 is a Cayley rotation of P); they are the
discrete analogues of the heavy top's Casimirs |gamma|^2 and L.gamma. The R1 map conserves them
only to O(ds) per unit length. The R1 map is singular where 1 + ds^3 Omega1 Omega2 Omega3 = 0
(det of the linear system for P1); the midpoint map never is. Both are first order in ds against the
continuum rod M' = M x Omega + P x Gamma, P' = P x Omega (the U-fields sit at node k in both).
"""
from __future__ import annotations

import numpy as np

from dnarod.core.energy import stresses
from dnarod.core.errors import DnarodError, SimulationError
from dnarod.core.parameters import StepParameters, check_stiffness
from dnarod.core.rotations import hat
from dnarod.physics.lax._checks import as_ds, as_reading

__all__ = ["StaticRod", "static_stress_step"]


def _vec3(name, v):
    v = np.asarray(v, dtype=float)
    if v.shape != (3,):
        raise DnarodError(f"{name}: expected a 3-vector, got shape {v.shape}")
    if not np.isfinite(v).all():
        raise DnarodError(f"{name}: contains non-finite values")
    return v


def _r1_force_matrix(Omega, ds):
    """Matrix S with (S x)_a = Omega_{a+1} x_{a+2}, so (4.1b) reads (I/ds + S) P1 = P/ds + (P_{a+1}Omega_{a+2})_a."""
    S = np.zeros((3, 3))
    for a in range(3):
        S[a, (a + 2) % 3] = Omega[(a + 1) % 3]
    return np.eye(3) / ds + S


def static_stress_step(Omega, Gamma, M, P, ds, reading="R1"):
    """Stresses at node k+1 from the static equations (4.1a,b), given node k.

    Parameters
    ----------
    Omega, Gamma : array_like, shape (3,)
        Strains at node k (1/nm, dimensionless).
    M, P : array_like, shape (3,)
        Moment and force stresses at node k.
    ds : float
        Step length (nm), > 0.
    reading : {"R1", "midpoint"}

    Returns
    -------
    M1, P1 : ndarray, shape (3,)
    """
    Omega, Gamma, M, P = (_vec3(n, v) for n, v in zip(("Omega", "Gamma", "M", "P"), (Omega, Gamma, M, P)))
    ds = as_ds(ds)
    reading = as_reading(reading)
    if reading == "R1":
        # det(I/ds + S) = 1/ds^3 + Omega1 Omega2 Omega3: the R1 map is singular where ds^3 O1 O2 O3 = -1
        if abs(1.0 + ds ** 3 * np.prod(Omega)) < 1e-10:
            raise SimulationError(f"static R1 map is singular at Omega = {Omega.tolist()} (1 + ds^3 O1 O2 O3 = 0); "
                                  f"reduce ds or use reading='midpoint'", term="static map")
        rhs = P / ds + np.roll(P, -1) * np.roll(Omega, -2)
        P1 = np.linalg.solve(_r1_force_matrix(Omega, ds), rhs)
        M1 = M - ds * (np.cross(Gamma, P1) + np.cross(Omega, M))
    else:
        W = 0.5 * ds * hat(Omega)
        lhs = np.eye(3) + W
        P1 = np.linalg.solve(lhs, (np.eye(3) - W) @ P)
        Pbar = 0.5 * (P + P1)
        M1 = np.linalg.solve(lhs, (np.eye(3) - W) @ M - ds * np.cross(Gamma, Pbar))
    return M1, P1


class StaticRod:
    """Equilibria of the static discrete rod (4.1)/(4.3) as a shooting map in k.

    Parameters
    ----------
    stiffness : array_like, shape (6, 6)
        Symmetric positive definite K = [[A, B], [B^T, C]] (kJ/mol nm, strain order Omega, Gamma).
    intrinsic : array_like, shape (6,)
        Intrinsic strains (Omega0 1/nm, Gamma0).
    ds : float
        Step length, nm.
    reading : {"R1", "midpoint"}
    """

    def __init__(self, stiffness, intrinsic, ds, reading="R1"):
        self.stiffness = check_stiffness(stiffness)
        xi0 = np.asarray(intrinsic, dtype=float)
        if xi0.shape != (6,) or not np.isfinite(xi0).all():
            raise DnarodError(f"intrinsic: expected 6 finite intrinsic strains, got shape {xi0.shape}")
        self.intrinsic = xi0
        self.ds = as_ds(ds)
        self.reading = as_reading(reading)
        self._params = StepParameters.uniform(self.stiffness, xi0, 1, name="static")

    def stresses(self, Omega, Gamma):
        """(M, P) of strains (shape (3,) each), via dnarod.core.energy.stresses."""
        M, P, _ = stresses(np.atleast_2d(Omega), np.atleast_2d(Gamma), self._params)
        return M[0], P[0]

    def strains_of(self, M, P):
        """Invert the constitutive law: (Omega, Gamma) with stresses (M, P)."""
        xi = np.linalg.solve(self.stiffness, np.concatenate([M, P])) + self.intrinsic
        return xi[:3], xi[3:]

    def step(self, Omega, Gamma):
        """Strains at node k+1 from strains at node k; returns (Omega1, Gamma1)."""
        M, P = self.stresses(_vec3("Omega", Omega), _vec3("Gamma", Gamma))
        M1, P1 = static_stress_step(Omega, Gamma, M, P, self.ds, self.reading)
        return self.strains_of(M1, P1)

    def shoot(self, Omega0, Gamma0, n_steps):
        """Iterate :meth:`step` from node 0.

        Parameters
        ----------
        Omega0, Gamma0 : array_like, shape (3,)
        n_steps : int

        Returns
        -------
        Omega, Gamma, M, P : ndarray, shape (n_steps + 1, 3)
        """
        if int(n_steps) != n_steps or n_steps < 0:
            raise DnarodError(f"n_steps: expected a non-negative integer, got {n_steps!r}")
        n = int(n_steps) + 1
        out = np.zeros((4, n, 3))
        out[0, 0], out[1, 0] = _vec3("Omega0", Omega0), _vec3("Gamma0", Gamma0)
        out[2, 0], out[3, 0] = self.stresses(out[0, 0], out[1, 0])
        for k in range(n - 1):
            M1, P1 = static_stress_step(out[0, k], out[1, k], out[2, k], out[3, k], self.ds, self.reading)
            out[0, k + 1], out[1, k + 1] = self.strains_of(M1, P1)
            out[2, k + 1], out[3, k + 1] = M1, P1
        return out[0], out[1], out[2], out[3]

    @staticmethod
    def casimirs(M, P):
        """(|P|^2, M.P) per node, shape (..., 2): exact invariants of the midpoint map."""
        M = np.asarray(M, dtype=float)
        P = np.asarray(P, dtype=float)
        return np.stack([np.einsum("...i,...i", P, P), np.einsum("...i,...i", M, P)], axis=-1)
