"""Standard load set-ups of the command line as :mod:`dnarod.physics.loads` dataclasses (tweezers, traps).

Units: the arguments are in the experimentalist's units (pN, pN nm, pN/nm) and converted here
through :mod:`dnarod.core.units`; the returned loads are in MD units.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import ParameterError


def pull_axis(model):
    """Unit vector from the first to the last node (a ring or a coiled start: node 0's d3)."""
    axis = model.positions[-1] - model.positions[0]
    if model.closure is not None or np.linalg.norm(axis) < 1e-9 * max(model.ds, 1.0):
        axis = model.frames[0][:, 2]
    return axis / np.linalg.norm(axis)


def parse_trap(text, n_nodes):
    """``"NODE:K"`` (K in pN/nm) -> (node index from 0, K). NODE is a base pair numbered from 1, as `dnarod steps`
    and every message number them; a negative NODE counts from the end (-1: the last)."""
    try:
        node, k = text.split(":")
        node, k = int(node), float(k)
    except ValueError:
        raise ParameterError(f"--trap {text!r}: expected NODE:STIFFNESS (a base pair numbered from 1, stiffness in "
                             f"pN/nm), e.g. 1:50") from None
    if node == 0:
        raise ParameterError(f"--trap {text!r}: base pairs are numbered from 1 (1 to {n_nodes}, or -1 for the last)")
    if not -n_nodes <= node <= n_nodes:
        raise ParameterError(f"--trap {text!r}: base pair {node} does not exist (the chain has {n_nodes} nodes, "
                             f"numbered from 1)")
    node = node - 1 if node > 0 else node
    if not (np.isfinite(k) and k > 0):
        raise ParameterError(f"--trap {text!r}: the stiffness must be positive (pN/nm)")
    return node, k


def tweezers_loads(model, pull=None, torque=None, rotation_clamp=None, turns=0.0, clamp_first=False, traps=()):
    """Loads of a tweezers-style set-up along the model's end-to-end axis.

    Parameters
    ----------
    model : RodModel
    pull : float or None
        Force pulling the ends apart, pN (with ``clamp_first`` only the last node is pulled).
    torque : float or None
        Torque on the last node about the axis, pN nm.
    rotation_clamp : float or None
        Orientation clamp of the last node, stiffness kJ/mol.
    turns : float
        Turns of the rotation clamp spread linearly over the run.
    clamp_first : bool
        Fix node 0 in space.
    traps : sequence of str
        ``"NODE:K"`` harmonic traps (K pN/nm) at the nodes' start positions.

    Returns
    -------
    tuple of dnarod.physics.loads dataclasses
    """
    from dnarod.physics.loads import Clamp, PullingForce, RotationClamp, Torque, Trap
    from dnarod.core.units import PN

    n = model.n_nodes
    if model.closure is not None and (pull is not None or torque is not None or rotation_clamp is not None
                                      or clamp_first):
        raise ParameterError("--pull/--torque/--rotation-clamp/--clamp-first need an open chain with two ends; "
                             "this model is closed (--ring/--circular)")
    for name, v in (("--pull", pull), ("--torque", torque), ("--rotation-clamp", rotation_clamp)):
        if v is not None and not np.isfinite(v):
            raise ParameterError(f"{name} {v}: must be a finite number")
    if rotation_clamp is not None and rotation_clamp <= 0:
        raise ParameterError(f"--rotation-clamp {rotation_clamp:g}: the stiffness must be positive (kJ/mol)")
    if turns and rotation_clamp is None:
        raise ParameterError("--turns needs --rotation-clamp (the clamp is what turns)")
    if turns is not None and not np.isfinite(turns):
        raise ParameterError(f"--turns {turns}: must be a finite number")
    if turns:
        from dnarod.physics.loads import intrinsic_turns

        lk0 = float(intrinsic_turns(model))
        # an untwisted rod (uniform force fields): the limit is a quarter turn per step
        if abs(turns) > (abs(lk0) if abs(lk0) >= 1 else n / 4):
            raise ParameterError(f"--turns {turns:g} is more than the {lk0:.1f} helical turns of this {n}-node chain "
                                 f"(sigma = {turns / lk0:+.3g}): the rod model cannot hold it (real DNA denatures "
                                 f"beyond |sigma| ~ 0.1); use |turns| <= {0.1 * abs(lk0):.2g} for real DNA")
    from dnarod.physics.loads import MAX_FORCE_PN  # below overstretching (~65 pN), which the rod model lacks

    if pull is not None and abs(pull) > MAX_FORCE_PN:
        raise ParameterError(f"--pull {pull:g} pN is above {MAX_FORCE_PN:g} pN: DNA overstretches near 65 pN, a "
                             f"transition the elastic rod model does not have; use forces up to {MAX_FORCE_PN:g} pN")
    if torque is not None and torque != 0 and not pull and not clamp_first:  # --pull 0 pulls nothing
        raise ParameterError(f"--torque {torque:g} on a free chain with no pulling force (--pull absent or 0) and no "
                             f"--clamp-first has no equilibrium (the chain spins up without bound); add --clamp-first "
                             f"and/or --pull")
    axis = pull_axis(model)
    loads = []
    if clamp_first:
        loads.append(Clamp(0))
    if pull is not None:
        loads.append(PullingForce(n - 1, pull * PN * axis))
        if not clamp_first:
            loads.append(PullingForce(0, -pull * PN * axis))
    if torque is not None:
        loads.append(Torque(n - 1, torque * PN * axis))
    if rotation_clamp is not None:
        loads.append(RotationClamp(n - 1, rotation_clamp, axis=axis, turns=float(turns)))
    trapped = {}
    for t in traps:
        node, k = parse_trap(t, n)
        if node % n in trapped:  # two traps on one node add up silently: say so
            raise ParameterError(f"--trap {t!r}: base pair {node % n + 1} already has a trap ({trapped[node % n]!r}); "
                                 f"give one --trap per base pair with the stiffness you want")
        trapped[node % n] = t
        loads.append(Trap(node, k * PN))
    return tuple(loads)
