"""The Monte Carlo engine: equilibrium sampling of the exact rod model behind the run layer.

:class:`MCEngine` samples ``exp(-E/kT)`` on SE(3)^n with the energy the OpenMM engine integrates: the exact
SMK elastic energy, the excluded-volume and Debye-Hueckel pairs of :mod:`dnarod.physics.nonbonded` (same
functional form, exclusions, cutoffs and charge), the loads of :mod:`dnarod.physics.loads` (pulling force, dead
torque, rotation clamp, trap, clamp) and the magnetic-tweezers walls (:class:`dnarod.physics.loads.Walls`, on the
particles the OpenMM engine carries each node with, :mod:`dnarod.engines.openmm.walls`). The moves, their detailed
balance and the topology they keep are described in :mod:`dnarod.engines.mc.kernels`.

Time. The engine satisfies the run layer's engine protocol (:mod:`dnarod.run.engine`) with one *step* = one
*sweep* = ``n_nodes`` attempted moves (of the types mixed by ``moves``), and ``dt = 1``: the run layer's
picoseconds count sweeps (``--time 1`` ns = 1000 sweeps, ``--frame-interval 10`` ps = a frame every 10 sweeps).
There are no velocities: :meth:`MCEngine.node_state` reports zeros, :meth:`MCEngine.energies` a kinetic energy
of 0 and a temperature of NaN (a Monte Carlo state has no kinetic temperature).

Amplitudes (per move type and segment-length octave) are tuned towards :data:`TARGET_ACCEPTANCE` during the first
``tune_sweeps`` sweeps only (adapting them later would break detailed balance); those sweeps belong to the
equilibration.
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
#: Move types, in the order of :mod:`dnarod.engines.mc.kernels` (``MT_*``).
MOVE_TYPES = ("node", "crankshaft", "pivot", "hinge", "twist", "end_twist", "slide")
#: Default mixes of move types (fractions of the attempted moves). A chain held at one end (the tweezers surface)
#: relaxes its extension and bead position by hinge-pair moves (the far end translates without turning), its shape
#: by crankshafts, its twist by segment and end twists, its total length (stretch) by slides.
DEFAULT_MOVES = {"node": 0.25, "crankshaft": 0.25, "pivot": 0.0, "hinge": 0.2, "twist": 0.1, "end_twist": 0.05,
                 "slide": 0.15}
#: Open chain without a clamped node: pivots (whole-chain turns included) relax its orientation and shape.
DEFAULT_MOVES_FREE = {"node": 0.2, "crankshaft": 0.2, "pivot": 0.2, "hinge": 0.1, "twist": 0.05, "end_twist": 0.05,
                      "slide": 0.2}
DEFAULT_MOVES_RING = {"node": 0.3, "crankshaft": 0.4, "pivot": 0.0, "hinge": 0.0, "twist": 0.15, "end_twist": 0.0,
                      "slide": 0.15}
#: A chord longer than this many times the intrinsic rise is refused when the excluded volume is on (part of the
#: topology criterion, kernels module docstring): at 1.9 times the stretch energy of dna-default is 33 kT.
CHORD_LIMIT = 1.9
#: Attempts of one (type, length octave) after which its amplitude is adjusted during tuning.
TUNE_ATTEMPTS = 20


class MCEngine:
    """Metropolis Monte Carlo sampler of a :class:`~dnarod.core.model.RodModel` (run-layer engine ``"mc"``).

    Parameters
    ----------
    model : RodModel
        Start pose, parameters, closure.
    temperature : float
        K (> 0).
    loads : sequence
        :mod:`dnarod.physics.loads` dataclasses, the tweezers :class:`~dnarod.physics.loads.Walls` included.
    nonbonded : NonbondedSettings, bool or None
        Non-bonded terms (``True``: the defaults of :class:`~dnarod.physics.nonbonded.NonbondedSettings`;
        ``False``/``None``, or both terms off: none).
    seed : int or None
    moves : dict, optional
        Fractions of the move types (:data:`MOVE_TYPES`), normalised.
    amplitudes : dict, optional
        Starting amplitudes: ``node_nm``, ``node_rad``, and ``crankshaft_rad``, ``pivot_rad``, ``hinge_rad``,
        ``twist_rad`` (every segment length).
    tune_sweeps : int
        Sweeps during which the amplitudes are tuned (0: never).
    max_segment : int, optional
        Largest segment (nodes) of crankshaft, pivot, hinge and twist moves (default: the whole chain).
    duration_ps : float, optional
        Run length (sweeps) over which rotation clamps' ``turns`` are spread.
    """

    name = "mc"
    dt = 1.0
    omega_max = None

    def __init__(self, model, temperature=300.0, loads=(), nonbonded=None, seed=None, moves=None,
                 amplitudes=None, tune_sweeps=200, max_segment=None, duration_ps=None):
        from dnarod.core.units import kT
        from dnarod.physics.loads import resolve_loads

        self.model = model
        T = float(temperature)
        if not (math.isfinite(T) and T > 0):
            raise ParameterError(f"the Monte Carlo engine samples at a temperature > 0 K, got {temperature}")
        self.temperature = T
        self.seed = int(np.random.SeedSequence().entropy % 2**31) if seed is None else int(seed)
        self.loads = tuple(loads or ())
        self.duration_ps = duration_ps
        n = model.n_nodes
        if n < 3:
            raise ParameterError(f"the Monte Carlo engine needs a chain of at least 3 nodes, got {n}")
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
        self.movable = np.ascontiguousarray(~rl.clamped)
        self.clamp_prefix = np.concatenate([[0], np.cumsum(rl.clamped)]).astype(np.int64)
        self.force = np.ascontiguousarray(rl.force, float).copy()
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
        self.tq_last = np.zeros(n)
        self.tq_phi = np.zeros(n)
        has_load = (np.abs(self.force).sum(axis=1) > 0) | (self.trap_k > 0) | (self.rc_k > 0) | (self.tq_mag > 0)
        self.ext_nodes = np.flatnonzero(has_load & self.movable).astype(np.int64)
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
        fp = np.zeros(kn.N_F)
        ip = np.zeros(kn.N_I, np.int64)
        fp[kn.F_DS] = model.ds
        fp[kn.F_KT] = kt
        ip[kn.I_N] = n
        ip[kn.I_CIRC] = int(circ)
        ip[kn.I_LEAF] = kn.LEAF
        ip[kn.I_IDCLOS] = int(identity_closure)
        ip[kn.I_AXI] = int(_axisymmetric(self.K, self.xi0))
        self.numbers = None
        rise = model.ds * float(np.max(self.xi0[:, 5]))
        fp[kn.F_LMAX] = CHORD_LIMIT * rise
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
                if not fp[kn.F_RHC] > 1.05 * fp[kn.F_LMAX]:
                    raise ParameterError(
                        f"the excluded-volume diameter {nb['sigma']:g} nm is too small against the chords "
                        f"({fp[kn.F_LMAX]:.3g} nm) for topology-preserving Monte Carlo moves; use a diameter of at "
                        f"least {1.05 * fp[kn.F_LMAX] * s6 ** (1.0 / 6.0):.2g} nm")
        if rl.walls is not None:
            ip[kn.I_WALLS] = 1
            ip[kn.I_SKIP] = int(rl.walls.skip)
            fp[kn.F_WZ0] = self.z_surface
            fp[kn.F_WK] = float(rl.walls.k)
            fp[kn.F_PRAD] = float(self.radius.max())
        self.P, self.tlo, self.thi = kn.tree_ranges(n, kn.LEAF)
        ip[kn.I_P] = self.P
        self.tcen = np.zeros((2 * self.P, 3))
        self.trad = np.zeros(2 * self.P)
        self.ip, self.fp = ip, fp
        self.topology_preserved = bool(ip[kn.I_EV])
        # moves
        mix = dict(DEFAULT_MOVES_RING if circ else (DEFAULT_MOVES if rl.clamped.any() else DEFAULT_MOVES_FREE))
        if moves:
            unknown = set(moves) - set(MOVE_TYPES)
            if unknown:
                raise ParameterError(f"unknown Monte Carlo move(s) {sorted(unknown)}; choose from "
                                     f"{', '.join(MOVE_TYPES)}")
            mix = {k: float(moves.get(k, 0.0)) for k in MOVE_TYPES}
        if circ:
            mix["pivot"] = mix["hinge"] = mix["end_twist"] = 0.0
        p = np.array([max(0.0, mix.get(k, 0.0)) for k in MOVE_TYPES])
        if not p.sum() > 0:
            raise ParameterError("the Monte Carlo move mix has no move with a positive fraction")
        self.moves = dict(zip(MOVE_TYPES, (p / p.sum()).tolist()))
        self.p_cum = np.cumsum(p / p.sum())
        self.p_cum[-1] = 1.0
        self.amp = self._default_amplitudes(kt)
        if amplitudes:
            for key, v in amplitudes.items():
                if key == "node_nm":
                    self.amp[kn.MT_NODE, 0] = float(v)
                elif key == "node_rad":
                    self.amp[kn.MT_NODE, 1] = float(v)
                elif key.endswith("_rad") and key[:-4] in MOVE_TYPES[1:] and key != "slide_rad":
                    self.amp[MOVE_TYPES.index(key[:-4]), :] = float(v)
                elif key == "slide_nm":
                    self.amp[kn.MT_SLIDE, :] = float(v)
                else:
                    raise ParameterError(f"unknown Monte Carlo amplitude {key!r}")
        self._cap_amplitudes()
        ms = n if max_segment is None else max(1, int(max_segment))
        self.lmax = np.array([1, ms, ms, ms, ms, ms, ms], np.int64)
        self.tune_sweeps = int(tune_sweeps)
        self.counts = np.zeros((kn.N_TYPES, kn.N_BINS, 2), np.int64)
        self.tune_counts = np.zeros((kn.N_TYPES, kn.N_BINS, 2), np.int64)
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
        amp = np.zeros((kn.N_TYPES, kn.N_BINS))
        amp[kn.MT_NODE, 0] = 1.5 * s_r
        amp[kn.MT_NODE, 1] = 2.0 * s_w
        amp[kn.MT_CRANK] = 2.0 * s_w
        amp[kn.MT_PIVOT] = 0.5 * s_w
        amp[kn.MT_HINGE] = 1.0 * s_w
        amp[kn.MT_TWIST] = 3.0 * s_w
        amp[kn.MT_ENDTWIST] = 1.0 * s_w
        amp[kn.MT_SLIDE] = 1.0 * s_r
        return amp

    def _cap_amplitudes(self):
        self.amp[kn.MT_NODE, 0] = min(self.amp[kn.MT_NODE, 0], 0.5)
        self.amp[kn.MT_NODE, 1] = min(self.amp[kn.MT_NODE, 1], 1.0)
        np.minimum(self.amp[1:], math.pi, out=self.amp[1:])
        np.minimum(self.amp[kn.MT_SLIDE], 0.5, out=self.amp[kn.MT_SLIDE])

    def _setup_caches(self):
        n = self.model.n_nodes
        m = self.model.n_steps
        self.estep = np.empty(m)
        el = kn.elastic_energies(self.pos, self.frm, self.K, self.xi0, self.model.ds, self.model.closure is not None,
                                 self.Qc, self.tc, self.estep)
        if not np.isfinite(el):
            k = int(np.argmax(~np.isfinite(self.estep)))
            raise ParameterError(f"step {k + 1} of the start pose rotates at or beyond the Cayley limit (steps "
                                 f"numbered from 1)")
        self.enode = np.zeros(n)
        for k in self.ext_nodes:
            self.enode[k] = self._node_loads(k, self.pos[k], self.frm[k])
        self.esurf = np.zeros(n)
        self.ebead = np.zeros(n)
        e_w = kn.wall_energies(self.pos, self.frm, self.radius, self.ip, self.fp, self.esurf, self.ebead) \
            if self.ip[kn.I_WALLS] else 0.0
        kn.tree_build(self.pos, self.P, self.tlo, self.thi, self.tcen, self.trad)
        e_nb = kn.nonbonded_total(self.pos, self.ip, self.fp)[0] if self.ip[kn.I_NB] else 0.0
        self.running = np.array([el, e_nb, float(self.enode.sum()) + e_w])

    def _node_loads(self, k, r, L):
        return kn.node_loads(int(k), r, L, self.force, self.trap_k, self.trap_c, self.rc_k, self.rc_T, self.tq_mag,
                             self.tq_axis, self.tq_ref, self.tq_last, self.tq_phi)

    # --- sampling ----------------------------------------------------------------------------------------------------
    def advance(self, n_steps):
        """Run ``n_steps`` sweeps (``n_nodes`` attempted moves each); tunes the amplitudes while
        ``step < tune_sweeps``."""
        n_steps = int(n_steps)
        while n_steps > 0:
            if self.step < self.tune_sweeps:
                chunk = min(n_steps, 5, self.tune_sweeps - self.step)
                before = self.counts.copy()
                self._sweeps(chunk)
                self.tune_counts += self.counts - before
                self._tune()
            else:
                chunk = n_steps
                self._sweeps(chunk)
            n_steps -= chunk

    def _sweeps(self, n):
        rc = kn.sweep(self.pos, self.frm, self.K, self.xi0, self.Qc, self.tc, self.movable, self.clamp_prefix,
                      self.ext_nodes, self.force, self.trap_k, self.trap_c, self.rc_k, self.rc_T, self.tq_mag,
                      self.tq_axis, self.tq_ref, self.tq_last, self.tq_phi, self.radius, self.ip, self.fp, self.estep,
                      self.enode, self.esurf, self.ebead, self.tlo, self.thi, self.tcen, self.trad, self.rng,
                      int(n) * self.n_moves, self.p_cum, self.amp, self.lmax, self.counts, self.running)
        self.step += int(n)
        if rc != 0 or not np.isfinite(self.running).all():
            bad = int(np.argmax(~np.isfinite(self.running))) if not np.isfinite(self.running).all() else 0
            raise SimulationError(f"Monte Carlo sweep {self.step}: a non-finite energy was accepted (term "
                                  f"{['elastic', 'nonbonded', 'external'][bad]})", step=self.step, node=-1,
                                  term=["elastic", "nonbonded", "external"][bad])

    def _tune(self):
        c = self.tune_counts
        for t in range(kn.N_TYPES):
            for b in range(kn.N_BINS):
                att, acc = c[t, b]
                if att < TUNE_ATTEMPTS:
                    continue
                f = math.exp(2.0 * (acc / att - TARGET_ACCEPTANCE))
                if t == kn.MT_NODE:
                    self.amp[t, :2] *= f
                else:
                    self.amp[t, b] *= f
                c[t, b] = 0
        self._cap_amplitudes()

    def acceptance(self):
        """Accepted fraction of each move type so far (dict; NaN for a type never tried)."""
        tot = self.counts.sum(axis=1)
        return {name: (float(tot[t, 1] / tot[t, 0]) if tot[t, 0] else float("nan"))
                for t, name in enumerate(MOVE_TYPES)}

    def amplitudes(self):
        """Current move amplitudes (dict: ``node_nm``, ``node_rad``, and per move type the amplitude (rad) of each
        segment-length octave that was tried, ``{"1": a, "2-3": b, ...}``)."""
        out = {"node_nm": float(self.amp[0, 0]), "node_rad": float(self.amp[0, 1])}
        tot = self.counts.sum(axis=0)
        for t, name in enumerate(MOVE_TYPES[1:], start=1):
            octaves = {(f"{2 ** b}" if b == 0 else f"{2 ** b}-{2 ** (b + 1) - 1}"): float(self.amp[t, b])
                       for b in range(kn.N_BINS) if self.counts[t, b, 0] > 0}
            out[f"{name}_nm" if name == "slide" else f"{name}_rad"] = octaves
        del tot
        return out

    def potential_local(self, pos, frm):
        """Potential energy (kJ/mol) of a pose under this engine's loads, without the non-bonded terms (which
        depend on the centres only): elastic, loads (dead torques excluded: their energy depends on the path) and
        walls."""
        n = self.model.n_nodes
        el = kn.elastic_energies(pos, frm, self.K, self.xi0, self.model.ds, self.model.closure is not None, self.Qc,
                                 self.tc, np.empty(self.model.n_steps))
        ext = 0.0
        for k in self.ext_nodes:
            if self.tq_mag[k] > 0:
                raise ParameterError("potential_local: dead torques have no potential energy")
            ext += self._node_loads(k, pos[k], frm[k])
        if self.ip[kn.I_WALLS]:
            ext += kn.wall_energies(pos, frm, self.radius, self.ip, self.fp, np.empty(n), np.empty(n))
        return float(el + ext)

    def set_pose(self, pos, frm):
        """Replace the pose (positions (n, 3) nm, frames (n, 3, 3)) and recompute every cache (a replica swap)."""
        self.pos[...] = pos
        self.frm[...] = frm
        self._setup_caches()

    # --- observables -------------------------------------------------------------------------------------------------
    def clamp_torque_z(self):
        """The z torque (kJ/mol) the rotation clamps exert on their nodes, at the current pose (the direct estimator;
        its thermal spread is that of the clamp angle, ``sqrt(k kT)``)."""
        from dnarod.physics.loads import rotation_clamp_load

        return float(sum(rotation_clamp_load(self.frm[rc.node], self.rc_T[rc.node], rc.k)[1][2]
                         for rc in self.resolved.rotation_clamps))

    def tail_torque_z(self, profile=False, weighted=False):
        """Low-variance estimate of :meth:`clamp_torque_z`'s mean (kJ/mol), from an exact identity.

        Turning the tail ``k+1 .. n-1`` of an open chain rigidly about a lab z axis preserves the invariant measure
        and leaves the walls, z forces and the tail's own energy unchanged, so the mean z torque on the tail
        vanishes: the clamps' mean torque equals minus the mean z torque (about node k+1) of step k, of the
        non-bonded pairs across step k and of the tail's other loads, for every k whose tail holds every rotation
        clamp and no clamped node. Each sample here is an average of those per-step values: in a stretched chain
        it reads the twist moment of every step, whose average spreads by about ``kT sqrt(C / L)`` instead of
        ``sqrt(k kT)``; non-bonded torques across plectonemes and bending moments are included exactly.

        Weights. The identity holds for each step k also after multiplying by any function ``w(X)`` that the turn of
        the tail leaves unchanged (integrate ``d/dalpha (w exp(-U/kT))`` over the invariant measure), and every
        function of the nodes' heights alone is unchanged by every such turn. So the average over the steps may be
        weighted by ``w_k(z)`` normalised over k without bias. ``weighted=True`` keeps the steps that no
        interacting pair straddles at a height difference below the contact range (the WCA cut-off
        ``2^(1/6) sigma``, or the non-bonded cut-off without excluded volume): this drops the steps inside a
        plectoneme, whose bending moments and contact forces swing by tens of pN nm from sample to sample, and
        keeps every step of a stretched chain (there it equals the plain average). If no step qualifies, the plain
        average is returned. It lowers the spread per sample, not the slow part of the error: where the kept steps
        are few (a short chain mostly in a plectoneme) or the run is short against the plectoneme's relaxation,
        the plain average's error can be as small or smaller (``docs/mc.md``), hence not the default.

        Parameters
        ----------
        profile : bool
            Return the per-step values (n - 1,) (NaN where the identity does not apply) instead of their mean.
        weighted : bool
            Weight the steps by the height criterion above (default False: the plain average over the steps).

        Returns
        -------
        float or ndarray
            kJ/mol (divide by ``dnarod.core.units.PN`` for pN nm).

        Raises
        ------
        ParameterError
            For a ring, or without a rotation clamp.
        """
        n = self.model.n_nodes
        if self.model.closure is not None or not self.resolved.rotation_clamps:
            raise ParameterError("the tail-torque estimator needs an open chain with a rotation clamp")
        first_rc = min(rc.node for rc in self.resolved.rotation_clamps)
        clamped = np.flatnonzero(self.resolved.clamped)
        k_first = int(clamped.max()) if clamped.size else 0
        if k_first >= first_rc:
            raise ParameterError("the tail-torque estimator needs the rotation clamps beyond every clamped node")
        out = np.empty(n - 1)
        kn.tail_torque_profile(self.pos, self.frm, self.K, self.xi0, self.model.ds, self.force, self.trap_k,
                               self.trap_c, self.tq_mag, self.tq_axis, self.tlo, self.thi, self.tcen, self.trad,
                               self.ip, self.fp, k_first, out)
        out[first_rc:] = np.nan
        if profile:
            return out
        if weighted and self.ip[kn.I_NB]:
            w = self.tail_torque_weights()
            ok = np.isfinite(out) & (w > 0)
            if ok.any():
                return float(np.mean(out[ok]))
        return float(np.nanmean(out))

    def tail_torque_weights(self):
        """Weights (n - 1,) of the per-step tail-torque values in :meth:`tail_torque_z` (1 for a step no interacting
        pair straddles at a height difference below the contact range, else 0): functions of the heights only.
        All ones without non-bonded terms."""
        w = np.ones(self.model.n_nodes - 1)
        if self.ip[kn.I_NB]:
            r0 = self.fp[kn.F_RCWCA] if self.ip[kn.I_EV] else self.fp[kn.F_CUT]
            kn.height_clear_steps(np.ascontiguousarray(self.pos[:, 2]), int(self.ip[kn.I_NEX]), float(r0), w)
        return w

    # --- engine protocol ---------------------------------------------------------------------------------------------
    def node_state(self, *, copy: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(positions (n, 3) nm, frames (n, 3, 3), zeros, zeros)``: Monte Carlo has no velocities (copies always)."""
        n = self.model.n_nodes
        return self.pos.copy(), self.frm.copy(), np.zeros((n, 3)), np.zeros((n, 3))

    def node_pose(self):
        """Positions (n, 3) nm and frames (n, 3, 3) (copies)."""
        return self.pos.copy(), self.frm.copy()

    def energies(self):
        """kJ/mol per term, recomputed from the pose: elastic, nonbonded, external (loads and walls), potential;
        kinetic 0 and temperature NaN (no velocities in Monte Carlo)."""
        el = kn.elastic_energies(self.pos, self.frm, self.K, self.xi0, self.model.ds, self.model.closure is not None,
                                 self.Qc, self.tc, np.empty(self.model.n_steps))
        nb = kn.nonbonded_total(self.pos, self.ip, self.fp)[0] if self.ip[kn.I_NB] else 0.0
        ext = sum(self._node_loads(k, self.pos[k], self.frm[k]) for k in self.ext_nodes)
        if self.ip[kn.I_WALLS]:
            n = self.model.n_nodes
            ext += kn.wall_energies(self.pos, self.frm, self.radius, self.ip, self.fp, np.empty(n), np.empty(n))
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
            for k in self.ext_nodes:
                self.enode[k] = self._node_loads(k, self.pos[k], self.frm[k])
            self.running[2] = float(self.enode.sum()) + float(self.esurf.sum() + self.ebead.sum())

    def save_checkpoint(self, path, extra=None):
        """Pose, sweep count, random-number state, amplitudes, counters and the torque angles, atomically (npz)."""
        meta = dict(format="dnarod-mc-checkpoint", version=2, step=self.step, n_nodes=self.model.n_nodes,
                    fingerprint=self.fingerprint, temperature=self.temperature, seed=self.seed,
                    moves=self.moves, extra=extra or {})
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, positions=self.pos, frames=self.frm, rng=self.rng, amp=self.amp, counts=self.counts,
                         tune_counts=self.tune_counts, tq_phi=self.tq_phi, tq_last=self.tq_last, rc_T=self.rc_T,
                         meta=np.array(json.dumps(meta)))

    def load_checkpoint(self, path):
        """Restore a checkpoint of :meth:`save_checkpoint` for this model and temperature; returns its metadata."""
        keys = ("positions", "frames", "rng", "amp", "counts", "tune_counts", "tq_phi", "tq_last", "rc_T")
        meta, a = read_checkpoint(path, "dnarod-mc-checkpoint", keys)
        n = self.model.n_nodes
        if meta.get("n_nodes") != n or meta.get("fingerprint") != self.fingerprint or a["positions"].shape != (n, 3):
            raise ParameterError(f"{path}: checkpoint belongs to another model ({meta.get('n_nodes')} nodes, "
                                 f"different parameters); resume with the model it was written for")
        if not math.isclose(float(meta.get("temperature", -1)), self.temperature, rel_tol=1e-12):
            raise ParameterError(f"{path}: checkpoint was written at {meta.get('temperature')} K, this run samples "
                                 f"at {self.temperature} K")
        if a["amp"].shape != self.amp.shape or a["counts"].shape != self.counts.shape:
            raise ParameterError(f"{path}: checkpoint of another version of the Monte Carlo engine; start a new run")
        self.pos[...] = a["positions"]
        self.frm[...] = a["frames"]
        self.rng[...] = a["rng"].astype(np.uint64)
        self.amp[...] = a["amp"]
        self.counts[...] = a["counts"]
        self.tune_counts[...] = a["tune_counts"]
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
    for (i, j) in [(0, 1), (3, 4)]:
        if np.abs(K[:, i, i] - K[:, j, j]).max() > tol * scale:
            return False
    for i in (0, 1, 3, 4):
        for j in (2, 5):
            if np.abs(K[:, i, j]).max() > tol * scale or np.abs(K[:, j, i]).max() > tol * scale:
                return False
    for (i, j) in [(0, 1), (3, 4), (0, 4), (3, 1)]:
        if np.abs(K[:, i, j]).max() > tol * scale or np.abs(K[:, j, i]).max() > tol * scale:
            return False
    # the x-x coupling of the two vectors (K[0, 3] and K[1, 4]) must be equal
    if np.abs(K[:, 0, 3] - K[:, 1, 4]).max() > tol * scale or np.abs(K[:, 3, 0] - K[:, 4, 1]).max() > tol * scale:
        return False
    return True
