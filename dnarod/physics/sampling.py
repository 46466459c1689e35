"""Exact independent samples of the free open chain in thermal equilibrium (docs/formulation.md §8).

Steps are i.i.d. with density ``exp(-ds H/kT) (1 + ds^2 |Omega|^2 / 4)^-2`` in Cayley strains.
The Haar factor is at most 1, so rejection sampling from the Gaussian
``N(xi0, kT (ds K)^-1)`` with acceptance probability ``(1 + ds^2 |Omega|^2 / 4)^-2`` is exact.
Chains are built with :func:`dnarod.core.strains.chain_from_strains`. Used as the reference sample
of the analysis tests and of validation runs.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.core.parameters import StepParameters
from dnarod.core.strains import chain_from_strains
from dnarod.core.trajectory import Trajectory


def sample_steps(stiffness, intrinsic, ds, kt, n, rng):
    """``n`` exact equilibrium samples of one step, shape (n, 6): :func:`dnarod.physics.thermal.sample_step_strains`."""
    from dnarod.physics.thermal import sample_step_strains

    return sample_step_strains(stiffness, intrinsic, ds, kt, n, rng)


def sample_chains(params: StepParameters, ds, kt, n_chains, rng, time_step=1.0):
    """Independent equilibrium conformations of an open chain, as a trajectory (one chain per frame).

    Parameters
    ----------
    params : StepParameters
        ``n_steps`` steps (the chain has ``n_steps + 1`` nodes).
    ds, kt : float
    n_chains : int
    rng : numpy.random.Generator
    time_step : float
        Nominal ps between frames.

    Returns
    -------
    Trajectory
        ``n_chains`` frames of ``n_steps + 1`` nodes; node 0 at the origin with the identity
        frame in every frame.
    """
    if n_chains < 1:
        raise DnarodError(f"n_chains must be positive, got {n_chains}")
    from dnarod.physics.thermal import sample_open_chain_strains

    m = params.n_steps
    xi = sample_open_chain_strains(params, ds, kt, rng, n_chains)
    pos = np.empty((n_chains, m + 1, 3))
    frm = np.empty((n_chains, m + 1, 3, 3))
    for c in range(n_chains):
        pos[c], frm[c] = chain_from_strains(xi[c, :, :3], xi[c, :, 3:], ds)
    return Trajectory(np.arange(n_chains) * time_step, pos, frm, metadata={"source": "exact i.i.d. sample"})


def tweezers_reference(model, temperature, force_pN, n_chains, rng, clamp_k=None, clamp_frame=None, walls=None,
                       batch=20000):
    """Exact equilibrium averages of a chain clamped at node 0 and pulled at its last node along the lab z axis
    (magnetic tweezers without walls), its last node optionally rotation-clamped: exact free-chain samples
    reweighted by ``exp((F z - E_clamp)/kT)``.

    Node 0 clamped in position and orientation leaves the rest of the chain distributed as the free open chain
    built from node 0's pose (the steps are independent, docs/formulation.md §8); a dead force F on the last node
    along z adds ``-F z_end`` to the energy and a rotation clamp ``k (1 - cos theta)`` of the last frame against
    ``clamp_frame`` (:func:`dnarod.physics.loads.rotation_clamp_load`) its energy, so weighting the free samples by
    ``exp((F (z_end - z_0) - E_clamp)/kT)`` gives the loaded chain's averages exactly (self-normalised importance
    sampling; its own standard error and effective sample size are returned). Efficient while ``F`` times the free
    chain's spread of z_end and the clamp's stiffness stay within a few kT: short chains, moderate forces, soft
    clamps.

    Parameters
    ----------
    model : RodModel
        Open chain; node 0's pose is the clamp's (its d3 should point along +z).
    temperature : float
        K.
    force_pN : float
        Pulling force on the last node along +z, pN.
    n_chains : int
        Free samples drawn.
    rng : numpy.random.Generator
    clamp_k : float, optional
        Rotation-clamp stiffness, kJ/mol (None: the last node is torsionally free).
    clamp_frame : ndarray, shape (3, 3), optional
        The clamp's target frame.
    walls : tuple, optional
        ``(k, skip, offsets)``: the tweezers walls (:class:`dnarod.physics.loads.Walls`, stiffness k kJ/mol/nm^2)
        on the points ``centre + L offsets[i]`` of each node (``offsets`` (m, 3) body-frame vectors, nm: the
        engine's particles; ``np.zeros((1, 3))`` for the node centres): the surface (z of node 0) below the points
        of nodes ``skip..n-1``, the bead plane (z of the last node) above the first point of nodes ``0..n-1-skip``,
        each ``k/2 d^2`` on the penetration d; their energy joins the weights.

    Returns
    -------
    dict
        ``extension_nm``, ``clamp_torque_pN_nm`` (z torque of the clamp on the last node), ``lag1`` (the mean over
        steps of ``d3(k) . d3(k+1)``): each ``(mean, standard error)``; ``ess`` the effective sample size.
    """
    from dnarod.core.rotations import cayley
    from dnarod.core.units import PN, kT
    from dnarod.physics.loads import rotation_clamp_load
    from dnarod.physics.thermal import sample_open_chain_strains

    if model.closure is not None:
        raise DnarodError("tweezers_reference is for open chains")
    beta = 1.0 / kT(temperature)
    F = float(force_pN) * PN
    p, ds = model.params, model.ds
    logw, ext, tq, c1 = [], [], [], []
    left = int(n_chains)
    while left > 0:
        b = min(batch, left)
        left -= b
        xi = sample_open_chain_strains(p, ds, kT(temperature), rng, b)
        R = cayley(ds * xi[..., :3].reshape(-1, 3)).reshape(b, p.n_steps, 3, 3)
        L = np.broadcast_to(model.frames[0], (b, 3, 3)).copy()
        r = np.zeros((b, 3))
        for k in range(p.n_steps):
            r += ds * np.einsum("bij,bj->bi", L, xi[:, k, 3:])
            L = L @ R[:, k]
        lw = beta * F * r[:, 2]
        if walls is not None:
            lw -= beta * _wall_energy(model, xi, R, walls)
        torque = np.zeros(b)
        if clamp_k is not None:
            S = L @ np.asarray(clamp_frame, float).T
            e = 0.5 * float(clamp_k) * (3.0 - np.trace(S, axis1=1, axis2=2))
            lw -= beta * e
            torque = 0.5 * float(clamp_k) * (S[:, 0, 1] - S[:, 1, 0]) / PN
            assert np.isclose(torque[0], rotation_clamp_load(L[0], np.asarray(clamp_frame, float), clamp_k)[1][2] / PN)
        logw.append(lw)
        ext.append(r[:, 2])
        tq.append(torque)
        c1.append(R[:, :, 2, 2].mean(axis=1))
    lw = np.concatenate(logw)
    w = np.exp(lw - lw.max())
    w /= w.sum()
    out = {"ess": float(1.0 / np.sum(w * w))}
    for name, x in (("extension_nm", ext), ("clamp_torque_pN_nm", tq), ("lag1", c1)):
        x = np.concatenate(x)
        m = float(w @ x)
        out[name] = (m, float(np.sqrt(np.sum(w * w * (x - m) ** 2))))
    return out


def _wall_energy(model, xi, R, walls):
    """Energy (kJ/mol) of the tweezers walls for a batch of chains built from node 0's pose, shape (b,)."""
    k, skip, offsets = float(walls[0]), int(walls[1]), np.atleast_2d(np.asarray(walls[2], float))
    b, m = xi.shape[0], xi.shape[1]
    n = m + 1
    L = np.broadcast_to(model.frames[0], (b, 3, 3)).copy()
    r = np.broadcast_to(model.positions[0], (b, 3)).copy()
    z0 = float(model.positions[0, 2])
    zp = np.empty((b, n, len(offsets)))  # z of each node's points
    zp[:, 0] = r[:, 2:3] + np.einsum("bj,ij->bi", L[:, 2], offsets)
    for j in range(m):
        r += model.ds * np.einsum("bij,bj->bi", L, xi[:, j, 3:])
        L = L @ R[:, j]
        zp[:, j + 1] = r[:, 2:3] + np.einsum("bj,ij->bi", L[:, 2], offsets)
    z_end = r[:, 2]
    e = 0.5 * k * np.sum(np.minimum(0.0, zp[:, skip:] - z0) ** 2, axis=(1, 2))
    e += 0.5 * k * np.sum(np.maximum(0.0, zp[:, :n - skip, 0] - z_end[:, None]) ** 2, axis=1)
    return e
