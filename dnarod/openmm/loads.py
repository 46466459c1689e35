"""External loads on nodes: pulling forces, torques, rotation clamps, clamped nodes, traps.

Plain numbers are in OpenMM MD units (forces kJ/mol/nm, torques kJ/mol, stiffnesses kJ/mol/nm^2
or kJ/mol/rad^2, positions nm); an ``openmm.unit.Quantity`` in any compatible unit is
converted (``1 pN = 0.6022 kJ/mol/nm``, ``1 pN nm = 0.6022 kJ/mol``). A value of the wrong
shape or of an incompatible unit raises :class:`~dnarod.errors.ParameterError`.

* :class:`PullingForce` -- constant lab force on a node (spread over its three particles).
* :class:`Torque` -- constant lab torque on a node about its centre (magnetic tweezers in
  torque mode); the reported energy is ``-|tau| phi`` with phi the unwrapped rotation of the
  node about the torque axis since the start of the run.
* :class:`RotationClamp` -- orientation restraint ``E = k (1 - cos theta)`` (theta: angle of
  the rotation from the node's frame to the target frame; ``k theta^2/2`` for small angles);
  the target can be turned during a run (:func:`set_clamp_rotation`), magnetic tweezers in
  rotation mode.
* :class:`Clamp` -- the node is fixed in space (position and orientation; its particles get
  zero mass and no constraints).
* :class:`Trap` -- harmonic trap ``k |c - c0|^2 / 2`` on a node's centre (optical tweezers).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import openmm
from openmm import unit

from ..errors import ParameterError
from .forces import GROUPS
from .particles import SQRT3


_FORCE_UNIT = unit.kilojoule_per_mole / unit.nanometer
_TORQUE_UNIT = unit.kilojoule_per_mole
_STIFF_UNIT = unit.kilojoule_per_mole / unit.nanometer**2
_LENGTH_UNIT = unit.nanometer


def as_md(value, md_unit, shape, what):
    """Convert a number/array or Quantity to MD units and check its shape.

    Parameters
    ----------
    value : float, array_like or openmm.unit.Quantity
    md_unit : openmm.unit.Unit
        The MD unit to convert to.
    shape : tuple
        Required shape, e.g. ``(3,)`` or ``()``.
    what : str
        Name used in error messages.

    Returns
    -------
    ndarray or float
    """
    if unit.is_quantity(value):
        try:
            value = value.value_in_unit(md_unit)
        except TypeError:
            try:  # per-molecule units (pN, pN*nm): times Avogadro's number
                value = (value * unit.AVOGADRO_CONSTANT_NA).value_in_unit(md_unit)
            except TypeError:
                raise ParameterError(f"{what}: unit {value.unit} is not compatible with {md_unit}") from None
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(f"{what}: expected numbers in {md_unit}, got {value!r}") from None
    if arr.shape != tuple(shape):
        raise ParameterError(f"{what}: expected shape {tuple(shape)} ({md_unit}), got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ParameterError(f"{what}: values must be finite, got {arr}")
    return float(arr) if arr.ndim == 0 else arr


@dataclass
class PullingForce:
    """Constant lab force (kJ/mol/nm, shape (3,)) on node ``node`` (negative counts from the end)."""

    node: int
    force: object

    def __post_init__(self):
        self.force = as_md(self.force, _FORCE_UNIT, (3,), f"pulling force on node {self.node}")


@dataclass
class Torque:
    """Constant lab torque (kJ/mol, shape (3,)) on node ``node`` about its centre."""

    node: int
    torque: object

    def __post_init__(self):
        self.torque = as_md(self.torque, _TORQUE_UNIT, (3,), f"torque on node {self.node}")


@dataclass
class RotationClamp:
    """Orientation restraint of node ``node``: ``E = k (1 - cos theta)``, k in kJ/mol (per rad^2).

    ``frame`` (3, 3) is the target at angle 0 (default: the node's starting frame); ``axis``
    (3,) the lab axis about which :func:`set_clamp_rotation` turns the target (default: the
    target's d3).
    """

    node: int
    k: object
    frame: np.ndarray | None = None
    axis: np.ndarray | None = None

    def __post_init__(self):
        self.k = as_md(self.k, _TORQUE_UNIT, (), f"rotation clamp stiffness on node {self.node}")
        if self.k <= 0:
            raise ParameterError(f"rotation clamp stiffness on node {self.node} must be positive, got {self.k}")


@dataclass
class Clamp:
    """Fix node ``node`` in space (position and orientation)."""

    node: int


@dataclass
class Trap:
    """Harmonic trap on the centre of node ``node``: stiffness k (kJ/mol/nm^2), centre (nm, (3,))
    (default: the node's starting position)."""

    node: int
    k: object
    centre: object = None

    def __post_init__(self):
        self.k = as_md(self.k, _STIFF_UNIT, (), f"trap stiffness on node {self.node}")
        if self.k <= 0:
            raise ParameterError(f"trap stiffness on node {self.node} must be positive, got {self.k}")
        if self.centre is not None:
            self.centre = as_md(self.centre, _LENGTH_UNIT, (3,), f"trap centre of node {self.node}")


def resolve_node(node, n_nodes, what="load"):
    """A node index in range (negative indices count from the end)."""
    k = int(node)
    if not -n_nodes <= k < n_nodes:
        raise ParameterError(f"{what}: node {node} does not exist (the model has {n_nodes} nodes)")
    return k % n_nodes


class TorqueCallback:
    """PythonForce computation of constant torques (applied to a subset of particles)."""

    def __init__(self, torques, frames0):
        self.torques = np.asarray(torques, float).reshape(-1, 3)
        self.ref = np.asarray(frames0, float).reshape(-1, 3, 3)
        self.phi = np.zeros(len(self.torques))
        self.last_angle = np.zeros(len(self.torques))

    def __call__(self, state):
        from .particles import loads_to_particle_forces, node_poses

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


def build_load_forces(loads, model, radius, system):
    """Add the OpenMM forces of ``loads`` to ``system``.

    Parameters
    ----------
    loads : list
        :class:`PullingForce`, :class:`Torque`, :class:`RotationClamp`, :class:`Clamp`, :class:`Trap`.
    model : RodModel
    radius : ndarray, shape (n_nodes,)
        Triangle circumradius, nm.
    system : openmm.System

    Returns
    -------
    dict
        ``clamped`` (sorted node list), ``rotation_clamps`` (list of (node, parameter prefix,
        frame, axis)), ``torque_callback`` (or None).
    """
    n = model.n_nodes
    out = dict(clamped=[], rotation_clamps=[], torque_callback=None)
    pulls, torques, traps, rclamps = [], [], [], []
    for load in loads:
        kind = type(load).__name__
        if not isinstance(load, (PullingForce, Torque, RotationClamp, Clamp, Trap)):
            raise ParameterError(f"unknown load {load!r}; use PullingForce, Torque, RotationClamp, Clamp or Trap")
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
        frame = model.frames[k] if rc.frame is None else np.asarray(rc.frame, float)
        axis = frame[:, 2] if rc.axis is None else np.asarray(rc.axis, float)
        axis = axis / np.linalg.norm(axis)
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
        f = openmm.PythonForce(cb)
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
    from ..rotations import rotation_about_axis

    _, pre, frame, axis = clamp_info
    T = rotation_about_axis(axis, float(angle)) @ frame
    for r in range(3):
        for c in range(3):
            context.setParameter(f"{pre}T{r + 1}{c + 1}", float(T[r, c]))
