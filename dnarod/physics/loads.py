"""External loads on nodes, engine-neutral: pulling forces, torques, clamps, rotation clamps, traps.

One vocabulary for both engines: the OpenMM engine translates these dataclasses into OpenMM forces
(:mod:`dnarod.engines.openmm.loads`), the Lax-form engine into its boundary conditions
(:mod:`dnarod.engines.lax.boundary`); the static solver (:mod:`dnarod.physics.statics`), the modes
(:mod:`dnarod.physics.modes`) and the observables (:mod:`dnarod.physics.observables`) use :func:`resolve_loads` and
:meth:`ResolvedLoads.evaluate`, the numpy reference of the load physics.

Plain numbers are in OpenMM MD units (forces kJ/mol/nm, torques kJ/mol, translational stiffness
kJ/mol/nm^2, rotational stiffness kJ/mol (per rad^2), positions nm); an ``openmm.unit.Quantity`` in
any compatible unit is converted (``1 pN = 0.6022 kJ/mol/nm``, ``1 pN nm = 0.6022 kJ/mol``). A value
of the wrong shape or of an incompatible unit raises :class:`~dnarod.core.errors.ParameterError`.

* :class:`PullingForce` -- constant lab force on a node centre (dead load), energy ``-F . r``.
* :class:`Torque` -- constant lab torque on a node about its centre (dead load; magnetic tweezers in
  torque mode).
* :class:`RotationClamp` -- orientation restraint ``E = k (1 - cos theta)`` (theta: angle of the
  rotation from the node's frame to the target frame; ``k theta^2/2`` for small angles). The target
  turns about ``axis`` by ``turns`` full turns spread linearly over the run, or at ``turns_per_ns``
  (magnetic tweezers in rotation mode).
* :class:`Clamp` -- the node is fixed in space (position and orientation). Any node may be clamped.
* :class:`Trap` -- harmonic trap ``k |r - c|^2 / 2`` on a node's centre (optical tweezers).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from dnarod.core.errors import ParameterError
from dnarod.core.docs import fill_doc
from dnarod.core.rotations import rotation_about_axis
from dnarod.core.model import RodModel
from dnarod.core.units import PN, kT
from dnarod.physics.thermal import mean_twist_angles

__all__ = ["PullingForce", "Torque", "RotationClamp", "Clamp", "Trap", "LOAD_TYPES", "as_md", "resolve_node",
           "resolve_loads", "ResolvedLoads", "clamp_angle", "intrinsic_turns", "torque_free_offset", "MAX_FORCE_PN",
           "MAX_SIGMA", "Walls", "tweezers", "pull_axis", "ANCHORS", "AXES"]


def _md_units() -> dict[str, Any]:
    from openmm import unit

    return dict(force=unit.kilojoule_per_mole / unit.nanometer, torque=unit.kilojoule_per_mole,
                stiffness=unit.kilojoule_per_mole / unit.nanometer**2, length=unit.nanometer,
                rate=unit.nanosecond**-1)


def as_md(value: Any, md_unit: Any, shape: tuple[int, ...], what: str) -> Any:
    """Convert a number/array or Quantity to MD units and check its shape.

    Parameters
    ----------
    value : float, array_like or openmm.unit.Quantity
    md_unit : openmm.unit.Unit or str
        The MD unit to convert to (or one of ``"force"``, ``"torque"``, ``"stiffness"``, ``"length"``).
    shape : tuple
        Required shape, e.g. ``(3,)`` or ``()``.
    what : str
        Name used in error messages.

    Returns
    -------
    ndarray or float
    """
    if hasattr(value, "unit") and hasattr(value, "value_in_unit"):  # an openmm Quantity
        from openmm import unit

        if isinstance(md_unit, str):
            md_unit = _md_units()[md_unit]
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
    force: Any  # (3,) array_like or Quantity; an ndarray in kJ/mol/nm after construction

    def __post_init__(self) -> None:
        self.force = as_md(self.force, "force", (3,), f"pulling force on node {self.node}")


@dataclass
class Torque:
    """Constant lab torque (kJ/mol, shape (3,)) on node ``node`` about its centre."""

    node: int
    torque: Any  # (3,) array_like or Quantity; an ndarray in kJ/mol after construction

    def __post_init__(self) -> None:
        self.torque = as_md(self.torque, "torque", (3,), f"torque on node {self.node}")


@dataclass
class RotationClamp:
    """Orientation restraint of node ``node``: ``E = k (1 - cos theta)``, k in kJ/mol (per rad^2).

    Parameters
    ----------
    node : int
    k : float or Quantity
        kJ/mol.
    frame : ndarray (3, 3), optional
        Target at angle 0 (default: the node's starting frame).
    axis : ndarray (3,), optional
        Lab axis about which the target turns (default: the target's d3).
    turns : float
        Total turns applied linearly over a run (positive: right-handed about ``axis``).
    turns_per_ns : float, optional
        Turning rate instead of ``turns`` (turns per ns).
    offset_turns : float
        Turns by which the target at angle 0 is turned about ``axis`` from ``frame`` (or the node's starting
        frame) before the run: the 0 K offset of turns counted from the torque-free state at the run's
        temperature (:func:`torque_free_offset`; ``tweezers(..., turns_from="torque_free")``).
    """

    node: int
    k: Any  # float or Quantity; a float in kJ/mol after construction
    frame: npt.ArrayLike | None = None
    axis: npt.ArrayLike | None = None
    turns: float = 0.0
    turns_per_ns: float | None = None
    offset_turns: float = 0.0

    def target0(self, start_frame: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """The target at angle 0 (3, 3) and the unit axis (3,) for a node whose starting frame is ``start_frame``."""
        frame = np.asarray(start_frame if self.frame is None else self.frame, float)
        axis = frame[:, 2] if self.axis is None else np.asarray(self.axis, float)
        axis = axis / np.linalg.norm(axis)
        if self.offset_turns:
            frame = rotation_about_axis(axis, 2.0 * np.pi * self.offset_turns) @ frame
        return frame, axis

    def __post_init__(self) -> None:
        self.k = as_md(self.k, "torque", (), f"rotation clamp stiffness on node {self.node}")
        if self.k <= 0:
            raise ParameterError(f"rotation clamp stiffness on node {self.node} must be positive, got {self.k}")
        if self.frame is not None:
            f = np.asarray(self.frame, float)
            if f.shape != (3, 3) or not np.allclose(f.T @ f, np.eye(3), atol=1e-6) or np.linalg.det(f) < 0:
                raise ParameterError(f"rotation clamp frame of node {self.node} must be a rotation matrix (3, 3)")
            self.frame = f
        if self.axis is not None:
            a = as_md(self.axis, "length", (3,), f"rotation clamp axis of node {self.node}")
            if np.linalg.norm(a) == 0:
                raise ParameterError(f"rotation clamp axis of node {self.node} must be a nonzero vector")
            self.axis = a / np.linalg.norm(a)
        self.offset_turns = float(self.offset_turns)
        if not np.isfinite(self.offset_turns):
            raise ParameterError(f"rotation clamp offset_turns of node {self.node} must be finite")
        self.turns = float(self.turns)
        if not np.isfinite(self.turns):
            raise ParameterError(f"rotation clamp turns of node {self.node} must be finite, got {self.turns}")
        if self.turns_per_ns is not None:
            self.turns_per_ns = float(self.turns_per_ns)
            if not np.isfinite(self.turns_per_ns):
                raise ParameterError(f"rotation clamp turns_per_ns of node {self.node} must be finite")
            if self.turns != 0.0:
                raise ParameterError(f"rotation clamp of node {self.node}: give turns (over the run) or "
                                     f"turns_per_ns (a rate), not both")


@dataclass
class Clamp:
    """Fix node ``node`` in space (position and orientation)."""

    node: int


@dataclass
class Trap:
    """Harmonic trap on the centre of node ``node``: stiffness k (kJ/mol/nm^2), centre (nm, (3,))
    (default: the node's starting position)."""

    node: int
    k: Any  # float or Quantity; a float in kJ/mol/nm^2 after construction
    centre: Any = None  # (3,) array_like or Quantity, nm; None: the node's starting position

    def __post_init__(self) -> None:
        self.k = as_md(self.k, "stiffness", (), f"trap stiffness on node {self.node}")
        if self.k <= 0:
            raise ParameterError(f"trap stiffness on node {self.node} must be positive, got {self.k}")
        if self.centre is not None:
            self.centre = as_md(self.centre, "length", (3,), f"trap centre of node {self.node}")


@dataclass
class Walls:
    """The surface and the bead of a magnetic-tweezers set-up, as two planar walls normal to the lab z axis.

    Node 0 is anchored at the surface and the last node is pulled along +z (``tweezers(anchor="surface",
    axis="z")``): every node but the first ``skip`` stays above the surface plane (node 0's starting z) and every
    node but the last ``skip`` stays below the pulled node (a plane through it: the large-bead limit), each with
    the harmonic penalty ``k/2 d^2`` on the penetration d. Without them the chain could swing below its anchor or
    around the free end and change its linking number through the closure (a real surface and a micron bead forbid
    both). Engines translate them (the OpenMM engine: :mod:`dnarod.engines.openmm.walls`, which defines the energy
    on the particles that carry each node).

    Parameters
    ----------
    k : float
        Stiffness, kJ/mol/nm^2 (default 100: a penetration of ``sqrt(kT/k)`` = 0.16 nm at 300 K).
    skip : int
        Nodes next to each end the walls leave alone (they sit at the walls by construction).
    """

    k: float = 100.0
    skip: int = 3

    def __post_init__(self) -> None:
        self.k = as_md(self.k, "stiffness", (), "wall stiffness")
        if self.k <= 0:
            raise ParameterError(f"wall stiffness must be positive, got {self.k}")
        if isinstance(self.skip, bool) or int(self.skip) != self.skip or self.skip < 0:
            raise ParameterError(f"wall skip must be a whole number of nodes >= 0, got {self.skip!r}")
        self.skip = int(self.skip)


LOAD_TYPES = (PullingForce, Torque, RotationClamp, Clamp, Trap, Walls)


def resolve_node(node: int, n_nodes: int, what: str = "load") -> int:
    """A node index in range (negative indices count from the end)."""
    try:
        k = int(node)
    except (TypeError, ValueError):
        raise ParameterError(f"{what}: node index must be an integer, got {node!r}") from None
    if not -n_nodes <= k < n_nodes:
        raise ParameterError(f"{what}: node {node} does not exist (the model has {n_nodes} nodes)")
    return k % n_nodes


def clamp_angle(clamp: RotationClamp, time_ps: float, duration_ps: float | None = None) -> float:
    """Angle (rad) by which a rotation clamp's target has turned at ``time_ps``.

    ``turns`` are spread linearly over ``duration_ps`` (the run length, ps); ``turns_per_ns`` is a rate.
    """
    if clamp.turns_per_ns is not None:
        return 2.0 * np.pi * clamp.turns_per_ns * float(time_ps) * 1e-3
    if clamp.turns == 0.0:
        return 0.0
    if duration_ps is None or not duration_ps > 0:
        raise ParameterError(f"rotation clamp of node {clamp.node}: turns={clamp.turns} are spread over the run, "
                             f"so the run length must be known (give a positive duration)")
    return 2.0 * np.pi * clamp.turns * min(float(time_ps) / float(duration_ps), 1.0)


@dataclass
class ResolvedClamp:
    """A rotation clamp resolved against a model: node index, k (kJ/mol), frame0 (3, 3), unit axis (3,)."""

    node: int
    k: float
    frame0: np.ndarray
    axis: np.ndarray
    load: RotationClamp

    def target(self, angle: float) -> np.ndarray:
        """Target frame (3, 3) turned by ``angle`` rad about the axis."""
        return rotation_about_axis(self.axis, float(angle)) @ self.frame0


@dataclass
class ResolvedLoads:
    """Loads resolved against a model (node indices in range, defaults filled in).

    Attributes
    ----------
    n_nodes : int
    clamped : ndarray of bool, shape (n_nodes,)
    force : ndarray, shape (n_nodes, 3)
        Dead lab forces, kJ/mol/nm.
    torque : ndarray, shape (n_nodes, 3)
        Dead lab torques, kJ/mol.
    traps : list of (node, k kJ/mol/nm^2, centre (3,) nm)
    rotation_clamps : list of ResolvedClamp
    walls : Walls or None
        The tweezers walls, which engines translate themselves (:meth:`evaluate` does not include them).
    """

    n_nodes: int
    clamped: np.ndarray
    force: np.ndarray
    torque: np.ndarray
    traps: list[tuple[int, float, np.ndarray]] = field(default_factory=list)
    rotation_clamps: list[ResolvedClamp] = field(default_factory=list)
    loads: tuple[Any, ...] = ()
    walls: Walls | None = None

    @property
    def position_dependent(self) -> bool:
        """True if some load depends on the pose (traps, rotation clamps)."""
        return bool(self.traps or self.rotation_clamps)

    @property
    def empty(self) -> bool:
        """True if there are no loads at all (no clamp, force, torque, trap or rotation clamp)."""
        return not (self.clamped.any() or self.force.any() or self.torque.any() or self.position_dependent)

    def clamp_angles(self, time_ps: float = 0.0, duration_ps: float | None = None) -> np.ndarray:
        """Angles (rad) of the rotation clamps' targets at ``time_ps``; shape (n_rotation_clamps,)."""
        return np.array([clamp_angle(c.load, time_ps, duration_ps) for c in self.rotation_clamps])

    @fill_doc
    def evaluate(self, positions: np.ndarray, frames: np.ndarray,
                 angles: Sequence[float] | np.ndarray | None = None) -> tuple[float, np.ndarray, np.ndarray]:
        """Energy and lab loads of all external loads at a pose (clamped nodes not zeroed).

        Parameters
        ----------
        %(pose)s
        angles : sequence of float, optional
            Rotation clamp target angles, rad (default 0).

        Returns
        -------
        E : float
            Conservative external energy, kJ/mol: traps, rotation clamps and ``-F . r`` of the pulling
            forces (dead torques have no potential; their work is tracked by the caller).
        F : ndarray, shape (n_nodes, 3)
            kJ/mol/nm.
        tau : ndarray, shape (n_nodes, 3)
            kJ/mol.
        """
        F = self.force.copy()
        tau = self.torque.copy()
        E = -float(np.sum(self.force * positions))
        for k, kk, c in self.traps:
            d = positions[k] - c
            E += 0.5 * kk * float(d @ d)
            F[k] -= kk * d
        for i, rc in enumerate(self.rotation_clamps):
            T = rc.target(0.0 if angles is None else angles[i])
            e_c, t_c = rotation_clamp_load(frames[rc.node], T, rc.k)
            E += e_c
            tau[rc.node] += t_c
        return E, F, tau

    def clamp_torques(self, frames: np.ndarray, angles: Sequence[float] | np.ndarray | None = None) -> np.ndarray:
        """Lab torque (kJ/mol) each rotation clamp applies to its node; shape (n_rotation_clamps, 3)."""
        out = np.zeros((len(self.rotation_clamps), 3))
        for i, rc in enumerate(self.rotation_clamps):
            T = rc.target(0.0 if angles is None else angles[i])
            out[i] = rotation_clamp_load(frames[rc.node], T, rc.k)[1]
        return out


def rotation_clamp_load(L: np.ndarray, T: np.ndarray, k: float) -> tuple[float, np.ndarray]:
    """Energy ``k (1 - cos theta) = k (3 - tr(T^T L)) / 2`` (kJ/mol) and lab torque (kJ/mol) on frame L.

    With lab virtual rotations ``dL = hat(dth) L``: ``d tr(T^T L) = dth . v`` with
    ``v = (S23 - S32, S31 - S13, S12 - S21)``, ``S = L T^T``; the torque is ``-dE/dth = k v / 2``.
    """
    S = L @ T.T
    v = np.array([S[1, 2] - S[2, 1], S[2, 0] - S[0, 2], S[0, 1] - S[1, 0]])
    return 0.5 * k * (3.0 - np.trace(S)), 0.5 * k * v


def resolve_loads(loads: Any, model: RodModel, positions: np.ndarray | None = None,
                  frames: np.ndarray | None = None) -> ResolvedLoads:
    """Resolve a sequence of loads against a model.

    Parameters
    ----------
    loads : sequence, ResolvedLoads or BoundaryConditions
        :class:`PullingForce`, :class:`Torque`, :class:`RotationClamp`, :class:`Clamp`, :class:`Trap`
        (a :class:`ResolvedLoads` is returned as is; a Lax-form ``BoundaryConditions`` is resolved).
    model : RodModel
    positions, frames : ndarray, optional
        Starting pose for the defaults (trap centres, clamp frames); default the model's.

    Returns
    -------
    ResolvedLoads

    Raises
    ------
    ParameterError
        For an unknown load, a node out of range, a force/torque/trap/rotation clamp on a clamped node
        (it would be absorbed by the clamp) or two rotation clamps on one node.
    """
    if isinstance(loads, ResolvedLoads):
        return loads
    if hasattr(loads, "resolved") and hasattr(loads, "clamped"):  # integrators.BoundaryConditions
        return loads.resolved(model, positions, frames)
    n = model.n_nodes
    pos = model.positions if positions is None else np.asarray(positions, float)
    frm = model.frames if frames is None else np.asarray(frames, float)
    if isinstance(loads, LOAD_TYPES):
        loads = (loads,)
    loads = tuple(loads or ())
    clamped = np.zeros(n, bool)
    for load in loads:
        if not isinstance(load, LOAD_TYPES):
            raise ParameterError(f"unknown load {load!r}; use PullingForce, Torque, RotationClamp, Clamp, Trap or "
                                 f"Walls")
        if isinstance(load, Clamp):
            clamped[resolve_node(load.node, n, "Clamp")] = True
    out = ResolvedLoads(n, clamped, np.zeros((n, 3)), np.zeros((n, 3)), loads=loads)
    seen_rc: set[int] = set()
    walls = [ld for ld in loads if isinstance(ld, Walls)]
    if len(walls) > 1:
        raise ParameterError("Walls given twice; a tweezers set-up has one surface and one bead")
    if walls and walls[0].skip >= n:
        raise ParameterError(f"Walls skip {walls[0].skip}: must be below the {n} nodes of the chain")
    out.walls = walls[0] if walls else None
    for load in loads:
        kind = type(load).__name__
        if isinstance(load, (Clamp, Walls)):
            continue
        k = resolve_node(load.node, n, kind)
        if clamped[k]:
            raise ParameterError(f"{kind} on node {load.node}: the node is clamped, so the load would be absorbed by "
                                 f"the clamp; remove one of the two")
        if isinstance(load, PullingForce):
            out.force[k] += load.force
        elif isinstance(load, Torque):
            out.torque[k] += load.torque
        elif isinstance(load, Trap):
            out.traps.append((k, float(load.k), pos[k].copy() if load.centre is None else np.asarray(load.centre)))
        else:
            if k in seen_rc:
                raise ParameterError(f"RotationClamp on node {load.node}: the node already has a rotation clamp")
            seen_rc.add(k)
            frame0, axis = load.target0(frm[k])
            out.rotation_clamps.append(ResolvedClamp(k, float(load.k), frame0.copy(), axis.copy(), load))
    return out


#: Largest pulling force (pN) a member accepts: real DNA overstretches near 65 pN (a structural transition
#: the elastic rod does not have), and its stretch modulus is calibrated at low force.
MAX_FORCE_PN = 50.0


#: Largest |sigma| = |turns| / Lk0: beyond a few percent real DNA denatures (underwinding) or forms other
#: structures (overwinding) under tension; the rod's quadratic twist energy is far outside its calibration at
#: 10 % and its Cayley twist coordinate stays regular only below 180 degrees per step.
MAX_SIGMA = 0.1


def torque_free_offset(model: RodModel, temperature: float) -> float:
    """Turns from the intrinsic twist at 0 K to the torque-free state at ``temperature``.

    The sum over the steps of the exact thermal mean of each Cayley twist angle less its intrinsic value, over
    2 pi (:func:`dnarod.physics.thermal.mean_twist_angles`; the Haar measure of the step rotations and the
    concavity of the angle in the strain pull the mean below the intrinsic twist): about -0.42 turns for 1 kbp of
    ``dna-default`` at 300 K, where a chain held at the 0 K twist carries about +2.4 pN nm. It agrees with the
    sampled relaxed ribbon twist (:func:`dnarod.physics.thermal.relaxed_ribbon_twist`) within its error and is
    exact and noise-free. Turns counted from the torque-free state (as magnet turns and other codes count them)
    are the turns from 0 K less this offset: ``turns_0K = turns + offset``. 0 at 0 K.

    Returns
    -------
    float
        Turns (negative for DNA at room temperature).
    """
    T = float(temperature)
    if not T > 0:
        return 0.0
    p = model.params
    th0 = 2.0 * np.arctan(0.5 * model.ds * p.intrinsic[:, 2])
    off = float(np.sum(mean_twist_angles(p, model.ds, kT(T)) - th0) / (2.0 * np.pi))
    # ten decimals: the quadrature's BLAS sums differ in the last bits with the thread count (dask workers run one
    # thread), and a member must start from the same pose in any process (bit-for-bit reproducible samples)
    return round(off, 10)


def intrinsic_turns(model: RodModel) -> float:
    """Relaxed linking number Lk0 of an open chain: its intrinsic twist in turns (Cayley twist angles)."""
    return float(np.sum(2.0 * np.arctan(0.5 * model.ds * model.params.Omega0[:, 2])) / (2.0 * np.pi))


#: Where a tweezers set-up holds the chain: "ends" pulls both ends apart (a free chain in an optical trap),
#: "surface" clamps node 0 (the surface of a magnetic-tweezers flow cell) and pulls the last node (the bead).
ANCHORS = ("ends", "surface")
#: The pull axis of a tweezers set-up: the chain's end-to-end direction at set-up, or the lab z axis.
AXES = ("end-to-end", "z")


def pull_axis(model: RodModel, axis: str = "end-to-end") -> np.ndarray:
    """Unit pull axis (3,) of a set-up: lab z, or from the first to the last node (a ring or a coiled start whose
    ends coincide: node 0's d3)."""
    if axis == "z":
        return np.array([0.0, 0.0, 1.0])
    a = model.positions[-1] - model.positions[0]
    if model.closure is not None or np.linalg.norm(a) < 1e-9 * max(model.ds, 1.0):
        a = model.frames[0][:, 2]
    return a / np.linalg.norm(a)


# one keyword per element of a tweezers set-up (the command line's options)
def tweezers(model: RodModel, force_pN: float | None = None, torque_pN_nm: float | None = None,
             rotation_clamp: float | None = None, turns: float = 0.0, anchor: str = "ends",
             axis: str = "end-to-end", traps: Sequence[tuple[int, float]] = (), walls: bool = False,
             clamp_frame: np.ndarray | None = None, turns_offset: float = 0.0) -> tuple[Any, ...]:
    """The loads of a tweezers set-up: the one way dnarod pulls and twists a chain (``dnarod simulate``, ensemble
    members and the protocols all build their loads here).

    Parameters
    ----------
    model : RodModel
        The chain at set-up (its pose defines the end-to-end axis and, by default, the rotation clamp's target).
    force_pN : float, optional
        Pulling force, pN: on the last node along the axis, and (``anchor="ends"``) the opposite force on node 0.
    torque_pN_nm : float, optional
        Torque on the last node about the axis, pN nm.
    rotation_clamp : float, optional
        Stiffness of an orientation clamp of the last node, kJ/mol (``E = k (1 - cos theta)``), turning about the
        axis.
    turns : float
        Turns of the rotation clamp spread linearly over the run (0: the clamp holds its target).
    anchor : {"ends", "surface"}
        See :data:`ANCHORS`.
    axis : {"end-to-end", "z"}
        See :data:`AXES`.
    traps : sequence of (int, float)
        ``(node, k)`` harmonic traps at the nodes' start positions, k in pN/nm (node index from 0; negative counts
        from the end; the command line numbers base pairs from 1).
    walls : bool
        Add the surface and bead :class:`Walls` (``anchor="surface"``, ``axis="z"`` only).
    clamp_frame : ndarray (3, 3), optional
        Target of the rotation clamp (default: the last node's frame when the engine starts).
    turns_offset : float
        Turns the clamp's target is turned by before the run (``RotationClamp.offset_turns``): with
        :func:`torque_free_offset` of the model at the run's temperature, ``turns`` count from the torque-free
        state at that temperature (as magnet turns do) instead of from the intrinsic twist at 0 K.

    Returns
    -------
    tuple of load dataclasses (MD units)

    Raises
    ------
    ParameterError
        One line naming the option: loads on a closed ring, a force above :data:`MAX_FORCE_PN`, turns without a
        clamp or beyond the chain's helical turns, a torque on a free chain with no force, a non-positive
        stiffness, two traps on one node, an unknown anchor or axis.
    """
    n = model.n_nodes
    if anchor not in ANCHORS:
        raise ParameterError(f"anchor {anchor!r}: choose one of {', '.join(ANCHORS)}")
    if axis not in AXES:
        raise ParameterError(f"axis {axis!r}: choose one of {', '.join(AXES)}")
    surface = anchor == "surface"
    if model.closure is not None and (force_pN is not None or torque_pN_nm is not None or rotation_clamp is not None
                                      or surface or walls):
        raise ParameterError("--pull/--torque/--rotation-clamp/--clamp-first need an open chain with two ends; "
                             "this model is closed (--ring/--circular)")
    for name, v in (("--pull", force_pN), ("--torque", torque_pN_nm), ("--rotation-clamp", rotation_clamp)):
        if v is not None and not np.isfinite(v):
            raise ParameterError(f"{name} {v}: must be a finite number")
    if rotation_clamp is not None and rotation_clamp <= 0:
        raise ParameterError(f"--rotation-clamp {rotation_clamp:g}: the stiffness must be positive (kJ/mol)")
    if turns is not None and not np.isfinite(turns):
        raise ParameterError(f"--turns {turns}: must be a finite number")
    if turns and rotation_clamp is None:
        raise ParameterError("--turns needs --rotation-clamp (the clamp is what turns)")
    if turns:
        lk0 = intrinsic_turns(model)
        # an untwisted rod (uniform force fields): the limit is a quarter turn per step
        if abs(turns) > (abs(lk0) if abs(lk0) >= 1 else n / 4):
            raise ParameterError(f"--turns {turns:g} is more than the {lk0:.1f} helical turns of this {n}-node chain "
                                 f"(sigma = {turns / lk0:+.3g}): the rod model cannot hold it (real DNA denatures "
                                 f"beyond |sigma| ~ 0.1); use |turns| <= {0.1 * abs(lk0):.2g} for real DNA")
    if force_pN is not None and abs(force_pN) > MAX_FORCE_PN:
        raise ParameterError(f"--pull {force_pN:g} pN is above {MAX_FORCE_PN:g} pN: DNA overstretches near 65 pN, a "
                             f"transition the elastic rod model does not have; use forces up to {MAX_FORCE_PN:g} pN")
    if torque_pN_nm is not None and torque_pN_nm != 0 and not force_pN and not surface:  # --pull 0 pulls nothing
        raise ParameterError(f"--torque {torque_pN_nm:g} on a free chain with no pulling force (--pull absent or 0) "
                             f"and no --clamp-first has no equilibrium (the chain spins up without bound); add "
                             f"--clamp-first and/or --pull")
    if walls and not (surface and axis == "z"):
        raise ParameterError("walls need the surface anchor and the lab z axis (a magnetic-tweezers set-up: node 0 on "
                             "the surface, the bead pulled along +z)")
    a = pull_axis(model, axis)
    loads: list[Any] = []
    if surface:
        loads.append(Clamp(0))
    if force_pN is not None:
        loads.append(PullingForce(n - 1, force_pN * PN * a))
        if not surface:
            loads.append(PullingForce(0, -force_pN * PN * a))
    if torque_pN_nm is not None:
        loads.append(Torque(n - 1, torque_pN_nm * PN * a))
    if rotation_clamp is not None:
        loads.append(RotationClamp(n - 1, rotation_clamp, frame=clamp_frame, axis=a, turns=float(turns),
                                   offset_turns=float(turns_offset)))
    trapped: dict[int, float] = {}
    for node, k in traps:
        k_node = resolve_node(node, n, "trap")
        if not (np.isfinite(k) and k > 0):
            raise ParameterError(f"trap on base pair {k_node + 1}: the stiffness must be positive (pN/nm), got {k}")
        if k_node in trapped:  # two traps on one node add up silently: say so
            raise ParameterError(f"trap on base pair {k_node + 1} given twice ({trapped[k_node]:g} and {k:g} pN/nm); "
                                 f"give one trap per base pair with the stiffness you want")
        trapped[k_node] = k
        loads.append(Trap(node, k * PN))
    if walls:
        loads.append(Walls())
    return tuple(loads)
