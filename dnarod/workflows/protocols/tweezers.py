"""Tweezers members: one chain, one force and one number of turns, sampled at equilibrium.

Geometry (magnetic tweezers): node 0 is clamped (position and orientation: the surface), the last node
carries a constant pulling force F along +z (the bead), walls keep the chain above the surface plane and
below the bead (:class:`dnarod.physics.loads.Walls`; without them the chain unwinds around its ends) and, for
rotation-clamped protocols, an orientation restraint ``E = k (1 - cos theta)`` whose target is the last
node's start frame turned by ``turns`` about z (the magnets). Without a rotation clamp the bead end is torsionally free
(force-extension).

Turns count from the torque-free state at the member's temperature, as magnet turns do: ``turns = 0`` is the
chain's relaxed twist at T (:func:`dnarod.physics.loads.torque_free_offset`: the thermal mean twist of the free
steps, about 0.42 turns below the 0 K intrinsic twist for 1 kbp at 300 K), so the chain carries
``turns + turns_offset_0K`` turns from its 0 K intrinsic twist; ``delta_lk`` is ``Lk`` less the relaxed linking
number at T, ``delta_lk_0K`` less the 0 K one, and ``turns_offset_0K`` is reported beside them.

Start ("relaxed under load"): the uniformly strained straight helix that is the static equilibrium of a
uniform chain under tension F with ``turns`` applied (:func:`strained_helix`), refined by
:func:`dnarod.physics.statics.solve_static` under the member's loads (two Newton steps for dna-default): the twist
per step carries the turns, and the other strains follow the linear constitutive law ``K dxi = (0, 0, tau, 0, 0, F)``
(twist-stretch coupling included). Past buckling this state is unstable and thermal noise takes the chain
into its plectonemic state during equilibration. A member can start instead from a given pose, e.g. another
member's final pose (``final_pose.npz``), with the turns it was sampled at (``previous_turns``): the difference is
added as twist (``build_member(..., start_pose=...)``, :func:`dnarod.workflows.protocols.poses.add_turns`), so a
series of members can continue each other's configurations.

Friction and equilibration (:func:`mode_relaxation`): the equilibrium does not depend on the friction, so it is
chosen to decorrelate fast: ``zeta = 2 omega_1``, critical damping of the slowest normal mode of the member's own
start pose with its loads (:mod:`dnarod.physics.relaxation`: node 0 clamped, the bead pulled, the rotation clamp;
the tension is in the Hessian of the pose under the force), whose relaxation time is then ``1/omega_1``. A chain
clamped at the surface with a laterally free bead relaxes several times more slowly than the same chain free at
both ends (the formula :func:`dnarod.analysis.polymer.bending_relaxation_time` assumes). The default equilibration
is five of these relaxation times (two after a sweep's turn increment). Every mean is stated with the error of
:func:`dnarod.analysis.statistics.estimate` (autocorrelation, the start's transient dropped and reported, flagged
when the member is too short for it), see :func:`summarize`.

Units: pN, pN nm and nm at this interface (converted to MD units inside), ps, K.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.core.units import PN
from dnarod.physics.loads import MAX_FORCE_PN, MAX_SIGMA, intrinsic_turns, torque_free_offset

DEFAULT_CLAMP_K = 250.0  # kJ/mol: ~100 kT, clamp angle fluctuations ~0.1 rad

#: Observables sampled per frame (column names of ``samples.csv``).
COLUMNS = ("time_ps", "extension_nm", "end_turns", "clamp_torque_pN_nm", "twist_torque_pN_nm", "Tw", "Wr", "Lk",
           "plectoneme_fraction", "plectoneme_length_nm", "plectonemic")


def check_tweezers(force_pN, turns=None, rotation_clamp=True, n_bp=None, lk0=None, torque_pN_nm=None):
    """Refuse loads the protocol or the model cannot represent (one-line :class:`DnarodError`).

    Parameters
    ----------
    force_pN : float
    turns : float or None
    rotation_clamp : bool
        Whether the bead end is rotation-clamped.
    lk0 : float, optional
        Relaxed linking number (for the |sigma| limit).
    torque_pN_nm : float, optional
        A constant torque on the bead end.
    """
    F = float(force_pN)
    if not math.isfinite(F) or F < 0:
        raise DnarodError(f"force {force_pN} pN: give a pulling force >= 0 pN")
    if torque_pN_nm not in (None, 0, 0.0) and F <= 0:
        raise DnarodError(f"a torque of {torque_pN_nm} pN nm on a free end with no pulling force has no "
                          f"equilibrium (the end rotates and wanders away): add a pulling force (--force)")
    if F <= 0:
        raise DnarodError("tweezers need a pulling force > 0 pN (at zero force the bead end has no equilibrium "
                          "position): give --force")
    if F > MAX_FORCE_PN:
        raise DnarodError(f"force {F:g} pN is above {MAX_FORCE_PN:g} pN: DNA overstretches near 65 pN, a transition "
                          f"the elastic rod model does not have; use forces up to {MAX_FORCE_PN:g} pN")
    if turns not in (None, 0, 0.0):
        if not rotation_clamp:
            raise DnarodError(f"turns = {turns} without a rotation clamp: the bead end is torsionally free and "
                              f"turns cannot be imposed; use a rotation-clamped protocol (hat, torque-turns)")
        t = float(turns)
        if not math.isfinite(t):
            raise DnarodError(f"turns must be finite, got {turns}")
        if lk0:
            sigma = t / lk0
            if abs(sigma) > MAX_SIGMA:
                raise DnarodError(f"turns {t:g} is a supercoiling density sigma = {sigma:+.3f} for Lk0 = {lk0:.1f}: "
                                  f"beyond |sigma| = {MAX_SIGMA:g} real DNA denatures or changes structure and "
                                  f"the elastic rod is outside its calibration; use |turns| <= "
                                  f"{MAX_SIGMA * lk0:.1f}")


def strained_helix(model, force_pN, turns):
    """The straight helix uniformly strained by tension and turns (start "relaxed under load").

    Parameters
    ----------
    model : RodModel
        Open chain at its intrinsic straight shape along z (node 0 at the origin, identity frame).
    force_pN : float
    turns : float
        Extra turns spread evenly over the steps.

    Returns
    -------
    RodModel
    """
    from dnarod.core.strains import chain_from_strains

    n = model.n_steps
    K = model.params.stiffness
    xi0 = model.params.intrinsic
    F = float(force_pN) * PN
    th0 = 2.0 * np.arctan(0.5 * model.ds * xi0[:, 2])
    th = th0 + 2.0 * np.pi * float(turns) / n
    if np.abs(th).max() >= 0.9 * np.pi:
        raise DnarodError(f"turns {turns}: the twist per step would reach {np.degrees(np.abs(th).max()):.0f} "
                          f"degrees; the model represents steps only well below 180 degrees")
    d3 = 2.0 / model.ds * np.tan(0.5 * th) - xi0[:, 2]
    Ci = np.linalg.inv(K)
    tau = (d3 - Ci[:, 2, 5] * F) / Ci[:, 2, 2]
    s = np.zeros((n, 6))
    s[:, 2], s[:, 5] = tau, F
    xi = xi0 + np.einsum("kij,kj->ki", Ci, s)
    pos, frm = chain_from_strains(xi[:, :3], xi[:, 3:], model.ds, model.positions[0], model.frames[0])
    return model.with_pose(pos, frm)


#: Collision rates the automatic friction is kept within, 1/ps.
FRICTION_RANGE = (1e-4, 1.0)


def mode_relaxation(model, loads, temperature, friction=None):
    """Friction and slowest relaxation time of a member from the normal modes of its start pose with its loads.

    Parameters
    ----------
    model : RodModel
        The start pose (a static equilibrium of ``loads``).
    loads : sequence
        The member's loads (walls aside: they do not touch the straight start).
    temperature : float
        K.
    friction : float, optional
        1/ps; default: ``2 omega_1`` (critical damping of the slowest mode) within :data:`FRICTION_RANGE`.

    Returns
    -------
    dict
        ``friction_per_ps``, ``tau_ps`` (the slowest mode's relaxation time at that friction), ``omega_1``
        (rad/ps) and ``n_unstable`` (directions in which the start pose is unstable: past buckling).
    """
    from dnarod.physics.relaxation import decay_rate, slowest_modes

    w, unstable = slowest_modes(model, tuple(loads), k=2, temperature=temperature)
    # six significant digits: eigensolvers differ in the last bits between processes and thread counts, and a
    # member must run the same steps wherever it runs (bit-for-bit reproducible samples)
    w1 = float(f"{float(w[0]):.6g}")
    fr = float(f"{float(np.clip(2.0 * w1, *FRICTION_RANGE)):.6g}") if friction is None else float(friction)
    lam = float(decay_rate(w1, fr))
    return dict(friction_per_ps=fr, tau_ps=1.0 / lam if lam > 0 else float("inf"), omega_1=w1, n_unstable=unstable)


def _settings(s):
    from dnarod.physics.nonbonded import DEFAULT_CHARGE, DEFAULT_CUTOFF_DEBYE
    from dnarod.engines.openmm.platforms import member_platform

    out = dict(n_bp=200, forcefield="dna-default", sequence=None, force_pN=1.0, turns=None, time_ns=1.0,
               equilibration_ns=None, temperature_K=300.0, salt_M=0.15, seed=1, clamp_k_kJ_mol=DEFAULT_CLAMP_K,
               friction_per_ps=None, sample_ps=None, platform=None, threads=None, electrostatics=True,
               excluded_volume=True, charge=DEFAULT_CHARGE, cutoff_debye=DEFAULT_CUTOFF_DEBYE, elastic="auto",
               previous_turns=None, start_pose_sha256=None)
    unknown = set(s) - set(out)
    if unknown:
        raise DnarodError(f"unknown tweezers setting(s) {sorted(unknown)}; known: {sorted(out)}")
    out.update({k: v for k, v in s.items() if v is not None or k == "turns"})
    out.update(member_platform(out["platform"], out["threads"], out["elastic"]))  # the platform it runs on, in its key
    return out


def build_member(settings, start_pose=None):
    """Model, start pose, loads and run parameters of one tweezers member (validated).

    Parameters
    ----------
    settings : dict
        Member settings (see ``_settings``).
    start_pose : tuple of ndarray, optional
        ``(positions (n, 3) nm, frames (n, 3, 3))``: a pose of the same chain sampled at ``settings["previous_turns"]``
        turns (e.g. another member's final pose). The member starts from it with ``turns - previous_turns`` added as
        twist (:func:`dnarod.workflows.protocols.poses.add_turns`) instead of from the static pose; equilibration
        then defaults to two slowest bending relaxation times.

    Returns
    -------
    dict
        ``model`` (start pose), ``loads``, ``clamp_target`` (3, 3) or None, ``friction``, ``tau_ps``,
        ``equilibration_ps``, ``production_ps``, ``sample_ps``, ``lk0`` and the resolved settings.
    """
    from dnarod.core.forcefield import load_forcefield
    from dnarod.physics.loads import Walls, tweezers
    from dnarod.physics.thermal import persistence_length
    from dnarod.core.units import kT

    s = _settings(settings)
    ff = load_forcefield(s["forcefield"])
    model = ff.model_from_sequence(s["sequence"]) if s["sequence"] else ff.model_from_sequence(n_nodes=int(s["n_bp"]))
    lk0 = intrinsic_turns(model)
    clamp = s["turns"] is not None
    check_tweezers(s["force_pN"], s["turns"], rotation_clamp=clamp, lk0=lk0)
    turns = float(s["turns"] or 0.0)
    T = float(s["temperature_K"])
    # turns count from the torque-free state at T (as magnet turns do): the chain carries turns + offset from its
    # intrinsic twist at 0 K (offset ~ -0.42 turns for 1 kbp at 300 K)
    offset = torque_free_offset(model, T) if clamp else 0.0
    turns_0K = turns + offset
    start = strained_helix(model, s["force_pN"], turns_0K)
    # the one tweezers set-up: node 0 on the surface, the bead pulled along +z; the start pose already carries the
    # turns, so the clamp holds the start's last frame (turns=0 here)
    target = start.frames[-1].copy() if clamp else None
    loads = list(tweezers(start, s["force_pN"], None, float(s["clamp_k_kJ_mol"]) if clamp else None, 0.0,
                          anchor="surface", axis="z", clamp_frame=target))
    ref_frame = start.frames[-1].copy()  # the bead node's frame with exactly ``turns`` (from the torque-free state)
    if start_pose is not None:
        from dnarod.workflows.protocols.poses import add_turns

        if s["previous_turns"] is None:
            raise DnarodError("a start pose needs previous_turns (the turns it was sampled at)")
        pos, frm = (np.asarray(a, float) for a in start_pose)
        if pos.shape != start.positions.shape or frm.shape != start.frames.shape:
            raise DnarodError(f"start pose of {len(pos)} nodes for a chain of {start.n_nodes}: a member starts only "
                              f"from a pose of its own chain (the same source)")
        dt_ = turns - float(s["previous_turns"])
        start = start.with_pose(*add_turns(pos, frm, dt_))
        start_info = f"given pose sampled at {float(s['previous_turns']):+g} turns, turned by {dt_:+g} turns"
    from dnarod.physics.statics import solve_static

    # the exact static equilibrium under the loads (a few Newton steps from the helix; the walls, added below, do not
    # touch the straight pose): the static start, and the pose whose normal modes set the relaxation time
    static, info = solve_static(strained_helix(model, s["force_pN"], turns_0K), loads)
    if start_pose is None:
        start = static
        start_info = (f"static equilibrium under the loads (dnarod.physics.statics, "
                      f"{info['iterations']} Newton steps)")
    lp = persistence_length(model.params, model.ds, kT(T))
    # relaxation from the modes of the member's own pose and loads (not of a chain free at both ends)
    rel = mode_relaxation(static, loads, T, s["friction_per_ps"])
    fr, tau = rel["friction_per_ps"], rel["tau_ps"]
    eq = (2.0 if start_pose is not None else 5.0) * tau if s["equilibration_ns"] is None \
        else 1000.0 * float(s["equilibration_ns"])
    prod = 1000.0 * float(s["time_ns"])
    # at least ~200 samples per member (the autocorrelation time is measured from them), at most 10 per tau_1
    sample = float(np.clip(min(tau / 10.0, prod / 200.0), 1.0, 200.0)) if s["sample_ps"] is None \
        else float(s["sample_ps"])
    loads.append(Walls())
    return dict(settings=s, model=start, loads=loads, clamp_target=target, friction=fr, tau_ps=tau, start=start_info,
                ref_frame=ref_frame, slowest_mode_omega=rel["omega_1"], start_unstable_modes=rel["n_unstable"],
                equilibration_ps=eq, production_ps=prod, sample_ps=sample, lk0=lk0,
                persistence_length_nm=lp, turns=turns, turns_offset_0K=offset, lk_T=lk0 + offset)


def _member_simulation(m, model, dt=None):
    """The member's RodSimulation from ``model``'s pose (loads, walls, friction and seed of ``m``; ``dt`` ps, default
    the model's own, :class:`~dnarod.engines.openmm.simulation.RodSimulation`)."""
    from dnarod.physics.nonbonded import member_nonbonded
    from dnarod.engines.openmm.simulation import RodSimulation

    s = m["settings"]
    nb = member_nonbonded(s)
    # the walls are loads (dnarod.physics.loads.Walls): the engine builds them before its Context exists, so the
    # automatic elastic path (the compiled plugin where it is built) applies; settings["elastic"] can force another
    # path. The walls' form follows the platform.
    return RodSimulation.create(model, temperature=float(s["temperature_K"]), friction=m["friction"],
                                platform=s["platform"],
                         nonbonded=nb, loads=m["loads"], seed=int(s["seed"]), threads=s["threads"],
                         elastic=s["elastic"], dt=dt)


def observe_tweezers(positions, frames, model, end_turns, clamp_target, clamp_k, sep_nm, contact_nm):
    """The observables of one tweezers sample (:data:`COLUMNS` but ``time_ps``).

    Parameters
    ----------
    positions : ndarray, shape (n, 3)
        Node centres, nm (node 0 on the surface, the last node the bead's).
    frames : ndarray, shape (n, 3, 3)
        Directors as columns.
    model : RodModel
        The member's model (``params``, ``ds``).
    end_turns : float
        The bead's unwrapped rotation about z, turns (the caller follows it between samples).
    clamp_target : ndarray, shape (3, 3) or None
        The rotation clamp's target frame (None: no clamp, zero clamp torque).
    clamp_k : float
        Clamp stiffness, kJ/mol.
    sep_nm, contact_nm : float
        The plectoneme detector's distances (:func:`dnarod.workflows.protocols.measure.detector_distances`).

    Returns
    -------
    dict
        Column -> value (extension nm, torques pN nm, Tw, Wr, Lk in turns, plectoneme fraction, length nm, flag).
    """
    from dnarod.workflows.protocols.measure import clamp_torque_z, plectoneme_state, twisting_moment
    from dnarod.physics.observables import twist_writhe_open

    row = {"extension_nm": positions[-1, 2] - positions[0, 2], "end_turns": end_turns,
           "clamp_torque_pN_nm": (clamp_torque_z(frames[-1], clamp_target, clamp_k)
                                  if clamp_target is not None else 0.0)}
    tw, wr = twist_writhe_open(positions, frames)
    row["Tw"], row["Wr"], row["Lk"] = tw, wr, tw + wr
    f, length, plec, mask = plectoneme_state(positions, model.ds, sep_nm, contact_nm, return_mask=True)
    row["twist_torque_pN_nm"] = twisting_moment(positions, frames, model.params, model.ds, mask)
    row["plectoneme_fraction"], row["plectoneme_length_nm"], row["plectonemic"] = f, length, plec
    return row


class EndRotation:
    """Follows the bead's rotation about z between samples and unwraps it (turns), so a member's ``end_turns``
    counts whole turns; its state travels in the member's checkpoint (:class:`dnarod.run.sampling.SampleReporter`).
    Reports must be closer than half a turn apart."""

    def __init__(self, ref_frame):
        self.ref = np.asarray(ref_frame, float)
        self.last_angle, self.turns = 0.0, 0.0

    def update(self, positions, frames, step):
        from dnarod.workflows.protocols.measure import rotation_about_z

        a = float(rotation_about_z(frames[-1], self.ref))
        self.turns += ((a - self.last_angle + np.pi) % (2 * np.pi) - np.pi) / (2 * np.pi)
        self.last_angle = a

    def state(self):
        return {"last_angle": self.last_angle, "turns": self.turns}

    def restore(self, state):
        self.last_angle, self.turns = float(state["last_angle"]), float(state["turns"])


def sample_member(m, progress=None, checkpoint=None, checkpoint_wall_s=None, pose_out=None):
    """Run one member built by :func:`build_member` on the run layer; returns the per-sample observables (dict of
    arrays) and costs.

    The member's engine runs through the run loop with a :class:`dnarod.run.sampling.SampleReporter`
    (:func:`dnarod.run.sampling.run_sampling`): equilibration, then one sample every ``sample_ps``; the engine's
    checkpoint carries the samples so far and the unwrapped end rotation.

    Parameters
    ----------
    m : dict
        From :func:`build_member`.
    progress : callable, optional
        ``progress(i, n)`` after each sample.
    checkpoint : path, optional
        The member's checkpoint (the engine's format, with the samples): written every ``checkpoint_wall_s`` wall
        seconds (default :data:`dnarod.run.loop.CHECKPOINT_WALL_S`) and at the end; if it exists at the start
        (same settings), the member resumes from it, so an interrupted member gives the samples an uninterrupted
        one would. Removed by :func:`run_member` once the member is written.
    pose_out : path, optional
        Where to write the last pose (``.npz``, ``positions`` and ``frames``): a following member may start from it.
    """
    from dnarod.physics.nonbonded import member_nonbonded
    from dnarod.run.sampling import SampleReporter, run_sampling
    from dnarod.workflows.protocols.measure import detector_distances

    s = m["settings"]
    model = m["model"]
    sim = _member_simulation(m, model)
    dt = sim.dt
    stride = max(1, int(round(m["sample_ps"] / dt)))
    n_eq = stride * int(math.ceil(m["equilibration_ps"] / dt / stride))  # whole strides: samples on the schedule
    n_samp = max(4, int(round(m["production_ps"] / (stride * dt))))
    k_clamp = float(s["clamp_k_kJ_mol"])
    # the plectoneme detector's distances follow the member's non-bonded terms and salt
    sep_nm, contact_nm = detector_distances(member_nonbonded(s), float(s["temperature_K"]), model.ds)
    end = EndRotation(m["ref_frame"])

    def observe(pos, frm, snapshot):  # the start frame already carries the turns
        return observe_tweezers(pos, frm, model, m["turns"] + end.turns, m["clamp_target"], k_clamp, sep_nm,
                                contact_nm)

    sampler = SampleReporter(COLUMNS, stride, observe, start=n_eq, n_samples=n_samp, follow=end)
    key = json.dumps(_jsonable_settings(s), sort_keys=True)
    out = run_sampling(sim, sampler, checkpoint, extra={"settings": key}, checkpoint_wall_s=checkpoint_wall_s,
                       progress=progress)
    if pose_out is not None:
        from dnarod.workflows.protocols.poses import save_pose

        save_pose(pose_out, *sim.node_pose())
    wall, cpu = out["wall_s"], out["cpu_s"]
    steps = n_eq + n_samp * stride
    cost = dict(wall_s=wall, cpu_s=cpu, dt_ps=dt, n_steps=steps, n_samples=n_samp,
                elastic_path=sim.rs.elastic, plectoneme_contact_nm=contact_nm, plectoneme_min_separation_nm=sep_nm,
                sample_ps=stride * dt, ns_per_day=steps * dt * 1e-3 / wall * 86400.0)
    return out["samples"], cost


#: Observables whose transients set the frames dropped from every column (the headline observables).
TRANSIENT_COLUMNS = ("extension_nm", "Wr", "twist_torque_pN_nm")


def summarize(samples, m, cost):
    """Means of a member's samples with their errors from :func:`dnarod.analysis.statistics.estimate`.

    The start's transient is detected on the headline observables (:data:`TRANSIENT_COLUMNS`) and the latest of
    their ends is dropped from every column (``transient_dropped_samples``, ``transient_dropped_ps``); each mean then
    has its autocorrelation error (``_err``), autocorrelation time (``_tau_ps``), effectively independent samples
    (``_n_eff``) and, where the member is too short for it, a flag (``_flag``; the production must also span
    :data:`dnarod.analysis.statistics.RELAXATION_TIMES_REQUIRED` relaxation times of the slowest normal mode of the
    loaded chain). ``flags`` joins those of the headline observables (one string, or None).
    """
    from dnarod.analysis.statistics import estimate

    s = m["settings"]
    L0 = m["model"].ds * m["model"].n_steps
    res = {k: s[k] for k in ("n_bp", "force_pN", "turns", "temperature_K", "salt_M", "seed")}
    res["turns"] = m["turns"] if s["turns"] is not None else None
    res["previous_turns"] = s.get("previous_turns")
    res.update(start=m["start"], contour_length_nm=L0, lk0=m["lk0"], friction_per_ps=m["friction"],
               tau_bend_estimate_ps=m["tau_ps"], slowest_mode_omega=m.get("slowest_mode_omega"),
               relaxation_from="normal modes of the member's static pose with its loads (dnarod.physics.relaxation)",
               equilibration_ps=m["equilibration_ps"], production_ps=m["production_ps"], **cost)
    dt_s = cost["sample_ps"]
    n = len(samples["extension_nm"])
    t0 = max(estimate(np.asarray(samples[c], float), what=c).n_dropped for c in TRANSIENT_COLUMNS
             if np.isfinite(np.asarray(samples[c], float)).all()) if n >= 4 else 0
    res["transient_dropped_samples"], res["transient_dropped_ps"] = int(t0), float(t0 * dt_s)
    flags = []
    for c in COLUMNS[1:]:
        x = np.asarray(samples[c], float)[t0:]
        if not np.isfinite(x).all():  # the twisting moment is NaN where every step is in a plectoneme
            x = x[np.isfinite(x)]
        if len(x) == 0:
            res[c], res[c + "_err"], res[c + "_tau_ps"], res[c + "_n_eff"], res[c + "_flag"] = (None,) * 5
            continue
        e = estimate(x, transient=False, what=c, relaxation_samples=m["tau_ps"] / dt_s)
        res[c], res[c + "_err"] = e.mean, e.error
        res[c + "_tau_ps"] = float(e.tau * dt_s) if np.isfinite(e.tau) else None
        res[c + "_n_eff"], res[c + "_flag"] = e.n_eff, e.flag
        if e.flag and c in TRANSIENT_COLUMNS:
            flags.append(e.flag)
    res["flags"] = " | ".join(flags) or None  # one string: the ensemble keeps scalars per member
    samples = {k: np.asarray(v)[t0:] for k, v in samples.items()}
    lk_T = m.get("lk_T", m["lk0"])  # the linking number of the torque-free state at T (end_turns count from it)
    slips = np.rint(np.asarray(samples["Lk"]) - lk_T - np.asarray(samples["end_turns"]))
    res["lk_slips"] = int(np.abs(slips).max())  # nonzero: the chain passed through the closure (see measure)
    res["relative_extension"] = res["extension_nm"] / L0
    res["relative_extension_err"] = res["extension_nm_err"] / L0
    # linking difference from the torque-free state at T (the supercoiling); the 0 K offset beside it
    res["delta_lk"] = res["Lk"] - lk_T
    res["delta_lk_0K"] = res["Lk"] - m["lk0"]
    res["turns_offset_0K"] = m.get("turns_offset_0K", 0.0)
    res["relaxed_twist_thermal"] = lk_T
    res["writhe_fraction"] = res["Wr"] / res["delta_lk"] if abs(res["delta_lk"]) > 0.25 else None
    res["writhe_fraction_err"] = (
        math.hypot(res["Wr_err"], res["writhe_fraction"] * res["Lk_err"]) / abs(res["delta_lk"])
        if res["writhe_fraction"] is not None else None)
    res["extension_sd_nm"] = float(np.std(samples["extension_nm"], ddof=1)) if len(samples["extension_nm"]) > 1 \
        else None
    res["n_effective_extension"] = res["extension_nm_n_eff"]
    return res


def run_member(settings, member_dir, progress=None, start_pose=None):
    """Run (or reuse) one tweezers member in ``member_dir``: writes ``samples.csv``, ``final_pose.npz`` and
    ``protocol_result.json`` (and ``start_pose.npz`` for a member started from a given pose).

    A finished member (``protocol_result.json`` present with the same settings) is returned without rerunning.
    With ``start_pose`` (see :func:`dnarod.workflows.protocols.tweezers.build_member`) the key also holds the pose's
    SHA-256, so the member is reused only if it started from that very pose.
    """
    from dnarod.core.io import ensure_dir, jsonable, write_text_atomic
    from dnarod.workflows.protocols.poses import FINAL_POSE, START_POSE, pose_sha256, save_pose

    member_dir = ensure_dir(Path(member_dir), "member folder")
    if start_pose is not None:
        settings = dict(settings, start_pose_sha256=pose_sha256(*start_pose))
    m = build_member(settings, start_pose=start_pose)
    done = member_dir / "protocol_result.json"
    # start options left unset are not part of the key (members recorded before they existed stay valid)
    key = jsonable({k: v for k, v in m["settings"].items()
                    if not (k in ("previous_turns", "start_pose_sha256") and v is None)})
    if done.exists():
        old = json.loads(done.read_text())
        if old.get("settings") == key:
            return old["result"]
    ckpt = member_dir / "member_checkpoint.npz"
    if start_pose is not None:
        save_pose(member_dir / START_POSE, m["model"].positions, m["model"].frames)
    samples, cost = sample_member(m, progress, checkpoint=ckpt, pose_out=member_dir / FINAL_POSE)
    res = summarize(samples, m, cost)
    from dnarod.physics.nonbonded import member_nonbonded, nonbonded_record

    # the non-bonded terms as run: charge model, e per node, cutoff in Debye lengths and nm
    res["nonbonded"] = nonbonded_record(member_nonbonded(m["settings"]), m["model"].ds,
                                        float(m["settings"]["temperature_K"]))
    lines = [",".join(COLUMNS)] + [",".join(f"{samples[c][i]:.10g}" for c in COLUMNS)
                                   for i in range(len(samples["time_ps"]))]
    write_text_atomic(member_dir / "samples.csv", "\n".join(lines) + "\n")
    write_text_atomic(done, json.dumps(jsonable({"settings": key, "result": res}), indent=1) + "\n")
    ckpt.unlink(missing_ok=True)
    return jsonable(res)


def _jsonable_settings(s):
    from dnarod.core.io import jsonable

    return jsonable(s)
