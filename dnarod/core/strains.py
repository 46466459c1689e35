"""The strain map of the discrete rod (docs/formulation.md §2): the one place strains are computed.

Step k joins nodes k and k+1. With ``R_k = L_k^T L_{k+1}`` and ``e_k = r_{k+1} - r_k``::

    Gamma_k = L_k^T e_k / ds                          (dimensionless; frame-k components)
    Omega_k = (2/ds) axial(R - R^T) / (1 + tr R)      (1/nm; Cayley vector / ds)

and the inverse ``R_k = cayley(ds Omega_k)``, ``r_{k+1} = r_k + ds L_k Gamma_k`` is exact.

A circular chain has as many steps as nodes; its last step joins node N-1 to the image of
node 0 under the screw closure ``S = (Q, t)``: ``r_N = Q r_0 + t``, ``L_N = Q L_0``.

Shapes: positions ``(n_nodes, 3)`` nm, frames ``(n_nodes, 3, 3)`` with directors as columns,
strains ``(n_steps, 3)``. The Lax-form integrator, the OpenMM engine and the analyses all
import these functions; nothing computes strains a second way.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from dnarod.core.errors import GeometryError
from dnarod.core.rotations import cayley, cayley_inverse


@dataclass(frozen=True)
class Closure:
    """Screw closure of a circular chain: the image of node 0 after node N-1 is ``(Q L_0, Q r_0 + t)``.

    Parameters
    ----------
    Q : ndarray, shape (3, 3)
        Proper rotation.
    t : ndarray, shape (3,)
        Translation, nm.
    """

    Q: np.ndarray
    t: np.ndarray

    @staticmethod
    def identity():
        """The plain ring closure (node N is node 0)."""
        return Closure(np.eye(3), np.zeros(3))

    def __post_init__(self):
        Q = np.asarray(self.Q, dtype=float)
        t = np.asarray(self.t, dtype=float)
        if Q.shape != (3, 3) or t.shape != (3,):
            raise GeometryError(f"closure Q must have shape (3, 3) and t shape (3,), got {Q.shape} and {t.shape}")
        if not (np.allclose(Q.T @ Q, np.eye(3), atol=1e-8) and np.linalg.det(Q) > 0):
            raise GeometryError("closure Q must be a proper rotation matrix (orthonormal, det +1)")
        object.__setattr__(self, "Q", Q)
        object.__setattr__(self, "t", t)


def step_ends(positions, frames, closure=None):
    """Positions and frames of both ends of every step, vectorised over leading (frame) axes.

    Returns
    -------
    r0, L0, r1, L1 : ndarrays, shapes (..., n_steps, 3) and (..., n_steps, 3, 3)
        Left and right ends; for a circular chain the last right end is the image of node 0
        under the screw closure.
    """
    if closure is None:
        return positions[..., :-1, :], frames[..., :-1, :, :], positions[..., 1:, :], frames[..., 1:, :, :]
    r_img = positions[..., 0, :] @ closure.Q.T + closure.t
    L_img = closure.Q @ frames[..., 0, :, :]
    r_next = np.concatenate([positions[..., 1:, :], r_img[..., None, :]], axis=-2)
    L_next = np.concatenate([frames[..., 1:, :, :], L_img[..., None, :, :]], axis=-3)
    return positions, frames, r_next, L_next


def step_geometry(positions, frames, closure=None):
    """Relative rotations and lab-frame chords of every step.

    Parameters
    ----------
    positions : ndarray, shape (..., n_nodes, 3)
        Node centres, nm (optional leading axes, e.g. trajectory frames).
    frames : ndarray, shape (..., n_nodes, 3, 3)
        Directors as columns.
    closure : Closure or None
        Screw closure of a circular chain; ``None`` for an open chain.

    Returns
    -------
    R : ndarray, shape (..., n_steps, 3, 3)
        ``L_k^T L_{k+1}``.
    e : ndarray, shape (..., n_steps, 3)
        Lab chord ``r_{k+1} - r_k``, nm.
    """
    r0, L0, r1, L1 = step_ends(np.asarray(positions, float), np.asarray(frames, float), closure)
    R = np.swapaxes(L0, -1, -2) @ L1
    return R, r1 - r0


def strains(positions, frames, ds, closure=None):
    """Exact strains of every step (docs/formulation.md §2).

    Parameters
    ----------
    positions : ndarray, shape (..., n_nodes, 3)
        Node centres, nm; leading axes (e.g. trajectory frames) are vectorised over.
    frames : ndarray, shape (..., n_nodes, 3, 3)
        Directors as columns (proper rotations).
    ds : float
        Reference arc length per step, nm.
    closure : Closure or None
        Screw closure for a circular chain.

    Returns
    -------
    Omega : ndarray, shape (..., n_steps, 3)
        Bend, bend, twist strains, 1/nm (Cayley vector of ``R_k`` divided by ``ds``).
    Gamma : ndarray, shape (..., n_steps, 3)
        Shear, shear, extension strains (dimensionless), in frame k.

    Raises
    ------
    GeometryError
        If a step rotates by 180 deg or more (the message names the step).
    """
    positions = np.asarray(positions, dtype=float)
    frames = np.asarray(frames, dtype=float)
    R, e = step_geometry(positions, frames, closure)
    L0 = frames if closure is not None else frames[..., :-1, :, :]
    Omega = cayley_inverse(R, what="step") / ds
    Gamma = np.einsum("...kji,...kj->...ki", L0, e) / ds
    return Omega, Gamma


def strains_dot_form(positions, frames, ds):
    """Strains of an open chain from dot products of directors (docs/formulation.md §2, the OpenMM expression form).

    A literal transcription of the dot-product formulas, kept as the slow reference the
    OpenMM energy expression and :func:`strains` are tested against.

    Parameters
    ----------
    positions : ndarray, shape (n_nodes, 3)
    frames : ndarray, shape (n_nodes, 3, 3)
    ds : float

    Returns
    -------
    Omega, Gamma : ndarray, shape (n_nodes - 1, 3)
    """
    d = [frames[:, :, a] for a in range(3)]
    def dot(a, b):
        return np.einsum("ki,ki->k", d[a][:-1], d[b][1:])  # d_a(k) . d_b(k+1)
    D = 1.0 + dot(0, 0) + dot(1, 1) + dot(2, 2)
    Om = np.stack([dot(2, 1) - dot(1, 2), dot(0, 2) - dot(2, 0), dot(1, 0) - dot(0, 1)], axis=1)
    Omega = 2.0 * Om / (ds * D[:, None])
    e = positions[1:] - positions[:-1]
    Gamma = np.stack([np.einsum("ki,ki->k", d[a][:-1], e) for a in range(3)], axis=1) / ds
    return Omega, Gamma


def chain_from_strains(Omega, Gamma, ds, r0=None, frame0=None):
    """Build node poses from strains: the exact inverse of :func:`strains` for an open chain.

    Parameters
    ----------
    Omega, Gamma : ndarray, shape (n_steps, 3)
        Strains (1/nm and dimensionless).
    ds : float
        Arc length per step, nm.
    r0 : ndarray, shape (3,), optional
        Position of node 0, nm (default origin).
    frame0 : ndarray, shape (3, 3), optional
        Frame of node 0 (default identity).

    Returns
    -------
    positions : ndarray, shape (n_steps + 1, 3)
    frames : ndarray, shape (n_steps + 1, 3, 3)
    """
    Omega = np.asarray(Omega, dtype=float)
    Gamma = np.asarray(Gamma, dtype=float)
    if Omega.shape != Gamma.shape or Omega.ndim != 2 or Omega.shape[1] != 3:
        raise GeometryError(f"Omega and Gamma must both have shape (n_steps, 3), got {Omega.shape} and {Gamma.shape}")
    n = Omega.shape[0] + 1
    R = cayley(ds * Omega)
    positions = np.empty((n, 3))
    frames = np.empty((n, 3, 3))
    positions[0] = np.zeros(3) if r0 is None else r0
    frames[0] = np.eye(3) if frame0 is None else frame0
    _chain_kernel(np.ascontiguousarray(R), np.ascontiguousarray(Gamma), float(ds), positions, frames)
    return positions, frames


@numba.njit(cache=True)
def _chain_kernel(R, Gamma, ds, positions, frames):
    """The sequential product of :func:`chain_from_strains` (each frame depends on the previous one, so
    there is no vectorised form; compiled because a Python loop takes seconds at 10^6 nodes)."""
    for k in range(R.shape[0]):
        for a in range(3):
            acc = 0.0
            for b in range(3):
                acc += frames[k, a, b] * Gamma[k, b]
            positions[k + 1, a] = positions[k, a] + ds * acc
        for a in range(3):
            for b in range(3):
                acc = 0.0
                for c in range(3):
                    acc += frames[k, a, c] * R[k, c, b]
                frames[k + 1, a, b] = acc
