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
