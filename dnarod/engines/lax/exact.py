"""The exact Lax-form (zero-curvature) system in strain space (docs/formulation.md §6), integrated with DOP853.

State: strains ``Omega_k, Gamma_k`` of every step (equivalently ``U_k = g_k^-1 g_{k+1}`` in SE(3)),
body velocities ``omega_k`` (rad/ps) and ``gamma_k = L_k^T dr_k/dt`` (nm/ps) of every node, and the
pose of node 0 (position, unit quaternion). The right-hand side is

* the exact strain rates (the column form of ``dU_k/dt = U_k V_{k+1} - V_k U_k``)::

    dOmega_k = (w_{k+1} - w_k)/ds + 1/2 Omega_k x (w_k + w_{k+1}) + ds/4 Omega_k [Omega_k . (w_{k+1} - w_k)]
    dGamma_k = (R_k g_{k+1} - g_k)/ds + Gamma_k x w_k          (w = omega, g = gamma)

* the exact node balance laws (body frame of node k, stresses of steps k-1 and k)::

    m_k (dg_k + w_k x g_k)       = P_k - R_{k-1}^T P_{k-1}
    J_k dw_k + w_k x J_k w_k     = T_k^T M_k - T_{k-1} M_{k-1} + ds Gamma_k x P_k

Stresses come from :func:`dnarod.core.energy.stresses` and ``T`` is :func:`dnarod.core.rotations.cayley_T`;
poses are rebuilt with ``g_{k+1} = g_k U_k`` by :func:`dnarod.core.strains.chain_from_strains`.
Circular chains use periodic indices: the image node N = S g_0 has the body velocity of node 0
because the screw closure S is constant. Energy, momentum and angular momentum are conserved
exactly in continuous time.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from dnarod.core.energy import stresses
from dnarod.core.errors import DnarodError, SimulationError
from dnarod.core.strains import chain_from_strains
from dnarod.physics.thermal import node_kinetic_energy
from dnarod.core.trajectory import Trajectory
from dnarod.engines.lax.boundary import BoundaryConditions
from dnarod.core.rotations import hat


def _rot_apply(w, v, transpose=False):
    """``cay(w) v`` (or ``cay(w)^T v``) for stacks of Cayley vectors ``w`` and vectors ``v``, shape (m, 3)."""
    s = -1.0 if transpose else 1.0
    wxv = np.cross(w, v)
    return v + (s * wxv + 0.5 * np.cross(w, wxv)) / (1.0 + 0.25 * np.einsum("ki,ki->k", w, w))[:, None]


def strain_rates(Omega, Gamma, omega, gamma, ds, circular=False):
    """Exact time derivatives of the Cayley strains (docs/formulation.md §6).

    Parameters
    ----------
    Omega, Gamma : ndarray, shape (n_steps, 3)
        Strains, 1/nm and dimensionless.
    omega, gamma : ndarray, shape (n_nodes, 3)
        Body angular velocities (rad/ps) and body centre velocities ``L^T dr/dt`` (nm/ps).
    ds : float
        nm.
    circular : bool
        Periodic indexing (``n_steps == n_nodes``).

    Returns
    -------
    dOmega : ndarray, shape (n_steps, 3)
        1/(nm ps).
    dGamma : ndarray, shape (n_steps, 3)
        1/ps.
    """
    w0, g0 = omega[: Omega.shape[0]], gamma[: Omega.shape[0]]
    if circular:
        w1, g1 = np.roll(omega, -1, axis=0), np.roll(gamma, -1, axis=0)
    else:
        w1, g1 = omega[1:], gamma[1:]
    dw = w1 - w0
    dOmega = (dw / ds + 0.5 * np.cross(Omega, w0 + w1)
              + 0.25 * ds * Omega * np.einsum("ki,ki->k", Omega, dw)[:, None])
    dGamma = (_rot_apply(ds * Omega, g1) - g0) / ds + np.cross(Gamma, w0)
    return dOmega, dGamma


def body_loads(Omega, Gamma, params, ds, n_nodes, circular=False):
    """Body-frame force and torque on every node from the step stresses (docs/formulation.md §6).

    Returns
    -------
    f : ndarray, shape (n_nodes, 3)
        ``L_k^T F_k``, kJ/mol/nm.
    t : ndarray, shape (n_nodes, 3)
        ``L_k^T tau_k``, kJ/mol.
    E : float
        Elastic energy, kJ/mol.
    """
    M, P, H = stresses(Omega, Gamma, params)
    w = ds * Omega
    wM = np.einsum("ki,ki->k", w, M)[:, None]
    TtM = M + 0.5 * np.cross(w, M) + 0.25 * w * wM    # T_k^T M_k, acts on the left node
    TM = M - 0.5 * np.cross(w, M) + 0.25 * w * wM     # T_k M_k, acts (negatively) on the right node
    RtP = _rot_apply(w, P, transpose=True)             # R_k^T P_k in the right node's frame
    m = Omega.shape[0]
    f = np.zeros((n_nodes, 3))
    t = np.zeros((n_nodes, 3))
    f[:m] += P
    t[:m] += TtM + ds * np.cross(Gamma, P)
    if circular:
        f -= np.roll(RtP, 1, axis=0)
        t -= np.roll(TM, 1, axis=0)
    else:
        f[1:] -= RtP
        t[1:] -= TM
    return f, t, float(ds * H.sum())


def lax_matrices(positions, frames, velocities_body, angular_velocities_body, closure=None):
    """The exact Lax pair in the column convention: ``U_k = g_k^-1 g_{k+1}`` and ``V_k = g_k^-1 dg_k/dt``.

    Parameters
    ----------
    positions : ndarray, shape (n_nodes, 3)
    frames : ndarray, shape (n_nodes, 3, 3)
    velocities_body : ndarray, shape (n_nodes, 3)
        ``gamma_k = L_k^T dr_k/dt``, nm/ps.
    angular_velocities_body : ndarray, shape (n_nodes, 3)
        rad/ps.
    closure : Closure or None

    Returns
    -------
    U : ndarray, shape (n_steps, 4, 4)
    V : ndarray, shape (n_nodes, 4, 4)
    """
    n = positions.shape[0]
    g = np.zeros((n + 1, 4, 4))
    g[:n, :3, :3], g[:n, :3, 3], g[:, 3, 3] = frames, positions, 1.0
    if closure is not None:
        g[n, :3, :3], g[n, :3, 3] = closure.Q @ frames[0], closure.Q @ positions[0] + closure.t
    m = n if closure is not None else n - 1
    U = np.linalg.inv(g[:m]) @ g[1:m + 1]
    V = np.zeros((n, 4, 4))
    V[:, :3, :3], V[:, :3, 3] = hat(angular_velocities_body), velocities_body
    return U, V


class ExactSystem:
    """The strain-space ODE of a model (docs/formulation.md §6), packed for :func:`scipy.integrate.solve_ivp`.

    Parameters
    ----------
    model : RodModel
    boundary : BoundaryConditions, optional

    Notes
    -----
    State vector layout: ``Omega (m*3), Gamma (m*3), omega (n*3), gamma (n*3), r_0 (3), q_0 (4)``
    with the quaternion scalar-last (scipy convention).
    """

    def __init__(self, model, boundary=None):
        self.model = model
        self.n = model.n_nodes
        self.m = model.n_steps
        self.ds = model.ds
        self.circular = model.circular
        self.boundary = boundary or BoundaryConditions()
        self.clamp, self.F_ext, self.tau_ext = self.boundary.resolve(self.n, self.circular)
        self.loaded = np.flatnonzero(np.abs(self.F_ext).sum(1) + np.abs(self.tau_ext).sum(1) > 0)
        self.mass = model.mass
        self.inertia = model.inertia

    # --- packing ---------------------------------------------------------------------------
    def pack(self, Omega, Gamma, omega, gamma, r0, L0):
        q0 = Rotation.from_matrix(L0).as_quat()
        return np.concatenate([Omega.ravel(), Gamma.ravel(), omega.ravel(), gamma.ravel(), r0, q0])

    def unpack(self, y):
        m3, n3 = 3 * self.m, 3 * self.n
        Omega = y[:m3].reshape(self.m, 3)
        Gamma = y[m3:2 * m3].reshape(self.m, 3)
        omega = y[2 * m3:2 * m3 + n3].reshape(self.n, 3)
        gamma = y[2 * m3 + n3:2 * m3 + 2 * n3].reshape(self.n, 3)
        r0 = y[2 * m3 + 2 * n3:2 * m3 + 2 * n3 + 3]
        q0 = y[2 * m3 + 2 * n3 + 3:]
        return Omega, Gamma, omega, gamma, r0, q0

    def initial_state(self, velocities=None, angular_velocities=None):
        """State vector of the model's pose with lab centre velocities (nm/ps) and body angular velocities (rad/ps)."""
        model = self.model
        v = np.zeros((self.n, 3)) if velocities is None else np.asarray(velocities, float)
        om = np.zeros((self.n, 3)) if angular_velocities is None else np.asarray(angular_velocities, float)
        if v.shape != (self.n, 3) or om.shape != (self.n, 3):
            raise DnarodError(f"velocities and angular velocities must have shape ({self.n}, 3), "
                              f"got {v.shape}, {om.shape}")
        moving = (np.abs(v).sum(1) + np.abs(om).sum(1)) > 0
        if np.any(moving & self.clamp):
            k = int(np.flatnonzero(moving & self.clamp)[0])
            raise DnarodError(f"node {k} is clamped but was given a nonzero initial velocity; "
                              f"a clamped node is at rest")
        Omega, Gamma = model.strains()
        gamma = np.einsum("kji,kj->ki", model.frames, v)
        return self.pack(Omega, Gamma, om, gamma, model.positions[0], model.frames[0])

    # --- poses -------------------------------------------------------------------------------
    def poses(self, y):
        """Node positions (n, 3) nm and frames (n, 3, 3) rebuilt by ``g_{k+1} = g_k U_k``."""
        Omega, Gamma, _, _, r0, q0 = self.unpack(y)
        L0 = Rotation.from_quat(q0).as_matrix()  # normalises the quaternion
        k = self.n - 1
        return chain_from_strains(Omega[:k], Gamma[:k], self.ds, r0, L0)

    def _frames_of(self, y, nodes):
        if len(nodes) == 0:
            return {}
        if np.all(nodes == 0):
            return {0: Rotation.from_quat(self.unpack(y)[5]).as_matrix()}
        _, frames = self.poses(y)
        return {int(k): frames[k] for k in nodes}

    # --- dynamics ------------------------------------------------------------------------------
    def rhs(self, t, y):
        """``dy/dt`` of the exact system."""
        Omega, Gamma, omega, gamma, r0, q0 = self.unpack(y)
        params, ds = self.model.params, self.ds
        dOmega, dGamma = strain_rates(Omega, Gamma, omega, gamma, ds, self.circular)
        f, tq, _ = body_loads(Omega, Gamma, params, ds, self.n, self.circular)
        for k, L in self._frames_of(y, self.loaded).items():
            f[k] += L.T @ self.F_ext[k]
            tq[k] += L.T @ self.tau_ext[k]
        J = self.inertia
        dgamma = f / self.mass[:, None] - np.cross(omega, gamma)
        domega = (tq - np.cross(omega, J * omega)) / J
        dgamma[self.clamp] = 0.0
        domega[self.clamp] = 0.0
        qn = q0 / np.linalg.norm(q0)
        L0 = Rotation.from_quat(qn).as_matrix()
        dr0 = L0 @ gamma[0]
        v, s = qn[:3], qn[3]
        dq = 0.5 * np.concatenate([s * omega[0] + np.cross(v, omega[0]), [-v @ omega[0]]])
        return np.concatenate([dOmega.ravel(), dGamma.ravel(), domega.ravel(), dgamma.ravel(), dr0, dq])

    def energy(self, y):
        """Total energy (elastic + kinetic - work potential of the end forces), kJ/mol."""
        Omega, Gamma, omega, gamma, _, _ = self.unpack(y)
        _, _, H = stresses(Omega, Gamma, self.model.params)
        E = self.ds * H.sum() + node_kinetic_energy(self.mass, self.inertia, gamma, omega)
        if len(self.loaded):
            pos, _ = self.poses(y)
            E -= np.sum(self.F_ext * pos)
        return float(E)

    def momenta(self, y):
        """Lab linear momentum (3,) amu nm/ps and angular momentum about the origin (3,) amu nm^2/ps."""
        _, _, omega, gamma, _, _ = self.unpack(y)
        pos, frames = self.poses(y)
        p = self.mass[:, None] * np.einsum("kij,kj->ki", frames, gamma)
        ang = np.einsum("kij,kj->ki", frames, self.inertia * omega)
        return p.sum(0), (np.cross(pos, p) + ang).sum(0)

    def lab_velocities(self, y):
        """Lab centre velocities (n, 3) and body angular velocities (n, 3)."""
        _, _, omega, gamma, _, _ = self.unpack(y)
        _, frames = self.poses(y)
        return np.einsum("kij,kj->ki", frames, gamma), omega.copy()


@dataclass
class ExactResult:
    """Output of :func:`integrate_exact`.

    Attributes
    ----------
    trajectory : Trajectory
        Poses and velocities at the report times.
    energy : ndarray, shape (n_frames,)
        Total energy, kJ/mol.
    momentum, angular_momentum : ndarray, shape (n_frames, 3)
        Lab momentum (amu nm/ps) and angular momentum about the origin (amu nm^2/ps).
    system : ExactSystem
    y : ndarray, shape (n_frames, n_state)
        Raw state vectors.
    nfev : int
    """

    trajectory: Trajectory
    energy: np.ndarray
    momentum: np.ndarray
    angular_momentum: np.ndarray
    system: ExactSystem
    y: np.ndarray
    nfev: int


def integrate_exact(model, t_end, velocities=None, angular_velocities=None, boundary=None,
                    rtol=1e-10, atol=1e-10, n_frames=101, t_eval=None, method="DOP853"):
    """Integrate the exact strain-space system with an adaptive high-order method.

    Parameters
    ----------
    model : RodModel
        Initial pose, parameters, masses and inertias.
    t_end : float
        Length of the run, ps.
    velocities : ndarray, shape (n_nodes, 3), optional
        Initial lab centre velocities, nm/ps (default 0).
    angular_velocities : ndarray, shape (n_nodes, 3), optional
        Initial body angular velocities, rad/ps (default 0).
    boundary : BoundaryConditions, optional
    rtol, atol : float
        Tolerances of the adaptive integrator (relative; absolute in state units).
    n_frames : int
        Number of equally spaced report times from 0 to ``t_end`` (ignored if ``t_eval``).
    t_eval : array_like, optional
        Report times, ps.
    method : str
        A scipy ``solve_ivp`` method (default ``"DOP853"``).

    Returns
    -------
    ExactResult

    Raises
    ------
    SimulationError
        If the integrator fails (step size underflow, non-finite state).
    """
    if not (np.isfinite(t_end) and t_end > 0):
        raise DnarodError(f"t_end must be a positive time in ps, got {t_end}")
    system = ExactSystem(model, boundary)
    y0 = system.initial_state(velocities, angular_velocities)
    if t_eval is None:
        t_eval = np.linspace(0.0, t_end, int(n_frames))
    sol = solve_ivp(system.rhs, (0.0, t_end), y0, method=method, rtol=rtol, atol=atol, t_eval=t_eval)
    Y = sol.y.T
    bad = ~np.isfinite(Y).all(axis=1)
    if not sol.success or bad.any():
        t_fail = sol.t[int(np.argmax(bad))] if bad.any() else (sol.t[-1] if len(sol.t) else 0.0)
        raise SimulationError(f"exact integrator failed near t = {t_fail:g} ps: {sol.message}", step=None,
                              node=None, term="state")
    pos, frm, vel, ang = [], [], [], []
    E, P, L = [], [], []
    for y in Y:
        p, f = system.poses(y)
        v, w = system.lab_velocities(y)
        pos.append(p), frm.append(f), vel.append(v), ang.append(w)
        E.append(system.energy(y))
        mom = system.momenta(y)
        P.append(mom[0]), L.append(mom[1])
    traj = Trajectory(sol.t, np.array(pos), np.array(frm), np.arange(len(sol.t)), np.array(vel), np.array(ang),
                      metadata=dict(engine="dnarod-lax-exact", method=method, rtol=rtol, atol=atol))
    return ExactResult(traj, np.array(E), np.array(P), np.array(L), system, Y, sol.nfev)
