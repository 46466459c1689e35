"""The Monte Carlo engine: equilibrium sampling of the exact rod model behind the run layer.

:class:`MCEngine` samples ``exp(-E/kT)`` on SE(3)^n with the energy the OpenMM engine integrates: the exact
SMK elastic energy, the excluded-volume and Debye-Hueckel pairs of :mod:`dnarod.openmm.nonbonded` (same
functional form, exclusions, cutoffs and charge), the loads of :mod:`dnarod.loads` (pulling force, dead torque,
rotation clamp, trap, clamp) and, for magnetic tweezers, the surface and bead walls of
:mod:`dnarod.openmm.walls` (:class:`TweezersWalls`). The moves and their detailed balance are described in
:mod:`dnarod.engines.mc.kernels`.

Time. The engine satisfies the run layer's engine protocol (:mod:`dnarod.run.engine`) with one *step* = one
*sweep* = ``n_nodes`` attempted moves (of the types mixed by ``moves``), and ``dt = 1``: the run layer's
picoseconds count sweeps (``--time 1`` ns = 1000 sweeps, ``--frame-interval 10`` ps = a frame every 10 sweeps).
There are no velocities: :meth:`MCEngine.node_state` reports zeros, :meth:`MCEngine.energies` a kinetic energy
of 0 and a temperature of NaN (a Monte Carlo state has no kinetic temperature).

Amplitudes are tuned towards :data:`TARGET_ACCEPTANCE` during the first ``tune_sweeps`` sweeps only (adapting
them later would break detailed balance); those sweeps belong to the equilibration.
"""
from __future__ import annotations

import json
import math
import numpy as np

from dnarod.core.errors import ParameterError, SimulationError
from dnarod.core.io import atomic_path, read_checkpoint
from dnarod.core.model import model_fingerprint
from dnarod.engines.mc import kernels as kn

#: Acceptance the amplitudes are tuned towards.
TARGET_ACCEPTANCE = 0.4
#: Move types, in the order of :func:`dnarod.engines.mc.kernels.sweep`.
MOVE_TYPES = ("node", "crankshaft", "pivot", "twist")
#: Default mix of move types (fractions of the attempted moves), open and circular chains.
DEFAULT_MOVES = {"node": 0.6, "crankshaft": 0.2, "pivot": 0.05, "twist": 0.15}
#: Open chain without a clamped node: pivots (whole-chain turns included) relax its orientation and shape.
DEFAULT_MOVES_FREE = {"node": 0.3, "crankshaft": 0.3, "pivot": 0.4, "twist": 0.0}
DEFAULT_MOVES_RING = {"node": 0.6, "crankshaft": 0.25, "pivot": 0.0, "twist": 0.15}
#: Nodes per bounding-sphere block of the non-bonded pair search.
BLOCK_SIZE = 16
#: A chord longer than this many times the intrinsic rise is refused when the excluded volume is on (part of the
#: topology criterion, kernels module docstring): at 1.9 times the stretch energy of dna-default is 33 kT.
CHORD_LIMIT = 1.9


class MCEngine:
    """Metropolis Monte Carlo sampler of a :class:`~dnarod.model.RodModel` (run-layer engine ``"mc"``).

    Parameters
    ----------
    model : RodModel
        Start pose, parameters, closure.
    temperature : float
        K (> 0).
    loads : sequence
        :mod:`dnarod.physics.loads` dataclasses, the tweezers :class:`~dnarod.physics.loads.Walls` included.
    nonbonded : NonbondedSettings, bool or None
        Non-bonded terms (``True``: the defaults of :class:`~dnarod.openmm.nonbonded.NonbondedSettings`;
        ``False``/``None``: none).
    seed : int or None
    moves : dict, optional
        Fractions of the move types (:data:`MOVE_TYPES`), normalised.
    amplitudes : dict, optional
        Starting amplitudes: ``node_nm``, ``node_rad``, ``crankshaft_rad``, ``pivot_rad``, ``twist_rad``.
    tune_sweeps : int
        Sweeps during which the amplitudes are tuned (0: never).
    max_segment : int, optional
        Largest segment (nodes) of crankshaft, pivot and twist moves (default: the whole chain).
    duration_ps : float, optional
        Run length (sweeps) over which rotation clamps' ``turns`` are spread.
    """

    name = "mc"
    dt = 1.0
    omega_max = None

    def __init__(self, model, temperature=300.0, loads=(), nonbonded=None, seed=None, moves=None,
                 amplitudes=None, tune_sweeps=200, max_segment=None, duration_ps=None):
        from dnarod.physics.loads import resolve_loads
        from dnarod.core.units import kT

        self.model = model
        T = float(temperature)
        if not (math.isfinite(T) and T > 0):
            raise ParameterError(f"the Monte Carlo engine samples at a temperature > 0 K, got {temperature}")
        self.temperature = T
        self.seed = int(np.random.SeedSequence().entropy % 2**31) if seed is None else int(seed)
        self.loads = tuple(loads or ())
        self.duration_ps = duration_ps
        n = model.n_nodes
        circ = model.closure is not None
        self.pos = np.ascontiguousarray(model.positions, float).copy()
        self.frm = np.ascontiguousarray(model.frames, float).copy()
        self.K = np.ascontiguousarray(model.params.stiffness, float)
        self.xi0 = np.ascontiguousarray(model.params.intrinsic, float)
        self.Qc = np.ascontiguousarray(model.closure.Q if circ else np.eye(3), float)
        self.tc = np.ascontiguousarray(model.closure.t if circ else np.zeros(3), float)
        identity_closure = (not circ) or (np.allclose(self.Qc, np.eye(3), atol=1e-12)
                                          and np.allclose(self.tc, 0.0, atol=1e-12))
        # loads
        rl = resolve_loads(self.loads, model)
        self.resolved = rl
        self.movable = ~rl.clamped
        self.force = np.ascontiguousarray(rl.force, float).copy()
        if np.any(rl.torque[rl.clamped] != 0):
            raise ParameterError("a torque on a clamped node is absorbed by the clamp")
        self.trap_k = np.zeros(n)
        self.trap_c = np.zeros((n, 3))
        for k, kk, c in rl.traps:
            self.trap_k[k] += kk
            self.trap_c[k] = c
        self.rc_k = np.zeros(n)
        self.rc_T = np.zeros((n, 3, 3))
        for rc in rl.rotation_clamps:
            self.rc_k[rc.node] = rc.k
            self.rc_T[rc.node] = rc.target(0.0)
        self.tq_mag = np.linalg.norm(rl.torque, axis=1)
        self.tq_axis = np.zeros((n, 3))
        nz = self.tq_mag > 0
        self.tq_axis[nz] = rl.torque[nz] / self.tq_mag[nz, None]
        self.tq_ref = self.frm.copy()
        self.ext = np.zeros(n, np.int8)
        self.ext[(np.abs(self.force).sum(axis=1) > 0) | (self.trap_k > 0)] = 1
        self.ext[(self.rc_k > 0) | (self.tq_mag > 0)] = 2
        self._work_i = np.zeros(3 * n + 8, np.int64)
        self._work_f = np.zeros((n + 2, 8))
        self.tq_last = np.zeros(n)
        self.tq_phi = np.zeros(n)
        # walls: the tweezers surface (node 0's start z) and bead planes, on the particles of the OpenMM engine's
        # triangle (circumradius sqrt(J3 / m), dnarod.engines.openmm.particles) so that both engines share one energy
        self.walls = rl.walls
        if rl.walls is not None:
            if circ:
                raise ParameterError("tweezers walls act on an open chain (node 0 at the surface, the last node "
                                     "pulled), not on a circular one")
            J = np.asarray(model.inertia, float).reshape(-1, 3)
            m = np.asarray(model.mass, float).reshape(-1)
            if not (np.allclose(J[:, 0], J[:, 1], rtol=1e-6) and np.allclose(J[:, 2], J[:, 0] + J[:, 1], rtol=1e-6)
                    and (m > 0).all()):
                raise ParameterError("tweezers walls act on the particles of a planar equilateral triangle per node "
                                     "(inertia m l^2 (1/2, 1/2, 1)); this model's inertia is not of that form")
            self.radius = np.ascontiguousarray(np.sqrt(J[:, 2] / m), float)
            self.z_surface = float(model.positions[0, 2])
        else:
            self.radius = np.zeros(n)
            self.z_surface = 0.0
        # non-bonded
        if nonbonded is True:
            from dnarod.physics.nonbonded import NonbondedSettings

            nonbonded = NonbondedSettings()
        self.nonbonded = nonbonded if nonbonded and (nonbonded.excluded_volume or nonbonded.electrostatics) else None
        kt = kT(T)
        fp = np.zeros(15)
        ip = np.zeros(10, np.int64)
        fp[kn.F_DS] = model.ds
        fp[kn.F_KT] = kt
        ip[kn.I_N] = n
        ip[kn.I_CIRC] = int(circ)
        ip[kn.I_BS] = BLOCK_SIZE
        ip[kn.I_IDCLOS] = int(identity_closure)
        ip[kn.I_AXI] = int(_axisymmetric(self.K, self.xi0))
        self.numbers = None
        rise = model.ds * float(np.max(self.xi0[:, 5]))
        fp[kn.F_LMAX] = CHORD_LIMIT * rise
        fp[kn.F_DMAX] = np.inf
        if self.nonbonded is not None:
            nb = self.nonbonded.resolve(model.ds, T)
            self.numbers = nb
            ip[kn.I_NB] = 1
            ip[kn.I_NEX] = nb["n_exclude"]
            ip[kn.I_EV] = int(self.nonbonded.excluded_volume)
            fp[kn.F_EPS] = nb["eps"]
            fp[kn.F_S2] = nb["sigma"] ** 2
            fp[kn.F_RCWCA] = nb["rc_wca"]
            fp[kn.F_ADH] = nb["a_dh"]
            fp[kn.F_KAPPA] = nb["kappa"]
            fp[kn.F_RCDH] = nb["rc_dh"]
            fp[kn.F_SHIFT] = nb["a_dh"] * math.exp(-nb["kappa"] * nb["rc_dh"]) / nb["rc_dh"] if nb["rc_dh"] > 0 else 0
            fp[kn.F_CUT] = nb["cutoff"]
            if self.nonbonded.excluded_volume:
                # 4 (s6^2 - s6) + 1 = HARD_CORE_KT  ->  s6 = (1 + sqrt(HARD_CORE_KT)) / 2
                s6 = 0.5 * (1.0 + math.sqrt(kn.HARD_CORE_KT))
                fp[kn.F_RHC] = nb["sigma"] / s6 ** (1.0 / 6.0)
                dmax = 2.0 * (fp[kn.F_RHC] - fp[kn.F_LMAX])
                if not dmax > 0.05 * model.ds:
                    raise ParameterError(
                        f"the excluded-volume diameter {nb['sigma']:g} nm is too small against the chords "
                        f"({fp[kn.F_LMAX]:.3g} nm) for topology-preserving Monte Carlo moves; use a diameter of at least "
                        f"{3.2 * fp[kn.F_LMAX]:.2g} nm")
                fp[kn.F_DMAX] = dmax
        if rl.walls is not None:
            ip[kn.I_WALLS] = 1
            ip[kn.I_SKIP] = int(rl.walls.skip)
            fp[kn.F_WZ0] = self.z_surface
            fp[kn.F_WK] = float(rl.walls.k)
        self.ip, self.fp = ip, fp
        self.topology_preserved = bool(ip[kn.I_EV])
        # moves
        mix = dict(DEFAULT_MOVES_RING if circ else (DEFAULT_MOVES if rl.clamped.any() else DEFAULT_MOVES_FREE))
        if moves:
            unknown = set(moves) - set(MOVE_TYPES)
            if unknown:
                raise ParameterError(f"unknown Monte Carlo move(s) {sorted(unknown)}; choose from {', '.join(MOVE_TYPES)}")
            mix = {k: float(moves.get(k, 0.0)) for k in MOVE_TYPES}
        if circ:
            mix["pivot"] = 0.0
        p = np.array([max(0.0, mix.get(k, 0.0)) for k in MOVE_TYPES])
        if not p.sum() > 0:
            raise ParameterError("the Monte Carlo move mix has no move with a positive fraction")
        self.moves = dict(zip(MOVE_TYPES, (p / p.sum()).tolist()))
        self.p_cum = np.cumsum(p / p.sum())
        self.p_cum[-1] = 1.0
        self.amp = self._default_amplitudes(kt)
        if amplitudes:
            for i, key in enumerate(("node_nm", "node_rad", "crankshaft_rad", "pivot_rad", "twist_rad")):
                if key in amplitudes:
                    self.amp[i] = float(amplitudes[key])
        self._cap_amplitudes()
        ms = n if max_segment is None else max(1, int(max_segment))
        self.lmax = np.array([1, ms, ms, ms], np.int64)
        self.tune_sweeps = int(tune_sweeps)
        self.counts = np.zeros((4, 2), np.int64)
        self.rng = kn.rng_seed(self.seed)
        self.step = 0
        self.n_moves = int(n)
        self._setup_caches()
        if self.topology_preserved:
            _, dmin = kn.nonbonded_total(self.pos, self.ip, self.fp)
            if dmin < fp[kn.F_RHC]:
                raise ParameterError(f"the start pose has two interacting nodes {dmin:.3g} nm apart, inside the "
                                     f"excluded-volume core ({fp[kn.F_RHC]:.3g} nm): an overlapping pose cannot be "
                                     f"sampled with its topology kept")
            e = np.diff(self.pos, axis=0) if not circ else np.roll(self.pos, -1, axis=0) - self.pos
            if np.max(np.linalg.norm(e[: model.n_steps if not circ else n - (0 if identity_closure else 1)], axis=1)) \
                    > fp[kn.F_LMAX]:
                raise ParameterError(f"a step of the start pose is longer than {fp[kn.F_LMAX]:.3g} nm "
                                     f"({CHORD_LIMIT} times the rise): give a pose near equilibrium")
        self.fingerprint = model_fingerprint(model, pose=False)

    # --- set-up -----------------------------------------------------------------------------------------------------
    def _default_amplitudes(self, kt):
        """Amplitudes from the stiffness (a thermal move of one node between fixed neighbours)."""
        K = self.K
        ds = self.model.ds
        c = float(np.max(K[:, 3:, 3:].diagonal(axis1=1, axis2=2)))
        a = float(np.max(K[:, :3, :3].diagonal(axis1=1, axis2=2)))
        s_r = math.sqrt(kt * ds / (2.0 * c))
        s_w = math.sqrt(kt / (2.0 * a / ds + ds * float(np.min(K[:, 3:5, 3:5].diagonal(axis1=1, axis2=2)))))
        return np.array([1.5 * s_r, 2.0 * s_w, 2.0 * s_w, 0.5 * s_w, 3.0 * s_w, 0.0])

    def _cap_amplitudes(self):
        dmax = self.fp[kn.F_DMAX]
        if math.isfinite(dmax):
            self.amp[0] = min(self.amp[0], 0.9 * dmax / math.sqrt(3.0))
        self.amp[1] = min(self.amp[1], 0.5)
        self.amp[2] = min(self.amp[2], 1.0)
        self.amp[3] = min(self.amp[3], 0.5)
        self.amp[4] = min(self.amp[4], 1.0)

    def _setup_caches(self):
        n = self.model.n_nodes
        m = self.model.n_steps
        self.estep = np.empty(m)
        el = kn.elastic_energies(self.pos, self.frm, self.K, self.xi0, self.model.ds, self.model.closure is not None,
                                 self.Qc, self.tc, self.estep)
        if not np.isfinite(el):
            k = int(np.argmax(~np.isfinite(self.estep)))
            raise ParameterError(f"step {k} of the start pose rotates at or beyond the Cayley limit")
        self.enode = np.array([self._node_external(k, self.pos[k], self.frm[k]) for k in range(n)])
        nbk = max(1, -(-n // BLOCK_SIZE))
        self.bc = np.zeros((nbk, 3))
        self.br = np.zeros(nbk)
        kn.update_blocks(self.pos, 0, nbk - 1, BLOCK_SIZE, self.bc, self.br)
        e_nb = kn.nonbonded_total(self.pos, self.ip, self.fp)[0] if self.ip[kn.I_NB] else 0.0
        e_ext = float(self.enode.sum()) + kn.bead_energy(self.pos, self.frm, self.radius, self.ip, self.fp)
        self.running = np.array([el, e_nb, e_ext])

    def _node_external(self, k, r, L):
        return kn.node_external(k, r, L, self.model.n_nodes, self.force, self.trap_k, self.trap_c, self.rc_k,
                                self.rc_T, self.tq_mag, self.tq_axis, self.tq_ref, self.tq_last, self.tq_phi,
                                self.radius, self.ip, self.fp)

    # --- sampling -------------------------------------------------------------------------------------------------------
    def advance(self, n_steps):
        """Run ``n_steps`` sweeps (``n_nodes`` attempted moves each); tunes the amplitudes while
        ``step < tune_sweeps``."""
        n_steps = int(n_steps)
        while n_steps > 0:
            if self.step < self.tune_sweeps:
                chunk = min(n_steps, 10, self.tune_sweeps - self.step)
                before = self.counts.copy()
                self._sweeps(chunk)
                self._tune(self.counts - before)
            else:
                chunk = n_steps
                self._sweeps(chunk)
            n_steps -= chunk

    def _sweeps(self, n):
        rc = kn.sweep(self.pos, self.frm, self.K, self.xi0, self.Qc, self.tc, self.movable, self.ext, self.force, self.trap_k,
                      self.trap_c, self.rc_k, self.rc_T, self.tq_mag, self.tq_axis, self.tq_ref, self.tq_last,
                      self.tq_phi, self.radius, self.ip, self.fp, self.estep, self.enode, self.bc, self.br, self.rng,
                      int(n) * self.n_moves, self.p_cum, self.amp, self.lmax, self.counts, self.running,
                      self._work_i, self._work_f)
        self.step += int(n)
        if rc != 0 or not np.isfinite(self.running).all():
            raise SimulationError(f"Monte Carlo sweep {self.step}: a non-finite energy was accepted (term "
                                  f"{['elastic', 'nonbonded', 'external'][int(np.argmax(~np.isfinite(self.running)))]})",
                                  step=self.step, node=-1, term="elastic")

    def _tune(self, c):
        for t in range(4):
            att, acc = c[t]
            if att < 20:
                continue
            f = math.exp(2.0 * (acc / att - TARGET_ACCEPTANCE))
            idx = (0, 1) if t == 0 else ((2,), (3,), (4,))[t - 1]
            for i in idx:
                self.amp[i] *= f
        self._cap_amplitudes()

    def acceptance(self):
        """Accepted fraction of each move type so far (dict; NaN for a type never tried)."""
        return {name: (float(self.counts[t, 1] / self.counts[t, 0]) if self.counts[t, 0] else float("nan"))
                for t, name in enumerate(MOVE_TYPES)}

    def amplitudes(self):
        """Current move amplitudes (dict: nm or rad)."""
        return dict(zip(("node_nm", "node_rad", "crankshaft_rad", "pivot_rad", "twist_rad"), self.amp[:5].tolist()))

    # --- engine protocol ------------------------------------------------------------------------------------------------
    def node_state(self):
        n = self.model.n_nodes
        return self.pos.copy(), self.frm.copy(), np.zeros((n, 3)), np.zeros((n, 3))

    def energies(self):
        """kJ/mol per term, recomputed from the pose: elastic, nonbonded, external (loads and walls), potential;
        kinetic 0 and temperature NaN (no velocities in Monte Carlo)."""
        el = kn.elastic_energies(self.pos, self.frm, self.K, self.xi0, self.model.ds, self.model.closure is not None,
                                 self.Qc, self.tc, np.empty(self.model.n_steps))
        nb = kn.nonbonded_total(self.pos, self.ip, self.fp)[0] if self.ip[kn.I_NB] else 0.0
        ext = sum(self._node_external(k, self.pos[k], self.frm[k]) for k in range(self.model.n_nodes))
        ext += kn.bead_energy(self.pos, self.frm, self.radius, self.ip, self.fp)
        return dict(elastic=float(el), nonbonded=float(nb), external=float(ext), potential=float(el + nb + ext),
                    kinetic=0.0, temperature=float("nan"))

    def current_model(self):
        return self.model.with_pose(self.pos.copy(), self.frm.copy())

    def update_loads(self, time_ps, duration_ps=None):
        """Turn rotation clamps with ``turns``/``turns_per_ns`` to their angle at ``time_ps`` (sweeps)."""
        from dnarod.physics.loads import clamp_angle

        changed = False
        for rc in self.resolved.rotation_clamps:
            if rc.load.turns or rc.load.turns_per_ns is not None:
                d = duration_ps if duration_ps is not None else self.duration_ps
                self.rc_T[rc.node] = rc.target(clamp_angle(rc.load, time_ps, d))
                changed = True
        if changed:
            self.enode[:] = [self._node_external(k, self.pos[k], self.frm[k]) for k in range(self.model.n_nodes)]
            self.running[2] = float(self.enode.sum()) + kn.bead_energy(self.pos, self.frm, self.radius, self.ip,
                                                                         self.fp)

    def save_checkpoint(self, path, extra=None):
        """Pose, sweep count, random-number state, amplitudes, counters and the torque angles, atomically (npz)."""
        meta = dict(format="dnarod-mc-checkpoint", version=1, step=self.step, n_nodes=self.model.n_nodes,
                    fingerprint=self.fingerprint, temperature=self.temperature, seed=self.seed,
                    moves=self.moves, extra=extra or {})
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, positions=self.pos, frames=self.frm, rng=self.rng, amp=self.amp, counts=self.counts,
                         tq_phi=self.tq_phi, tq_last=self.tq_last, rc_T=self.rc_T, meta=np.array(json.dumps(meta)))

    def load_checkpoint(self, path):
        """Restore a checkpoint of :meth:`save_checkpoint` for this model and temperature; returns its metadata."""
        meta, a = read_checkpoint(path, "dnarod-mc-checkpoint",
                                  ("positions", "frames", "rng", "amp", "counts", "tq_phi", "tq_last", "rc_T"))
        n = self.model.n_nodes
        if meta.get("n_nodes") != n or meta.get("fingerprint") != self.fingerprint or a["positions"].shape != (n, 3):
            raise ParameterError(f"{path}: checkpoint belongs to another model ({meta.get('n_nodes')} nodes, "
                                 f"different parameters); resume with the model it was written for")
        if not math.isclose(float(meta.get("temperature", -1)), self.temperature, rel_tol=1e-12):
            raise ParameterError(f"{path}: checkpoint was written at {meta.get('temperature')} K, this run samples "
                                 f"at {self.temperature} K")
        self.pos[...] = a["positions"]
        self.frm[...] = a["frames"]
        self.rng[...] = a["rng"].astype(np.uint64)
        self.amp[...] = a["amp"]
        self.counts[...] = a["counts"]
        self.tq_phi[...] = a["tq_phi"]
        self.tq_last[...] = a["tq_last"]
        self.rc_T[...] = a["rc_T"]
        self.step = int(meta["step"])
        self._setup_caches()
        return meta


def _axisymmetric(K, xi0, tol=1e-12):
    """True if every step's energy is unchanged when both its frames turn about their own d3 by one angle: the
    stiffness commutes with diag(Rz, Rz) and the intrinsic bend and shear are zero."""
    if np.abs(xi0[:, [0, 1, 3, 4]]).max(initial=0.0) > tol:
        return False
    scale = max(1.0, float(np.abs(K).max()))
    # invariance under R = diag(Rz(phi), Rz(phi)) for all phi: K_xx = K_yy, K_xy = -K_yx, no x/y-z coupling
    idx_xy = [(0, 1), (3, 4), (0, 4), (3, 1)]
    for (i, j) in [(0, 1), (3, 4)]:
        if np.abs(K[:, i, i] - K[:, j, j]).max() > tol * scale:
            return False
    for i in (0, 1, 3, 4):
        for j in (2, 5):
            if np.abs(K[:, i, j]).max() > tol * scale or np.abs(K[:, j, i]).max() > tol * scale:
                return False
    for (i, j) in idx_xy:
        if np.abs(K[:, i, j]).max() > tol * scale or np.abs(K[:, j, i]).max() > tol * scale:
            return False
    # the x-x coupling of the two vectors (K[0, 3] and K[1, 4]) must be equal
    if np.abs(K[:, 0, 3] - K[:, 1, 4]).max() > tol * scale or np.abs(K[:, 3, 0] - K[:, 4, 1]).max() > tol * scale:
        return False
    return True
