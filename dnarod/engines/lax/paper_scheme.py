"""The paper's printed s-discrete SMK equations (3.13) as an ODE, for comparison only (docs/lax.md).

The right-hand side is :func:`dnarod.physics.lax.smk_rhs` (reading ``"R1"``: the printed (3.13) with the
index misprint of (3.13a) fixed). Its variables are densities per unit length, all indexed by k:
strains ``Gamma_k, Omega_k`` of step k, momenta ``p_k = rho gamma_k`` and ``m_k = I omega_k`` of
node k (``rho = m_node/ds``, ``I = J/ds``), velocities and stresses. The exact system of docs/formulation.md §6
(:mod:`.exact`) is written in the same variables by :func:`exact_density_rhs`, so the two can be
compared term by term:

* :func:`distance_to_exact` evaluates both on smooth fields at several ``ds`` and gives the
  O(ds) distance and its observed order;
* :func:`growth_rate` is the largest real part of the eigenvalues of the strain-space Jacobian at
  the intrinsic state of a periodic rod: positive for the paper's scheme (it is linearly unstable:
  forward differences in both kinematics and balance laws), zero for the exact system.
* :func:`integrate_paper` integrates the paper's system for a short time (energy grows).

Never use the paper's scheme as an integrator (docs/lax.md).
"""
from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from dnarod.core.energy import stresses
from dnarod.core.errors import DnarodError
from dnarod.engines.lax.exact import body_loads, strain_rates
from dnarod.physics.lax import smk_rhs


class DensitySystem:
    """Periodic rod in density variables ``y = (Gamma, Omega, p, m)``, each (n, 3), flattened.

    Parameters
    ----------
    model : RodModel
        A circular chain (periodic indices); parameters, masses and inertias per node.
    scheme : {"paper", "exact"}
    reading : str
        Reading of :func:`dnarod.physics.lax.smk_rhs` for the paper scheme (``"R1"`` or ``"midpoint"``).
    """

    def __init__(self, model, scheme="paper", reading="R1"):
        if not model.circular:
            raise DnarodError("the paper-scheme comparison needs a circular (periodic) chain; build one with "
                              "circular=True or dnarod.physics.testsystems.TwistedRod")
        if scheme not in ("paper", "exact"):
            raise DnarodError(f"scheme must be 'paper' or 'exact', got {scheme!r}")
        self.model, self.scheme, self.reading = model, scheme, reading
        self.n = model.n_nodes
        self.ds = model.ds
        self.rho = model.mass[:, None] / model.ds
        self.I = model.inertia / model.ds

    def state(self, omega=None, gamma=None, Omega=None, Gamma=None):
        """Pack a state: strains (default: the model's) and body velocities (default 0)."""
        if Omega is None or Gamma is None:
            Omega, Gamma = self.model.strains()
        omega = np.zeros((self.n, 3)) if omega is None else omega
        gamma = np.zeros((self.n, 3)) if gamma is None else gamma
        return np.concatenate([Gamma.ravel(), Omega.ravel(), (self.rho * gamma).ravel(), (self.I * omega).ravel()])

    def unpack(self, y):
        return y.reshape(4, self.n, 3)

    def rhs(self, t, y):
        Gamma, Omega, p, m = self.unpack(y)
        if self.scheme == "exact":
            out = exact_density_rhs(Gamma, Omega, p, m, self.model.params, self.ds, self.rho, self.I)
        else:
            gamma, omega = p / self.rho, m / self.I
            M, P, _ = stresses(Omega, Gamma, self.model.params)
            out = smk_rhs(Gamma, Omega, p, m, gamma, omega, P, M, self.ds, reading=self.reading, periodic=True)
        return np.concatenate([np.asarray(o).ravel() for o in out])

    def energy(self, y):
        """Elastic + kinetic energy, kJ/mol."""
        Gamma, Omega, p, m = self.unpack(y)
        _, _, H = stresses(Omega, Gamma, self.model.params)
        return float(self.ds * (H.sum() + 0.5 * np.sum(p**2 / self.rho) + 0.5 * np.sum(m**2 / self.I)))

    def jacobian(self, y, eps=1e-6):
        """Central-difference Jacobian of the right-hand side, (12n, 12n), relative step ``eps``."""
        y = np.asarray(y, float)
        Jm = np.empty((y.size, y.size))
        for i in range(y.size):
            h = eps * max(1.0, abs(y[i]))
            yp, ym = y.copy(), y.copy()
            yp[i] += h
            ym[i] -= h
            Jm[:, i] = (self.rhs(0.0, yp) - self.rhs(0.0, ym)) / (2 * h)
        return Jm


def exact_density_rhs(Gamma, Omega, p, m, params, ds, rho, I):
    """The exact system of docs/formulation.md §6 (periodic) in the density variables of (3.13).

    ``dp = rho (dgamma) = f/ds - omega x p``, ``dm = I (domega) = tau/ds + m x omega`` with the exact body
    loads ``f, tau`` of :func:`.exact.body_loads` and the exact strain rates of :func:`.exact.strain_rates`.

    Returns
    -------
    dGamma, dOmega, dp, dm : ndarray, shape (n, 3)
    """
    gamma, omega = p / rho, m / I
    dOmega, dGamma = strain_rates(Omega, Gamma, omega, gamma, ds, circular=True)
    f, tq, _ = body_loads(Omega, Gamma, params, ds, Gamma.shape[0], circular=True)
    return dGamma, dOmega, f / ds - np.cross(omega, p), tq / ds + np.cross(m, omega)


def growth_rate(model, scheme="paper", reading="R1", eps=1e-6):
    """Largest real part (1/ps) of the eigenvalues of the strain-space Jacobian at the model's pose at rest.

    For a stress-free periodic rod the exact system is Hamiltonian and neutrally stable (result ~0,
    at the level of the finite-difference error); the paper's printed (3.13) gives a positive rate.
    """
    sysm = DensitySystem(model, scheme, reading)
    lam = np.linalg.eigvals(sysm.jacobian(sysm.state(), eps))
    return float(lam.real.max())


def smooth_fields(n, length, ds_model, params_row, amplitude=0.05, seed=0):
    """Smooth periodic strain and velocity fields at n points on a ring of given length (nm).

    Each component is its intrinsic value plus a few random long-wave Fourier modes (wavelength >= length/3).
    Returns Omega, Gamma, omega, gamma, each (n, 3).
    """
    rng = np.random.default_rng(seed)
    s = np.arange(n) * (length / n)
    out = []
    base = [params_row[:3], params_row[3:], np.zeros(3), np.zeros(3)]
    scale = [1.0, 0.2, 0.3, 0.3]
    for b, sc in zip(base, scale):
        f = np.tile(b, (n, 1)).astype(float)
        for mode in (1, 2, 3):
            a, ph = rng.standard_normal((2, 3))
            f += amplitude * sc * a * np.sin(2 * np.pi * mode * s[:, None] / length + ph)
        out.append(f)
    return out


def distance_to_exact(make_model, n_list=(16, 32, 64, 128), length=None, reading="R1", seed=0):
    """Distance between the paper's (3.13) and the exact right-hand side on smooth fields, for several ds.

    Parameters
    ----------
    make_model : callable n -> RodModel
        Builds the periodic rod of n nodes with ds = length / n and ds-independent material
        parameters (densities rho, I and per-length strains), e.g. ``lambda n: TwistedRod(n,
        ds=L/n, theta0=..., mass=rho*L/n, ...).model()``.
    n_list : sequence of int
    length : float, optional
        Ring length, nm (default n_list[0] * model ds).

    Returns
    -------
    dict
        ``ds`` (k,), ``distance`` (k, 4): max-norm of the difference of (dGamma, dOmega, dp, dm),
        each divided by the max-norm of the exact term; ``order`` (4,): observed orders from the
        last two ds.
    """
    ds_l, dist = [], []
    for n in n_list:
        model = make_model(n)
        L = n * model.ds if length is None else length
        Om, Ga, om, ga = smooth_fields(n, L, model.ds, model.params.intrinsic[0], seed=seed)
        ex = DensitySystem(model, "exact")
        pa = DensitySystem(model, "paper", reading)
        y = ex.state(om, ga, Om, Ga)
        a = ex.unpack(ex.rhs(0, y))
        b = pa.unpack(pa.rhs(0, y))
        dist.append([np.abs(a[i] - b[i]).max() / np.abs(a[i]).max() for i in range(4)])
        ds_l.append(model.ds)
    ds_a, dist = np.array(ds_l), np.array(dist)
    order = np.log(dist[-2] / dist[-1]) / np.log(ds_a[-2] / ds_a[-1])
    return dict(ds=ds_a, distance=dist, order=order)


def integrate_paper(model, t_end, omega=None, gamma=None, reading="R1", rtol=1e-8, atol=1e-10, n_frames=21):
    """Integrate the paper's (3.13) for a short time from a periodic model's pose.

    Returns
    -------
    t : ndarray (k,), ps
    energy : ndarray (k,), kJ/mol (grows for R1: the scheme is unstable)
    success : bool
        False when the integrator gave up (the solution blew up).
    """
    sysm = DensitySystem(model, "paper", reading)
    y0 = sysm.state(omega, gamma)
    sol = solve_ivp(sysm.rhs, (0.0, t_end), y0, method="DOP853", rtol=rtol, atol=atol,
                    t_eval=np.linspace(0, t_end, n_frames))
    return sol.t, np.array([sysm.energy(y) for y in sol.y.T]), bool(sol.success)
