"""Exact thermal equilibrium of the free open chain (docs/formulation.md §8).

The configuration measure is Haar on SE(3)^N, so steps are independent with density
``p(Omega, Gamma) ~ exp(-ds H / kT) (1 + ds^2 |Omega|^2 / 4)^-2``. Integrating Gamma out
leaves a Gaussian in ``w = ds Omega`` of covariance ``kT ds S^-1`` (``S = A - B C^-1 B^T``)
times the Haar factor ``(1 + |w|^2/4)^-2``. Expectations over that 3D density are computed
here by tensor Gauss-Hermite quadrature about the Gaussian (exact up to quadrature error,
which the tests bound against Monte Carlo and a finer rule).

Units: kT in kJ/mol, lengths in nm.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.parameters import StepParameters
from dnarod.core.rotations import cayley, rotation_about_axis
from dnarod.core.units import BOLTZMANN, kT
from dnarod.physics.writhe import _perp, _signed_angle, _transport
from dnarod.core.strains import chain_from_strains
from dnarod.core.errors import DnarodError


def node_kinetic_energy(mass, inertia, velocities, angular_velocities):
    """Kinetic energy of rigid nodes, kJ/mol: ``sum m v^2/2 + sum J_a w_a^2/2``.

    Parameters
    ----------
    mass : (n,) amu;  inertia : (n, 3) amu nm^2
    velocities : (..., n, 3) nm/ps (lab);  angular_velocities : (..., n, 3) rad/ps (body frame)

    Returns
    -------
    float or ndarray, shape (...)
    """
    v = np.asarray(velocities, float)
    w = np.asarray(angular_velocities, float)
    return 0.5 * (np.einsum("k,...ki,...ki->...", mass, v, v) + np.einsum("ki,...ki,...ki->...", inertia, w, w))


def kinetic_temperature(kinetic_energy, n_dof):
    """Temperature (K) of ``n_dof`` degrees of freedom holding ``kinetic_energy`` (kJ/mol); 0 if none."""
    if type(kinetic_energy) is float:  # one value per report of a run: the same arithmetic without numpy's overhead
        return 2.0 * kinetic_energy / (n_dof * BOLTZMANN) if n_dof > 0 else 0.0
    return 2.0 * np.asarray(kinetic_energy) / (n_dof * BOLTZMANN) if n_dof > 0 else 0.0 * np.asarray(kinetic_energy)


def bend_twist_schur(stiffness):
    """Rotational stiffness with translations relaxed, ``S = A - B C^-1 B^T``; shape (..., 3, 3)."""
    K = np.asarray(stiffness, float)
    A, B, C = K[..., :3, :3], K[..., :3, 3:], K[..., 3:, 3:]
    return A - B @ np.linalg.solve(C, np.swapaxes(B, -1, -2))


def _quadrature(S, w0, ds, kt, order):
    """Nodes (q, 3) and normalised weights (q,) of the exact Cayley-vector density of one step."""
    x, wts = np.polynomial.hermite.hermgauss(order)
    cov = kt * ds * np.linalg.inv(S)
    L = np.linalg.cholesky(0.5 * (cov + cov.T))
    g = np.stack(np.meshgrid(x, x, x, indexing="ij"), axis=-1).reshape(-1, 3)
    W = (wts[:, None, None] * wts[None, :, None] * wts[None, None, :]).reshape(-1)
    w = w0 + np.sqrt(2.0) * g @ L.T
    W = W * (1.0 + 0.25 * np.einsum("qi,qi->q", w, w)) ** -2
    return w, W / W.sum()


def mean_rotation(params: StepParameters, ds, kt, order=24):
    """Exact thermal mean of each step's relative rotation, ``<R_k>``.

    Parameters
    ----------
    params : StepParameters
    ds : float
        nm.
    kt : float
        Thermal energy, kJ/mol.
    order : int
        Gauss-Hermite points per axis.

    Returns
    -------
    ndarray, shape (n_steps, 3, 3)
    """
    S = bend_twist_schur(params.stiffness)
    out = np.empty((params.n_steps, 3, 3))
    cache = {}
    for k in range(params.n_steps):
        key = (S[k].tobytes(), params.Omega0[k].tobytes())
        if key not in cache:
            w, W = _quadrature(S[k], ds * params.Omega0[k], ds, kt, order)
            cache[key] = np.einsum("q,qij->ij", W, cayley(w))
        out[k] = cache[key]
    return out


def tangent_correlation(params: StepParameters, ds, kt, n_max, order=24):
    """Exact ``<d3(0)·d3(n)>`` for n = 0..n_max along an open chain starting at step 0.

    Returns
    -------
    ndarray, shape (n_max + 1,)
    """
    Rm = mean_rotation(params, ds, kt, order)
    out = np.empty(n_max + 1)
    P = np.eye(3)
    out[0] = 1.0
    for n in range(1, n_max + 1):
        P = P @ Rm[(n - 1) % params.n_steps]
        out[n] = P[2, 2]
    return out


def exact_tangent_correlation(params, ds, kt, n_max, exclude_ends=0):
    """Exact ``<d3(k)·d3(k+n)>`` of a free open chain in equilibrium, averaged over the start node k
    exactly as :class:`~dnarod.analysis.polymer.TangentCorrelation` averages (docs/formulation.md §8:
    ``<d3(k)·d3(k+n)> = (<R_k> <R_{k+1}> ⋯ <R_{k+n-1}>)_33``).

    Parameters
    ----------
    params : StepParameters
        Per-step stiffness and intrinsic strains (n_steps steps).
    ds : float
        nm.
    kt : float
        kJ/mol.
    n_max : int
        Largest lag, steps.
    exclude_ends : int
        Nodes left out at each end (as the analysis does).

    Returns
    -------
    ndarray, shape (n_max + 1,)
    """
    Rm = mean_rotation(params, ds, kt)
    e = int(exclude_ends)
    n_nodes = len(Rm) + 1 - 2 * e
    out = np.ones(n_max + 1)
    P = np.broadcast_to(np.eye(3), (n_nodes, 3, 3)).copy()  # products starting at node e + k
    for n in range(1, n_max + 1):
        k = np.arange(n_nodes - n)
        P = P[:n_nodes - n] @ Rm[e + k + n - 1]
        out[n] = P[:, 2, 2].mean()
    return out


def lag1_moments(params: StepParameters, ds, kt, order=24):
    """Exact mean and variance of each step's lag-1 tangent correlation ``d3(k) · d3(k+1) = (R_k)_33`` in the free
    chain's equilibrium (the same quadrature as :func:`mean_rotation`).

    The steps of a free open chain are independent, so the lag-1 correlation averaged over M steps of one frame has
    the exact variance ``sum_k var_k / M^2``: what the frames of a run would scatter by if they were independent.

    Returns
    -------
    mean, variance : ndarray, shape (n_steps,)
    """
    S = bend_twist_schur(params.stiffness)
    mean, var = np.empty(params.n_steps), np.empty(params.n_steps)
    cache = {}
    for k in range(params.n_steps):
        key = (S[k].tobytes(), params.Omega0[k].tobytes())
        if key not in cache:
            w, W = _quadrature(S[k], ds * params.Omega0[k], ds, kt, order)
            r33 = cayley(w)[:, 2, 2]
            m = float(W @ r33)
            cache[key] = (m, float(W @ (r33 - m) ** 2))
        mean[k], var[k] = cache[key]
    return mean, var


def mean_twist_angles(params: StepParameters, ds, kt, order=24):
    """Exact thermal mean of each step's Cayley twist angle ``2 atan(ds Omega_3 / 2)`` (rad) in the free chain's
    equilibrium (the quadrature of :func:`mean_rotation`), shape (n_steps,).

    Its sum over the steps less the intrinsic angles is the twist by which the torque-free chain at T lies below
    its 0 K helix (the Haar factor and the concavity of the angle in the strain pull it down): the noise-free form
    of :func:`relaxed_ribbon_twist` (bending and shear add nothing measurable to it; 300 bp of ``dna-default`` at
    300 K: -0.1259 turns by quadrature, -0.1291 +- 0.0027 from 4000 exact chains).
    """
    S = bend_twist_schur(params.stiffness)
    out = np.empty(params.n_steps)
    cache = {}
    for k in range(params.n_steps):
        key = (S[k].tobytes(), params.Omega0[k].tobytes())
        if key not in cache:
            w, W = _quadrature(S[k], ds * params.Omega0[k], ds, kt, order)
            cache[key] = float(W @ (2.0 * np.arctan(0.5 * w[:, 2])))
        out[k] = cache[key]
    return out


def persistence_length(params: StepParameters, ds, kt, order=24):
    """Bending persistence length of the discrete model, nm: ``-ds / ln c`` (docs/formulation.md §8).

    For a uniform axisymmetric step ``c = <R_33>`` and this is exact. For a sequence the
    tangent correlation is averaged per step over one period of the parameter list:
    ``c = ((prod_k <R_k>)_33)^(1/n_steps)``.
    """
    Rm = mean_rotation(params, ds, kt, order)
    if params.n_steps == 1:
        c = Rm[0, 2, 2]
    else:
        P = np.eye(3)
        for R in Rm:
            P = P @ R
        c = P[2, 2] ** (1.0 / params.n_steps)
    return -ds / np.log(c)


def reweighted_covariance_expected(params: StepParameters, ds, kt):
    """The exact identity ``<dxi dxi^T W>/<W> = kT (ds K)^-1`` (docs/formulation.md §8); shape (n_steps, 6, 6)."""
    return kt * np.linalg.inv(ds * params.stiffness)


# --- exact equilibrium sampling of the free open chain --------------------------------------------------------------
def sample_step_strains(stiffness, intrinsic, ds, kt, n, rng):
    """``n`` exact equilibrium samples of one step's strains (docs/formulation.md §8).

    The step density is ``exp(-ds H/kT) (1 + ds^2 |Omega|^2/4)^-2``. The Haar factor is at most 1,
    so drawing from the Gaussian ``N(xi0, kT (ds K)^-1)`` and accepting with probability
    ``(1 + ds^2 |Omega|^2/4)^-2`` is exact rejection sampling (acceptance ~ 0.99 for DNA).

    Parameters
    ----------
    stiffness : ndarray, shape (6, 6)
        K (A kJ/mol nm, B kJ/mol, C kJ/mol/nm).
    intrinsic : ndarray, shape (6,)
        ``(Omega0 1/nm, Gamma0)``.
    ds : float
        nm.
    kt : float
        kJ/mol.
    n : int
    rng : numpy.random.Generator

    Returns
    -------
    ndarray, shape (n, 6)
        ``(Omega, Gamma)`` per sample.
    """
    cov = kt * np.linalg.inv(ds * np.asarray(stiffness, float))
    L = np.linalg.cholesky(0.5 * (cov + cov.T))
    xi0 = np.asarray(intrinsic, float)
    out = np.empty((0, 6))
    while len(out) < n:
        m = int(1.3 * (n - len(out))) + 16
        x = xi0 + rng.standard_normal((m, 6)) @ L.T
        w2 = ds * ds * np.einsum("ni,ni->n", x[:, :3], x[:, :3])
        out = np.concatenate([out, x[rng.random(m) < (1.0 + 0.25 * w2) ** -2]])
    return out[:n]


def sample_open_chain_strains(params: StepParameters, ds, kt, rng, n_chains=1):
    """Exact equilibrium strains of ``n_chains`` free open chains, shape (n_chains, n_steps, 6).

    Steps are independent (docs/formulation.md §8); steps sharing ``(K, xi0)`` are drawn together.
    """
    m = params.n_steps
    xi = np.empty((n_chains, m, 6))
    groups = {}
    for k in range(m):
        groups.setdefault((params.stiffness[k].tobytes(), params.intrinsic[k].tobytes()), []).append(k)
    for steps in groups.values():
        k0 = steps[0]
        s = sample_step_strains(params.stiffness[k0], params.intrinsic[k0], ds, kt, n_chains * len(steps), rng)
        xi[:, steps] = s.reshape(n_chains, len(steps), 6)
    return xi


def relaxed_ribbon_twist(model, temperature, n_samples=400, seed=0):
    """The relaxed linking number of the model's ring at temperature T: the mean ribbon twist of its free steps.

    The linking difference that sets the supercoiling of a closed ring is ``Lk - <Tw>_relaxed``, with
    ``<Tw>_relaxed`` the mean twist (of d1 about the polygon through the nodes: the Tw of ``Lk = Tw + Wr``) of
    the same steps free of any constraint (``<Wr> = 0`` for the relaxed ring by mirror symmetry of a model
    without chiral bending couplings). At T = 0 it is the sum of the intrinsic Cayley twist angles over 2 pi
    (``dnarod.physics.loads.intrinsic_turns``); at finite T it is lower, because the step rotations are
    distributed with the invariant (Haar) measure, whose density in Cayley coordinates ``w = ds Omega`` falls
    as ``(1 + |w|²/4)^-2`` and so pulls the mean twist strain of a step below its intrinsic value, and because
    the twist angle ``2 atan(w_3/2)`` is concave in the strain. For ``dna-default`` at 300 K this is 0.44
    milliturn per step (-0.27 turns in a 600-bp ring, 9 % of the linking difference at sigma = -0.05); bending
    and shear fluctuations add nothing measurable (test). Computed from ``n_samples`` exact equilibrium chains
    of the model's steps (:func:`sample_open_chain_strains`), each step's twist being the rotation of d1 about
    its edge plus the corner rotation at its start node relative to parallel transport (the terms of
    :func:`dnarod.physics.writhe.twist`), so any bend-twist coupling of a parameter set is included; the
    closing corner is taken as the mean of the others.

    Parameters
    ----------
    model : RodModel
        A ring (or any chain: its steps are used).
    temperature : float
        K.

    Returns
    -------
    tuple of float
        ``(Tw0_T, standard_error)`` in turns, for all ``model.params.n_steps`` steps.
    """
    rng = np.random.default_rng(seed)
    xi = sample_open_chain_strains(model.params, model.ds, kT(temperature), rng, n_chains=int(n_samples))
    tot = np.empty(len(xi))
    for i, x in enumerate(xi):
        P, F = chain_from_strains(x[:, :3], x[:, 3:], model.ds)
        U = F[:, :, 0]
        e = np.diff(P, axis=0)
        t = e / np.linalg.norm(e, axis=1)[:, None]
        a0, a1 = _perp(U[:-1], t), _perp(U[1:], t)
        along = _signed_angle(a0, a1, t)
        corner = _signed_angle(_transport(a1[:-1], t[:-1], t[1:]), a0[1:], t[1:])
        tot[i] = along.sum() + corner.sum() + corner.mean()
    tot /= (2.0 * np.pi)
    return float(tot.mean()), float(tot.std(ddof=1) / np.sqrt(len(tot)))


def equilibrium_sample(model, temperature, seed=None, align=None):
    """A pose drawn exactly from the free open chain's thermal equilibrium (docs/formulation.md §8).

    Used as ``start="equilibrium"`` of a run: an independent sample of the configuration
    measure ``exp(-E/kT)`` on SE(3)^N of the force-free chain, so no equilibration of the
    internal degrees of freedom is needed (velocities are drawn separately, Maxwell-Boltzmann).

    Parameters
    ----------
    model : RodModel
        An open chain (any sequence: each step is drawn with its own stiffness and intrinsic strain).
    temperature : float
        K.
    seed : int, optional
        Seed of the random generator (``None``: fresh entropy).
    align : array_like, shape (3,), optional
        If given, the sample is rotated rigidly about node 0 so that its end-to-end vector points
        along ``align`` (used to start pulled chains on the right side); otherwise node 0 keeps
        the model's position and frame.

    Returns
    -------
    RodModel
        The model with the sampled pose (same parameters, masses, sequence).

    Raises
    ------
    DnarodError
        For a circular chain (its closure couples all steps; no exact i.i.d. sampler) or a
        non-positive temperature.
    """
    if model.closure is not None:
        raise DnarodError("start 'equilibrium' samples the free open chain exactly; this model is circular "
                          "(a ring or a periodic chain): use start 'intrinsic' or 'minimized'")
    T = float(temperature)
    if not (np.isfinite(T) and T > 0):
        raise DnarodError(f"start 'equilibrium' needs a positive temperature, got {temperature} K")
    rng = np.random.default_rng(seed)
    xi = sample_open_chain_strains(model.params, model.ds, kT(T), rng)[0]
    pos, frm = chain_from_strains(xi[:, :3], xi[:, 3:], model.ds, model.positions[0], model.frames[0])
    if align is not None:
        a = np.asarray(align, float)
        a = a / np.linalg.norm(a)
        e = pos[-1] - pos[0]
        e = e / np.linalg.norm(e)
        axis = np.cross(e, a)
        s, c = np.linalg.norm(axis), float(e @ a)
        if s < 1e-12:
            R = np.eye(3) if c > 0 else rotation_about_axis(_any_perpendicular(a), np.pi)
        else:
            R = rotation_about_axis(axis / s, np.arctan2(s, c))
        pos = pos[0] + (pos - pos[0]) @ R.T
        frm = R @ frm
    return model.with_pose(pos, frm)


def _any_perpendicular(a):
    """A unit vector perpendicular to unit vector ``a``."""
    b = np.eye(3)[int(np.argmin(np.abs(a)))]
    v = np.cross(a, b)
    return v / np.linalg.norm(v)
