"""Replica exchange of Monte Carlo engines along the turns of a rotation clamp (parallel tempering in Lk).

Why. Near buckling a long chain under a rotation clamp is bistable (straight or plectonemic) and past it the
plectoneme's length relaxes slowly; a ladder of replicas at neighbouring turn values lets a configuration change
state through its neighbours (the MD engine's ladder, :mod:`dnarod.workflows.protocols.exchange`, does the same
with Langevin dynamics).

Ladder. One :class:`~dnarod.engines.mc.engine.MCEngine` per turn value ``n_0 < n_1 < ...``: the same chain and
loads, the rotation clamp's target turned by ``n_i`` about z (the rung). Each engine keeps its rung (its random
numbers, amplitudes and counters); configurations move between rungs.

Move. A swap of rungs i and i+1 carries configuration X of rung i to rung i+1 with ``delta = n_{i+1} - n_i``
turns added as twist spread along the chain (node k turned about its own d3 by ``2 pi delta k / (n - 1)``:
a fixed right multiplication of each frame, so it preserves the invariant measure, keeps the centres, hence the
non-bonded energy, and is inverted by ``-delta``), and configuration Y of rung i+1 to rung i with ``-delta``.
Accepting with ``min(1, exp(-Delta/kT))``, ``Delta = U_{i+1}(T_delta X) - U_i(X) + U_i(T_-delta Y) - U_{i+1}(Y)``
(U the potential energy; the non-bonded terms cancel) leaves the product of the rungs' Boltzmann distributions
invariant. Pairs of alternating parity are attempted at each :meth:`TurnLadder.exchange`.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import ParameterError
from dnarod.engines.mc import kernels as kn


def twist_ramp(frames, delta_turns):
    """``delta_turns`` turns of twist spread along a chain: node k of n turned about its own d3 by
    ``2 pi delta k / (n - 1)``; frames (n, 3, 3), directors as columns. ``twist_ramp(twist_ramp(F, d), -d) == F``
    up to rounding."""
    n = frames.shape[0]
    phi = 2.0 * np.pi * float(delta_turns) * np.arange(n) / (n - 1)
    c, s = np.cos(phi), np.sin(phi)
    out = frames.copy()
    out[:, :, 0] = c[:, None] * frames[:, :, 0] + s[:, None] * frames[:, :, 1]
    out[:, :, 1] = -s[:, None] * frames[:, :, 0] + c[:, None] * frames[:, :, 1]
    return out


class TurnLadder:
    """Monte Carlo replicas along the turns, with swaps between neighbours (module docstring).

    Parameters
    ----------
    engines : sequence of MCEngine
        One per rung, ordered by ``turns``: same model, temperature and loads but for the rotation clamp's target.
    turns : sequence of float
        The rungs' turns (increasing; only their differences enter the swap map).
    seed : int
        Seed of the swap decisions.
    """

    def __init__(self, engines, turns, seed=0):
        self.engines = list(engines)
        self.turns = np.asarray(turns, float)
        if len(self.engines) != len(self.turns) or len(self.engines) < 2:
            raise ParameterError("a turn ladder needs one engine per rung and at least two rungs")
        if not np.all(np.diff(self.turns) > 0):
            raise ParameterError("the ladder's turns must increase from rung to rung")
        e0 = self.engines[0]
        for e in self.engines:
            if e.fingerprint != e0.fingerprint or e.temperature != e0.temperature:
                raise ParameterError("the rungs of a turn ladder must share the model and the temperature")
            if not e.resolved.rotation_clamps or e.model.closure is not None:
                raise ParameterError("a turn ladder needs open chains with a rotation clamp")
            if np.any(e.tq_mag > 0):
                raise ParameterError("a turn ladder does not carry dead torques (their energy is path dependent)")
        self.rng = np.random.default_rng(seed)
        self.parity = 0
        self.attempts = np.zeros(len(self.engines) - 1, np.int64)
        self.accepts = np.zeros(len(self.engines) - 1, np.int64)
        #: replica label held by each rung (labels start equal to the rung index)
        self.labels = np.arange(len(self.engines))

    def advance(self, n_sweeps):
        """Advance every rung by ``n_sweeps`` sweeps."""
        for e in self.engines:
            e.advance(n_sweeps)

    def exchange(self):
        """Attempt swaps of the neighbour pairs of this round's parity; returns the number accepted."""
        acc = 0
        kt = self.engines[0].fp[kn.F_KT]
        for i in range(self.parity, len(self.engines) - 1, 2):
            a, b = self.engines[i], self.engines[i + 1]
            d = self.turns[i + 1] - self.turns[i]
            fx = twist_ramp(a.frm, d)
            fy = twist_ramp(b.frm, -d)
            delta = (b.potential_local(a.pos, fx) - a.potential_local(a.pos, a.frm)
                     + a.potential_local(b.pos, fy) - b.potential_local(b.pos, b.frm))
            self.attempts[i] += 1
            if delta <= 0.0 or self.rng.random() < np.exp(-delta / kt):
                px, py = a.pos.copy(), b.pos.copy()
                a.set_pose(py, fy)
                b.set_pose(px, fx)
                self.labels[i], self.labels[i + 1] = self.labels[i + 1], self.labels[i]
                self.accepts[i] += 1
                acc += 1
        self.parity = 1 - self.parity
        return acc

    def acceptance(self):
        """Accepted fraction of the swaps of each neighbour pair (NaN where none was tried)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.attempts > 0, self.accepts / np.maximum(self.attempts, 1), np.nan)
