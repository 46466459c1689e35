"""OpenMM translation of the engine-neutral loads of :mod:`dnarod.physics.loads`.

The load dataclasses (:class:`~dnarod.physics.loads.PullingForce`, ``Torque``, ``RotationClamp``, ``Clamp``,
``Trap``) live in :mod:`dnarod.physics.loads`; this module turns them into OpenMM forces:

* pulling force: a ``CustomExternalForce`` ``-F . x`` spread over the node's three particles;
* torque: a ``PythonForce`` (constant lab torque about the node centre; the reported energy is
  ``-|tau| phi`` with phi the unwrapped rotation about the torque axis since the start);
* rotation clamp: a ``CustomCompoundBondForce`` ``k/4 sum_a |d_a - t_a|^2 = k (1 - cos theta)`` whose
  target frame is a set of global parameters (turned by :func:`set_clamp_rotation`);
* clamp: zero-mass particles without constraints;
* trap: a ``CustomCentroidBondForce`` on the node centre.
"""
from __future__ import annotations

import numpy as np
import openmm

from dnarod.core.errors import ParameterError
from dnarod.physics.loads import LOAD_TYPES, Clamp, PullingForce, Torque, Trap, Walls, resolve_node, resolve_loads
from dnarod.engines.openmm.forces import GROUPS, python_force
from dnarod.engines.openmm.particles import SQRT3, loads_to_particle_forces, node_poses
from dnarod.core.rotations import rotation_about_axis
from dnarod.engines.openmm.walls import wall_forces

__all__ = ["TorqueCallback", "build_load_forces", "set_clamp_rotation"]


class TorqueCallback:
    """PythonForce computation of constant torques (applied to a subset of particles)."""

    def __init__(self, torques, frames0):
        self.torques = np.asarray(torques, float).reshape(-1, 3)
        self.ref = np.asarray(frames0, float).reshape(-1, 3, 3)
        self.phi = np.zeros(len(self.torques))
        self.last_angle = np.zeros(len(self.torques))

    def __call__(self, state):
        p = state.getPositions(asNumpy=True)._value
        _, frames = node_poses(p)
        E = 0.0
        for i, (tau, L0) in enumerate(zip(self.torques, self.ref)):
            mag = np.linalg.norm(tau)
            if mag == 0:
                continue
            n = tau / mag
            R = frames[i] @ L0.T  # lab rotation since the start
            # twist angle about n (swing-twist): 2 atan2(v.n, w) of the quaternion, via the matrix.
            ax = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
            ang = 2.0 * np.arctan2(ax @ n, 1.0 + np.trace(R))
            d = (ang - self.last_angle[i] + np.pi) % (2 * np.pi) - np.pi
            self.phi[i] += d
            self.last_angle[i] = ang
            E -= mag * self.phi[i]
        zeros = np.zeros((len(self.torques), 3))
        return E, loads_to_particle_forces(p, zeros, self.torques)


def _director_defs(i, j, k, ua, va):
    defs = ["a3x = a1y*a2z - a1z*a2y", "a3y = a1z*a2x - a1x*a2z", "a3z = a1x*a2y - a1y*a2x"]
    for c in "xyz":
        defs += [f"a1{c} = (2*{c}{i} - {c}{j} - {c}{k})*{ua}", f"a2{c} = ({c}{j} - {c}{k})*{va}"]
    return defs


def build_load_forces(loads, model, radius, system, platform="CPU"):
    """Add the OpenMM forces of ``loads`` to ``system``.

    Parameters
    ----------
    loads : list
        :class:`PullingForce`, :class:`Torque`, :class:`~dnarod.physics.loads.RotationClamp`, :class:`Clamp`,
        :class:`Trap`.
    model : RodModel
    radius : ndarray, shape (n_nodes,)
        Triangle circumradius, nm.
    system : openmm.System
    platform : str
        The OpenMM platform the forces will run on (chooses the form of the tweezers walls,
        :func:`dnarod.engines.openmm.walls.wall_forces`).

    Returns
    -------
    dict
        ``clamped`` (sorted node list), ``rotation_clamps`` (list of (node, parameter prefix,
        frame, axis)), ``torque_callback`` (or None).
    """
    resolve_loads(loads, model)  # the same validation as the Lax-form engine (one line per misuse)
    n = model.n_nodes
    out = dict(clamped=[], rotation_clamps=[], torque_callback=None)
    pulls, torques, traps, rclamps = [], [], [], []
    for load in loads:
        kind = type(load).__name__
        if not isinstance(load, LOAD_TYPES):
            raise ParameterError(f"unknown load {load!r}; use PullingForce, Torque, RotationClamp, Clamp, Trap or "
                                 f"Walls")
        if isinstance(load, Walls):
            for f in wall_forces(n, float(model.positions[0, 2]), float(load.k), load.skip, platform=platform):
                system.addForce(f)
            continue
        k = resolve_node(load.node, n, kind)
        if isinstance(load, Clamp):
            out["clamped"].append(k)
        elif isinstance(load, PullingForce):
            pulls.append((k, load.force))
        elif isinstance(load, Torque):
            torques.append((k, load.torque))
        elif isinstance(load, Trap):
            traps.append((k, load.k, model.positions[k] if load.centre is None else load.centre))
        else:
            rclamps.append((k, load))
    out["clamped"] = sorted(set(out["clamped"]))
    if pulls:
        f = openmm.CustomExternalForce("-(dnarod_fx*x + dnarod_fy*y + dnarod_fz*z)")
        for name in ("dnarod_fx", "dnarod_fy", "dnarod_fz"):
            f.addPerParticleParameter(name)
        for k, F in pulls:
            for i in range(3):
                f.addParticle(3 * k + i, list(F / 3.0))
        f.setForceGroup(GROUPS["external"])
        f.setName("dnarod pulling force")
        system.addForce(f)
    if traps:
        f = openmm.CustomCentroidBondForce(
            1, "0.5*dnarod_trap_k*((x1 - dnarod_trap_x)^2 + (y1 - dnarod_trap_y)^2 + (z1 - dnarod_trap_z)^2)")
        for name in ("dnarod_trap_k", "dnarod_trap_x", "dnarod_trap_y", "dnarod_trap_z"):
            f.addPerBondParameter(name)
        for k, kk, c0 in traps:
            g = f.addGroup([3 * k, 3 * k + 1, 3 * k + 2], [1.0, 1.0, 1.0])
            f.addBond([g], [kk, *map(float, c0)])
        f.setForceGroup(GROUPS["external"])
        f.setName("dnarod traps")
        system.addForce(f)
    for k, rc in rclamps:
        frame, axis = rc.target0(model.frames[k])  # the target at angle 0, its 0 K offset included
        pre = f"dnarod_clamp{k}_"
        terms = [f"(a{a}{c} - {pre}T{'xyz'.index(c) + 1}{a})^2" for a in (1, 2, 3) for c in "xyz"]
        expr = "; ".join([f"0.25*{pre}k*({' + '.join(terms)})"] + _director_defs(1, 2, 3, "ua", "va"))
        f = openmm.CustomCompoundBondForce(3, expr)
        for r in range(3):
            for c in range(3):
                f.addGlobalParameter(f"{pre}T{r + 1}{c + 1}", float(frame[r, c]))
        for name in (f"{pre}k", "ua", "va"):
            f.addPerBondParameter(name)
        f.addBond([3 * k, 3 * k + 1, 3 * k + 2], [rc.k, 1 / (3 * radius[k]), 1 / (SQRT3 * radius[k])])
        f.setForceGroup(GROUPS["external"])
        f.setName(f"dnarod rotation clamp node {k}")
        system.addForce(f)
        out["rotation_clamps"].append((k, pre, frame, axis))
    if torques:
        nodes = [k for k, _ in torques]
        cb = TorqueCallback([t for _, t in torques], model.frames[nodes])
        f = python_force(cb)
        f.setParticles([3 * k + i for k in nodes for i in range(3)])
        f.setForceGroup(GROUPS["external"])
        f.setName("dnarod torques")
        system.addForce(f)
        out["torque_callback"] = cb
    return out


def set_clamp_rotation(context, clamp_info, angle):
    """Turn a rotation clamp's target by ``angle`` (rad) about its axis, from its frame at angle 0.

    Parameters
    ----------
    context : openmm.Context
    clamp_info : tuple
        An entry of ``build_load_forces(...)["rotation_clamps"]``.
    angle : float
        rad (2 pi per turn).
    """
    _, pre, frame, axis = clamp_info
    T = rotation_about_axis(axis, float(angle)) @ frame
    for r in range(3):
        for c in range(3):
            context.setParameter(f"{pre}T{r + 1}{c + 1}", float(T[r, c]))
