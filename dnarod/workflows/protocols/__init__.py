"""Single-molecule protocols: force-extension, magnetic tweezers (hat curves), torque-turns, supercoiled rings.

Each protocol is an ensemble over its axes (:mod:`dnarod.workflows.ensemble`): a member is one chain at one force and
one number of turns (or one ring at one linking difference), sampled at equilibrium by
:func:`dnarod.workflows.protocols.tweezers.run_member` / :func:`dnarod.workflows.protocols.rings.run_ring_member`, and reports
extension, turns, clamp torque (and a low-noise twisting-moment estimate), Lk, Tw, Wr, the plectoneme
detector, block standard errors and measured integrated autocorrelation times. The curve (one row per
member) is written as ``curve.csv`` and ``curve.png`` with the measured experimental points of
``data/experimental/`` drawn beside where they exist.

Example (40 bp at 0.5 pN, three turn values, 0.05 ns per member after 0.05 ns of equilibration: a first look
in seconds; a converged curve needs ns per member, see docs/protocols.md):

>>> from dnarod.workflows.protocols import hat_curve
>>> curve = hat_curve([-0.3, 0, 0.3], "hat", force_pN=0.5, source="40",
...                   base=dict(time_ns=0.05, equilibration_ns=0.05), workers=0, progress=False)
>>> len(curve.rows), sorted(curve.files)     # one dict per member; the curve's CSV and PNG
(3, ['csv', 'png'])

Nicked rings (Lk free): :func:`dnarod.workflows.protocols.nicked.run_nicked_member` samples the writhe of a ring free to
writhe (soft twist, exactly reweighted) for ``<ΔLk²> = <ΔTw²> + <Wr²>``.

Protocol objects for ensemble specs (``protocol = "dnarod.workflows.protocols:MAGNETIC_TWEEZERS"``):
:data:`FORCE_EXTENSION`, :data:`MAGNETIC_TWEEZERS`, :data:`TORQUE_TURNS`, :data:`RINGS`.
"""
from __future__ import annotations

from dnarod.workflows.protocols.curves import (Curve, force_extension, hat_curve, ring_supercoiling, run_protocol, torque_turns)  # noqa: F401
from dnarod.workflows.protocols.ensemble_hooks import FORCE_EXTENSION, MAGNETIC_TWEEZERS, RINGS, TORQUE_TURNS  # noqa: F401
from dnarod.workflows.protocols.nicked import run_nicked_member  # noqa: F401
from dnarod.workflows.ensemble.protocol import register_protocol

# the names ensemble specs give (also entry points of dnarod in pyproject.toml), and their import paths
for _name, _attr, _obj in (("force-extension", "FORCE_EXTENSION", FORCE_EXTENSION),
                           ("magnetic-tweezers", "MAGNETIC_TWEEZERS", MAGNETIC_TWEEZERS),
                           ("torque-turns", "TORQUE_TURNS", TORQUE_TURNS), ("rings", "RINGS", RINGS)):
    register_protocol(_name, _obj, aliases=(f"{__name__}:{_attr}",))

__all__ = ["Curve", "force_extension", "hat_curve", "torque_turns", "ring_supercoiling", "run_protocol",
           "FORCE_EXTENSION", "MAGNETIC_TWEEZERS", "TORQUE_TURNS", "RINGS", "run_nicked_member"]
