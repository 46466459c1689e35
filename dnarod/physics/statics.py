"""Static equilibrium of a loaded rod: damped Newton on the exact energy with the analytic loads.

``solve_static(model, loads)`` finds the pose where the elastic loads balance the external ones
(clamps of any node, dead forces and torques, traps, rotation clamps) to a gradient of ``gtol``
times the load scale. Each iteration:

* gradient ``g = -(F, tau)`` (lab forces kJ/mol/nm and torques kJ/mol on the free nodes): by default the
  exact numpy/numba loads (:func:`dnarod.core.energy.loads` + :meth:`dnarod.physics.loads.ResolvedLoads.evaluate`,
  what the Lax-form engine integrates); an engine may pass its own (``load_fn``; the OpenMM engine's is
  :func:`dnarod.engines.openmm.simulation.static_load_fn`), so the fixed point is that engine's equilibrium;
* Hessian: the exact sparse block-tridiagonal Hessian of :mod:`dnarod.physics.modes` in the chart
  ``(dr_k, dtheta_k)`` (``L_k -> exp(hat(dtheta_k)) L_k``), shifted by ``mu I`` (Levenberg) until it
  is positive definite;
* step: ``(H + mu I) d = -g`` (sparse LU, scipy), then a backtracking line search on the energy
  (elastic + traps + rotation clamps - F.r of the dead forces - tau.dtheta of the dead torques; the
  last is exact along the line because each node turns about a fixed axis).

Converged when ``max(|g_F|, |g_tau| / ds) <= gtol * load_scale`` over the free nodes, with
``load_scale = max(|applied forces|, |applied torques| / ds, |trap and clamp loads|)`` at the start
or at the current pose, whichever is larger (1 kJ/mol/nm if there is no load). Near the solution Newton converges
quadratically; the finite-difference Hessian (relative error ~1e-10) only affects the rate, not the fixed point.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import DnarodError, GeometryError
from dnarod.physics.loads import resolve_loads
from dnarod.physics.modes import _block_cholesky_ok, hessian_blocks
from dnarod.core.rotations import rotation_about_axis

__all__ = ["solve_static", "StaticResult"]


def _rotate(frames, dth):
    ang = np.linalg.norm(dth, axis=1)
    axis = dth / np.where(ang > 0, ang, 1.0)[:, None]
    axis[ang == 0] = (0.0, 0.0, 1.0)
    return rotation_about_axis(axis, ang) @ frames


def _lax_loads(model, rl, angles):
    def fn(pos, frm):
        E, F, tau = model.loads(pos, frm)
        Ee, Fe, te = rl.evaluate(pos, frm, angles)
        return E + Ee, F + Fe, tau + te

    return fn


class StaticResult(dict):
    """Info of a static solve: ``iterations``, ``gradient_norm`` (kJ/mol/nm, max over free nodes of
    ``|g_F|`` and ``|g_tau|/ds``), ``load_scale`` (kJ/mol/nm), ``relative_gradient``, ``converged``,
    ``energy_kJ_mol`` (elastic + external, dead torques excluded)."""


class _Newton:
    """One damped Newton step of :func:`solve_static` and what it needs: the gradient on the free nodes, its norm,
    the load scale and the merit (exact energy less the work of the dead torques)."""

    def __init__(self, model, rl, angles, load_fn):
        self.model, self.rl, self.angles = model, rl, angles
        self.free = ~rl.clamped
        self.ds = model.ds
        self.merit_fn = _lax_loads(model, rl, angles)
        self.grad_fn = self.merit_fn if load_fn is None else load_fn

    def gradient(self, p, f):
        _, F, tau = self.grad_fn(p, f)
        g = -np.concatenate([F, tau], axis=1)
        g[~self.free] = 0.0
        return g

    def gnorm(self, g):
        return max(np.abs(g[:, :3]).max(), np.abs(g[:, 3:]).max() / self.ds)

    def load_scale(self, p, f):
        _, Fe, te = self.rl.evaluate(p, f, self.angles)
        free = self.free
        return max(np.abs(Fe[free]).max(initial=0.0), np.abs(te[free]).max(initial=0.0) / self.ds, 1e-300)

    def merit(self, p, f, work):
        E, _, _ = self.merit_fn(p, f)
        return E - work

    def direction(self, pos, frm, g, mu):
        """The Newton direction ``-(H + mu I)^-1 g`` on the free nodes (rows of zeros for clamped ones), with the
        Levenberg shift ``mu`` raised until ``H + mu I`` is positive definite; returns ``(D (n, 6), mu, diagonal
        scale of H)``."""
        from scipy.sparse import identity  # scipy.sparse.linalg is slow to import: not at the CLI's start-up
        from scipy.sparse.linalg import spsolve

        free = self.free
        B = hessian_blocks(self.model, self.rl, pos, frm, mass_weighted=False, angles=self.angles)
        H = B.to_sparse(free_only=True).tocsc()
        dscale = float(np.abs(H.diagonal()).max())
        BRn, _ = B.block_rows()
        BRn = -BRn
        Lw = np.empty_like(BRn)
        mu = max(mu * 0.1, 0.0)
        # (H + mu I) positive definite: sigma I - (-H) with sigma = mu (clamped rows are 0 + mu > 0 for mu > 0)
        shift_free = (~free).any()
        while not _block_cholesky_ok(BRn, mu if mu > 0 else (1e-14 * dscale if shift_free else 0.0), Lw):
            mu = max(10 * mu, 1e-10 * dscale)
        d = -spsolve(H + mu * identity(H.shape[0], format="csc"), g[free].ravel())
        D = np.zeros_like(g)
        D[free] = d.reshape(-1, 6)
        return D, mu, dscale

    def step(self, pos, frm, work, g, mu):
        """A Newton step with a backtracking line search on the merit; returns the new ``(pos, frm, work, g, mu)``
        (the old pose with a larger ``mu`` if no step along the direction is accepted)."""
        D, mu, dscale = self.direction(pos, frm, g, mu)
        m0 = self.merit(pos, frm, work)
        slope = float(g[self.free].ravel() @ D[self.free].ravel())
        alpha = 1.0
        for _ in range(40):
            p2 = pos + alpha * D[:, :3]
            try:
                f2 = _rotate(frm, alpha * D[:, 3:])
                w2 = work + alpha * float(np.sum(self.rl.torque * D[:, 3:]))
                m2 = self.merit(p2, f2, w2)
            except GeometryError:
                m2 = np.inf
            if np.isfinite(m2) and (m2 <= m0 + 1e-4 * alpha * slope or abs(m2 - m0) <= 1e-13 * max(abs(m0), 1.0)):
                g2 = self.gradient(p2, f2)
                if m2 < m0 or self.gnorm(g2) < self.gnorm(g):
                    return p2, f2, w2, g2, mu
            alpha *= 0.5
        return pos, frm, work, g, max(10 * mu, 1e-6 * dscale)


def solve_static(model, loads=(), gtol=1e-8, load_fn=None, max_iter=200, angles=None, positions=None, frames=None):
    """Relax a loaded rod to static equilibrium.

    Parameters
    ----------
    model : RodModel
        Parameters and the starting pose.
    loads : sequence of :mod:`dnarod.physics.loads` dataclasses
        Clamps (any node), pulling forces, torques, traps, rotation clamps.
    gtol : float
        Relative gradient tolerance (of the load scale, see the module docstring).
    load_fn : callable, optional
        ``load_fn(positions, frames) -> (E, F, tau)``: the loads whose balance defines the equilibrium (kJ/mol,
        (n, 3) kJ/mol/nm, (n, 3) kJ/mol); default the exact loads (see the module docstring). The energy it
        returns is not used (the line search uses the exact energy).
    max_iter : int
        Newton iterations.
    angles : sequence of float, optional
        Rotation clamp target angles, rad (default 0: the clamps' initial targets).
    positions, frames : ndarray, optional
        Starting pose (default the model's).

    Returns
    -------
    model : RodModel
        The relaxed pose (same parameters).
    info : StaticResult

    Raises
    ------
    DnarodError
        A free chain with a net dead load (no equilibrium), or no convergence.
    """
    if not (np.isfinite(gtol) and gtol > 0):
        raise DnarodError(f"gtol must be a positive number, got {gtol}")
    pos = np.array(model.positions if positions is None else positions, float)
    frm = np.array(model.frames if frames is None else frames, float)
    rl = resolve_loads(loads, model, pos, frm)
    angles = np.zeros(len(rl.rotation_clamps)) if angles is None else np.asarray(angles, float)
    anchored = rl.clamped.any() or rl.traps
    if not anchored and (np.abs(rl.force.sum(0)).max() > 0):
        raise DnarodError("the dead forces do not sum to zero and nothing anchors the chain (no Clamp or Trap): "
                          "there is no static equilibrium; add a Clamp or a Trap, or balance the forces")
    nt = _Newton(model, rl, angles, load_fn)
    g = nt.gradient(pos, frm)
    work = 0.0  # work of the dead torques along the path (tau . dtheta per step)
    scale0 = nt.load_scale(pos, frm)   # loads of the starting pose (a trap's pull may vanish at equilibrium)
    mu = 0.0
    it = 0
    converged = False
    for it in range(max_iter + 1):
        scale = max(nt.load_scale(pos, frm), scale0)
        if scale <= 1e-300:
            scale = 1.0  # no load: 1 kJ/mol/nm
        if nt.gnorm(g) <= gtol * scale:
            converged = True
            break
        if it == max_iter:
            break
        pos, frm, work, g, mu = nt.step(pos, frm, work, g, mu)
    gnorm, merit_fn = nt.gnorm, nt.merit_fn
    info = StaticResult(iterations=it, gradient_norm=float(gnorm(g)), load_scale=float(scale),
                        relative_gradient=float(gnorm(g) / scale), converged=bool(converged),
                        energy_kJ_mol=float(merit_fn(pos, frm)[0]))
    if not converged:
        raise DnarodError(f"static solve did not converge in {max_iter} Newton iterations (gradient "
                          f"{info['gradient_norm']:.3g} kJ/mol/nm, {info['relative_gradient']:.3g} of the load "
                          f"scale, tolerance {gtol:g}); the loads may have no equilibrium (buckling, a free chain "
                          f"with a net torque) or raise max_iter")
    return model.with_pose(pos, frm), info
