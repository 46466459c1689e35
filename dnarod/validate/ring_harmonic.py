"""Harmonic (small-fluctuation) writhe variance of the model's relaxed ring free to writhe.

An independent reference for the nicked-ring writhe of short rings: no dynamics and no Monte Carlo, only the
model's own Hessian at its relaxed planar ring and exact writhe evaluations.

* The pose: the model's planar ring (:meth:`dnarod.core.model.RodModel.ring`) with the intrinsic twist per step set
  to ``2 pi Lk / n`` (so the ring carries no twist stress; with a stress ``eps`` the Hessian would hold a
  twist-writhe term ``(C/L) eps Wr`` that a nick removes), relaxed to static equilibrium
  (:func:`dnarod.physics.statics.solve_static`; loads below 1e-10 kJ/mol/nm).
* Position covariance: ``Sigma = kT H^+`` of the lab-chart Hessian (:func:`dnarod.physics.modes.hessian`, 6 per node),
  zero modes (rigid motions, the uniform spin of the frames about the tangents) projected out, restricted to
  the positions. At a relaxed ring (twist unstressed) the fixed linking number does not enter the Hessian: the
  twist energy ``(C / 2L) (Wr + ...)^2`` is quartic in the displacements. So ``Sigma`` is also the harmonic
  covariance of the nicked ring, whose Lk is free.
* Writhe expansion: the writhe of the axis smoothed over blocks of ``block`` nodes
  (:func:`dnarod.workflows.protocols.nicked.smoothed_axis`, the quantity the MD records) is ``Wr(x0 + d) = g.d +
  d.M d / 2 + ...``. At a planar ring ``g = 0`` exactly (Wr is odd under the mirror image in the ring's plane,
  which leaves the planar ring in place), so the linear-response form ``kT g^T H^+ g`` vanishes and the leading
  term is second order: for Gaussian ``d`` (covariance ``Sigma``), ``<Wr> = tr(M Sigma)/2`` (zero by the same
  symmetry) and ``<Wr²> = g^T Sigma g + tr((M Sigma)^2) / 2 + <Wr>^2``. ``g`` and ``M`` are central finite
  differences of the exact polygon writhe (:func:`dnarod.physics.writhe.writhe`) with respect to the smoothed
  axis's vertices (the axis is linear in the node positions: ``Sigma_axis = B Sigma B^T``).
* ``gaussian_samples``: the exact writhe of ``x0 + d`` for ``d`` drawn from the same Gaussian, which tests the
  truncation of the writhe at second order (not the harmonic energy).

Valid while the fluctuations are small: ``<Wr²> ∝ (L/A)²`` at fixed shape, which holds for L up to about one
persistence length; beyond, the ring's large excursions (anharmonic bending, the Jacobian of the rotations)
take over and the MD or the Monte Carlo is the reference.

Units: nm, turns, K.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.core.model import RodModel
from dnarod.physics.statics import solve_static
from dnarod.physics.modes import hessian, total_load_fn
from dnarod.core.units import kT
from dnarod.physics.writhe import writhe
from dnarod.workflows.protocols.nicked import smoothed_axis, AXIS_BLOCK
from dnarod.core.rotations import rotation_about_axis


def relaxed_ring(model):
    """The planar ring of ``model`` (a ring RodModel) with its intrinsic twist set to ``2 pi Lk / n`` per step.

    Returns
    -------
    RodModel
        Same stiffness, masses and linking number; ``Omega0_3 = (2/ds) tan(pi Lk / n)`` at every step.
    """
    if model.closure is None:
        raise DnarodError("the harmonic writhe needs a ring; give a closed model (ForceField.ring)")
    lk = int(model.metadata["linking_number"])
    n = model.n_nodes
    xi0 = np.array(model.params.intrinsic, float)
    xi0[:, 2] = (2.0 / model.ds) * math.tan(math.pi * lk / n)
    params = dataclasses.replace(model.params, intrinsic=xi0)
    ring = RodModel.ring(params, model.ds, model.mass, model.inertia, lk, sequence=model.sequence)
    # the planar pose (d3 along the chords) carries a small torque (~0.015 kJ/mol at 100 bp): relax it

    return solve_static(ring)[0]


def position_covariance(model, temperature=300.0, zero_tol=1e-12):
    """Harmonic covariance (nm²) of the node positions of ``model`` at its pose, shape (3n, 3n), and the spectrum.

    Returns
    -------
    cov : ndarray (3n, 3n)
    info : dict
        ``n_zero_modes`` (eigenvalues below ``zero_tol`` times the largest), ``smallest_kept`` and
        ``largest`` eigenvalue (kJ/mol per nm² or rad²), ``max_load`` (largest |force| at the pose, kJ/mol/nm).
    """
    H = hessian(model).toarray()
    H = 0.5 * (H + H.T)
    lam, V = np.linalg.eigh(H)
    zero = np.abs(lam) < zero_tol * lam.max()
    if np.any(lam[~zero] < 0):
        raise DnarodError(f"the ring's Hessian has a negative eigenvalue {lam[~zero].min():.3g}: the pose is not "
                          f"a minimum")
    n = model.n_nodes
    pos_idx = (np.arange(n)[:, None] * 6 + np.arange(3)[None, :]).ravel()
    Vp = V[pos_idx][:, ~zero]
    cov = (Vp * (kT(temperature) / lam[~zero])) @ Vp.T

    F, tau = total_load_fn(model)(model.positions, model.frames)
    return cov, dict(n_zero_modes=int(zero.sum()), smallest_kept=float(lam[~zero].min()), largest=float(lam.max()),
                     max_load=float(max(np.abs(F).max(), np.abs(tau).max())))


def tangent_curve(positions, frames):
    """The closed curve whose step directions are the frames' tangents d3, shape (n, 3), nm.

    Step k runs along the mean of ``d3_k`` and ``d3_{k+1}`` with the length of the chord ``r_{k+1} - r_k``;
    the (small) closure gap is spread evenly over the steps. Its writhe is the shape writhe without the
    shear wiggles of the node polygon (what ``Lk`` minus the step twist measures; see
    :func:`dnarod.workflows.protocols.nicked.step_twist_sum`).
    """
    P = np.asarray(positions, float)
    t = np.asarray(frames, float)[:, :, 2]
    n = len(P)
    steps = 0.5 * (t + np.roll(t, -1, axis=0)) * np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)[:, None]
    steps -= steps.sum(axis=0) / n
    return np.cumsum(steps, axis=0)


def gaussian_writhe_samples(model, n_samples, temperature=300.0, seed=0, curves=("tangent",)):
    """Exact writhe (turns) of ``n_samples`` poses drawn from the harmonic ensemble of ``model``'s relaxed ring.

    Displacements ``(dr, dtheta)`` ~ N(0, kT H^+) over all 6n coordinates (zero modes left out), frames rotated
    by ``exp(hat(dtheta))``. ``curves``: any of ``"tangent"`` (:func:`tangent_curve`), ``"axis"``
    (:func:`dnarod.workflows.protocols.nicked.smoothed_axis`), ``"nodes"`` (the node polygon).

    Returns
    -------
    dict of str to ndarray (n_samples,)
    """
    ring = relaxed_ring(model)
    H = hessian(ring).toarray()
    lam, V = np.linalg.eigh(0.5 * (H + H.T))
    keep = np.abs(lam) > 1e-12 * lam.max()
    amp = np.sqrt(kT(temperature) / lam[keep])
    Vk = V[:, keep]
    rng = np.random.default_rng(seed)
    n = ring.n_nodes
    out = {c: np.empty(int(n_samples)) for c in curves}
    for i in range(int(n_samples)):
        d = (Vk @ (rng.standard_normal(int(keep.sum())) * amp)).reshape(n, 6)
        P = ring.positions + d[:, :3]
        ang = np.linalg.norm(d[:, 3:], axis=1)
        F = np.array([rotation_about_axis(v / a if a > 0 else np.array([0.0, 0.0, 1.0]), a) @ f
                      for v, a, f in zip(d[:, 3:], ang, ring.frames)])
        for c in curves:
            X = tangent_curve(P, F) if c == "tangent" else smoothed_axis(P) if c == "axis" else P
            out[c][i] = writhe(X)
    return out


def writhe_derivatives(points, h=None):
    """Gradient (3m,) and Hessian (3m, 3m) of the writhe (turns) of the closed polygon ``points`` (m, 3), nm.

    Central differences of the exact writhe with step ``h`` (default 1e-3 of the mean edge length); the
    writhe is smooth away from self-contact, and the truncation error is O(h²) (relative ~1e-6).
    """
    x0 = np.asarray(points, float)
    m = len(x0)
    if h is None:
        h = 1e-3 * float(np.mean(np.linalg.norm(np.roll(x0, -1, axis=0) - x0, axis=1)))
    flat = x0.ravel()
    N = flat.size

    def f(dx):
        return writhe((flat + dx).reshape(m, 3))

    e = np.eye(N) * h
    f0 = f(np.zeros(N))
    fp = np.array([f(e[i]) for i in range(N)])
    fm = np.array([f(-e[i]) for i in range(N)])
    g = (fp - fm) / (2 * h)
    M = np.zeros((N, N))
    M[np.diag_indices(N)] = (fp - 2 * f0 + fm) / h ** 2
    for i in range(N):
        for j in range(i + 1, N):
            v = (f(e[i] + e[j]) - f(e[i] - e[j]) - f(-e[i] + e[j]) + f(-e[i] - e[j])) / (4 * h * h)
            M[i, j] = M[j, i] = v
    return g, M


def harmonic_writhe_variance(model, temperature=300.0, block=None, gaussian_samples=0, seed=0):
    """``<Wr²>`` (turns²) of the smoothed axis of ``model``'s relaxed ring at harmonic order (module docstring).

    Parameters
    ----------
    model : RodModel
        A ring (e.g. ``ForceField.ring(n_nodes=...)``); its twist is relaxed first (:func:`relaxed_ring`).
    temperature : float
        K.
    block : int, optional
        Nodes per vertex of the smoothed axis (default :data:`dnarod.workflows.protocols.nicked.AXIS_BLOCK`).
    gaussian_samples : int
        If > 0, also the exact writhe's second moment over this many Gaussian samples of the axis.

    Returns
    -------
    dict
        ``wr2`` (second order), ``linear_term`` (``g^T Sigma g``), ``mean_wr`` (``tr(M Sigma)/2``),
        ``wr2_gaussian`` and ``wr2_gaussian_err`` (when sampled), ``n_zero_modes``, ``max_load``,
        ``axis_vertices``.
    """
    block = AXIS_BLOCK if block is None else int(block)
    ring = relaxed_ring(model)
    cov, info = position_covariance(ring, temperature)
    n = ring.n_nodes
    # the smoothed axis is linear in the positions: axis = B @ positions
    B = smoothed_axis(np.eye(n), block)  # (m, n): row k averages the nodes of block k
    m = B.shape[0]
    B3 = np.kron(B, np.eye(3))  # (3m, 3n) acting on positions.ravel()
    S = B3 @ cov @ B3.T
    S = 0.5 * (S + S.T)
    x0 = B @ ring.positions
    g, M = writhe_derivatives(x0)
    MS = M @ S
    mean = 0.5 * float(np.trace(MS))
    lin = float(g @ S @ g)
    wr2 = lin + 0.5 * float(np.sum(MS * MS.T)) + mean * mean
    res = dict(wr2=wr2, linear_term=lin, mean_wr=mean, axis_vertices=m, n_nodes=n, **info)
    if gaussian_samples:
        rng = np.random.default_rng(seed)
        w, U = np.linalg.eigh(S)
        w = np.clip(w, 0.0, None)
        d = rng.standard_normal((int(gaussian_samples), len(w))) * np.sqrt(w)
        wr = np.array([writhe(x0 + (U @ di).reshape(m, 3)) for di in d])
        res["wr2_gaussian"] = float(np.mean(wr * wr))
        res["wr2_gaussian_err"] = float(np.std(wr * wr, ddof=1) / np.sqrt(len(wr)))
    return res
