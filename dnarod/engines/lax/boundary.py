"""Boundary conditions of the Lax-form engine: the translation of :mod:`dnarod.physics.loads`.

A clamped node keeps its position and frame (its velocities are zero and stay zero; the
reaction load is whatever holds it). Prescribed loads are constant lab-frame forces
(kJ/mol/nm) and torques (kJ/mol) on chosen nodes ("dead loads"). Traps and rotation clamps
(position-dependent loads) are evaluated by :meth:`dnarod.physics.loads.ResolvedLoads.evaluate` at every
step. Build from the engine-neutral load vocabulary with :meth:`BoundaryConditions.from_loads`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.physics.loads import LOAD_TYPES, resolve_loads, resolve_node, Clamp, PullingForce, Torque


@dataclass
class BoundaryConditions:
    """Clamps and end loads.

    Parameters
    ----------
    clamped : sequence of int
        Nodes held fixed (position and frame). For the strain-space exact integrator only the ends
        of an open chain (0 and -1 or ``n_nodes - 1``) may be clamped (a circular chain has no
        ends); the splitting integrator accepts any node (``resolve(..., any_node=True)``).
    forces : dict {int: array_like (3,)}
        Constant lab forces on nodes, kJ/mol/nm.
    torques : dict {int: array_like (3,)}
        Constant lab torques on nodes, kJ/mol.
    loads : tuple
        :mod:`dnarod.physics.loads` dataclasses (added to the tables above; traps and rotation clamps are
        honoured by the splitting integrator).
    duration_ps : float, optional
        Run length, ps, over which rotation clamps' ``turns`` are spread.
    """

    clamped: tuple = ()
    forces: dict = field(default_factory=dict)
    torques: dict = field(default_factory=dict)
    loads: tuple = ()
    duration_ps: float | None = None

    @classmethod
    def from_loads(cls, loads, duration_ps=None):
        """Boundary conditions from :mod:`dnarod.physics.loads` dataclasses.

        Parameters
        ----------
        loads : sequence
            :class:`~dnarod.physics.loads.PullingForce`, :class:`~dnarod.physics.loads.Torque`,
            :class:`~dnarod.physics.loads.Clamp`, :class:`~dnarod.physics.loads.RotationClamp`,
            :class:`~dnarod.physics.loads.Trap`.
        duration_ps : float, optional
            Run length, ps, over which ``turns`` of each :class:`~dnarod.physics.loads.RotationClamp` are spread.
        """
        if isinstance(loads, LOAD_TYPES):
            loads = (loads,)
        return cls(loads=tuple(loads or ()), duration_ps=duration_ps)

    def resolved(self, model, positions=None, frames=None):
        """All loads (the ``clamped``/``forces``/``torques`` tables and ``loads``) resolved against ``model``.

        Returns
        -------
        dnarod.physics.loads.ResolvedLoads
        """
        self.resolve(model.n_nodes, model.circular, any_node=True)  # the table checks, with their messages
        return resolve_loads(self._as_loads(), model, positions, frames)

    def _as_loads(self):
        return (tuple(Clamp(k) for k in self.clamped) + tuple(PullingForce(k, v) for k, v in self.forces.items())
                + tuple(Torque(k, v) for k, v in self.torques.items()) + tuple(self.loads))

    def resolve(self, n_nodes, circular, any_node=False):
        """Validate against a chain and return arrays.

        Returns
        -------
        clamp : ndarray of bool, shape (n_nodes,)
        F_ext : ndarray, shape (n_nodes, 3)
            kJ/mol/nm, lab.
        tau_ext : ndarray, shape (n_nodes, 3)
            kJ/mol, lab.

        Raises
        ------
        DnarodError
            For a clamp on a circular chain or an interior node, a node index out of range,
            a load on a clamped node (it would be absorbed by the clamp) or a non-finite load.
        """
        n = int(n_nodes)
        clamped = list(self.clamped) + [ld.node for ld in self.loads if isinstance(ld, Clamp)]
        forces = list(self.forces.items()) + [(ld.node, ld.force) for ld in self.loads if isinstance(ld, PullingForce)]
        torques = list(self.torques.items()) + [(ld.node, ld.torque) for ld in self.loads if isinstance(ld, Torque)]
        other = [ld for ld in self.loads if not isinstance(ld, (Clamp, PullingForce, Torque))]
        if other and not any_node:
            raise DnarodError(f"{type(other[0]).__name__} on node {other[0].node}: the strain-space exact integrator "
                              f"takes clamps, forces and torques only; use the splitting integrator")

        clamp = np.zeros(n, bool)
        for k in clamped:
            kk = resolve_node(k, n, "clamped")
            if any_node:
                clamp[kk] = True
                continue
            if circular:
                raise DnarodError(f"clamped node {k}: a circular chain has no ends to clamp; remove the clamp "
                                  f"or use an open chain")
            if kk not in (0, n - 1):
                raise DnarodError(f"clamped node {k}: only the ends of an open chain (0 or {n - 1}) can be clamped")
            clamp[kk] = True
        if clamp.all():
            pass  # both ends clamped is fine
        F = np.zeros((n, 3))
        tau = np.zeros((n, 3))
        for name, table, arr in (("force", forces, F), ("torque", torques, tau)):
            for k, v in table:
                kk = resolve_node(k, n, f"end {name}")
                v = np.asarray(v, float)
                if v.shape != (3,) or not np.isfinite(v).all():
                    raise DnarodError(f"end {name} on node {k}: must be 3 finite numbers (lab frame), got {v!r}")
                if clamp[kk]:
                    raise DnarodError(f"end {name} on node {k}: the node is clamped, so the load would be absorbed "
                                      f"by the clamp; remove one of the two conditions")
                arr[kk] += v
        return clamp, F, tau

    @property
    def empty(self):
        return not (self.clamped or self.forces or self.torques or self.loads)
