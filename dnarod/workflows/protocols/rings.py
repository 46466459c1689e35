"""Ring members: a closed DNA ring with a chosen linking number, sampled at equilibrium.

The ring is :meth:`dnarod.core.forcefield.ForceField.ring` (a planar circle with ``Lk = Lk0 + delta_lk``, the
relaxed ``Lk0 = round(intrinsic twist / 2 pi)``), run with Langevin dynamics (the dynamics conserve Lk);
each sample reports Tw (ribbon twist of d1), Wr (exact polygon writhe), Lk = Tw + Wr (checked to be the
integer set), the writhe fraction ``Wr / (Lk - Tw0_T)`` with ``Tw0_T`` the relaxed ring's mean twist at the
run's temperature (:func:`dnarod.physics.theory.supercoil.thermal_relaxed_twist`; ``intrinsic_turns`` is the
T = 0 value, the sum of intrinsic twist angles, 0.27 turns higher for 600 bp of dna-default), and the plectoneme
detector of :mod:`dnarod.workflows.protocols.measure` with chain separations wrapping around, and the number of
plectoneme end loops (:func:`~dnarod.workflows.protocols.measure.plectoneme_end_loops`: 2 for an unbranched plectoneme,
more if it branches).

Nicked rings (free linking number) are not sampled by this module: a nick with zero twist stiffness
still cannot let the strand pass 180 degrees of step rotation in the Cayley coordinates (the energy
diverges there), so the linking number cannot change. Their ``<ΔLk²> = <ΔTw²> + <Wr²>`` is computed by
:mod:`dnarod.workflows.protocols.nicked` (writhe of a ring free to writhe) and check ``nicked_ring``.

Units: nm, turns, ps.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.core.io import jsonable
from dnarod.physics.loads import MAX_SIGMA, intrinsic_turns

COLUMNS = ("time_ps", "Tw", "Wr", "Lk", "plectoneme_fraction", "plectoneme_length_nm", "plectonemic",
           "radius_of_gyration_nm", "end_loops")


def _settings(s):
    from dnarod.physics.nonbonded import DEFAULT_CHARGE, DEFAULT_CUTOFF_DEBYE
    from dnarod.engines.openmm.platforms import member_platform

    out = dict(n_bp=600, forcefield="dna-default", sequence=None, delta_lk=0, time_ns=1.0, equilibration_ns=None,
               temperature_K=300.0, salt_M=0.15, seed=1, friction_per_ps=None, sample_ps=None, platform=None,
               threads=None, electrostatics=True, excluded_volume=True, charge=DEFAULT_CHARGE,
               cutoff_debye=DEFAULT_CUTOFF_DEBYE, start_pose_sha256=None)
    unknown = set(s) - set(out)
    if unknown:
        raise DnarodError(f"unknown ring setting(s) {sorted(unknown)}; known: {sorted(out)}")
    out.update({k: v for k, v in s.items() if v is not None})
    out.update(member_platform(out["platform"], out["threads"], "auto"))  # the platform it runs on, in its key
    return out


def check_ring(delta_lk, lk0):
    """Refuse linking differences the model cannot represent (|sigma| > 0.1), one line."""
    d = float(delta_lk)
    if d != int(d):
        raise DnarodError(f"delta_lk {delta_lk}: the linking number of a closed ring is an integer")
    if abs(d / lk0) > MAX_SIGMA:
        raise DnarodError(f"delta_lk {int(d)} is sigma = {d / lk0:+.3f} for Lk0 = {lk0:.1f}: beyond |sigma| = "
                          f"{MAX_SIGMA:g} real DNA denatures or changes structure and the elastic rod is outside its "
                          f"calibration; use |delta_lk| <= {int(MAX_SIGMA * lk0)}")


def _ring_from_pose(model, pose):
    """``model`` at ``pose`` (positions, frames), refused (one line) unless it is a pose of this ring with its
    linking number (Tw + Wr within 0.05 turns of the planar start's; the dynamics conserve it)."""
    from dnarod.physics.writhe import twist, writhe

    pos, frm = (np.asarray(a, float) for a in pose)
    if pos.shape != model.positions.shape or frm.shape != model.frames.shape:
        raise DnarodError(f"start pose of {len(pos)} nodes for a ring of {model.n_nodes}: a ring member starts only "
                          f"from a pose of its own ring")
    lk0 = twist(model.positions, model.frames[:, :, 0]) + writhe(model.positions)
    lk = twist(pos, frm[:, :, 0]) + writhe(pos)
    if abs(lk - lk0) > 0.05:
        raise DnarodError(f"start pose with linking number {lk:.3f}, not the member's {lk0:.3f}: a closed ring keeps "
                          f"its linking number, so a start pose must have it")
    return model.with_pose(pos, frm)


def cached_member(member_dir, key):
    """``(result or None, path)``: the stored result of a member folder if it was run with settings ``key``."""
    from dnarod.core.io import ensure_dir

    done = ensure_dir(Path(member_dir), "member folder") / "protocol_result.json"
    if done.exists():
        old = json.loads(done.read_text())
        if old.get("settings") == key:
            return old["result"], done
    return None, done


def sample_ring(model, s, lp, columns, record=None, *, tau_fraction, samples_per_ns, max_sample_ps, min_samples,
                progress=None, checkpoint=None, checkpoint_wall_s=None, relaxation_model=None):
    """Run one ring member (closed or nicked) on the run layer and sample it: the plan both ring protocols share.

    Friction: critical damping of the slowest normal mode of the closed ring (``relaxation_model``'s pose, default
    ``model``'s; :func:`~dnarod.workflows.protocols.tweezers.mode_relaxation`) unless ``s["friction_per_ps"]`` is
    set; equilibration: five relaxation times of that mode (``s["equilibration_ns"]`` overrides); a sample
    every ``min(tau * tau_fraction, time / samples_per_ns)`` ps, clipped to [1, ``max_sample_ps``]
    (``s["sample_ps"]`` overrides), at least ``min_samples`` samples. Each sample has ``time_ps``, ``Tw``,
    ``Wr``, ``Lk`` (turns) and ``radius_of_gyration_nm``; ``record(positions, frames) -> dict`` gives the caller's
    other columns. The engine runs through the run loop with a :class:`dnarod.run.sampling.SampleReporter`;
    ``checkpoint`` (the engine's checkpoint, with the samples) makes an interrupted member resume where it was.

    Returns
    -------
    out : dict of str to ndarray, shape (n_samples,)
    run : dict
        ``friction_per_ps, tau_bend_estimate_ps, equilibration_ps, production_ps, wall_s, cpu_s, dt_ps,
        n_steps, n_samples, sample_ps, ns_per_day, contour_length_nm``, ``stride`` (steps per sample),
        ``elastic_path`` and ``nonbonded`` (the terms' record, :func:`dnarod.physics.nonbonded.nonbonded_record`:
        charge model, e per node, cutoff in Debye lengths and nm).
    """
    from dnarod.engines.openmm.simulation import RodSimulation
    from dnarod.physics.nonbonded import member_nonbonded, nonbonded_record
    from dnarod.physics.writhe import twist, writhe
    from dnarod.run.sampling import SampleReporter, run_sampling
    from dnarod.workflows.protocols.tweezers import mode_relaxation

    T = float(s["temperature_K"])
    # the modes of the closed ring itself (a ring relaxes as a closed chain, not as one free at both ends)
    rel = mode_relaxation(model if relaxation_model is None else relaxation_model, (), T, s["friction_per_ps"])
    fr, tau = rel["friction_per_ps"], rel["tau_ps"]
    L = model.ds * model.n_nodes
    eq = 5.0 * tau if s["equilibration_ns"] is None else 1000.0 * float(s["equilibration_ns"])
    sample = float(np.clip(min(tau * tau_fraction, 1000.0 * float(s["time_ns"]) / samples_per_ns), 1.0,
                           max_sample_ps)) if s["sample_ps"] is None else float(s["sample_ps"])
    nb = member_nonbonded(s)
    sim = RodSimulation.create(model, temperature=T, friction=fr, platform=s["platform"], nonbonded=nb,
                               seed=int(s["seed"]),
                        threads=s["threads"])
    dt = sim.dt
    stride = max(1, int(round(sample / dt)))
    n_eq = stride * int(math.ceil(eq / dt / stride))  # whole strides: samples on the schedule
    n_samp = max(min_samples, int(round(1000.0 * float(s["time_ns"]) / (stride * dt))))

    def observe(pos, frm, snapshot):
        tw, wr = twist(pos, frm[:, :, 0]), writhe(pos)
        row = {"Tw": tw, "Wr": wr, "Lk": tw + wr,
               "radius_of_gyration_nm": float(np.sqrt(((pos - pos.mean(axis=0)) ** 2).sum(axis=1).mean()))}
        if record is not None:
            row.update(record(pos, frm))
        return row

    sampler = SampleReporter(columns, stride, observe, start=n_eq, n_samples=n_samp)
    key = json.dumps(jsonable(s), sort_keys=True)
    res = run_sampling(sim, sampler, checkpoint, extra={"settings": key}, checkpoint_wall_s=checkpoint_wall_s,
                       progress=progress)
    wall, cpu = res["wall_s"], res["cpu_s"]
    steps = n_eq + n_samp * stride
    run = dict(contour_length_nm=L, friction_per_ps=fr, tau_bend_estimate_ps=tau, slowest_mode_omega=rel["omega_1"],
               equilibration_ps=n_eq * dt,
               production_ps=n_samp * stride * dt, wall_s=wall, cpu_s=cpu, dt_ps=dt, n_steps=steps,
               n_samples=n_samp, sample_ps=stride * dt, ns_per_day=steps * dt * 1e-3 / wall * 86400.0,
               stride=stride, elastic_path=sim.rs.elastic, nonbonded=nonbonded_record(nb, model.ds, T))
    return res["samples"], run


def write_member(member_dir, done, key, columns, out, res):
    """Write ``samples.csv`` (the sampled columns) and ``protocol_result.json`` of a member atomically."""
    from dnarod.core.io import jsonable, write_text_atomic

    n = len(out[columns[0]])
    lines = [",".join(columns)] + [",".join(f"{out[c][i]:.10g}" for c in columns) for i in range(n)]
    write_text_atomic(Path(member_dir) / "samples.csv", "\n".join(lines) + "\n")
    write_text_atomic(done, json.dumps(jsonable({"settings": key, "result": res}), indent=1) + "\n")


def run_ring_member(settings, member_dir, progress=None, start_pose=None):
    """Run (or reuse) one ring member; writes ``samples.csv`` and ``protocol_result.json``, returns the row.

    Parameters
    ----------
    settings : dict
        Ring member settings (``n_bp`` or ``sequence``, ``delta_lk``, ``time_ns``, ``seed``, ...; see ``_settings``).
    member_dir : path
        The member's folder; a finished member there with the same settings is returned without rerunning, an
        interrupted one resumes from its checkpoint.
    progress : callable, optional
    start_pose : tuple of ndarray, optional
        ``(positions (n, 3) nm, frames (n, 3, 3))``: a pose of the same ring with the same linking number (e.g.
        one prepared under other conditions, to approach equilibrium from another side) to start from instead
        of the planar circle. Its SHA-256 joins the member's key and it is written as ``start_pose.npz``.
    """
    from dnarod.analysis.statistics import estimate
    from dnarod.core.forcefield import load_forcefield
    from dnarod.core.io import jsonable
    from dnarod.physics.thermal import persistence_length
    from dnarod.core.units import kT
    from dnarod.physics.nonbonded import member_nonbonded
    from dnarod.workflows.protocols.measure import detector_distances, plectoneme_end_loops, plectoneme_state

    if start_pose is not None:
        from dnarod.workflows.protocols.poses import pose_sha256

        settings = dict(settings, start_pose_sha256=pose_sha256(*start_pose))
    s = _settings(settings)
    # start options left unset are not part of the key (members recorded before they existed stay valid)
    key = jsonable({k: v for k, v in s.items() if not (k == "start_pose_sha256" and v is None)})
    cached, done = cached_member(member_dir, key)
    if cached is not None:
        return cached
    ff = load_forcefield(s["forcefield"])
    tw0_model = ff.ring(s["sequence"], n_nodes=None if s["sequence"] else int(s["n_bp"]), delta_linking_number=0)
    tw0 = intrinsic_turns(tw0_model)
    check_ring(s["delta_lk"], tw0)
    # delta_lk counts from the relaxed ring at the member's temperature: its linking number is the integer nearest
    # the thermal relaxed twist plus delta_lk (the same integer as from the 0 K twist unless the ~0.4-turn-per-kbp
    # offset crosses a half turn)
    from dnarod.physics.loads import torque_free_offset

    T = float(s["temperature_K"])
    offset = torque_free_offset(tw0_model, T)
    shift = int(round(tw0 + offset)) - int(round(tw0))
    model = ff.ring(s["sequence"], n_nodes=None if s["sequence"] else int(s["n_bp"]),
                    delta_linking_number=int(s["delta_lk"]) + shift)
    if start_pose is not None:
        from dnarod.workflows.protocols.poses import START_POSE, save_pose

        model = _ring_from_pose(model, start_pose)
        save_pose(Path(member_dir) / START_POSE, model.positions, model.frames)
    T = float(s["temperature_K"])
    lp = persistence_length(model.params, model.ds, kT(T))
    # the plectoneme detector's distances follow the member's non-bonded terms and salt
    sep_nm, contact_nm = detector_distances(member_nonbonded(s), T, model.ds)

    def record(pos, frm):
        f, length, plec = plectoneme_state(pos, model.ds, sep_nm, contact_nm, circular=True)
        # end loops: 2 unbranched, more branched
        loops = plectoneme_end_loops(pos, model.ds, circular=True, min_separation_nm=sep_nm,
                                     contact_distance_nm=contact_nm)[0]
        return {"plectoneme_fraction": f, "plectoneme_length_nm": length, "plectonemic": plec, "end_loops": loops}

    ckpt = Path(member_dir) / "member_checkpoint.npz"
    out, run = sample_ring(model, s, lp, COLUMNS, record, tau_fraction=0.1, samples_per_ns=200.0,
                           max_sample_ps=200.0, min_samples=4, progress=progress, checkpoint=ckpt,
                           relaxation_model=tw0_model)
    stride, dt = run.pop("stride"), run["dt_ps"]
    run.pop("elastic_path")
    res = dict(n_bp=model.n_nodes, delta_lk=int(s["delta_lk"]), temperature_K=T, salt_M=float(s["salt_M"]),
               seed=int(s["seed"]), intrinsic_turns=tw0, sigma=int(s["delta_lk"]) / tw0,
               plectoneme_contact_nm=contact_nm, plectoneme_min_separation_nm=sep_nm, **run)
    # the start's transient, detected on the writhe (the slow observable of a ring), is dropped from every column
    t0 = estimate(out["Wr"], what="Wr").n_dropped if len(out["Wr"]) >= 4 else 0
    res["transient_dropped_samples"], res["transient_dropped_ps"] = int(t0), float(t0 * stride * dt)
    flags = []
    for c in COLUMNS[1:]:
        e = estimate(np.asarray(out[c], float)[t0:], transient=False, what=c,
                     relaxation_samples=run["tau_bend_estimate_ps"] / (stride * dt))
        res[c], res[c + "_err"], res[c + "_n_eff"], res[c + "_flag"] = e.mean, e.error, e.n_eff, e.flag
        res[c + "_tau_ps"] = float(e.tau * stride * dt) if np.isfinite(e.tau) else None
        if e.flag and c in ("Wr", "Tw"):
            flags.append(e.flag)
    res["flags"] = " | ".join(flags) or None  # one string: the ensemble keeps scalars per member
    res["lk_integer"] = int(np.rint(out["Lk"]).min()) if np.ptp(np.rint(out["Lk"])) == 0 else None
    res["delta_lk_measured"] = res["Lk"] - round(tw0 + offset)
    res["turns_offset_0K"] = offset  # relaxed twist at T less the 0 K intrinsic twist
    from dnarod.physics.thermal import relaxed_ribbon_twist as thermal_relaxed_twist

    # the linking difference that supercoils the ring is relative to the relaxed ring's mean twist at T
    res["relaxed_twist_thermal"], res["relaxed_twist_thermal_err"] = thermal_relaxed_twist(model, T)
    d = res["Lk"] - res["relaxed_twist_thermal"]
    res["delta_lk_thermal"] = d  # the supercoiling: Lk less the relaxed ring's twist at T (not an integer)
    res["writhe_fraction"] = res["Wr"] / d if abs(d) > 0.25 else None
    res["writhe_fraction_err"] = (abs(res["Wr_err"] / d) if res["writhe_fraction"] is not None else None)
    write_member(member_dir, done, key, COLUMNS, out, res)
    ckpt.unlink(missing_ok=True)
    return jsonable(res)
