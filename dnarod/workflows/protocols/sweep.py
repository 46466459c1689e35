"""Turn sweeps: tweezers members run as chains along the turns axis, "as the magnets are turned in the lab".

Past buckling a member started from the straight (static) pose has to grow its plectoneme from nothing, which
takes longer than the production itself at 1 kbp. In a sweep, the members of one force run one after the other
in order of |turns| away from zero: each starts from the previous turn value's final pose with the turn
increment added (:func:`~dnarod.workflows.protocols.poses.add_turns`: the clamp target and the linking number follow)
and settles for
``settle_ns`` before its production. Only the first member of a chain starts from the static pose, with the
full equilibration. Turns >= 0 form one chain (ascending), turns < 0 another (descending), so a two-worker
cluster runs the two sides of a hat curve at once (:func:`sweep_chains`).

Inward sweeps (``inward=True``, ``start="sweep-in"``) run the other way: each chain begins at the largest |turns|
from a plectoneme grown for :data:`GROW_NS` at :data:`GROW_FORCE_FRACTION` of the member's force (same turns and
clamp target, so the same linking number; :func:`dnarod.workflows.protocols.tweezers.sample_member`) and the turns are taken
out step by step, so the post-buckling members start plectonemic instead of from a straight chain that has to
nucleate its first loop (an outward sweep can stay straight, metastable, past the buckling point).

Settle where it is needed (``settle_buckled_ns``): before buckling a chained member is settled after a short
``settle_ns`` (its extension relaxes in a few ns after a turn increment); at and past buckling the plectoneme has
to nucleate, grow or shrink, which takes tens to hundreds of ns. :func:`buckling_turns` places the buckling point
by Marko's two-phase model with the model's own parameters and a margin; chained members at or beyond it settle
for ``settle_buckled_ns`` instead (:func:`member_settles`).

Seeds: every member draws its own noise stream (:func:`dnarod.workflows.protocols.ensemble_hooks.member_seed` of the curve's
seed, the protocol, force, turns and the sweep direction), so a chained member does not restart the stream the
previous member began with.

Resume: a chained member's key holds the previous turn value and the SHA-256 of its start pose, so a finished
member is reused only if it was started from the previous member's present final pose; an interrupted member
resumes from its checkpoint (:func:`dnarod.workflows.protocols.tweezers.run_member`).

Units: turns; ns; positions nm; frames (n, 3, 3) with the directors d1, d2, d3 as columns.
"""
from __future__ import annotations

from pathlib import Path


from dnarod.core.errors import DnarodError
from dnarod.workflows.protocols.poses import FINAL_POSE, load_pose

#: Head of an inward sweep: its plectoneme is grown at this fraction of the member's force ...
GROW_FORCE_FRACTION = 0.3
#: ... for this long (ns), before its equilibration at the member's force.
GROW_NS = 20.0
#: Plectoneme twist stiffness P (nm) that places the buckling point (:func:`buckling_turns`): the model's own,
#: from its plectonemic 600-bp ring at Delta Lk = -5 (``dna-default``, 0.15 M, 300 K; ``dnarod validate buckling``,
#: docs/protocols.md): 17.3 +- 0.3 nm (19.7 nm at Delta Lk = -3, 14.5 nm from the measured plateau torque).
PLECTONEME_P_NM = 17.3
#: Members with |Delta Lk at T| >= this fraction of Marko's buckling Delta Lk count as at or past buckling: 0.8
#: covers any P down to 12 nm at 1 pN (a smaller P buckles earlier) and the torque overshoot's spread of the
#: buckling point (the settle is long for a member or two before buckling rather than short for one past it).
BUCKLING_MARGIN = 0.8


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


def check_sweep(kind, settle_ns, settle_buckled_ns=None):
    """Refuse a sweep where it has no meaning, and a settle time that is not a positive number (one line)."""
    import math

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


def buckling_turns(source, force_pN, temperature_K=300.0, forcefield="dna-default", margin=BUCKLING_MARGIN,
                   P_nm=PLECTONEME_P_NM):
    """Turn values ``(lo, hi)`` (lo < 0 < hi) at and beyond which a member counts as at or past buckling.

    Marko's two-phase model (:func:`dnarod.physics.theory.supercoil.marko_two_phase`) with the model's own
    parameters: A its exact persistence length, C_s the Moroz-Nelson effective twist persistence length at the
    force from its bare C (:func:`dnarod.validate.torsion.moroz_nelson`), P :data:`PLECTONEME_P_NM`, L its contour
    length; buckling at ``Delta Lk_b = Omega_s L / 2 pi``. Turns are counted, as the protocol counts them, from the
    T = 0 sum of intrinsic twist angles (``lk0``); the chain's relaxed linking number at T is lower
    (:func:`dnarod.physics.thermal.relaxed_ribbon_twist`), so ``Delta Lk at T = turns + (lk0 - Lk_T)`` and the hat curve's
    centre sits at ``turns = -(lk0 - Lk_T)`` (-0.44 turns for 1 kbp of ``dna-default`` at 300 K). A member is at or
    past buckling when ``|Delta Lk at T| >= margin Delta Lk_b``.

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
    from dnarod.physics.thermal import persistence_length, relaxed_ribbon_twist
    from dnarod.core.units import kT
    from dnarod.core.units import PN
    from dnarod.physics.theory.supercoil import marko_two_phase
    from dnarod.physics.theory.torsion import bare_twist_persistence, moroz_nelson
    from dnarod.physics.loads import intrinsic_turns

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
        :data:`GROW_NS` (an inward sweep).
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

    proto = {"magnetic_tweezers": hooks.MAGNETIC_TWEEZERS, "torque_turns": hooks.TORQUE_TURNS}[kind]
    settles = list(settle_ns) if isinstance(settle_ns, (list, tuple)) else [settle_ns] * len(members)
    if len(settles) != len(members):
        raise DnarodError(f"run_chain: {len(settles)} settle times for {len(members)} members")
    rows, prev = [], None
    for m, d, settle in zip(members, dirs, settles):
        s = proto.member_settings(m)
        # a noise stream of its own per direction too (the outward and inward members at one turn value differ)
        s["seed"] = hooks.member_seed(s["seed"], "sweep-in" if grow_head else "sweep")
        if prev is None:
            if grow_head:
                s = dict(s, start_force_pN=GROW_FORCE_FRACTION * float(s["force_pN"]), start_ns=GROW_NS)
            if head_equilibration_ns is not None:
                s["equilibration_ns"] = max(float(head_equilibration_ns), float(s.get("equilibration_ns") or 0.0))
            rows.append(run_member(s, d))
        else:
            pfile = Path(prev[1]) / FINAL_POSE
            if not pfile.exists():
                raise DnarodError(f"{pfile}: the previous member of the sweep has no final pose (finished before "
                                  f"sweeps existed?); delete {prev[1]} and run again")
            s = dict(s, previous_turns=float(prev[0]), equilibration_ns=settle)
            rows.append(run_member(s, d, start_pose=load_pose(pfile)))
        prev = (s["turns"], d)
    return rows
