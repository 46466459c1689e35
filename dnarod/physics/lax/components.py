"""The 12 component equations (3.9) for any real lam, and their lam -> 0 limit, the s-discrete SMK (3.13).

Both readings (docs/lax.md) are provided as right-hand sides ``d/dt (Gamma, Omega, p, m)``
given the V-fields ``(gamma, omega, P, M)``:

* ``reading="R1"``: the paper's entrywise reading (entries (a+1, a+2) and (a, 4) of the Lax
  residual set to zero), with the misprints #4-#7 of the table in docs/lax.md corrected::

    dGamma = (gamma1-gamma)/ds + Gamma x omega1 + Omega x gamma + lam^2 (M x p - m x P1)
    dOmega_a = (omega1-omega)_a/ds + (Omega_{a+1} omega1_{a+2} - omega_{a+1} Omega_{a+2})
             + lam^2 (P_{a+1} p_{a+2} - p_{a+1} P1_{a+2}) + lam^4 (Gamma_{a+1} gamma_{a+2} - gamma1_{a+1} Gamma_{a+2})
             + lam^6 (M1_{a+1} m_{a+2} - m_{a+1} M_{a+2})
    dp_a = (P1-P)_a/ds + (p_{a+1} omega1_{a+2} - omega_{a+1} p_{a+2}) - (P_{a+1} Omega_{a+2} - Omega_{a+1} P1_{a+2})
         + lam^4 (Gamma_{a+1} M_{a+2} - M1_{a+1} Gamma_{a+2} + m_{a+1} gamma_{a+2} - gamma1_{a+1} m_{a+2})
    dm = (M1-M)/ds + p x gamma + Gamma x P1 + Omega x M + m x omega1

* ``reading="midpoint"``: the so(4) projection of the residual, frame-covariant, with
  ``xbar = (x_k + x_{k+1})/2``::

    dGamma = (gamma1-gamma)/ds + Gamma x omegabar + Omega x gammabar + lam^2 (Mbar x p - m x Pbar)
    dOmega = (omega1-omega)/ds + Omega x omegabar - lam^2 p x Pbar + lam^4 Gamma x gammabar - lam^6 m x Mbar
    dp     = (P1-P)/ds + p x omegabar + Omega x Pbar + lam^4 (m x gammabar + Gamma x Mbar)
    dm     = (M1-M)/ds + m x omegabar + Gamma x Pbar + Omega x Mbar + p x gammabar

Superscript 1 = node k+1; for ``periodic=True`` it wraps around (node n-1 couples to node 0); for
``periodic=False`` the field at node n (past the last node) is taken as ZERO, so the last node sees
``x1 = 0`` (a free end with zero stress and zero velocity beyond it). Indices a+1, a+2 are mod 3.
"""
from __future__ import annotations

from dnarod.physics.lax._checks import as_ds, as_fields, as_lambda, as_reading, shift_next
from dnarod.physics.lax.pair import U_NAMES, V_NAMES

__all__ = ["component_rhs", "smk_rhs", "appendix_rhs"]


_P1 = [1, 2, 0]   # component a+1 (mod 3)
_P2 = [2, 0, 1]   # component a+2 (mod 3)


def _cyc(x, y):
    """Component a: x_{a+1} y_{a+2} (indices mod 3)."""
    return x[..., _P1] * y[..., _P2]


def _cross(x, y):
    """x × y over the last axis (np.cross has a large per-call overhead for small arrays)."""
    return x[..., _P1] * y[..., _P2] - x[..., _P2] * y[..., _P1]


def _r1(Gamma, Omega, p, m, gamma, omega, P, M, g1, w1, P1, M1, lam, ds):
    l2, l4, l6 = lam ** 2, lam ** 4, lam ** 6
    cross = _cross
    dGamma = (g1 - gamma) / ds + cross(Gamma, w1) + cross(Omega, gamma)
    dOmega = (w1 - omega) / ds + _cyc(Omega, w1) - _cyc(omega, Omega)
    dp = (P1 - P) / ds + _cyc(p, w1) - _cyc(omega, p) - (_cyc(P, Omega) - _cyc(Omega, P1))
    dm = (M1 - M) / ds + cross(p, gamma) + cross(Gamma, P1) + cross(Omega, M) + cross(m, w1)
    if lam != 0.0:
        dGamma = dGamma + l2 * (cross(M, p) - cross(m, P1))
        dOmega = (dOmega + l2 * (_cyc(P, p) - _cyc(p, P1)) + l4 * (_cyc(Gamma, gamma) - _cyc(g1, Gamma))
                  + l6 * (_cyc(M1, m) - _cyc(m, M)))
        dp = dp + l4 * (_cyc(Gamma, M) - _cyc(M1, Gamma) + _cyc(m, gamma) - _cyc(g1, m))
    return dGamma, dOmega, dp, dm


def _midpoint(Gamma, Omega, p, m, gamma, omega, P, M, g1, w1, P1, M1, lam, ds):
    l2, l4, l6 = lam ** 2, lam ** 4, lam ** 6
    cross = _cross
    gb, wb, Pb, Mb = 0.5 * (gamma + g1), 0.5 * (omega + w1), 0.5 * (P + P1), 0.5 * (M + M1)
    dGamma = (g1 - gamma) / ds + cross(Gamma, wb) + cross(Omega, gb)
    dOmega = (w1 - omega) / ds + cross(Omega, wb)
    dp = (P1 - P) / ds + cross(p, wb) + cross(Omega, Pb)
    dm = (M1 - M) / ds + cross(m, wb) + cross(Gamma, Pb) + cross(Omega, Mb) + cross(p, gb)
    if lam != 0.0:
        dGamma = dGamma + l2 * (cross(Mb, p) - cross(m, Pb))
        dOmega = dOmega - l2 * cross(p, Pb) + l4 * cross(Gamma, gb) - l6 * cross(m, Mb)
        dp = dp + l4 * (cross(m, gb) + cross(Gamma, Mb))
    return dGamma, dOmega, dp, dm


def component_rhs(Gamma, Omega, p, m, gamma, omega, P, M, lam, ds, reading="R1", periodic=True):
    """Right-hand sides of the 12 component equations (3.9), corrected, for a real spectral parameter.

    Parameters
    ----------
    Gamma, Omega, p, m : array_like, shape (n, 3)
        U-fields per node (Gamma dimensionless, Omega 1/nm, momenta per unit length).
    gamma, omega, P, M : array_like, shape (n, 3)
        V-fields per node (velocity nm/ps, angular velocity 1/ps, force, moment).
    lam : float
        Real spectral parameter (lam = 0 gives :func:`smk_rhs`).
    ds : float
        Step length (nm), > 0.
    reading : {"R1", "midpoint"}
        The paper's entrywise reading (corrected) or the covariant so(4) projection (module docstring).
    periodic : bool
        True: node k+1 of the last node is node 0. False: fields at node k+1 of the last node are 0.

    Returns
    -------
    dGamma, dOmega, dp, dm : ndarray, shape (n, 3)
        Time derivatives (per ps) of the U-fields.

    Raises
    ------
    DnarodError
        Wrong shapes, mismatched node counts, non-finite values, ds <= 0, unknown reading.
    """
    f = as_fields(U_NAMES + V_NAMES, (Gamma, Omega, p, m, gamma, omega, P, M))
    ds = as_ds(ds)
    lam = as_lambda(lam)
    reading = as_reading(reading)
    nxt = [shift_next(x, periodic) for x in f[4:]]
    fn = _r1 if reading == "R1" else _midpoint
    return fn(*f, *nxt, lam, ds)


def smk_rhs(Gamma, Omega, p, m, gamma, omega, P, M, ds, reading="R1", periodic=True):
    """The s-discrete SMK equations (3.13), corrected: the lam -> 0 limit of :func:`component_rhs`.

    ``reading="R1"`` is the paper's printed (3.13b,c,d) with (3.13a)'s repeated index fixed
    (misprint 4: ``eps_abc (Gamma_a omega1_b + Omega_a gamma_b)``)::

        dGamma = (gamma1-gamma)/ds + Gamma x omega1 + Omega x gamma
        dOmega_a = (omega1-omega)_a/ds + Omega_{a+1} omega1_{a+2} - omega_{a+1} Omega_{a+2}
        dp_a = (P1-P)_a/ds + p_{a+1} omega1_{a+2} - omega_{a+1} p_{a+2} + Omega_{a+1} P1_{a+2} - P_{a+1} Omega_{a+2}
        dm = (M1-M)/ds + m x omega1 + Gamma x P1 + Omega x M + p x gamma

    ``reading="midpoint"`` is the covariant form with ``xbar = (x_k + x_{k+1})/2``::

        dGamma = (gamma1-gamma)/ds + Gamma x omegabar + Omega x gammabar
        dOmega = (omega1-omega)/ds + Omega x omegabar
        dp = (P1-P)/ds + p x omegabar + Omega x Pbar
        dm = (M1-M)/ds + m x omegabar + Gamma x Pbar + Omega x Mbar + p x gammabar

    Parameters
    ----------
    Gamma, Omega, p, m : array_like, shape (n, 3)
        U-fields per node: strains Gamma (dimensionless), Omega (1/nm); momentum densities p, m.
    gamma, omega, P, M : array_like, shape (n, 3)
        V-fields per node: velocities gamma (nm/ps), omega (1/ps); stresses P (force), M (moment).
    ds : float
        Step length (nm), > 0.
    reading : {"R1", "midpoint"}
    periodic : bool
        True: the superscript-1 (node k+1) fields wrap around. False: at the last node the k+1
        fields are taken as zero.

    Returns
    -------
    dGamma, dOmega, dp, dm : ndarray, shape (n, 3)

    Notes
    -----
    These are the paper's equations, not the exact rod (docs/formulation.md §6): paired forward differences
    make the R1 system linearly unstable for a physical rod (docs/lax.md); use it for comparison.
    """
    return component_rhs(Gamma, Omega, p, m, gamma, omega, P, M, 0.0, ds, reading=reading, periodic=periodic)


def appendix_rhs(Gamma, Omega, p, m, gamma, omega, P, M, zeta, ds, reading="R1", periodic=True):
    """Corrected (A.4) of Appendix A for real zeta: identical to :func:`component_rhs` at lam = zeta.

    The 8x8 pair (A.2) with real zeta is the real form of the 4x4 pair conjugated by
    diag(1,1,1,-1) (docs/lax.md), so its component equations are those of (3.9); the printed (A.4)
    carries the sign misprints #9-#11 of the table in docs/lax.md. Reading "R1" uses entries (a+1, a+2) and
    (a, 4) of the upper-left block as for (3.9).
    """
    return component_rhs(Gamma, Omega, p, m, gamma, omega, P, M, zeta, ds, reading=reading, periodic=periodic)
