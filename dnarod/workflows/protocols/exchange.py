"""Replica exchange along the turns of a tweezers ladder (``dnarod protocol hat|torque-turns --start exchange``).

Why. Near buckling a long chain under a rotation clamp is bistable (straight or plectonemic), and the two states
outlive any member a hat curve can afford (at 1 kbp and 1 pN a member of a few hundred ns can keep the state it
started in), so independent members, or members continuing each other's poses along the turns, report their
start, not the equilibrium.
Replica exchange along the turns axis lets each rung's configuration change state through its neighbours: a
plectoneme carried to fewer turns dissolves there, a straight chain carried to more turns buckles there, and
each comes back when the Metropolis test lets it.

Ladder. One replica per turn value ``n_0 < n_1 < ... < n_{R-1}`` of one force (a rung: the member's loads, its
rotation-clamp target turned by ``n_i`` about z). Every ``exchange_ps`` all replicas advance, then the neighbour
pairs ``(i, i+1)`` with ``i`` of the round's parity (even, odd, even, ...) attempt a swap.

Move. A swap carries the configuration ``X`` of rung ``i`` to rung ``i+1`` with ``delta = n_{i+1} - n_i``
turns added as twist spread along the chain (:func:`dnarod.workflows.protocols.poses.add_turns`: node ``k`` of ``n``
turned about its own d3 by ``2 pi delta k/(n-1)``; centres, so the non-bonded and wall terms, are unchanged), and
the configuration ``Y`` of rung ``i+1`` to rung ``i`` with ``-delta``. The body angular velocities turn with
the frames (``Omega' = Q^T Omega``; centre velocities unchanged), so the map is the cotangent lift of a fixed
right multiplication of each frame: it preserves phase-space volume, and the ``+delta``/``-delta`` maps are each
other's inverse. Accepting with ``min(1, exp(-Delta/kT))``,
``Delta = H_{i+1}(T_delta X) - H_i(X) + H_i(T_{-delta} Y) - H_{i+1}(Y)``, therefore leaves the product of the
rungs' canonical distributions invariant (the Metropolis rule for a deterministic, volume-preserving, involutive
proposal; replica exchange with a configuration map). ``H`` is the full potential energy as OpenMM evaluates it
(elastic, clamp, walls, non-bonded) plus the kinetic energy, which the map leaves unchanged because every
node's inertia is symmetric about d3 (checked). Estimate of the cost (an argument, not used by the code): in the
post-buckling plateau the extra turns go into writhe, so the twist added by the map costs on average
``(2 pi delta)^2 k_tw / (n-1)`` with ``k_tw = kT C / ds`` the step's twist stiffness (7.4 kT for 0.8 turns on
1 kbp of ``dna-default``, C = 100 nm); with Gaussian energy differences the acceptance is then
``erfc(sqrt(mean/kT)/2)``, about 5 %; in the linear (straight) regime the twist terms cancel and swaps are
accepted almost always. Each pair's measured acceptance is reported.

Observables are sampled per rung (whichever replica holds it), as a member's are
(the member's ``observe`` in :mod:`dnarod.workflows.protocols.tweezers`), and each rung is written as a member
folder (``samples.csv``,
``protocol_result.json``, ``final_pose.npz``) beside ``exchange.json`` (acceptance per pair, replica round
trips, labels). Runs checkpoint every :data:`CHECKPOINT_WALL_S` wall seconds and resume from the last complete
checkpoint (same settings); a finished ladder is reused.

Parallelism: the replicas are split into ``workers`` groups, each a dask actor on its own worker process of the
:func:`dnarod.workflows.ensemble.cluster.local_cluster` (or any client); ``workers=0`` keeps one group in this process.
Only energies and labels travel between them: a configuration never moves between processes, its rung does.
"""
from __future__ import annotations

import contextlib
import json
import math
import time
import warnings
from pathlib import Path

import numpy as np

from dnarod.core.errors import DnarodError, RunWarning
from dnarod.workflows.protocols.poses import add_turns, save_pose, FINAL_POSE
from dnarod.workflows.protocols.tweezers import (_member_simulation, build_member, observe_tweezers, COLUMNS,
                                                 summarize)
from dnarod.workflows.protocols.measure import rotation_about_z, detector_distances
from dnarod.run.loop import run_engine
from dnarod.run.sampling import FollowReporter
from dnarod.engines.openmm.particles import particle_positions
from dnarod.physics.modes import DEFAULT_OMEGA_DT, omega_max
from dnarod.physics.nonbonded import member_nonbonded
from dnarod.core.io import ensure_dir, jsonable, write_text_atomic
from dnarod.core.units import kT
from dnarod.workflows.protocols import ensemble_hooks as hooks
from dnarod.workflows.protocols.settings import member_name
from dnarod.workflows.ensemble.cluster import client_for

#: Default time between exchange attempts (ps).
EXCHANGE_PS = 20.0
#: Wall-clock seconds between checkpoints of a running ladder.
CHECKPOINT_WALL_S = 120.0
#: Result file of a ladder (in its folder).
RESULT = "exchange.json"
CHECKPOINT = "exchange_checkpoint.json"


def twist_move(frames, omega_body, delta_turns):
    """The exchange map: ``delta_turns`` turns of twist spread along the chain, angular velocities turned along.

    Parameters
    ----------
    frames : ndarray, shape (n, 3, 3)
        Directors as columns.
    omega_body : ndarray, shape (n, 3)
        Body-frame angular velocities (on d1, d2, d3), rad/ps.
    delta_turns : float

    Returns
    -------
    frames, omega_body : ndarray
        Node ``k`` turned about its own d3 by ``phi_k = 2 pi delta k / (n - 1)``
        (:func:`dnarod.workflows.protocols.poses.add_turns`), ``Omega'_k = Q(phi_k)^T Omega_k`` so that the lab angular
        velocity is unchanged. ``twist_move(*twist_move(F, W, d), -d)`` returns ``(F, W)``.
    """
    F = np.asarray(frames, float)
    W = np.array(omega_body, float)
    n = len(F)
    _, F2 = add_turns(np.zeros((n, 3)), F, delta_turns)
    phi = 2.0 * np.pi * float(delta_turns) * np.arange(n) / (n - 1)
    c, s = np.cos(phi), np.sin(phi)
    w1, w2 = W[:, 0].copy(), W[:, 1].copy()
    W[:, 0] = c * w1 + s * w2
    W[:, 1] = -s * w1 + c * w2
    return F2, W


class _Replica:
    """One replica: its simulation, the rung it holds and the bead's unwrapped rotation relative to that rung."""

    def __init__(self, rid, label, member, rungs, dt):
        self.rid, self.label, self.init_label = int(rid), int(label), int(label)
        self.sim = _member_simulation(member, member["model"], dt=dt)
        inertia = np.asarray(self.sim.model.inertia, float)
        if not np.allclose(inertia[:, 0], inertia[:, 1], rtol=1e-12, atol=0.0):
            raise DnarodError("replica exchange along the turns needs nodes whose inertia is symmetric about d3 "
                              "(I1 = I2): the twist map would change the kinetic energy")
        self.rungs = rungs
        self.last_angle = self._angle(self.sim.node_pose()[1])
        self.turns_acc = 0.0

    def _angle(self, frames):
        return float(rotation_about_z(frames[-1], self.rungs[self.label]["ref_frame"]))

    def follow(self):
        """Unwrap the bead's rotation (call at least every half turn: every exchange round)."""
        self.update(*self.sim.node_pose(), self.sim.step)

    def update(self, positions, frames, step):
        """:meth:`follow` at a pose the run loop hands over (:class:`dnarod.run.sampling.FollowReporter`)."""
        a = self._angle(frames)
        self.turns_acc += ((a - self.last_angle + np.pi) % (2 * np.pi) - np.pi) / (2 * np.pi)
        self.last_angle = a

    def advance(self, n_steps):
        """Advance ``n_steps`` steps through the run loop, following the bead's rotation at the end."""
        n = int(n_steps)
        run_engine(self.sim, self.sim.step + n, [FollowReporter(self, n, origin=self.sim.step)], report_start=False)

    def _set_rung(self, label):
        dn = self.rungs[label]["turns"] - self.rungs[self.init_label]["turns"]
        self.sim.set_clamp_rotation(2.0 * np.pi * dn)

    def _potential(self):
        import openmm

        st = self.sim.context.getState(getEnergy=True)
        return st.getPotentialEnergy().value_in_unit(openmm.unit.kilojoule_per_mole)

    def trial(self, label):
        """``H_label(T X) - H_self(X)`` (kJ/mol) for this replica's configuration carried to rung ``label``; the
        context is left exactly as it was (positions restored bit for bit, the clamp turned back)."""
        import openmm


        sim = self.sim
        sim.invalidate()
        st = sim.context.getState(getPositions=True, getEnergy=True)
        x0 = st.getPositions(asNumpy=True).value_in_unit(openmm.unit.nanometer)
        e0 = st.getPotentialEnergy().value_in_unit(openmm.unit.kilojoule_per_mole)
        c, f = sim.node_pose()
        d = self.rungs[label]["turns"] - self.rungs[self.label]["turns"]
        f2, _ = twist_move(f, np.zeros((len(f), 3)), d)
        try:
            x = np.array(x0)
            x[:3 * len(c)] = particle_positions(c, f2, sim.rs.radius)
            sim.context.setPositions(x)
            self._set_rung(label)
            e1 = self._potential()
        finally:
            sim.context.setPositions(x0)
            self._set_rung(self.label)
            sim.invalidate()
        return e1 - e0

    def move(self, label):
        """Carry this replica's configuration to rung ``label`` (an accepted swap)."""
        sim = self.sim
        self.follow()
        c, f, v, w = sim.node_state()
        d = self.rungs[label]["turns"] - self.rungs[self.label]["turns"]
        f2, w2 = twist_move(f, w, d)
        sim.set_particle_positions(particle_positions(c, f2, sim.rs.radius))
        self.label = int(label)
        self._set_rung(label)
        sim.set_node_velocities(v, w2)
        self.last_angle = self._angle(f2)  # the bead and its rung's reference turned together: the offset stays


def twist_ramp_mismatch(params, angle=0.7):
    """How far the exchange map is from a symmetry of the steps' energy (0 for ``dna-default``).

    The ramp turns node ``k`` about its d3 by ``phi_k``; a step's strains then change by its twist increment and
    by the turn ``phi_k`` of their in-plane parts: ``(Omega1, Omega2)`` and
    ``(Gamma1, Gamma2)`` rotate about d3 (the Cayley vector and the body shear of a step are vectors in node
    ``k``'s frame). Where the energy is not invariant under that turn (unequal bending or shear stiffnesses,
    in-plane strains coupled to twist or extension, an intrinsic bend or shear), the rungs are not images of each
    other under the map and swaps cost energy in proportion to the turn squared, so few swaps between rungs far
    apart are accepted (on ``olson1998``, 40 bp, far fewer at 0.1 turns than on ``dna-default``; the acceptance
    measured on two-rung ladders: docs/misuse.md). The rule stays exact; only the acceptance falls.

    Parameters
    ----------
    params : StepParameters
    angle : float
        The test turn, rad.

    Returns
    -------
    float
        ``max_k (|G^T K_k G - K_k|_max / |K_k|_max + |G xi0_k - xi0_k|_max)`` for ``G`` the turn of the in-plane
        strain pairs by ``angle`` (dimensionless; ``xi0`` in the strains' units, 1/nm and 1).
    """
    c, s_ = math.cos(angle), math.sin(angle)
    G = np.eye(6)
    for i in (0, 3):
        G[i:i + 2, i:i + 2] = [[c, -s_], [s_, c]]
    K = np.asarray(params.stiffness, float)
    x0 = np.asarray(params.intrinsic, float)
    dk = np.abs(np.einsum("ai,kab,bj->kij", G, K, G) - K).max(axis=(1, 2)) / np.abs(K).max(axis=(1, 2))
    dx = np.abs(x0 @ G.T - x0).max(axis=1)
    return float((dk + dx).max())


def ladder_dt(members):
    """The ladder's common time step (ps): the smallest of the rungs' default steps
    (``DEFAULT_OMEGA_DT / omega_max`` of each start pose under its loads), since every replica visits every rung."""
    return min(DEFAULT_OMEGA_DT / omega_max(m["model"], loads=tuple(m["loads"])) for m in members)


class ReplicaGroup:
    """The replicas of one worker process (a dask actor, or a plain object with ``workers=0``).

    Parameters
    ----------
    settings : list of dict
        Tweezers member settings of every rung (:func:`dnarod.workflows.protocols.tweezers.build_member`), in rung
        order.
    rids : list of int
        The replicas of this group; replica ``r`` starts on rung ``r``, from that rung's static pose.
    """

    def __init__(self, settings, rids):
        t0, c0 = time.perf_counter(), time.process_time()
        self.members = [build_member(s) for s in settings]
        self.rungs = [dict(turns=m["turns"], ref_frame=m["ref_frame"], clamp_target=m["clamp_target"])
                      for m in self.members]
        self.dt = ladder_dt(self.members)
        self.replicas = {}
        for r in rids:
            self.replicas[int(r)] = _Replica(r, r, self.members[r], self.rungs, self.dt)
        s0 = self.members[0]["settings"]
        self.sep_nm, self.contact_nm = detector_distances(member_nonbonded(s0), float(s0["temperature_K"]),
                                                          self.members[0]["model"].ds)
        self.cpu = time.process_time() - c0
        self.wall = time.perf_counter() - t0

    def _timed(self, fn):
        c0 = time.process_time()
        try:
            return fn()
        finally:
            self.cpu += time.process_time() - c0

    def info(self):
        """dt (ps), elastic path and detector distances of this group's replicas."""
        sims = [r.sim for r in self.replicas.values()]
        return dict(dt_ps=[s.dt for s in sims], elastic_path=sims[0].rs.elastic, sep_nm=self.sep_nm,
                    contact_nm=self.contact_nm)

    def advance(self, n_steps):
        """Advance every replica ``n_steps`` steps (following the bead's rotation)."""
        def go():
            for r in self.replicas.values():
                r.advance(n_steps)
        return self._timed(go)

    def labels(self):
        return {rid: r.label for rid, r in self.replicas.items()}

    def trials(self, pairs):
        """For each replica on a rung of ``pairs`` (list of (i, i+1)): ``{rid: (label, target, dE kJ/mol)}``."""
        def go():
            want = {}
            for i, j in pairs:
                want[i], want[j] = j, i
            out = {}
            for rid, r in self.replicas.items():
                if r.label in want:
                    out[rid] = (r.label, want[r.label], r.trial(want[r.label]))
            return out
        return self._timed(go)

    def move(self, moves):
        """Apply accepted swaps: ``{rid: new label}``."""
        def go():
            for rid, label in moves.items():
                self.replicas[int(rid)].move(int(label))
        return self._timed(go)

    def sample(self):
        """One sample per replica: ``{label: row}`` (the member's ``observe`` in
        :mod:`dnarod.workflows.protocols.tweezers`)."""
        def go():
            out = {}
            for r in self.replicas.values():
                pos, frm = r.sim.node_pose()
                m = self.members[r.label]
                out[r.label] = observe_tweezers(pos, frm, m["model"], m["turns"] + r.turns_acc, m["clamp_target"],
                                       float(m["settings"]["clamp_k_kJ_mol"]), self.sep_nm, self.contact_nm)
                out[r.label]["replica"] = r.rid
            return out
        return self._timed(go)

    def poses(self):
        """``{label: (positions, frames)}`` of the replicas now on each rung."""
        return {r.label: tuple(np.asarray(a) for a in r.sim.node_pose()) for r in self.replicas.values()}

    def save(self, folder, round_):
        """Checkpoint every replica to ``folder/replica{rid}.r{round}.npz`` (atomic files)."""
        def go():
            for rid, r in self.replicas.items():
                r.follow()
                r.sim.save_checkpoint(Path(folder) / f"replica{rid:03d}.r{round_}.npz",
                                      extra=dict(label=r.label, init_label=r.init_label, last_angle=r.last_angle,
                                                 turns_acc=r.turns_acc, round=round_))
        return self._timed(go)

    def load(self, folder, round_):
        """Restore every replica from the checkpoints of :meth:`save` at ``round_``."""
        def go():
            for rid, r in self.replicas.items():
                meta = r.sim.load_checkpoint(Path(folder) / f"replica{rid:03d}.r{round_}.npz")["extra"]
                if int(meta["round"]) != int(round_) or int(meta["init_label"]) != r.init_label:
                    raise DnarodError(f"{folder}: replica {rid}'s checkpoint is of another ladder; delete the folder "
                                      f"or use a new one")
                r.label, r.last_angle, r.turns_acc = int(meta["label"]), float(meta["last_angle"]), \
                    float(meta["turns_acc"])
        return self._timed(go)

    def cost(self):
        """CPU seconds this group's process spent on it."""
        return dict(cpu_s=self.cpu)


class _Local:
    """A group called in this process with the actor's call form (``group.method(...).result()``)."""

    class _Done:
        def __init__(self, value):
            self.value = value

        def result(self):
            return self.value

    def __init__(self, group):
        self._g = group

    def __getattr__(self, name):
        fn = getattr(self._g, name)
        return lambda *a, **k: self._Done(fn(*a, **k))


def _accept(delta_kT, u):
    return delta_kT <= 0.0 or u < math.exp(-delta_kT)


def check_ladder(turns):
    """Refuse a ladder that cannot exchange: fewer than two distinct turn values."""
    t = sorted(float(x) for x in turns)
    if len(t) < 2:
        raise DnarodError(f"--start exchange needs at least two turn values (a ladder); got {len(t)}")
    if len(set(t)) != len(t):
        raise DnarodError(f"--start exchange: turn values {t} repeat one; give each rung once")
    return t


def run_ladder(settings, outdir, names, workers=0, client=None, exchange_ps=EXCHANGE_PS, seed=1, progress=True,
               checkpoint_wall_s=None):
    """Run one replica-exchange ladder (one force; rungs in increasing turns) and write its rungs as members.

    Parameters
    ----------
    settings : list of dict
        Tweezers member settings per rung (``turns`` increasing; the same force, times and non-bonded terms).
    outdir : path
        The ladder's folder (``exchange.json``, checkpoints); rung ``i`` is written to ``names[i]``.
    names : list of path
        Member folder of each rung.
    workers : int
        Groups of replicas, one dask actor each (0: one group in this process).
    client : distributed.Client, optional
    exchange_ps : float
        Time between exchange attempts, ps.
    seed : int
        Seed of the acceptance draws.

    Returns
    -------
    list of dict
        Each rung's result (:func:`dnarod.workflows.protocols.tweezers.summarize`, with ``exchange_*`` keys).
    """
    if not (isinstance(exchange_ps, (int, float)) and math.isfinite(exchange_ps) and exchange_ps > 0):
        raise DnarodError(f"exchange interval {exchange_ps!r} ps: give a time > 0")
    turns = [float(s["turns"]) for s in settings]
    if turns != sorted(turns) or len(set(turns)) != len(turns):
        raise DnarodError(f"run_ladder: rungs must be in increasing turns, got {turns}")
    outdir = ensure_dir(Path(outdir), "ladder folder")
    R = len(settings)
    key = json.dumps(jsonable(dict(settings=settings, exchange_ps=float(exchange_ps), seed=int(seed))),
                     sort_keys=True)
    done = outdir / RESULT
    if done.exists():
        old = json.loads(done.read_text())
        if old.get("key") == key and all((Path(n) / "protocol_result.json").exists() for n in names):
            return [json.loads((Path(n) / "protocol_result.json").read_text())["result"] for n in names]
    t0 = time.perf_counter()
    # the schedule: every rung shares the model, loads' stiffness and times (the first rung's member says them)
    m0 = build_member(settings[0])
    mismatch = twist_ramp_mismatch(m0["model"].params)
    if mismatch > 1e-9:
        warnings.warn(f"replica exchange on {settings[0].get('forcefield', 'this force field')}: the twist ramp is not "
                      f"a symmetry of its steps (anisotropic or intrinsically bent; mismatch {mismatch:.2g}), so "
                      f"swaps cost energy and few may be accepted; see each pair's acceptance in {RESULT}",
                      RunWarning, stacklevel=2)
    ck = outdir / CHECKPOINT
    resume = None
    if ck.exists():
        resume = json.loads(ck.read_text())
        if resume.get("key") != key:
            raise DnarodError(f"{ck}: a checkpoint of a ladder with other settings; delete {outdir} or use a "
                              f"new folder")
    n_groups = max(1, int(workers)) if client is None or workers else len(client.scheduler_info()["workers"])
    n_groups = min(n_groups, R)
    rid_groups = [list(range(g, R, n_groups)) for g in range(n_groups)]
    stack = contextlib.ExitStack()
    if workers or client is not None:
        c = stack.enter_context(client_for(client, None, n_groups))
        stack.enter_context(c.as_current())  # actor proxies find their client through it
        futs = [c.submit(ReplicaGroup, settings, rids, actor=True, pure=False) for rids in rid_groups]
        groups = [f.result() for f in futs]  # built at once, one per worker
    else:
        groups = [_Local(ReplicaGroup(settings, rids)) for rids in rid_groups]
    with stack:
        infos = [g.info().result() for g in groups]
        dts = sorted({d for i in infos for d in i["dt_ps"]})
        if dts[-1] - dts[0] > 1e-12 * dts[-1]:
            raise DnarodError(f"replica exchange: the rungs' time steps differ ({dts[0]:.6g}-{dts[-1]:.6g} ps); "
                              f"every rung must share the model and the clamp stiffness")
        dt = dts[0]
        steps_ex = max(1, int(round(float(exchange_ps) / dt)))
        ex_ps = steps_ex * dt
        per_sample = max(1, int(round(m0["sample_ps"] / ex_ps)))
        n_eq = int(math.ceil(m0["equilibration_ps"] / ex_ps))
        n_samp = max(4, int(round(m0["production_ps"] / (per_sample * ex_ps))))
        n_rounds = n_eq + n_samp * per_sample
        rng = np.random.default_rng(int(seed))
        samples = {i: {c: [] for c in COLUMNS + ("replica",)} for i in range(R)}
        attempts, accepts = np.zeros(R - 1, int), np.zeros(R - 1, int)
        label_of = list(range(R))  # label_of[rid]
        # round trips: a replica's last end rung (0 or R-1); a trip counts when it reaches the other end
        last_end = [0 if r == 0 else (R - 1 if r == R - 1 else -1) for r in range(R)]
        trips = np.zeros(R, int)
        start_round, cpu_before, wall_before = 0, 0.0, 0.0
        rep_dir = ensure_dir(outdir / "replicas", "replica checkpoints")
        if resume is not None:
            st = resume
            start_round = int(st["round"])
            for g in groups:
                g.load(str(rep_dir), start_round).result()
            rng.bit_generator.state = st["rng"]
            samples = {int(k): v for k, v in st["samples"].items()}
            attempts, accepts = np.array(st["attempts"]), np.array(st["accepts"])
            label_of, last_end, trips = st["label_of"], st["last_end"], np.array(st["trips"])
            cpu_before, wall_before = float(st["cpu_s"]), float(st["wall_s"])
        every = CHECKPOINT_WALL_S if checkpoint_wall_s is None else float(checkpoint_wall_s)
        last_ck = time.perf_counter()
        bar = None
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=n_rounds, initial=start_round, desc=f"exchange {R} rungs", unit="round", leave=False)

        def group_cpu():
            return sum(g.cost().result()["cpu_s"] for g in groups)

        for rnd in range(start_round, n_rounds):
            for f in [g.advance(steps_ex) for g in groups]:
                f.result()
            pairs = [(i, i + 1) for i in range(rnd % 2, R - 1, 2)]
            trial = {}
            for f in [g.trials(pairs) for g in groups]:
                trial.update({int(k): v for k, v in f.result().items()})
            holder = {lab: rid for rid, (lab, _, _) in trial.items()}
            kt = kT(float(m0["settings"]["temperature_K"]))
            moves = {}
            for i, j in pairs:
                a, b = holder[i], holder[j]
                delta = (trial[a][2] + trial[b][2]) / kt
                attempts[i] += 1
                if _accept(delta, rng.random()):
                    accepts[i] += 1
                    moves[a], moves[b] = j, i
            if moves:
                for f in [g.move({r: lab for r, lab in moves.items() if r in rids}) for g, rids in
                          zip(groups, rid_groups)]:
                    f.result()
                for r, lab in moves.items():
                    label_of[r] = lab
                    if lab in (0, R - 1):
                        if last_end[r] not in (-1, lab):
                            trips[r] += 1
                        last_end[r] = lab
            if rnd >= n_eq and (rnd - n_eq + 1) % per_sample == 0:
                i_s = (rnd - n_eq + 1) // per_sample
                rows = {}
                for f in [g.sample() for g in groups]:
                    rows.update({int(k): v for k, v in f.result().items()})
                for lab, row in rows.items():
                    samples[lab]["time_ps"].append((n_eq + i_s * per_sample) * ex_ps)
                    for c in COLUMNS[1:] + ("replica",):
                        samples[lab][c].append(float(row[c]))
            if bar is not None:
                bar.update(1)
            if rnd + 1 < n_rounds and time.perf_counter() - last_ck >= every:
                for f in [g.save(str(rep_dir), rnd + 1) for g in groups]:
                    f.result()
                cpu_now = group_cpu()
                state = dict(key=key, round=rnd + 1, rng=rng.bit_generator.state, samples=samples,
                             attempts=attempts.tolist(), accepts=accepts.tolist(), label_of=label_of,
                             last_end=last_end, trips=trips.tolist(), cpu_s=cpu_before + cpu_now,
                             wall_s=wall_before + time.perf_counter() - t0)
                write_text_atomic(ck, json.dumps(jsonable(state)) + "\n")
                for old in rep_dir.glob("replica*.r*.npz"):
                    if not old.name.endswith(f".r{rnd + 1}.npz"):
                        old.unlink(missing_ok=True)
                last_ck = time.perf_counter()
        if bar is not None:
            bar.close()
        cpu = cpu_before + group_cpu()  # the groups' processes, their set-up included
        wall = wall_before + time.perf_counter() - t0
        poses = {}
        for f in [g.poses() for g in groups]:
            poses.update({int(k): v for k, v in f.result().items()})
        info = infos[0]
    acc = np.where(attempts > 0, accepts / np.maximum(attempts, 1), np.nan)
    results = []
    steps = n_rounds * steps_ex
    for i, (s, name) in enumerate(zip(settings, names)):
        mdir = ensure_dir(Path(name), "member folder")
        m = build_member(s) if i else m0
        smp = {c: np.asarray(samples[i][c], float) for c in COLUMNS}
        cost = dict(wall_s=wall / R, cpu_s=cpu / R, equilibration_wall_s=None, dt_ps=dt, n_steps=steps,
                    n_samples=len(smp["time_ps"]), elastic_path=info["elastic_path"],
                    plectoneme_contact_nm=info["contact_nm"], plectoneme_min_separation_nm=info["sep_nm"],
                    sample_ps=per_sample * ex_ps, ns_per_day=steps * dt * 1e-3 / max(wall / R, 1e-9) * 86400.0)
        m = dict(m, equilibration_ps=n_eq * ex_ps, production_ps=n_samp * per_sample * ex_ps)
        res = summarize(smp, m, cost)
        res["start"] = (f"replica exchange along the turns ({R} rungs, swaps every {ex_ps:.4g} ps; "
                        f"{res['start']} at the start)")
        res.update(exchange_acceptance_down=float(acc[i - 1]) if i > 0 else None,
                   exchange_acceptance_up=float(acc[i]) if i < R - 1 else None,
                   exchange_replicas_visited=int(len(set(samples[i]["replica"]))),
                   exchange_ladder=str(outdir))
        lines = [",".join(COLUMNS)] + [",".join(f"{smp[c][k]:.10g}" for c in COLUMNS)
                                       for k in range(len(smp["time_ps"]))]
        write_text_atomic(mdir / "samples.csv", "\n".join(lines) + "\n")
        save_pose(mdir / FINAL_POSE, *poses[i])
        write_text_atomic(mdir / "protocol_result.json",
                          json.dumps(jsonable({"settings": jsonable(s), "result": res}), indent=1) + "\n")
        results.append(jsonable(res))
    summary = dict(key=key, rungs=turns, exchange_ps=ex_ps, rounds=n_rounds, equilibration_rounds=n_eq,
                   attempts=attempts.tolist(), accepts=accepts.tolist(),
                   acceptance=[None if not np.isfinite(a) else float(a) for a in acc],
                   round_trips=trips.tolist(), round_trips_total=int(trips.sum()), label_of_replica=label_of,
                   wall_s=wall, cpu_s=cpu, groups=n_groups, simulated_ns_per_rung=steps * dt * 1e-3,
                   twist_ramp_mismatch=mismatch)
    write_text_atomic(done, json.dumps(jsonable(summary), indent=1) + "\n")
    ck.unlink(missing_ok=True)
    for old in rep_dir.glob("replica*.npz"):
        old.unlink(missing_ok=True)
    return results


def check_exchange(kind, start, axes, exchange_ps):
    """Refuse what a replica-exchange ladder cannot run (one line each, before anything runs)."""
    if start != "exchange":
        raise DnarodError(f"exchange interval {exchange_ps:g} ps: it applies to --start exchange only")
    if kind not in ("magnetic_tweezers", "torque_turns"):
        raise DnarodError(f"--start exchange runs the rotation-clamp protocols (hat, torque-turns), not {kind}")
    if exchange_ps is not None and not (isinstance(exchange_ps, (int, float)) and math.isfinite(exchange_ps)
                                        and 0 < exchange_ps <= 1e4):
        raise DnarodError(f"exchange interval {exchange_ps!r} ps: give a time > 0 and at most 10 ns")
    check_ladder(np.atleast_1d(axes.get("turns", [])).tolist())


def run_ladders(kind, axes, members, outdir, workers, progress, client, exchange_ps=None):
    """Run each ladder of a protocol (one per value of the axes other than the turns; rungs = the turns) and
    return the curve rows (:func:`dnarod.workflows.protocols.curves.run_protocol` with ``start="exchange"``).

    Start: every rung from the static pose under its loads; past buckling thermal noise takes it to the
    plectonemic state during the ladder's equilibration (as it does an independent member), and the swaps carry
    either state along the ladder.
    """
    proto = {"magnetic_tweezers": hooks.MAGNETIC_TWEEZERS, "torque_turns": hooks.TORQUE_TURNS}[kind]
    others = [k for k in axes if k != "turns"]
    ladders = {}
    for m in members:
        ladders.setdefault(tuple(m.get(k) for k in others), []).append(m)
    rows = []
    outdir = Path(outdir)
    for key, ms in ladders.items():
        ms = sorted(ms, key=lambda m: float(m.get("turns") or 0.0))
        settings = []
        for m in ms:
            s = proto.member_settings(m)
            s["seed"] = hooks.member_seed(s["seed"], "exchange")
            settings.append(s)
        ladder = outdir / "ladders" / (member_name(ms[0], others) if others else "ladder")
        names = [str(outdir / "members" / ("exchange_" + member_name(m, axes))) for m in ms]
        seed = hooks.member_seed(int(ms[0].get("seed") or 1), "exchange", *[str(k) for k in key])
        res = run_ladder(settings, ladder, names, workers=workers, client=client,
                         exchange_ps=EXCHANGE_PS if exchange_ps is None else float(exchange_ps), seed=seed,
                         progress=progress)
        for m, r in zip(ms, res):
            rows.append(dict(r, **{k: m[k] for k in axes}))
    return rows
