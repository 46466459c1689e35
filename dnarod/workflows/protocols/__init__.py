"""Single-molecule protocols: force-extension, magnetic tweezers (hat curves), torque-turns, supercoiled rings.

Each protocol is an ensemble over its axes (:mod:`dnarod.workflows.ensemble`): a member is one chain at one force and
one number of turns (or one ring at one linking difference), sampled at equilibrium by
:func:`dnarod.workflows.protocols.tweezers.run_member` / :func:`dnarod.workflows.protocols.rings.run_ring_member`, and reports
extension, turns, clamp torque (and a low-noise twisting-moment estimate), Lk, Tw, Wr, the plectoneme
detector, block standard errors and measured integrated autocorrelation times. The curve (one row per
member) is written as ``curve.csv`` and ``curve.png`` with the measured experimental points of
``data/experimental/`` drawn beside where they exist.

Python::

    from dnarod.workflows.protocols import hat_curve
    curve = hat_curve(turns=[-4, -2, 0, 2, 4], force_pN=0.5, n_bp=600, time_ns=2.0, outdir="hat")
    curve.rows, curve.files     # one dict per member; {"csv": ..., "png": ...}

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
