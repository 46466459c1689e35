"""Turn sweeps: tweezers members run as chains along the turns axis, "as the magnets are turned in the lab".

Research code (``research/turn_sweeps``; until 2026-12-07 the start modes ``sweep``, ``sweep-in`` and ``bracket``
of ``dnarod protocol hat|torque-turns``). It runs on the product's public API: each member is
:func:`dnarod.workflows.protocols.tweezers.run_member`, chained members start from the previous member's final
pose (``start_pose`` + ``previous_turns``), and the curve is written by
:func:`dnarod.workflows.protocols.curves.write_curve`. Command (from the repository root)::

    python research/turn_sweeps/turn_sweep.py hat --source 1000 --force 1 --turns=-4.8,-4,...,4 \\
        --start sweep|sweep-in|bracket [--settle NS] [--settle-buckled NS] [--time NS] [--workers 2] -o OUT

Past buckling a member started from the straight (static) pose has to grow its plectoneme from nothing, which
takes longer than the production itself at 1 kbp. In a sweep, the members of one force run one after the other
in order of |turns| away from zero: each starts from the previous turn value's final pose with the turn
increment added (:func:`dnarod.workflows.protocols.poses.add_turns`: the clamp target and the linking number
follow) and settles for ``settle_ns`` before its production. Only the first member of a chain starts from the
static pose, with the full equilibration. Turns >= 0 form one chain (ascending), turns < 0 another (descending),
so a two-worker cluster runs the two sides of a hat curve at once (:func:`sweep_chains`).

Inward sweeps (``inward=True``, ``start="sweep-in"``) run the other way: each chain begins at the largest |turns|
from a plectoneme grown for :data:`GROW_NS` at :data:`GROW_FORCE_FRACTION` of the member's force (same turns and
clamp target, so the same linking number; :func:`run_grown_member`) and the turns are taken out step by step, so
the post-buckling members start plectonemic instead of from a straight chain that has to nucleate its first loop
(an outward sweep can stay straight, metastable, past the buckling point).

Bracket (``start="bracket"``): both sweeps at once; each turn value's curve point is the midpoint of its outward
and inward members with an error that covers the gap between them (:func:`bracket_rows`).

Settle where it is needed (``settle_buckled_ns``): before buckling a chained member is settled after a short
``settle_ns`` (its extension relaxes in a few ns after a turn increment); at and past buckling the plectoneme has
to nucleate, grow or shrink, which takes tens to hundreds of ns. :func:`buckling_turns` places the buckling point
by Marko's two-phase model with the model's own parameters and a margin; chained members at or beyond it settle
for ``settle_buckled_ns`` instead (:func:`member_settles`).

Seeds: every member draws its own noise stream
(:func:`dnarod.workflows.protocols.ensemble_hooks.member_seed` of the curve's seed, the protocol, force, turns
and the sweep direction), so a chained member does not restart the stream the previous member began with.

Resume: a chained member's key holds the previous turn value and the SHA-256 of its start pose, so a finished
member is reused only if it was started from the previous member's present final pose; an interrupted member
resumes from its checkpoint (:func:`dnarod.workflows.protocols.tweezers.run_member`).

Results (the 1-kbp hat curve at 1 pN, 2026-12-02): ``research/turn_sweeps/README.md`` and
``research/hat_curve/notes.md``.

Units: turns; ns; positions nm; frames (n, 3, 3) with the directors d1, d2, d3 as columns.
"""
from __future__ import annotations

import argparse
import math
import sys
from itertools import product
from pathlib import Path

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.workflows.protocols.poses import FINAL_POSE, load_pose

#: Start modes of this study (the product keeps "static" and "exchange": ``dnarod protocol hat --start``).
STARTS = ("sweep", "sweep-in", "bracket")
#: Head of an inward sweep: its plectoneme is grown at this fraction of the member's force ...
GROW_FORCE_FRACTION = 0.3
#: ... for this long (ns), before its equilibration at the member's force.
GROW_NS = 20.0
#: Plectoneme twist stiffness P (nm) that places the buckling point (:func:`buckling_turns`): the model's own,
#: from its plectonemic 600-bp ring at Delta Lk = -5 (``dna-default``, 0.15 M, 300 K; the
#: buckling check, research/buckling/notes.md): 17.3 +- 0.3 nm (19.7 nm at Delta Lk = -3, 14.5 nm from the
#: measured plateau torque).
PLECTONEME_P_NM = 17.3
#: Members with |Delta Lk at T| >= this fraction of Marko's buckling Delta Lk count as at or past buckling: 0.8
#: covers any P down to 12 nm at 1 pN (a smaller P buckles earlier) and the torque overshoot's spread of the
#: buckling point (the settle is long for a member or two before buckling rather than short for one past it).
BUCKLING_MARGIN = 0.8
#: Observables a bracketed curve point combines from its outward and inward members (each with its ``_err``).
BRACKET_KEYS = ("relative_extension", "extension_nm", "Wr", "Tw", "Lk", "twist_torque_pN_nm", "clamp_torque_pN_nm",
                "plectoneme_fraction", "plectoneme_length_nm", "plectonemic", "end_turns")
#: Per-member cost columns a bracketed point sums over its two members.
BRACKET_COSTS = ("wall_s", "cpu_s", "n_steps")
#: The protocol kinds a sweep can run (a rotation clamp turns the bead from one member to the next).
KINDS = {"hat": "magnetic_tweezers", "torque-turns": "torque_turns"}


def sweep_chains(turns, inward=False):
    """Split turn values into the chains of a sweep: ``[[0, 0.8, 1.6, ...], [-0.8, -1.6, ...]]``.

    Turns >= 0 ascending, turns < 0 descending (each chain moves away from zero; a side with no values is
    left out); with ``inward`` each chain is reversed (it starts at the largest |turns| and moves to zero).
    """
    t = sorted({float(x) for x in turns})
    up = [x for x in t if x >= 0]
    down = [x for x in reversed(t) if x < 0]
    chains = [c for c in (up, down) if c]
    return [c[::-1] for c in chains] if inward else chains


def check_sweep(kind, settle_ns, settle_buckled_ns=None, start="sweep"):
    """Refuse a sweep where it has no meaning, an unknown start, and a settle time that is not a positive number
    of ns up to the product's longest member time (one line)."""
    from dnarod.workflows.protocols.settings import MAX_MEMBER_NS

    if start not in STARTS:
        raise DnarodError(f"start {start!r}: choose 'sweep' (members chained along the turns axis away from zero), "
                          f"'sweep-in' (towards zero) or 'bracket' (both sweeps, combined)")
    if kind not in ("magnetic_tweezers", "torque_turns"):
        raise DnarodError(f"start 'sweep' turns the bead from one member to the next: it needs a rotation-clamp "
                          f"protocol (hat, torque-turns), not {kind.replace('_', '-')}")
    for name, value, what in (("settle", settle_ns, "the settling of each chained member after its turn increment"),
                              ("settle_buckled", settle_buckled_ns, "the settling of the chained members at or "
                                                                    "past the buckling point")):
        if value is None:
            continue
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise DnarodError(f"{name} {value!r}: give a time in ns > 0") from None
        if not (math.isfinite(v) and v > 0):
            raise DnarodError(f"{name} {value}: give a time in ns > 0 ({what})")
        if v > MAX_MEMBER_NS:
            raise DnarodError(f"{name} {v:g}: more than {MAX_MEMBER_NS:g} ns (10 us) per member would not finish "
                              f"here; give a shorter time")


def buckling_turns(source, force_pN, temperature_K=300.0, forcefield="dna-default", margin=BUCKLING_MARGIN,
                   P_nm=PLECTONEME_P_NM):
    """Turn values ``(lo, hi)`` (lo < 0 < hi) at and beyond which a member counts as at or past buckling.

    Marko's two-phase model (:func:`dnarod.physics.theory.supercoil.marko_two_phase`) with the model's own
    parameters: A its exact persistence length, C_s the Moroz-Nelson effective twist persistence length at the
    force from its bare C (:func:`dnarod.physics.theory.torsion.moroz_nelson`), P :data:`PLECTONEME_P_NM`, L its
    contour length; buckling at ``Delta Lk_b = Omega_s L / 2 pi``. Turns are counted, as the protocol counts
    them, from the T = 0 sum of intrinsic twist angles (``lk0``); the chain's relaxed linking number at T is lower
    (:func:`dnarod.physics.thermal.relaxed_ribbon_twist`), so ``Delta Lk at T = turns + (lk0 - Lk_T)`` and the hat
    curve's centre sits at ``turns = -(lk0 - Lk_T)`` (-0.44 turns for 1 kbp of ``dna-default`` at 300 K). A member
    is at or past buckling when ``|Delta Lk at T| >= margin Delta Lk_b``.

    Parameters
    ----------
    source : str or int
        Node count or sequence (as the protocol's ``source``).
    force_pN : float
    temperature_K : float
    forcefield : str
    margin : float
        In (0, 1]: see :data:`BUCKLING_MARGIN`.
    P_nm : float

    Returns
    -------
    tuple of float
        ``(lo, hi)`` turns (the numbers behind them: :func:`buckling_estimate`).
    """
    est = buckling_estimate(source, force_pN, temperature_K, forcefield, margin, P_nm)
    return est["turns_lo"], est["turns_hi"]


def buckling_estimate(source, force_pN, temperature_K=300.0, forcefield="dna-default", margin=BUCKLING_MARGIN,
                      P_nm=PLECTONEME_P_NM):
    """The numbers behind :func:`buckling_turns` (dict: ``A_nm``, ``C_nm``, ``C_s_nm``, ``P_nm``,
    ``buckling_delta_lk``, ``thermal_offset_turns`` (lk0 - Lk_T), ``margin``, ``turns_lo``, ``turns_hi``)."""
    from dnarod.core.forcefield import load_forcefield
    from dnarod.core.units import PN, kT
    from dnarod.physics.loads import intrinsic_turns
    from dnarod.physics.theory.supercoil import marko_two_phase
    from dnarod.physics.theory.torsion import bare_twist_persistence, moroz_nelson
    from dnarod.physics.thermal import persistence_length, relaxed_ribbon_twist

    if not (0.0 < float(margin) <= 1.0):
        raise DnarodError(f"buckling margin {margin}: give a fraction in (0, 1]")
    ff = load_forcefield(forcefield)
    src = str(source).strip()
    model = ff.model_from_sequence(n_nodes=int(src)) if src.isdigit() else ff.model_from_sequence(src)
    T = float(temperature_K)
    kt = kT(T) / PN
    A = persistence_length(model.params, model.ds, kT(T))
    C = bare_twist_persistence(model, T)
    c_s = float(moroz_nelson(C, A, float(force_pN), kt))
    L = model.ds * model.n_steps
    dlk_b = marko_two_phase(A, c_s, float(P_nm), float(force_pN), kt, L)["buckling_delta_lk"]
    offset = intrinsic_turns(model) - relaxed_ribbon_twist(model, T)[0]
    return dict(A_nm=A, C_nm=C, C_s_nm=c_s, P_nm=float(P_nm), buckling_delta_lk=dlk_b, thermal_offset_turns=offset,
                margin=float(margin), turns_lo=-margin * dlk_b - offset, turns_hi=margin * dlk_b - offset)


def member_settles(turns, settle_ns, settle_buckled_ns, bounds):
    """Settle (ns, or None for the default) of each chained member at ``turns``: ``settle_buckled_ns`` at or
    beyond the buckling bounds ``(lo, hi)`` (:func:`buckling_turns`), ``settle_ns`` before them."""
    lo, hi = bounds
    return [settle_buckled_ns if (settle_buckled_ns is not None and (t <= lo or t >= hi)) else settle_ns
            for t in turns]


def run_grown_member(settings, member_dir, grow_force_pN, grow_ns, progress=None):
    """A tweezers member started from a plectoneme grown at a lower force ("from above" the equilibrium).

    First a member of the same settings at ``grow_force_pN`` runs ``grow_ns`` ns (all of it equilibration, a few
    samples; same turns and clamp target, so the same linking number) in ``member_dir/grow``; then the member runs
    from its final pose (:func:`dnarod.workflows.protocols.tweezers.run_member` with ``start_pose`` and
    ``previous_turns`` = its own turns), equilibrating as long as from the static pose (five slowest bending
    relaxation times) unless ``equilibration_ns`` is given. Both are reused when finished. The returned row's
    ``start`` says so (``grown plectoneme``).
    """
    from dnarod.workflows.protocols.tweezers import build_member, run_member

    member_dir = Path(member_dir)
    grow = dict(settings, force_pN=float(grow_force_pN), equilibration_ns=float(grow_ns), time_ns=0.001)
    run_member(grow, member_dir / "grow")
    s = dict(settings, previous_turns=float(settings.get("turns") or 0.0))
    if s.get("equilibration_ns") is None:
        s["equilibration_ns"] = build_member(settings)["equilibration_ps"] / 1000.0
    row = run_member(s, member_dir, progress=progress, start_pose=load_pose(member_dir / "grow" / FINAL_POSE))
    return dict(row, start=f"grown plectoneme: {float(grow_ns):g} ns at {float(grow_force_pN):g} pN, then "
                           f"{row['start']}")


def _protocol(kind):
    from dnarod.workflows.protocols import ensemble_hooks as hooks

    return {"magnetic_tweezers": hooks.MAGNETIC_TWEEZERS, "torque_turns": hooks.TORQUE_TURNS}[kind]


def run_chain(kind, members, dirs, settle_ns=None, grow_head=False, head_equilibration_ns=None):
    """Run one chain of members in order (on a dask worker or in this process); returns their result rows.

    Parameters
    ----------
    kind : {"magnetic_tweezers", "torque_turns"}
    members : list of dict
        Ensemble-level member settings (``force_pN``, ``turns``, ``time_ns``, ...), in chain order.
    dirs : list of path
        One member folder each.
    settle_ns : float or list of float, optional
        Equilibration of every member after the first (default: two slowest bending relaxation times); a list
        gives one per member (:func:`member_settles`; the first entry, the chain head's, is not used).
    grow_head : bool
        The first member starts from a plectoneme grown at :data:`GROW_FORCE_FRACTION` of its force for
        :data:`GROW_NS` (an inward sweep; :func:`run_grown_member`).
    head_equilibration_ns : float, optional
        The first member equilibrates at least this long (a head at or past buckling: an inward sweep's head
        settles its plectoneme as long as the chained members past buckling do).

    Returns
    -------
    list of dict
        Each member's result (:func:`dnarod.workflows.protocols.tweezers.summarize`).
    """
    from dnarod.workflows.protocols import ensemble_hooks as hooks
    from dnarod.workflows.protocols.tweezers import run_member

    proto = _protocol(kind)
    settles = list(settle_ns) if isinstance(settle_ns, (list, tuple)) else [settle_ns] * len(members)
    if len(settles) != len(members):
        raise DnarodError(f"run_chain: {len(settles)} settle times for {len(members)} members")
    rows, prev = [], None
    for m, d, settle in zip(members, dirs, settles):
        s = proto.member_settings(m)
        # a noise stream of its own per direction too (the outward and inward members at one turn value differ)
        s["seed"] = hooks.member_seed(s["seed"], "sweep-in" if grow_head else "sweep")
        if prev is None:
            if head_equilibration_ns is not None:
                s["equilibration_ns"] = max(float(head_equilibration_ns), float(s.get("equilibration_ns") or 0.0))
            if grow_head:
                rows.append(run_grown_member(s, d, GROW_FORCE_FRACTION * float(s["force_pN"]), GROW_NS))
            else:
                rows.append(run_member(s, d))
        else:
            pfile = Path(prev[1]) / FINAL_POSE
            if not pfile.exists():
                raise DnarodError(f"{pfile}: the previous member of the sweep has no final pose; delete {prev[1]} "
                                  f"and run again")
            s = dict(s, previous_turns=float(prev[0]), equilibration_ns=settle)
            row = run_member(s, d, start_pose=load_pose(pfile))
            rows.append(dict(row, start=f"turn sweep: {row['start']}"))
        prev = (s["turns"], d)
    return rows


def run_sweep(kind, axes, members, outdir, workers=0, client=None, settle_ns=None, inward=False,
              settle_buckled_ns=None, directions=None):
    """Run the members as turn-sweep chains (one per force and side of zero turns; one dask task each).

    With ``settle_buckled_ns`` the chained members at or past the buckling point (per force and temperature)
    settle that long instead of ``settle_ns``, and a chain head at or past it (an inward sweep's) equilibrates
    at least that long. ``directions`` (a tuple of ``inward`` flags) runs several sweeps at once, their members
    in ``members/out_*`` and ``members/in_*``; every row carries ``sweep_direction`` ("out" or "in").
    """
    from dnarod.workflows.protocols.settings import member_name

    others = [k for k in axes if k != "turns"]
    groups = {}
    for m in members:
        groups.setdefault(tuple(m.get(k) for k in others), []).append(m)
    chains = []
    for group in groups.values():
        by_turns = {float(m.get("turns") or 0.0): m for m in group}
        est = None
        if settle_buckled_ns is not None:
            m0 = group[0]
            est = buckling_estimate(m0.get("source"), m0.get("force_pN"), m0.get("temperature_K") or 300.0,
                                    m0.get("forcefield") or "dna-default")
        for inw in (directions if directions is not None else (inward,)):
            prefix = ("in_" if inw else "out_") if directions is not None else ""
            for chain in sweep_chains(by_turns, inw):
                ms = [by_turns[t] for t in chain]
                settles = (member_settles(chain, settle_ns, settle_buckled_ns, (est["turns_lo"], est["turns_hi"]))
                           if est else settle_ns)
                head_past = est is not None and not (est["turns_lo"] < chain[0] < est["turns_hi"])
                head_eq = settle_buckled_ns if head_past else None
                chains.append((ms, [str(Path(outdir) / "members" / (prefix + member_name(m, axes))) for m in ms],
                               settles, est, inw, head_eq))
    out = []
    if not workers and client is None:
        for ms, dirs, settles, est, inw, head_eq in chains:
            out.append((ms, run_chain(kind, ms, dirs, settles, inw, head_eq), est, inw))
    else:
        from dnarod.workflows.ensemble.cluster import client_for

        with client_for(client, None, workers) as c:
            futs = [c.submit(run_chain, kind, ms, dirs, settles, inw, head_eq, pure=False)
                    for ms, dirs, settles, est, inw, head_eq in chains]
            for (ms, _, _, est, inw, _), f in zip(chains, futs):
                out.append((ms, f.result(), est, inw))
    rows = []
    for ms, results, est, inw in out:
        for m, r in zip(ms, results):
            row = dict(r, **{k: m[k] for k in axes}, sweep_direction="in" if inw else "out")
            if est:
                row.update(buckling_delta_lk_marko=est["buckling_delta_lk"], buckled_settle_from_turns_lo=
                           est["turns_lo"], buckled_settle_from_turns_hi=est["turns_hi"])
            rows.append(row)
    return rows


def bracket_rows(out_rows, in_rows, group_keys=("force_pN",)):
    """One curve point per turn value from an outward and an inward sweep member (``start="bracket"``).

    An outward member starts from the previous, smaller turn value's pose (its plectoneme too small, or none
    yet) and an inward one from the next larger turn value's (its plectoneme too large). If each relaxes
    towards equilibrium without overshooting, the equilibrium lies between the two, so the point is their
    midpoint ``m = (a + b)/2`` with an error that covers half the gap as well as the members' own standard
    errors: ``err = sqrt(((a - b)/2)^2 + (err_a^2 + err_b^2)/4)``. Where the two directions agree the error is
    the statistical one; where a member is still relaxing (or stuck straight past buckling) it is the gap. Near
    buckling the two may sit in different long-lived states (straight and plectonemic), in either order (the
    1-kbp run of round 8, research/hat_curve/notes.md): then the midpoint is no better than a guess and the
    error, half the gap, says so.

    Parameters
    ----------
    out_rows, in_rows : list of dict
        Member results (:func:`dnarod.workflows.protocols.tweezers.summarize` plus the axes), one per (group, turns).
    group_keys : sequence of str
        The other axes (``force_pN``): members match on them and on ``turns``.

    Returns
    -------
    list of dict
        The outward row's settings with, for every key ``k`` of :data:`BRACKET_KEYS` both have: ``k`` (midpoint),
        ``k_err``, ``k_out``, ``k_in``, ``k_out_err``, ``k_in_err`` and ``k_gap_z`` (gap / its standard error);
        ``relative_extension_rel_err`` (err / midpoint) and ``relative_extension_half_gap_rel``; costs summed.
        A turn value with only one direction is refused (run both).
    """
    def key(r):
        return tuple(float(r[k]) for k in group_keys) + (round(float(r["turns"]), 9),)

    ins = {key(r): r for r in in_rows}
    outs = {key(r): r for r in out_rows}
    if set(ins) != set(outs):
        odd = sorted(set(ins) ^ set(outs))
        raise DnarodError(f"bracket: turn values {[k[-1] for k in odd]} have a member in one sweep direction only")
    rows = []
    for k in sorted(outs):
        a, b = outs[k], ins[k]
        row = {kk: v for kk, v in a.items() if kk not in ("sweep_direction", "start", "previous_turns", "seed")}
        row.update(start="bracket: outward and inward turn sweeps", sweep_direction="both",
                   start_out=a.get("start"), start_in=b.get("start"), seed_out=a.get("seed"), seed_in=b.get("seed"))
        for c in BRACKET_KEYS:
            if a.get(c) is None or b.get(c) is None:
                continue
            va, vb = float(a[c]), float(b[c])
            ea, eb = float(a.get(c + "_err") or 0.0), float(b.get(c + "_err") or 0.0)
            row.update({c: 0.5 * (va + vb), c + "_err": math.sqrt((0.5 * (va - vb)) ** 2 + 0.25 * (ea * ea + eb * eb)),
                        c + "_out": va, c + "_in": vb, c + "_out_err": ea, c + "_in_err": eb,
                        c + "_gap_z": (va - vb) / math.hypot(ea, eb) if (ea or eb) else None})
            for t in ("_tau_ps", "_err_tau"):
                row.pop(c + t, None)
        if row.get("relative_extension"):
            m = row["relative_extension"]
            row["relative_extension_rel_err"] = row["relative_extension_err"] / abs(m)
            row["relative_extension_half_gap_rel"] = 0.5 * abs(row["relative_extension_out"]
                                                               - row["relative_extension_in"]) / abs(m)
        for c in BRACKET_COSTS:
            if a.get(c) is not None and b.get(c) is not None:
                row[c] = a[c] + b[c]
        rows.append(row)
    return rows


def _bracket_torque_offsets(base, rows):
    """The bracketed rows' member torques (``twist_torque_pN_nm_out`` / ``_in``) on the model's zero-torque offset,
    in place (:func:`dnarod.workflows.protocols.curves.write_curve` corrects the midpoint itself)."""
    from dnarod.core.forcefield import load_forcefield
    from dnarod.workflows.protocols.measure import twisting_moment_offset

    src = str(base.get("source", "")).strip()
    ff = load_forcefield(base.get("forcefield", "dna-default"))
    model = ff.model_from_sequence(None if src.isdigit() else src, n_nodes=int(src) if src.isdigit() else None)
    off, _ = twisting_moment_offset(model, float(base.get("temperature_K") or 300.0))
    for r in rows:
        for side in ("_out", "_in"):
            if r.get("twist_torque_pN_nm" + side) is not None:
                r["twist_torque_pN_nm" + side] -= off


def run_turn_sweep(kind, axes, base, outdir, start="sweep", settle_ns=None, settle_buckled_ns=None, workers=0,
                   client=None, plots=True, overwrite=False):
    """Run a rotation-clamp protocol's members as turn sweeps and write its curve (``curve.csv``, ``curve.png``;
    with ``start="bracket"`` also ``members.csv``, every member of both directions).

    Parameters
    ----------
    kind : {"magnetic_tweezers", "torque_turns"}
    axes : dict
        ``force_pN`` and ``turns`` (lists; crossed).
    base : dict
        Settings shared by the members (ensemble keys: ``source``, ``time_ns``, ``equilibration_ns``,
        ``temperature_K``, ``salt_M``, ``seed``, ``rotation_clamp_kJ_mol``, ``sample_ps``, ...).
    outdir : path
    start : {"sweep", "sweep-in", "bracket"}
    settle_ns, settle_buckled_ns : float, optional
        See :func:`run_sweep`.
    workers : int
        Dask local workers (one chain per task); 0 runs the chains in this process.
    overwrite : bool
        Run into a folder recorded with other settings (``protocol.json``, as ``dnarod protocol``).

    Returns
    -------
    dnarod.workflows.protocols.curves.Curve
    """
    from dnarod.core.io import check_output_folder, folder_lock, jsonable
    from dnarod.workflows.protocols.curves import _write_csv, write_curve
    from dnarod.workflows.protocols.folder import PROTOCOL_MARKERS, check_protocol_folder, write_protocol_record

    check_sweep(kind, settle_ns, settle_buckled_ns, start)
    proto = _protocol(kind)
    base = dict(base)
    base.setdefault("rotation_clamp_kJ_mol", 250.0)
    names = list(axes)
    members = [dict(base, **dict(zip(names, combo))) for combo in product(*[list(np.atleast_1d(axes[n]))
                                                                            for n in names])]
    for m in members:
        proto.check(m)  # refused as `dnarod protocol` refuses it, before any member runs
    shared = jsonable(dict(base, start=start, settle_ns=settle_ns, settle_buckled_ns=settle_buckled_ns))
    outdir = Path(outdir)
    check_output_folder(outdir, PROTOCOL_MARKERS, "protocol")
    check_protocol_folder(outdir, kind, shared, overwrite)
    with folder_lock(outdir):
        if start == "bracket":
            both = run_sweep(kind, axes, members, outdir, workers, client, settle_ns,
                             settle_buckled_ns=settle_buckled_ns, directions=(False, True))
            rows = bracket_rows([r for r in both if r["sweep_direction"] == "out"],
                                [r for r in both if r["sweep_direction"] == "in"], [k for k in axes if k != "turns"])
            _bracket_torque_offsets(base, rows)
            _write_csv(sorted(both, key=lambda r: (r["sweep_direction"], r.get("turns") or 0.0)),
                       outdir / "members.csv")
        else:
            rows = run_sweep(kind, axes, members, outdir, workers, client, settle_ns, start == "sweep-in",
                             settle_buckled_ns)
        curve = write_curve(kind, rows, base, outdir, plots)
        write_protocol_record(outdir, kind, shared)
    return curve


class OneLineParser(argparse.ArgumentParser):
    """argparse with every error as one line ``turn_sweep.py: error: ...`` and exit status 2."""

    def error(self, message):
        print(f"{self.prog}: error: {message}", file=sys.stderr)
        raise SystemExit(2)


def _floats(text, what):
    try:
        vals = [float(v) for v in str(text).replace(" ", "").split(",") if v != ""]
    except ValueError:
        raise DnarodError(f"{what}: expected comma-separated numbers, got {text!r}") from None
    if not vals or not all(math.isfinite(v) for v in vals):
        raise DnarodError(f"{what} {text}: give finite comma-separated numbers")
    return vals


def main(argv=None):
    """The command line (see the module docstring); returns the exit status (0, or 2 with one line)."""
    ap = OneLineParser(prog="turn_sweep.py", description="Turn sweeps of a rotation-clamp protocol (research).")
    ap.add_argument("protocol", choices=sorted(KINDS))
    ap.add_argument("--source", "-s", default="600")
    ap.add_argument("--force", default="1.0", help="force(s), pN, comma-separated")
    ap.add_argument("--turns", required=True, help="turns, comma-separated")
    ap.add_argument("--start", choices=STARTS, default="sweep")
    ap.add_argument("--settle", type=float, default=None, help="settle of each chained member, ns")
    ap.add_argument("--settle-buckled", type=float, default=None, help="settle at or past buckling, ns")
    ap.add_argument("--time", type=float, default=2.0, help="production per member, ns")
    ap.add_argument("--equilibration", type=float, default=None, help="equilibration of each chain head, ns")
    ap.add_argument("--temperature", type=float, default=300.0)
    ap.add_argument("--salt", type=float, default=0.15)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--clamp-k", type=float, default=250.0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--overwrite", action="store_true")
    ap.add_argument("--out", "-o", required=True)
    a = ap.parse_args(argv)
    base = dict(source=str(a.source), time_ns=a.time, temperature_K=a.temperature, salt_M=a.salt, seed=a.seed,
                rotation_clamp_kJ_mol=a.clamp_k)
    if a.equilibration is not None:
        base["equilibration_ns"] = a.equilibration
    try:
        if a.workers < 0:
            raise DnarodError(f"--workers {a.workers}: give a number >= 0")
        axes = {"force_pN": _floats(a.force, "--force"), "turns": _floats(a.turns, "--turns")}
        curve = run_turn_sweep(KINDS[a.protocol], axes, base, a.out, start=a.start, settle_ns=a.settle,
                               settle_buckled_ns=a.settle_buckled, workers=a.workers, overwrite=a.overwrite)
    except DnarodError as exc:
        print(f"turn_sweep.py: error: {exc}", file=sys.stderr)
        return 2
    for r in curve.rows:
        print(f"  turns {r.get('turns')}: x/L {r.get('relative_extension', float('nan')):.4g} "
              f"+- {r.get('relative_extension_err') or 0:.2g}, Wr {r.get('Wr', float('nan')):.3g}")
    print(f"wrote {curve.files.get('csv')} and {curve.files.get('png')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
