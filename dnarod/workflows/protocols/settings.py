"""The settings of protocol members in one home: the spec keys every protocol adds, the expansion of a protocol's
axes into member settings with every check a member needs before it runs, and a member's folder name. Used by the
protocol commands (:mod:`dnarod.workflows.protocols.curves`), the protocol objects the ensembles call
(:mod:`dnarod.workflows.protocols.ensemble_hooks`) and replica exchange."""
from __future__ import annotations

from itertools import product
from typing import Any

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.core.forcefield import load_forcefield
from dnarod.physics.loads import Clamp, RotationClamp, Walls, intrinsic_turns
from dnarod.physics.modes import check_load_stiffness
from dnarod.run.api import check_start_pose
from dnarod.run.spec import MAX_SALT, MAX_TEMPERATURE
from dnarod.structure.inputs import protocol_source
from dnarod.workflows.ensemble.schema import Key, RUN_KEYS, check_distinct, coerce, unknown_key
from dnarod.workflows.protocols.rings import check_ring
from dnarod.workflows.protocols.tweezers import DEFAULT_CLAMP_K, check_tweezers

__all__ = ["protocol_keys", "expand_members", "member_name", "MAX_MEMBER_NS"]


def protocol_keys() -> dict[str, Key]:
    """The keys every protocol adds to an ensemble spec (equilibration, sampling interval, friction mode)."""
    return {k.name: k for k in [
        Key("equilibration_ns", float, None, "equilibration before sampling, ns (default 5 slowest bending "
            "relaxation times)", ">0"),
        Key("sample_ps", float, None, "time between samples, ps (default min(tau_1/10, time/200) in [1, 200] ps)",
            ">0"),
        Key("friction_mode", str, "auto", "auto: critical damping of the slowest bending mode; fixed: "
            "friction_per_ps", "auto|fixed"),
    ]}


def expand_members(kind: str, axes: dict[str, Any], base: dict[str, Any]) -> list[dict[str, Any]]:
    """Expand the axes (cross product) into member settings, checking every member before any runs: the one check of
    a protocol member's settings (the protocol commands and the ensembles' protocol objects both call it)."""

    names = list(axes)
    values = [list(np.atleast_1d(axes[n]).tolist()) for n in names]
    for n, v in zip(names, values):
        if not v:
            raise DnarodError(f"{n}: give at least one value")
    base, values = _checked_settings(base, names, values)
    members = [dict(base, **dict(zip(names, combo))) for combo in product(*values)]

    ff = load_forcefield(base.get("forcefield", "dna-default"))

    # tweezers: the surface and bead walls leave Walls().skip nodes free at each end
    seq, n_nodes = protocol_source(base.get("source", ""), min_nodes=3 if kind == "rings" else 2 * Walls().skip + 2)
    if kind == "rings":
        ring = ff.ring(seq, n_nodes=n_nodes)
        tw0 = intrinsic_turns(ring)
        for m in members:
            check_ring(m.get("delta_lk", 0), tw0)
        # the start pose every member runs from, checked as `dnarod simulate` checks it (a tiny ring heats up)
        for dlk in sorted({int(m.get("delta_lk", 0)) for m in members}):
            for T in sorted({float(m.get("temperature_K") or 300.0) for m in members}):
                check_start_pose(ff.ring(seq, n_nodes=n_nodes, delta_linking_number=dlk), T)
    else:
        model = ff.model_from_sequence(seq, n_nodes=n_nodes)
        lk0 = intrinsic_turns(model)
        for m in members:
            check_tweezers(m.get("force_pN", 0.0), m.get("turns"), rotation_clamp=kind != "force_extension",
                           lk0=lk0, torque_pN_nm=m.get("torque_pN_nm"))
        check_start_pose(model, 300.0)
        if kind != "force_extension":
            _check_clamp_stiffness(model, members, "axes" if "rotation_clamp_kJ_mol" in names else "base")
    return members


def _check_clamp_stiffness(model, members, table):
    """The rotation clamp of the tweezers members against the one bound on load stiffness
    (:func:`dnarod.physics.loads.check_load_stiffness`, as ``dnarod simulate --rotation-clamp``), on the free chain with
    node 0 clamped; named as the setting ``rotation_clamp_kJ_mol`` (``--clamp-k``)."""

    for k in sorted({float(m.get("rotation_clamp_kJ_mol") or DEFAULT_CLAMP_K) for m in members}):
        loads = (Clamp(0), RotationClamp(model.n_nodes - 1, k, axis=[0.0, 0.0, 1.0]))
        check_load_stiffness(model, loads, names={"RotationClamp": f"[{table}] rotation_clamp_kJ_mol"})


def _checked_settings(base, names, values):
    """``base`` and the axis values checked against the ensemble schema (the keys the members read): an
    unknown key, a value of the wrong type, a non-finite or out-of-range number is one line naming it."""

    known = {**RUN_KEYS, **protocol_keys()}
    out = {}
    for key, value in base.items():
        if key not in known:
            raise unknown_key("base", key, known)
        out[key] = None if value is None else _checked(coerce("base", key, known[key], value), "base", key)
    vals = []
    for n, v in zip(names, values):
        if n not in known:
            raise unknown_key("axes", n, known)
        vals.append(check_distinct("axes", n, [_checked(coerce("axes", n, known[n], x), "axes", n) for x in v]))
    return out, vals


#: Longest production or equilibration of one protocol member, ns: the members sample every 1-200 ps into
#: memory and run at ~10-100 ns per hour here, so more is a typo (a time in ps) that would hang or exhaust memory.
MAX_MEMBER_NS = 1e4


def _checked(value, table, key):
    """Ranges the schema leaves to the run layer, refused here before any member runs."""
    if key == "seed" and not 0 <= value < 2**31:
        raise DnarodError(f"[{table}] seed: must be an integer in [0, 2^31), got {value}")
    if key in ("time_ns", "equilibration_ns", "salt_M") and not value > 0:
        raise DnarodError(f"[{table}] {key}: must be > 0, got {value:g}")
    if key in ("time_ns", "equilibration_ns") and value > MAX_MEMBER_NS:
        raise DnarodError(f"[{table}] {key}: {value:g} ns per member is more than {MAX_MEMBER_NS:g} ns (10 us): it "
                          f"would not finish here and its samples would not fit in memory; give a shorter time")
    if key == "salt_M" and value > MAX_SALT:
        raise DnarodError(f"[{table}] salt_M: must be at most {MAX_SALT:g} mol/L (Debye-Hueckel screening is "
                          f"meaningless beyond), got {value:g}")
    if key == "temperature_K" and not value > 0:
        raise DnarodError(f"[{table}] temperature_K: must be > 0 K, got {value:g}")
    if key == "temperature_K" and value > MAX_TEMPERATURE:
        raise DnarodError(f"[{table}] temperature_K: must be at most {MAX_TEMPERATURE:g} K (the model's solvent is "
                          f"liquid water), got {value:g}")
    return value


def member_name(m: dict[str, Any], axes: dict[str, Any]) -> str:
    """A member's folder name from its axis values (``force_pN+2_turns+0.5``)."""
    return "_".join(f"{k}{m[k]:+g}" if isinstance(m[k], (int, float)) else f"{k}{m[k]}" for k in axes) or "member"
