"""Case 3 of the paper: the discrete Kirchhoff (unshearable, inextensible) rod, (6.2), with its constraint.

With Gamma = chi = (0, 0, 1) fixed, (3.13a) does not disappear as (6.2) suggests (misprint 17): it
becomes the constraint (docs/lax.md, special cases: Case 3)::

    R1:       0 = (gamma1 - gamma)/ds + chi x omega1 + Omega x gamma
    midpoint: 0 = (gamma1 - gamma)/ds + chi x omegabar + Omega x gammabar

and the force P has no constitutive law: it is the Lagrange multiplier that keeps the constraint.
Unknowns: Omega, omega, gamma, M, P, m, p (21 per node) = 9 evolution equations ((3.13b,c,d))
+ 3 constraints + 9 constitutive relations M = A(Omega - Omega0), m = I omega, p = rho gamma
((6.2e-g)); the paper's count of 18 (misprint 18) omits P.

Here P is found at every instant from d/dt(constraint) = 0 (index reduction), a linear system of
size 3n. The evolution equations are those of :func:`dnarod.physics.lax.smk_rhs` (same code), so the
R1 reading inherits the linear instability of the paper's forward-forward pairing (docs/lax.md):
integrate it over short times only.
"""
from __future__ import annotations

import numpy as np

from dnarod.physics.lax.cases._ode import dop853
from dnarod.core.errors import DnarodError, SimulationError
from dnarod.physics.lax._checks import as_ds, as_fields, as_reading
from dnarod.physics.lax.components import _midpoint, _r1, smk_rhs

__all__ = ["KirchhoffRod"]


def _mat3(name, v):
    v = np.asarray(v, dtype=float)
    if v.shape == (3,):
        v = np.diag(v)
    if v.shape != (3, 3) or not np.isfinite(v).all():
        raise DnarodError(f"{name}: expected a finite 3x3 matrix or 3 principal values, got shape {v.shape}")
    if np.abs(v - v.T).max() > 1e-12 * np.abs(v).max() or np.linalg.eigvalsh(v)[0] <= 0:
        raise DnarodError(f"{name}: must be symmetric positive definite")
    return v


def _solve(L, b, what):
    """Least-squares (minimum-norm) solution of L x = b; raise if the system is inconsistent.

    L can be singular: rigid motions leave the midpoint constraint invariant, and a straight periodic
    rod has an undetermined uniform tension. Any solution is then valid; an inconsistent system is not.
    """
    x, *_ = np.linalg.lstsq(L, b, rcond=1e-12)
    scale = max(np.abs(L).max() * np.abs(x).max(), np.abs(b).max(), 1e-300)
    if np.abs(L @ x - b).max() > 1e-8 * scale:
        raise SimulationError(f"Kirchhoff rod: the linear system for the {what} has no solution "
                              f"(residual {np.abs(L @ x - b).max():.3g}); the configuration is degenerate",
                              term="constraint")
    return x


class KirchhoffRod:
    """Discrete Kirchhoff rod (6.2) plus the inextensibility constraint, P as multiplier.

    Parameters
    ----------
    A : array_like, shape (3, 3) or (3,)
        Bending/twisting modulus (kJ/mol nm).
    inertia : array_like, shape (3, 3) or (3,)
        Moment of inertia per unit length I (amu nm); m = I omega.
    rho : float
        Mass per unit length (amu/nm); p = rho gamma.
    ds : float
        Step length (nm).
    Omega0 : array_like, shape (3,)
        Intrinsic bend/twist (1/nm), default 0.
    chi : array_like, shape (3,)
        The fixed Gamma, default (0, 0, 1).
    reading : {"R1", "midpoint"}
    periodic : bool

    Notes
    -----
    The state vector is y = (Omega, m, p) flattened, shape (9 n,).
    """

    def __init__(self, A, inertia, rho, ds, Omega0=(0.0, 0.0, 0.0), chi=(0.0, 0.0, 1.0), reading="R1",
                 periodic=True):
        self.A = _mat3("A", A)
        self.inertia = _mat3("inertia", inertia)
        self.Iinv = np.linalg.inv(self.inertia)
        rho = float(rho)
        if not np.isfinite(rho) or rho <= 0:
            raise DnarodError(f"rho: must be positive, got {rho!r}")
        self.rho = rho
        self.ds = as_ds(ds)
        self.Omega0 = np.asarray(Omega0, dtype=float)
        self.chi = np.asarray(chi, dtype=float)
        for name, v in (("Omega0", self.Omega0), ("chi", self.chi)):
            if v.shape != (3,) or not np.isfinite(v).all():
                raise DnarodError(f"{name}: expected a finite 3-vector")
        self.reading = as_reading(reading)
        self.periodic = bool(periodic)
        self._fn = _r1 if self.reading == "R1" else _midpoint

    # ------------------------------------------------------------------ state helpers
    def split(self, y):
        """(Omega, m, p), each (n, 3), from the flat state."""
        y = np.asarray(y, dtype=float)
        if y.ndim != 1 or y.size % 9 or y.size == 0:
            raise DnarodError(f"y: expected a flat state of 9 n values (Omega, m, p), got shape {y.shape}")
        n = y.size // 9
        return y[:3 * n].reshape(n, 3), y[3 * n:6 * n].reshape(n, 3), y[6 * n:].reshape(n, 3)

    @staticmethod
    def join(Omega, m, p):
        """Flat state from (Omega, m, p)."""
        Omega, m, p = as_fields(("Omega", "m", "p"), (Omega, m, p))
        return np.concatenate([Omega.ravel(), m.ravel(), p.ravel()])

    def fields(self, y, P=None):
        """The 24 fields (Gamma, Omega, p, m, gamma, omega, P, M) of state y (P = 0 unless given)."""
        Omega, m, p = self.split(y)
        n = Omega.shape[0]
        Gamma = np.broadcast_to(self.chi, (n, 3)).copy()
        M = (Omega - self.Omega0) @ self.A.T
        omega = m @ self.Iinv.T
        gamma = p / self.rho
        P = np.zeros((n, 3)) if P is None else P
        return Gamma, Omega, p, m, gamma, omega, P, M

    def _step_fn(self, *f):
        nxt = []
        for x in f[4:]:
            x1 = np.roll(x, -1, axis=0)
            if not self.periodic:
                x1[-1] = 0.0
            nxt.append(x1)
        return self._fn(*f, *nxt, 0.0, self.ds)

    # ------------------------------------------------------------------ constraint and multiplier
    def constraint(self, y):
        """Residual of the inextensibility constraint (3.13a with Gamma = chi), shape (n, 3)."""
        return self._step_fn(*self.fields(y))[0]

    def _constraint_rate_linear(self, Omega, gdot, wdot):
        # d/dt of the constraint, the part linear in (gamma_dot, omega_dot) at fixed Omega (batch-aware)
        z = np.zeros_like(gdot)
        Om = Omega[:, None, :] if gdot.ndim == 3 else Omega
        chi = np.broadcast_to(self.chi, Om.shape)
        return self._step_fn(chi, Om, z, z, gdot, wdot, z, z)[0]

    def multiplier(self, y):
        """Force P (n, 3) for which the constraint rate vanishes (solves a 3n x 3n linear system)."""
        Gamma, Omega, p, m, gamma, omega, _, M = self.fields(y)
        n = Omega.shape[0]
        # P-independent part of the rates
        dG0, dO0, dp0, dm0 = self._step_fn(Gamma, Omega, p, m, gamma, omega, np.zeros((n, 3)), M)
        gbar = gamma if self.reading == "R1" else 0.5 * (gamma + self._next(gamma))
        c0 = self._constraint_rate_linear(Omega, dp0 / self.rho, dm0 @ self.Iinv.T) + np.cross(dO0, gbar)
        # the P-linear part, one batch column per unknown component of P
        E = np.zeros((n, 3 * n, 3))
        E[np.repeat(np.arange(n), 3), np.arange(3 * n), np.tile(np.arange(3), n)] = 1.0
        z = np.zeros_like(E)
        chi = np.broadcast_to(self.chi, (n, 3 * n, 3))
        _, _, dpP, dmP = self._step_fn(chi, Omega[:, None, :], z, z, z, z, E, z)
        cP = self._constraint_rate_linear(Omega, dpP / self.rho, dmP @ self.Iinv.T)   # (n, 3n, 3)
        L = np.transpose(cP, (0, 2, 1)).reshape(3 * n, 3 * n)
        return _solve(L, -c0.ravel(), "multiplier P").reshape(n, 3)

    def _next(self, x):
        x1 = np.roll(x, -1, axis=0)
        if not self.periodic:
            x1[-1] = 0.0
        return x1

    def consistent_momenta(self, Omega, m):
        """Linear momenta p (n, 3) that satisfy the constraint exactly for the given Omega and m."""
        Omega, m = as_fields(("Omega", "m"), (Omega, m))
        n = Omega.shape[0]
        omega = m @ self.Iinv.T
        z = np.zeros((n, 3))
        c_omega = self._constraint_rate_linear(Omega, z, omega)     # the gamma-independent part
        E = np.zeros((n, 3 * n, 3))
        E[np.repeat(np.arange(n), 3), np.arange(3 * n), np.tile(np.arange(3), n)] = 1.0
        cg = self._constraint_rate_linear(Omega, E, np.zeros_like(E))
        L = np.transpose(cg, (0, 2, 1)).reshape(3 * n, 3 * n)
        gamma = _solve(L, -c_omega.ravel(), "consistent momenta").reshape(n, 3)
        return self.rho * gamma

    # ------------------------------------------------------------------ dynamics
    def rhs(self, t, y):
        """d/dt y, y = (Omega, m, p) flattened; the multiplier P is solved at every call."""
        P = self.multiplier(y)
        Gamma, Omega, p, m, gamma, omega, _, M = self.fields(y)
        _, dO, dp, dm = smk_rhs(Gamma, Omega, p, m, gamma, omega, P, M, self.ds, reading=self.reading,
                                periodic=self.periodic)
        return np.concatenate([dO.ravel(), dm.ravel(), dp.ravel()])

    def integrate(self, y0, t_end, n_out=101, rtol=1e-12, atol=1e-12):
        """Integrate with DOP853; returns (t (n_out,), y (n_out, 9 n))."""
        y0 = np.asarray(y0, dtype=float)
        self.split(y0)
        return dop853(self.rhs, y0, t_end, n_out, rtol, atol, "Kirchhoff rod")
