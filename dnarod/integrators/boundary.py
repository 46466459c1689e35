"""Boundary conditions of the Lax-form engine: clamped ends and prescribed end loads.

A clamped node keeps its position and frame (its velocities are zero and stay zero; the
reaction load is whatever holds it). Prescribed loads are constant lab-frame forces
(kJ/mol/nm) and torques (kJ/mol) on chosen nodes ("dead loads").
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import DnarodError


@dataclass
class BoundaryConditions:
    """Clamps and end loads.

    Parameters
    ----------
    clamped : sequence of int
        Nodes held fixed (position and frame). Only the ends of an open chain (0 and -1 or
        ``n_nodes - 1``) may be clamped; a circular chain has no ends.
    forces : dict {int: array_like (3,)}
        Constant lab forces on nodes, kJ/mol/nm.
    torques : dict {int: array_like (3,)}
        Constant lab torques on nodes, kJ/mol.
    """

    clamped: tuple = ()
    forces: dict = field(default_factory=dict)
    torques: dict = field(default_factory=dict)

    def resolve(self, n_nodes, circular):
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

        def index(k, what):
            try:
                k = int(k)
            except (TypeError, ValueError):
                raise DnarodError(f"{what}: node index must be an integer, got {k!r}") from None
            if not -n <= k < n:
                raise DnarodError(f"{what}: node {k} does not exist (the chain has {n} nodes)")
            return k % n

        clamp = np.zeros(n, bool)
        for k in self.clamped:
            kk = index(k, "clamped")
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
        for name, table, arr in (("force", self.forces, F), ("torque", self.torques, tau)):
            for k, v in table.items():
                kk = index(k, f"end {name}")
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
        return not (self.clamped or self.forces or self.torques)
