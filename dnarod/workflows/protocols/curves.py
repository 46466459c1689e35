"""Protocol curves: run a protocol's members (an ensemble over its axes) and write ``curve.csv`` + ``curve.png``.

Members run on :class:`dnarod.workflows.ensemble.Ensemble` (dask ``LocalCluster``; ``workers=0`` runs them one after
the other in this process, which the tests use). Bad input is refused before anything runs, with one line
(:class:`~dnarod.core.errors.DnarodError`). Finished members are reused (same settings -> same folder).
"""
from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.run.spec import MAX_SALT, MAX_TEMPERATURE

#: Start modes of the rotation-clamp protocols (see :func:`run_protocol`); the last three chain the members.
STARTS = ("static", "sweep", "sweep-in", "bracket", "exchange")
SWEEP_STARTS = ("sweep", "sweep-in", "bracket")

@dataclass
class Curve:
    """A protocol's result: ``rows`` (one dict per member, sorted along the x axis) and written ``files``."""

    kind: str
    rows: list
    files: dict = field(default_factory=dict)


def _members(kind, axes, base):
    """Expand the axes (cross product) into member settings, checking every member before any runs."""
    from itertools import product

    from dnarod.physics.loads import intrinsic_turns
    from dnarod.workflows.protocols.rings import check_ring
    from dnarod.workflows.protocols.tweezers import check_tweezers

    names = list(axes)
    values = [list(np.atleast_1d(axes[n]).tolist()) for n in names]
    for n, v in zip(names, values):
        if not v:
            raise DnarodError(f"{n}: give at least one value")
    base, values = _checked_settings(base, names, values)
    members = [dict(base, **dict(zip(names, combo))) for combo in product(*values)]
    from dnarod.core.forcefield import load_forcefield

    ff = load_forcefield(base.get("forcefield", "dna-default"))
    from dnarod.structure.inputs import protocol_source
    from dnarod.run.api import check_start_pose
    from dnarod.physics.loads import Walls

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
    from dnarod.physics.loads import Clamp, RotationClamp
    from dnarod.physics.modes import check_load_stiffness
    from dnarod.workflows.protocols.tweezers import DEFAULT_CLAMP_K

    for k in sorted({float(m.get("rotation_clamp_kJ_mol") or DEFAULT_CLAMP_K) for m in members}):
        loads = (Clamp(0), RotationClamp(model.n_nodes - 1, k, axis=[0.0, 0.0, 1.0]))
        check_load_stiffness(model, loads, names={"RotationClamp": f"[{table}] rotation_clamp_kJ_mol"})


def _checked_settings(base, names, values):
    """``base`` and the axis values checked against the ensemble schema (the keys the members read): an
    unknown key, a value of the wrong type, a non-finite or out-of-range number is one line naming it."""
    from dnarod.workflows.ensemble.schema import RUN_KEYS, check_distinct, coerce, unknown_key
    from dnarod.workflows.protocols.ensemble_hooks import protocol_keys

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


def run_protocol(kind, axes, base, outdir, workers=2, progress=True, client=None, plots=True, start="static",
                 settle_ns=None, settle_buckled_ns=None, overwrite=False, exchange_ps=None):
    """Run a protocol over its axes and write its curve.

    Parameters
    ----------
    kind : {"force_extension", "magnetic_tweezers", "torque_turns", "rings"}
    axes : dict
        Axis name -> list of values (``force_pN``, ``turns``, ``delta_lk``, ``seed``); crossed.
    base : dict
        Settings shared by all members (ensemble keys: ``source``, ``time_ns``, ``equilibration_ns``,
        ``temperature_K``, ``salt_M``, ``rotation_clamp_kJ_mol``, ...).
    outdir : path
    workers : int
        Dask local workers; 0 runs the members serially in this process.
    start : {"static", "sweep", "sweep-in", "bracket", "exchange"}
        "static": every member starts from the static pose under its loads (independent members, one dask task
        each). "sweep" (hat and torque-turns): the members of each force run as chains along the turns axis
        away from zero, each from the previous turn value's final pose turned by the increment
        (:mod:`dnarod.workflows.protocols.sweep`; turns >= 0 and turns < 0 are two chains, two dask tasks); members in
        ``outdir/members/``. "sweep-in": the same chains run towards zero, each begun at its largest |turns|
        from a plectoneme grown at a lower force. "bracket": both sweeps at once (four chains per force; members
        in ``outdir/members/out_*`` and ``in_*``); each turn value's curve point is the midpoint of its outward
        and inward members with an error that covers the gap between them (:func:`bracket_rows`).
        "exchange" (hat and torque-turns): the turn values of each force are the rungs of one replica-exchange
        ladder (:mod:`dnarod.workflows.protocols.exchange`: swaps between neighbouring rungs with the turn difference
        carried as twist, Metropolis-accepted), run as ``workers`` dask actors; rungs in
        ``members/exchange_*``, the ladder's acceptance and round trips in ``ladders/*/exchange.json``.
    settle_ns : float, optional
        With ``start="sweep"``: equilibration of each chained member after its turn increment (default two
        slowest bending relaxation times); the first member of each chain equilibrates as a static start does.
    settle_buckled_ns : float, optional
        With a sweep: the settle of the chained members at or past the buckling point
        (:func:`dnarod.workflows.protocols.sweep.buckling_turns`: Marko's two-phase model with the model's parameters and a
        margin); default ``settle_ns`` for every member.
    exchange_ps : float, optional
        With ``start="exchange"``: time between exchange attempts, ps (default
        :data:`dnarod.workflows.protocols.exchange.EXCHANGE_PS`).
    overwrite : bool
        Run into ``outdir`` although it holds this protocol run made with other settings (or another protocol;
        :mod:`dnarod.workflows.protocols.folder`). Without it such a folder is refused, as is any other non-empty folder
        that is not a protocol's; the same settings reuse the finished members (more axis values extend the
        curve). While the protocol runs, ``outdir`` is locked against a second writer
        (:func:`dnarod.core.io.folder_lock`).

    Returns
    -------
    Curve

    Raises
    ------
    DnarodError
        Bad settings, a folder of another protocol run or of something else, a folder in use (before any member
        runs), or a failed member.
    """
    import json

    from dnarod.core.io import check_output_folder, folder_lock, jsonable, staged_folder
    from dnarod.workflows.protocols import ensemble_hooks as hooks
    from dnarod.workflows.protocols.folder import (PROTOCOL_FILES, PROTOCOL_MARKERS, check_protocol_folder,
                                                   replaces_other_settings, write_protocol_record)

    proto = hooks.protocol_of(kind)
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 0:
        raise DnarodError(f"workers {workers!r}: give a number of dask workers >= 0 (0: one after another in this "
                          f"process)")
    if start not in STARTS:
        raise DnarodError(f"start {start!r}: choose 'static' (every member from the static pose), 'sweep' "
                          f"(members chained along the turns axis away from zero), 'sweep-in' (towards zero) or "
                          f"'bracket' (both sweeps, combined)")
    if start == "exchange" or exchange_ps is not None:
        from dnarod.workflows.protocols.exchange import check_exchange

        check_exchange(kind, start, axes, exchange_ps)
    if start in SWEEP_STARTS:
        from dnarod.workflows.protocols.sweep import check_sweep

        check_sweep(kind, settle_ns, settle_buckled_ns)
    elif settle_ns is not None or settle_buckled_ns is not None:
        which = "settle" if settle_ns is not None else "settle_buckled"
        raise DnarodError(f"{which} {settle_ns if settle_ns is not None else settle_buckled_ns} ns: the settle time "
                          f"applies to a turn sweep only (start 'sweep', 'sweep-in' or 'bracket')")
    if not isinstance(outdir, (str, Path)) or not str(outdir).strip():
        raise DnarodError(f"output folder {outdir!r}: give a folder path (-o DIR)")
    # the settings every member shares, as given (protocol.json; the defaults below are the protocol's own)
    shared = jsonable(dict(base, start=start, settle_ns=settle_ns, settle_buckled_ns=settle_buckled_ns))
    if exchange_ps is not None:  # (absent otherwise: the records of earlier runs stay valid)
        shared["exchange_ps"] = float(exchange_ps)
    base = dict(base)
    if kind in ("magnetic_tweezers", "torque_turns"):
        base.setdefault("rotation_clamp_kJ_mol", 250.0)
    if kind == "rings":
        base["ring"] = True  # the ensemble's model check builds a closed ring for delta_lk
    members = _members(kind, axes, base)
    outdir = Path(outdir)
    check_output_folder(outdir, PROTOCOL_MARKERS, "protocol")
    check_protocol_folder(outdir, kind, shared, overwrite)
    with folder_lock(outdir):
        check_protocol_folder(outdir, kind, shared, overwrite)  # again: another process may have written it since
        if overwrite and replaces_other_settings(outdir, kind, shared):
            # made beside the old run (kept there if stopped: the same command continues it) and put in place when
            # its curve is written: until then the old run stays as it was
            import hashlib

            tag = hashlib.sha256(json.dumps([kind, shared], sort_keys=True).encode()).hexdigest()[:16]
            with staged_folder(outdir, PROTOCOL_FILES, what="protocol run", resume_name=tag) as work:
                curve = _run_members(kind, axes, base, members, work, workers, progress, client, plots, start,
                                     settle_ns, settle_buckled_ns, proto, exchange_ps)
                write_protocol_record(work, kind, shared)
            curve.files = {k: outdir / Path(v).name for k, v in curve.files.items()}
            return curve
        curve = _run_members(kind, axes, base, members, outdir, workers, progress, client, plots, start, settle_ns,
                             settle_buckled_ns, proto, exchange_ps)
        write_protocol_record(outdir, kind, shared)
    return curve


def _run_members(kind, axes, base, members, outdir, workers, progress, client, plots, start, settle_ns,
                 settle_buckled_ns, proto, exchange_ps=None):
    """The members of :func:`run_protocol` (run or reused) and the curve written from them."""
    if start == "exchange":
        from dnarod.workflows.protocols.exchange import run_ladders

        rows = run_ladders(kind, axes, members, outdir, workers, progress, client, exchange_ps)
    elif start == "bracket":
        both = _run_sweep(kind, axes, members, outdir, workers, progress, client, settle_ns,
                          settle_buckled_ns=settle_buckled_ns, directions=(False, True))
        rows = bracket_rows([r for r in both if r["sweep_direction"] == "out"],
                            [r for r in both if r["sweep_direction"] == "in"], [k for k in axes if k != "turns"])
        members_rows = sorted(both, key=lambda r: (r["sweep_direction"], r.get("turns") or 0.0))
        _write_csv(members_rows, outdir / "members.csv")
    elif start in ("sweep", "sweep-in"):
        rows = _run_sweep(kind, axes, members, outdir, workers, progress, client, settle_ns, start == "sweep-in",
                          settle_buckled_ns)
    elif workers:
        rows = _run_ensemble(kind, axes, base, outdir, proto, workers, progress, client)
    else:
        rows = []
        for i, m in enumerate(members):
            mdir = outdir / "members" / _member_name(m, axes)
            row = proto.execute(m, mdir)
            rows.append(dict(row, **{k: m[k] for k in axes}))
    from dnarod.workflows.protocols.ensemble_hooks import protocol_of

    x = protocol_of(kind).plot.x
    rows.sort(key=lambda r: (r.get(x) if r.get(x) is not None else 0.0))
    for r in rows:
        if kind == "rings" and "Tw" in r:
            r["Tw_minus_Tw0"] = r["Tw"] - r["intrinsic_turns"]
    _thermal_corrections(kind, base, rows)
    curve = Curve(kind, rows)
    curve.files["csv"] = _write_csv(rows, outdir / "curve.csv")
    if plots:
        curve.files["png"] = plot_curve(kind, rows, outdir / "curve.png")
    return curve


def _thermal_corrections(kind, base, rows):
    """Put the curve's torques and linking differences on the model's zero at its temperature, in place.

    ``twist_torque_pN_nm`` becomes the twisting moment less what it reads on a chain under no torque
    (:func:`dnarod.workflows.protocols.measure.twisting_moment_offset`, about -1.2 pN nm for ``dna-default`` at 300 K; the
    raw mean stays in ``twist_torque_pN_nm_raw``), and ``delta_lk_thermal`` is ``Lk`` less the relaxed linking
    number at T (:func:`dnarod.physics.thermal.relaxed_ribbon_twist`; ``delta_lk`` stays relative to the T = 0 sum of
    intrinsic twist angles). The clamp torque needs no correction. Members keep their own raw results.
    """
    from dnarod.core.forcefield import load_forcefield
    from dnarod.physics.thermal import relaxed_ribbon_twist
    from dnarod.workflows.protocols.measure import twisting_moment_offset

    if not rows:
        return
    ff = load_forcefield(base.get("forcefield", "dna-default"))
    src = str(base.get("source", "")).strip()
    seq, n_nodes = (None, int(src)) if src.isdigit() else (src, None)
    T = float(base.get("temperature_K") or 300.0)
    if kind == "rings":
        for r in rows:
            if r.get("relaxed_twist_thermal") is not None and r.get("Lk") is not None:
                r["delta_lk_thermal"] = r["Lk"] - r["relaxed_twist_thermal"]
        return
    model = ff.model_from_sequence(seq, n_nodes=n_nodes)
    lk_T, lk_T_se = relaxed_ribbon_twist(model, T)
    off, off_se = twisting_moment_offset(model, T) if kind != "force_extension" else (None, None)
    for r in rows:
        if r.get("Lk") is not None:
            r["delta_lk_thermal"] = r["Lk"] - lk_T
            r["relaxed_twist_thermal"], r["relaxed_twist_thermal_err"] = lk_T, lk_T_se
        if off is not None and r.get("twist_torque_pN_nm") is not None:
            r["twist_torque_pN_nm_raw"] = r["twist_torque_pN_nm"]
            r["twist_torque_pN_nm"] = r["twist_torque_pN_nm"] - off
            r["twist_torque_offset_pN_nm"], r["twist_torque_offset_err_pN_nm"] = off, off_se
            for side in ("_out", "_in"):  # a bracketed point's two members (start "bracket")
                if r.get("twist_torque_pN_nm" + side) is not None:
                    r["twist_torque_pN_nm" + side] -= off
            if r.get("twist_torque_pN_nm_err") is not None:
                r["twist_torque_pN_nm_err"] = float(np.hypot(r["twist_torque_pN_nm_err"], off_se))


def _member_name(m, axes):
    return "_".join(f"{k}{m[k]:+g}" if isinstance(m[k], (int, float)) else f"{k}{m[k]}" for k in axes) or "member"


def _run_sweep(kind, axes, members, outdir, workers, progress, client, settle_ns, inward=False,
               settle_buckled_ns=None, directions=None):
    """Run the members as turn-sweep chains (one per force and side of zero turns; one dask task each); with
    ``settle_buckled_ns`` the chained members at or past the buckling point (per force and temperature) settle
    that long instead of ``settle_ns``, and a chain head at or past it (an inward sweep's) equilibrates at least
    that long. ``directions`` (a tuple of ``inward`` flags) runs several sweeps at once, their members in
    ``members/out_*`` and ``members/in_*``; every row carries ``sweep_direction`` ("out" or "in")."""
    from dnarod.workflows.protocols.sweep import buckling_estimate, member_settles, run_chain, sweep_chains

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
                chains.append((ms, [str(outdir / "members" / (prefix + _member_name(m, axes))) for m in ms],
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


#: Observables a bracketed curve point combines from its outward and inward members (each with its ``_err``).
BRACKET_KEYS = ("relative_extension", "extension_nm", "Wr", "Tw", "Lk", "twist_torque_pN_nm", "clamp_torque_pN_nm",
                "plectoneme_fraction", "plectoneme_length_nm", "plectonemic", "end_turns")
#: Per-member cost columns a bracketed point sums over its two members.
BRACKET_COSTS = ("wall_s", "cpu_s", "n_steps")


def bracket_rows(out_rows, in_rows, group_keys=("force_pN",)):
    """One curve point per turn value from an outward and an inward sweep member (``start="bracket"``).

    An outward member starts from the previous, smaller turn value's pose (its plectoneme too small, or none
    yet) and an inward one from the next larger turn value's (its plectoneme too large). If each relaxes
    towards equilibrium without overshooting, the equilibrium lies between the two, so the point is their
    midpoint ``m = (a + b)/2`` with an error that covers half the gap as well as the members' own standard
    errors: ``err = sqrt(((a - b)/2)^2 + (err_a^2 + err_b^2)/4)``. Where the two directions agree the error is
    the statistical one; where a member is still relaxing (or stuck straight past buckling) it is the gap. Near
    buckling the two may sit in different long-lived states (straight and plectonemic), in either order (the
    1-kbp run of round 8, docs/protocols.md): then the midpoint is no better than a guess and the error, half the
    gap, says so.

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
    import math

    key = lambda r: tuple(float(r[k]) for k in group_keys) + (round(float(r["turns"]), 9),)
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


def _run_ensemble(kind, axes, base, outdir, proto, workers, progress, client):
    """Run the members through :mod:`dnarod.workflows.ensemble`; returns their observables rows (settings merged)."""
    from dnarod.workflows.ensemble import Ensemble

    doc = {"ensemble": {"name": kind, "protocol": proto.name},
           "base": {k: v for k, v in base.items()},
           "axes": {k: list(np.atleast_1d(v).tolist()) for k, v in axes.items()}}
    ens = Ensemble.from_dict(doc, outdir / "ensemble", overwrite=False)
    ens.run(client=client, workers=workers, progress=progress)
    rows = []
    from dnarod.workflows.ensemble.member import member_dir, read_result

    for m in ens.members:
        r = read_result(member_dir(ens.outdir, m.id)) or {}
        if r.get("status") != "ok":
            raise DnarodError(f"member {m.index} ({', '.join(f'{k}={m.settings.get(k)}' for k in axes)}) failed: "
                              f"{r.get('error', 'no result')}; see {member_dir(ens.outdir, m.id)}/member.log")
        rows.append(dict(r["observables"], **{k: m.settings.get(k) for k in axes}))
    return rows


def _write_csv(rows, path):
    from dnarod.core.io import write_text_atomic

    keys = []
    for r in rows:
        for k in r:
            if k not in keys:
                keys.append(k)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=keys, extrasaction="ignore")
    w.writeheader()
    for r in rows:
        w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in keys})
    write_text_atomic(path, buf.getvalue())
    return Path(path)


def plot_curve(kind, rows, path):
    """Plot a protocol's curve (mean +- block standard error per member) with its measured references beside
    (the protocol object's ``plot`` and ``references``, :mod:`dnarod.workflows.protocols.references`)."""
    from dnarod.analysis.plots import new_figure, save_figure
    from dnarod.workflows.protocols.ensemble_hooks import protocol_of

    proto = protocol_of(kind)
    plot = proto.plot
    fig, ax = new_figure(1, 1, width=6.0, height=5.4)
    a = ax[0, 0]
    x = np.array([float(r.get(plot.x) or 0.0) for r in rows])
    if plot.log_x:
        a.set_xscale("log")
    for yk in plot.ys:
        y = np.array([np.nan if r.get(yk) is None else float(r[yk]) for r in rows])
        e = np.array([np.nan if r.get(yk + "_err") is None else float(r[yk + "_err"]) for r in rows])
        a.errorbar(x, y, yerr=np.where(np.isfinite(e), e, 0.0), fmt="o-", capsize=3, label=f"dnarod: {yk}")
    if rows:
        for draw in proto.references:
            draw(a, rows)
    note = proto.missing_note()
    if note:
        # torque-turns legends fill the top left; the note goes bottom right there
        x0, y0, ha, va = (0.98, 0.03, "right", "bottom") if kind == "torque_turns" else (0.02, 0.97, "left", "top")
        a.text(x0, y0, note, transform=a.transAxes, fontsize=7, color="0.4", va=va, ha=ha)
    a.set_xlabel(plot.x_label)
    a.set_ylabel(plot.y_label)
    if rows:
        r0 = rows[0]
        a.set_title(f"{kind.replace('_', ' ')}: {r0.get('n_bp')} bp"
                    + (f", {r0.get('force_pN')} pN" if kind in ("magnetic_tweezers", "torque_turns") else ""),
                    fontsize=10)
    # below the axes: the measured overlays carry long labels (source and conditions) that would hide the data
    a.legend(fontsize=6.5, loc="upper center", bbox_to_anchor=(0.5, -0.14), frameon=False)
    out = Path(path)
    save_figure(fig, out.parent, out.name)
    return out


def force_extension(forces_pN, outdir, source="600", **kw):
    """Force-extension curve (torsionally free bead end): one member per force (pN). See :func:`run_protocol`."""
    return run_protocol("force_extension", {"force_pN": list(forces_pN)}, dict(kw.pop("base", {}), source=str(source)),
                        outdir, **kw)


def hat_curve(turns, outdir, force_pN=0.5, source="600", **kw):
    """Magnetic-tweezers hat curve: extension vs turns at constant force (one or several forces, pN)."""
    return run_protocol("magnetic_tweezers", {"force_pN": list(np.atleast_1d(force_pN)), "turns": list(turns)},
                        dict(kw.pop("base", {}), source=str(source)), outdir, **kw)


def torque_turns(turns, outdir, force_pN=1.0, source="600", **kw):
    """Torque-turns curve with a rotation clamp at constant force (pN)."""
    return run_protocol("torque_turns", {"force_pN": list(np.atleast_1d(force_pN)), "turns": list(turns)},
                        dict(kw.pop("base", {}), source=str(source)), outdir, **kw)


def ring_supercoiling(delta_lk, outdir, source="600", **kw):
    """Closed rings over a list of linking differences: Tw, Wr, writhe fraction, plectonemes."""
    return run_protocol("rings", {"delta_lk": list(delta_lk)}, dict(kw.pop("base", {}), source=str(source)),
                        outdir, **kw)
