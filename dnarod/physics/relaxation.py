"""Relaxation times of a chain from the normal modes of its actual pose with its loads, under Langevin friction.

dnarod's Langevin thermostats (OpenMM's and the Lax-form BAOAB) apply one collision rate ``zeta`` (1/ps) to every
degree of freedom with its own mass or moment of inertia, so in mass-weighted coordinates the friction is ``zeta I``
and the harmonic normal modes of a pose (:func:`dnarod.physics.modes.hessian`, mass-weighted) stay uncoupled: each
is a damped oscillator ``a'' + zeta a' + omega^2 a = noise`` whose amplitude relaxes at the rate

    ``lambda = zeta/2 - sqrt(zeta^2/4 - omega^2)``  (overdamped, ``zeta > 2 omega``; computed as
    ``omega^2 / (zeta/2 + sqrt(zeta^2/4 - omega^2))``), ``zeta/2`` otherwise,

and the relaxation time is ``1/lambda`` (``inf`` without friction: nothing but the dynamics relaxes a mode).

The slowest modes are the long bending modes, and the boundary conditions set them: a chain clamped at node 0
with a laterally free, pulled end (magnetic tweezers) has a slowest mode several times slower than the same chain
free at both ends (a cantilever's ``beta_1 L = 1.875`` against the free beam's 4.730), which the formula of
:func:`dnarod.analysis.polymer.bending_relaxation_time` assumes. The modes here come from the Hessian of the pose
itself with its loads: clamped nodes removed, rotation clamps and traps with their stiffness, and the tension of a
pulled chain in the elastic energy's second derivative at its static equilibrium under the force (a dead force
has no Hessian of its own; its stiffening is the pre-stressed chain's). The pose must be an equilibrium of the
loads (:func:`dnarod.physics.statics.solve_static`); at another pose the Hessian has negative directions, which are
reported and skipped.

The lowest modes are found by shift-invert Lanczos (scipy ``eigsh``) about a shift just below the lowest bending
frequency of a beam of the chain's length (rigid-body zero modes of a free chain are recognised by their size
against the bending scale and dropped).

Units: rad/ps, 1/ps, ps.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import DnarodError


def decay_rate(omega, friction):
    """Amplitude relaxation rate (1/ps) of damped oscillators of angular frequency ``omega`` (rad/ps) at collision
    rate ``friction`` (1/ps); ndarray like ``omega`` (0 without friction)."""
    w2 = np.asarray(omega, float) ** 2
    z = float(friction)
    if z <= 0:
        return np.zeros_like(w2)
    disc = 0.25 * z * z - w2
    over = disc > 0
    return np.where(over, w2 / (0.5 * z + np.sqrt(np.where(over, disc, 0.0))), 0.5 * z)


def _bending_scale(model, temperature=300.0):
    """``A / (rho L^4)`` (1/ps^2): the scale of the lowest bending eigenvalue of the chain (A from its exact
    persistence length at ``temperature``)."""
    from dnarod.core.units import kT
    from dnarod.physics.thermal import persistence_length

    A = kT(temperature) * persistence_length(model.params, model.ds, kT(temperature))
    rho = float(np.mean(model.mass)) / model.ds
    L = model.ds * (model.n_nodes if model.closure is not None else model.n_steps)
    return A / (rho * L ** 4)


def slowest_modes(model, loads=(), k=6, positions=None, frames=None, temperature=300.0):
    """The ``k`` slowest non-rigid normal modes of a pose with its loads.

    Parameters
    ----------
    model : RodModel
        The pose (an equilibrium of the loads).
    loads : sequence of :mod:`dnarod.physics.loads` dataclasses
    k : int
    positions, frames : ndarray, optional
        Pose other than the model's.
    temperature : float
        K (sets the bending scale of the shift only).

    Returns
    -------
    omega : ndarray, shape (m,), m <= k
        rad/ps, ascending, rigid-body and unstable directions left out.
    n_unstable : int
        Negative eigenvalues met (the pose is not a stable equilibrium of its loads).
    """
    from scipy.sparse.linalg import eigsh

    from dnarod.physics.modes import hessian

    H = hessian(model, loads, positions, frames, mass_weighted=True, free_only=True).tocsc()
    nf = H.shape[0]
    if nf < 2:
        raise DnarodError("no free degree of freedom: every node is clamped")
    scale = _bending_scale(model, temperature)
    m = min(int(k) + 8, nf - 1)  # room for the rigid-body zero modes of a free chain
    if nf <= 600:
        import scipy.linalg

        w2 = scipy.linalg.eigvalsh(H.toarray())
    else:
        # a fixed start vector: ARPACK's default is random, and the modes must not change from run to run
        w2 = eigsh(H, k=m, sigma=-0.5 * scale, which="LM", return_eigenvectors=False, v0=np.ones(nf))
    w2 = np.sort(w2)
    zero = np.abs(w2) < 1e-3 * scale  # rigid-body motions (numerically ~1e-10 of the largest eigenvalue)
    unstable = int(np.sum(w2 <= -1e-3 * scale))
    keep = w2[~zero & (w2 > 0)]
    return np.sqrt(keep[:int(k)]), unstable


def relaxation_times(model, loads=(), friction=1.0, k=6, positions=None, frames=None, temperature=300.0):
    """Relaxation times (ps) of the ``k`` slowest modes of a pose with its loads at collision rate ``friction``.

    Returns
    -------
    dict
        ``omega`` (rad/ps), ``rate`` (1/ps), ``tau_ps`` (ps, descending: the slowest first), ``tau_slowest_ps``,
        ``omega_slowest``, ``n_unstable`` (negative directions of the pose, skipped), ``friction_per_ps``.
    """
    w, unstable = slowest_modes(model, loads, k, positions, frames, temperature)
    if not len(w):
        raise DnarodError("the pose has no stable vibrational mode: it is not an equilibrium of its loads")
    lam = decay_rate(w, friction)
    with np.errstate(divide="ignore"):
        tau = np.where(lam > 0, 1.0 / np.where(lam > 0, lam, 1.0), np.inf)
    order = np.argsort(-tau)
    return dict(omega=w[order], rate=lam[order], tau_ps=tau[order], tau_slowest_ps=float(tau[order][0]),
                omega_slowest=float(w.min()), n_unstable=unstable, friction_per_ps=float(friction))


def critical_friction(omega):
    """The collision rate (1/ps) that damps a mode of angular frequency ``omega`` critically, ``2 omega``: its
    relaxation time is then the shortest any friction gives, ``1/omega``."""
    return 2.0 * float(omega)
