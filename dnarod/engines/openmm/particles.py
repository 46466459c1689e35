"""Rigid base-pair nodes as three massive particles (docs/formulation.md §7).

Node k (centre ``c``, frame ``L`` with directors d1, d2, d3 as columns) is carried by three
particles of mass ``m/3`` at the vertices of an equilateral triangle of circumradius ``l``
in the d1-d2 plane::

    p_0 = c + l d1
    p_1 = c + l (-1/2 d1 + sqrt(3)/2 d2)
    p_2 = c + l (-1/2 d1 - sqrt(3)/2 d2)

held rigid by three distance constraints (side ``sqrt(3) l``). The centre of mass is ``c``
and the principal inertia about (d1, d2, d3) is planar::

    J = m l^2 (1/2, 1/2, 1)        (J3 = J1 + J2)

so a model's node inertia is realisable only if ``J1 == J2`` and ``J3 == J1 + J2``; then
``l = sqrt(J3 / m)``. The dna-default node (650 amu, (117, 117, 234) amu nm^2) has
``l = 0.6 nm``. The Lax-form integrator uses the same inertia, so both engines simulate
the same mechanical system.

Reverse map (exact for a rigid triangle, and well defined for any slightly deformed one)::

    c  = (p_0 + p_1 + p_2) / 3
    d1 = (2 p_0 - p_1 - p_2) / (3 l)
    d2 = (p_1 - p_2) / (sqrt(3) l)
    d3 = d1 x d2

(:func:`node_poses` orthonormalises by Gram-Schmidt so the frames are proper rotations.)

Velocity convention: a node moves with centre velocity ``v`` (lab, nm/ps) and angular
velocity ``omega`` given in the **body frame** (rad/ps, components on d1, d2, d3, as in
docs/formulation.md §6 and the ``.dtraj`` format); particle i has velocity ``v + (L omega) x (p_i - c)``.

Particle order: node k owns particles ``3k, 3k+1, 3k+2``. With the portable elastic path a
circular chain's System holds three more, massless particles ``3n, 3n+1, 3n+2``: the closure
screw's image of node 0's particles (none for a plain ring, whose closure is the identity) (:func:`closure_image_positions`,
:func:`dnarod.engines.openmm.forces.add_closure_image`).
"""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import ParameterError

SQRT3 = np.sqrt(3.0)
#: Unit offsets of the three particles in body coordinates (rows), circumradius 1.
BODY_OFFSETS = np.array([[1.0, 0.0, 0.0], [-0.5, SQRT3 / 2, 0.0], [-0.5, -SQRT3 / 2, 0.0]])


def triangle_radius(mass, inertia, rtol=1e-6):
    """Circumradius of the triangle that gives each node its mass and inertia.

    Parameters
    ----------
    mass : ndarray, shape (n_nodes,)
        amu.
    inertia : ndarray, shape (n_nodes, 3)
        Principal moments about d1, d2, d3, amu nm^2.
    rtol : float
        Relative tolerance of the checks ``J1 == J2`` and ``J3 == J1 + J2 == m l^2``.

    Returns
    -------
    ndarray, shape (n_nodes,)
        ``l = sqrt(J3 / m)``, nm.

    Raises
    ------
    ParameterError
        Naming the first node whose inertia no planar equilateral triangle realises.
    """
    mass = np.asarray(mass, float).reshape(-1)
    inertia = np.asarray(inertia, float).reshape(-1, 3)
    J1, J2, J3 = inertia.T
    bad = ~(np.isclose(J1, J2, rtol=rtol, atol=0) & np.isclose(J3, J1 + J2, rtol=rtol, atol=0) & (mass > 0))
    if bad.any():
        k = int(np.argmax(bad))
        raise ParameterError(
            f"base pair {k + 1}: inertia {inertia[k].tolist()} amu nm^2 (mass {mass[k]} amu) cannot be carried by the "
            f"OpenMM engine's rigid equilateral triangle, which needs J1 == J2 and J3 == J1 + J2 "
            f"(J = m l^2 (1/2, 1/2, 1)); give the model such an inertia, e.g. m l^2 (0.5, 0.5, 1)"
        )
    return np.sqrt(J3 / mass)


def particle_positions(centres, frames, radius):
    """Particle positions of every node.

    Parameters
    ----------
    centres : ndarray, shape (n_nodes, 3)
        nm.
    frames : ndarray, shape (n_nodes, 3, 3)
        Directors as columns.
    radius : ndarray, shape (n_nodes,) or float
        Triangle circumradius, nm.

    Returns
    -------
    ndarray, shape (3 n_nodes, 3)
        nm; node k owns rows 3k..3k+2.
    """
    centres = np.asarray(centres, float)
    frames = np.asarray(frames, float)
    r = np.broadcast_to(np.asarray(radius, float), centres.shape[:1])
    off = np.einsum("kab,ib->kia", frames, BODY_OFFSETS) * r[:, None, None]
    return (centres[:, None, :] + off).reshape(-1, 3)


def closure_image_positions(particles, closure):
    """Positions of the screw image of node 0's particles, ``Q x_i + t`` (i = 0, 1, 2).

    Parameters
    ----------
    particles : ndarray, shape (3 n_nodes, 3) or longer
        nm; rows 0-2 are node 0's particles.
    closure : Closure
        The closure screw (``Q`` (3, 3), ``t`` (3,) nm).

    Returns
    -------
    ndarray, shape (3, 3)
        nm.
    """
    x = np.asarray(particles, float)[:3]
    return x @ np.asarray(closure.Q, float).T + np.asarray(closure.t, float)


def node_poses(particles):
    """Centres and orthonormal frames of the nodes from particle positions.

    Parameters
    ----------
    particles : ndarray, shape (3 n_nodes, 3)
        nm.

    Returns
    -------
    centres : ndarray, shape (n_nodes, 3)
    frames : ndarray, shape (n_nodes, 3, 3)
        Directors as columns (Gram-Schmidt on d1 = 2p0 - p1 - p2, d2 = p1 - p2).
    """
    p = np.asarray(particles, float).reshape(-1, 3, 3)
    c = p.mean(axis=1)
    a = 2 * p[:, 0] - p[:, 1] - p[:, 2]
    b = p[:, 1] - p[:, 2]
    d1 = a / np.linalg.norm(a, axis=1, keepdims=True)
    b = b - np.einsum("ki,ki->k", b, d1)[:, None] * d1
    d2 = b / np.linalg.norm(b, axis=1, keepdims=True)
    d3 = np.cross(d1, d2)
    return c, np.stack([d1, d2, d3], axis=2)


def particle_velocities(frames, radius, velocities, angular_velocities):
    """Particle velocities of rigid nodes.

    Parameters
    ----------
    frames : ndarray, shape (n_nodes, 3, 3)
    radius : ndarray, shape (n_nodes,) or float
        nm.
    velocities : ndarray, shape (n_nodes, 3)
        Centre velocities, lab frame, nm/ps.
    angular_velocities : ndarray, shape (n_nodes, 3)
        Angular velocities in the **body frame** (on d1, d2, d3), rad/ps.

    Returns
    -------
    ndarray, shape (3 n_nodes, 3)
        nm/ps.
    """
    frames = np.asarray(frames, float)
    n = frames.shape[0]
    r = np.broadcast_to(np.asarray(radius, float), (n,))
    off = np.einsum("kab,ib->kia", frames, BODY_OFFSETS) * r[:, None, None]
    w_lab = np.einsum("kab,kb->ka", frames, np.asarray(angular_velocities, float))
    v = np.asarray(velocities, float)[:, None, :] + np.cross(w_lab[:, None, :], off)
    return v.reshape(-1, 3)


def node_velocities(particles, particle_vel):
    """Centre velocities and body-frame angular velocities from particle velocities.

    Parameters
    ----------
    particles : ndarray, shape (3 n_nodes, 3)
        nm.
    particle_vel : ndarray, shape (3 n_nodes, 3)
        nm/ps.

    Returns
    -------
    velocities : ndarray, shape (n_nodes, 3)
        Lab centre velocities, nm/ps.
    angular_velocities : ndarray, shape (n_nodes, 3)
        Body-frame angular velocities, rad/ps (least squares over the three particles; exact
        for rigid motion).
    """
    p = np.asarray(particles, float).reshape(-1, 3, 3)
    u = np.asarray(particle_vel, float).reshape(-1, 3, 3)
    c, frames = node_poses(particles)
    v = u.mean(axis=1)
    x = p - c[:, None, :]
    du = u - v[:, None, :]
    # Rigid motion: du_i = w x x_i, so sum_i x_i x du_i = A w with A = sum_i (|x_i|^2 I - x_i x_i^T).
    rhs = np.cross(x, du).sum(axis=1)
    A = np.einsum("kij,kij->k", x, x)[:, None, None] * np.eye(3) - np.einsum("kia,kib->kab", x, x)
    w_lab = np.linalg.solve(A, rhs[..., None])[..., 0]
    return v, np.einsum("kab,ka->kb", frames, w_lab)


def loads_to_particle_forces(particles, forces, torques):
    """Distribute node forces and torques (about the centres) over the three particles.

    Each particle gets ``F/3 + a x x_i`` with ``x_i = p_i - c`` and ``a = A^{-1} tau``,
    ``A = sum_i (|x_i|^2 I - x_i x_i^T)``; then ``sum f_i = F`` and
    ``sum x_i x f_i = tau``. Under the rigid-body constraints only the total force and torque
    matter: any two distributions with the same totals give the same constrained motion.

    Parameters
    ----------
    particles : ndarray, shape (3 n_nodes, 3)
        nm.
    forces : ndarray, shape (n_nodes, 3)
        kJ/mol/nm.
    torques : ndarray, shape (n_nodes, 3)
        Lab torques about the centres, kJ/mol.

    Returns
    -------
    ndarray, shape (3 n_nodes, 3)
        kJ/mol/nm.
    """
    p = np.asarray(particles, float).reshape(-1, 3, 3)
    x = p - p.mean(axis=1, keepdims=True)
    A = np.einsum("kij,kij->k", x, x)[:, None, None] * np.eye(3) - np.einsum("kia,kib->kab", x, x)
    a = np.linalg.solve(A, np.asarray(torques, float)[..., None])[..., 0]
    f = np.asarray(forces, float)[:, None, :] / 3.0 + np.cross(a[:, None, :], x)
    return f.reshape(-1, 3)


def particle_forces_to_loads(particles, particle_forces):
    """Total force and torque (about the centre) on every node.

    Parameters
    ----------
    particles : ndarray, shape (3 n_nodes, 3)
        nm.
    particle_forces : ndarray, shape (3 n_nodes, 3)
        kJ/mol/nm.

    Returns
    -------
    forces, torques : ndarray, shape (n_nodes, 3)
        kJ/mol/nm and kJ/mol (lab frame).
    """
    p = np.asarray(particles, float).reshape(-1, 3, 3)
    f = np.asarray(particle_forces, float).reshape(-1, 3, 3)
    x = p - p.mean(axis=1, keepdims=True)
    return f.sum(axis=1), np.cross(x, f).sum(axis=1)
