"""Simulations of a rod model with OpenMM: minimisation, NVE, Langevin, reporters, checkpoints.

Conventions shared with the Lax-form integrator (so the two engines can be compared):

* node k is a rigid body of mass ``m_k`` and principal inertia ``J_k = m_k l_k^2 (1/2, 1/2, 1)``
  about (d1, d2, d3) (the model's ``inertia``; see :mod:`dnarod.openmm.particles`);
* node velocities are the centre velocity ``v`` (lab, nm/ps) and the angular velocity
  ``omega`` in the **body frame** (rad/ps, components on d1, d2, d3), as in the ``.dtraj``
  format; thermal initial velocities draw ``v_a ~ N(0, kT/m)`` and ``omega_a ~ N(0, kT/J_a)``;
* velocities are on-step: OpenMM's leapfrog half-step velocities are completed by the half
  kick of the current loads when read (:meth:`RodSimulation.node_state`) and offset by it when
  set (:meth:`RodSimulation.set_node_velocities`), so the ``.dtraj`` velocities are those of
  velocity Verlet / the Lax-form splitting at the frame's time;
* the kinetic temperature in ``energies.csv`` is OpenMM's (half-step velocities), counting 6
  degrees of freedom per free node; LangevinMiddle reads it high by O((omega dt)^2): +2.4% at
  the default omega dt = 0.4 and +1.2% at 0.2 (on-step velocities read -1.5% and -0.4%), while
  the configurations are sampled correctly (strain variances within 0.5% of the exact density).

Outputs of :meth:`RodSimulation.run` in ``outdir``: ``trajectory.dtraj`` (frames with
velocities), ``energies.csv``, ``checkpoint.npz`` (every ``checkpoint_interval`` steps) and
``final_model.npz``. ``resume=True`` continues from the checkpoint, truncating the trajectory
and the CSV to the checkpointed step, so no frame is lost or duplicated.
"""
from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import time
from pathlib import Path

import numpy as np
import openmm

from ..errors import DnarodError, ParameterError, SimulationError
from ..io_utils import atomic_path
from ..thermal import kT as kT_of, kinetic_temperature
from ..trajectory import TrajectoryWriter
from .forces import GROUPS, loads_kernel
from .particles import (node_poses, node_velocities, particle_forces_to_loads, particle_positions,
                        particle_velocities)
from .platforms import choose_platform
from .system import build_system

#: Default time step: omega_max * dt (design A4 recommends <= 0.25-0.5; leapfrog is unstable at 2).
DEFAULT_OMEGA_DT = 0.4
#: Largest accepted omega_max * dt (90% of the leapfrog limit 2).
MAX_OMEGA_DT = 1.8
CSV_COLUMNS = ["step", "time_ps", "potential_kJmol", "kinetic_kJmol", "total_kJmol", "temperature_K",
               "elastic_kJmol", "nonbonded_kJmol", "external_kJmol"]


def model_fingerprint(model):
    """SHA-256 of everything that defines the mechanical system (not the pose)."""
    h = hashlib.sha256()
    for a in (model.params.stiffness, model.params.intrinsic, model.mass, model.inertia, np.array([model.ds])):
        h.update(np.ascontiguousarray(a, float).tobytes())
    if model.closure is not None:
        h.update(model.closure.Q.tobytes())
        h.update(model.closure.t.tobytes())
    h.update(str(model.n_nodes).encode())
    return h.hexdigest()


def _window_omega_max(pos, frm, K, xi0, ds, mass, inertia, Q, t, circ, h=1e-6):
    """Largest frequency of one (sub)chain from its dense mass-weighted Hessian."""
    from ..rotations import cayley

    n = pos.shape[0]
    sm = 1 / np.sqrt(mass)
    Jis = np.einsum("kab,kb,kcb->kac", frm, 1 / np.sqrt(inertia), frm)  # lab L J^-1/2 L^T
    H = np.empty((6 * n, 6 * n))
    F = np.zeros((n, 3))
    tau = np.zeros((n, 3))
    for col in range(6 * n):
        kind, node, a = col // (3 * n), (col % (3 * n)) // 3, col % 3  # same order as the rows
        res = []
        for sgn in (1.0, -1.0):
            p2, f2 = pos.copy(), frm.copy()
            if kind == 0:
                p2[node, a] += sgn * h * sm[node]
            else:
                f2[node] = cayley(sgn * h * Jis[node][:, a]) @ frm[node]
            F[:] = 0.0
            tau[:] = 0.0
            loads_kernel(p2, f2, K, xi0, ds, Q, t, circ, F, tau)
            res.append(np.concatenate([F * sm[:, None], np.einsum("kab,kb->ka", Jis, tau)]).reshape(-1))
        H[:, col] = -(res[0] - res[1]) / (2 * h)
    return float(np.sqrt(max(np.linalg.eigvalsh(0.5 * (H + H.T)).max(), 0.0)))


def omega_max(model, positions=None, frames=None, window=32, n_windows=8):
    """Largest normal-mode frequency of the elastic energy, rad/ps (design A4).

    The eigenvalues of the mass-weighted Hessian ``M^{-1/2} H M^{-1/2}`` in node coordinates
    (lab translations, lab rotation vectors), with the Hessian from central differences of the
    analytic loads (numba kernel). The fastest modes are zone-boundary modes, local on the
    scale of a few steps, so chains longer than ``window`` nodes are evaluated on open
    windows: both ends, the windows centred on the ``n_windows`` stiffest steps (largest
    eigenvalue of K) and evenly spaced ones; the result is the maximum. A free window
    underestimates the infinite chain's band edge by about 0.3% at 20 nodes (design A4).

    Parameters
    ----------
    model : RodModel
    positions, frames : ndarray, optional
        Pose (default: the model's).
    window : int
        Window length, nodes.
    n_windows : int
        Stiffest-step and evenly spaced windows (each).

    Returns
    -------
    float
    """
    pos = np.ascontiguousarray(model.positions if positions is None else positions, float)
    frm = np.ascontiguousarray(model.frames if frames is None else frames, float)
    n = pos.shape[0]
    K = np.ascontiguousarray(model.params.stiffness, float)
    xi0 = np.ascontiguousarray(model.params.intrinsic, float)
    if n <= window:
        circ = model.closure is not None
        Q = model.closure.Q if circ else np.eye(3)
        t = model.closure.t if circ else np.zeros(3)
        return _window_omega_max(pos, frm, K, xi0, model.ds, model.mass, model.inertia, Q, t, circ)
    n_steps = K.shape[0]
    stiff = np.linalg.eigvalsh(K).max(axis=1)
    centres = set(np.argsort(stiff)[::-1][:n_windows].tolist())
    centres |= set(np.linspace(0, n_steps - 1, n_windows).astype(int).tolist())
    starts = {0, n - window} | {int(min(max(c - window // 2, 0), n - window)) for c in centres}
    best = 0.0
    Om, Ga = model.strains(pos, frm)
    xi = np.round(np.concatenate([Om, Ga], axis=1), 9)
    seen = set()
    for s0 in sorted(starts):
        sl = slice(s0, s0 + window)
        # identical windows (e.g. a uniform rod at its intrinsic shape) have identical spectra
        key = (K[s0:s0 + window - 1].tobytes(), xi0[s0:s0 + window - 1].tobytes(), xi[s0:s0 + window - 1].tobytes(),
               model.mass[sl].tobytes(), model.inertia[sl].tobytes())
        if key in seen:
            continue
        seen.add(key)
        best = max(best, _window_omega_max(pos[sl], frm[sl], K[s0:s0 + window - 1], xi0[s0:s0 + window - 1],
                                           model.ds, model.mass[sl], model.inertia[sl], np.eye(3), np.zeros(3),
                                           False))
    return best


class RodSimulation:
    """An OpenMM simulation of a :class:`~dnarod.model.RodModel`.

    Parameters
    ----------
    model : RodModel
        Starting pose (velocities are thermal at ``temperature``, or zero for NVE with
        ``temperature=0``).
    integrator : {"langevin", "verlet"}
        ``LangevinMiddleIntegrator`` at ``temperature`` or ``VerletIntegrator`` (NVE).
    temperature : float
        K.
    dt : float or None
        ps; default ``DEFAULT_OMEGA_DT / omega_max``. Values above ``MAX_OMEGA_DT / omega_max``
        raise :class:`~dnarod.errors.ParameterError`.
    friction : float
        1/ps (Langevin).
    platform : str or None
        OpenMM platform name ("CPU", "Reference", "CUDA", "OpenCL", "HIP"); ``None`` for the
        automatic choice of :func:`dnarod.openmm.platforms.choose_platform` (GPU, else the CPU
        fast path); the choice and its reason are in ``platform_name``, ``platform_reason``.
    elastic : {"auto", "fast", "portable"}
    nonbonded : bool or NonbondedSettings
    loads : sequence
        External loads (:mod:`dnarod.openmm.loads`).
    seed : int or None
        Seed of initial velocities and of the Langevin noise.
    threads : int or None
        CPU platform threads.
    precision : {"single", "mixed", "double"} or None
        GPU platforms' precision (default mixed).
    constraint_tolerance : float
    initial_velocities : tuple (v (n,3) nm/ps lab, omega (n,3) rad/ps body) or None
    """

    def __init__(self, model, integrator="langevin", temperature=300.0, dt=None, friction=1.0, platform=None,
                 elastic="auto", nonbonded=True, loads=(), seed=None, threads=None, constraint_tolerance=1e-8,
                 initial_velocities=None, precision=None):
        self.model = model
        self.temperature = float(temperature)
        if not (np.isfinite(self.temperature) and self.temperature >= 0):
            raise ParameterError(f"temperature must be >= 0 K, got {temperature}")
        if integrator not in ("langevin", "verlet"):
            raise ParameterError(f"integrator must be 'langevin' or 'verlet', got {integrator!r}")
        self.integrator_name = integrator
        plat, props, self.platform_reason = choose_platform(platform, model.n_nodes, elastic, threads, precision)
        self.platform_name = platform = plat.getName()
        self.omega_max = omega_max(model)
        limit = MAX_OMEGA_DT / self.omega_max
        if dt is None:
            dt = DEFAULT_OMEGA_DT / self.omega_max
        dt = float(dt)
        if not (np.isfinite(dt) and dt > 0):
            raise ParameterError(f"dt must be a positive time in ps, got {dt}")
        if dt > limit:
            raise ParameterError(f"dt = {dt:.4g} ps is above the stability limit {limit:.4g} ps of this model "
                                 f"(fastest mode omega_max = {self.omega_max:.4g} rad/ps, limit 1.8/omega_max); "
                                 f"use dt <= {DEFAULT_OMEGA_DT / self.omega_max:.3g} ps (the default)")
        self.dt = dt
        self.friction = float(friction)
        self.seed = int(np.random.SeedSequence().entropy % 2**31) if seed is None else int(seed)
        self.rs = build_system(model, platform, elastic, nonbonded, loads, self.temperature)
        if integrator == "langevin":
            integ = openmm.LangevinMiddleIntegrator(self.temperature, self.friction, dt)
            integ.setRandomNumberSeed(self.seed)
        else:
            integ = openmm.VerletIntegrator(dt)
        integ.setConstraintTolerance(constraint_tolerance)
        self.integrator = integ
        t0 = time.perf_counter()
        self.context = openmm.Context(self.rs.system, integ, plat, props)
        self.context.setPositions(particle_positions(model.positions, model.frames, self.rs.radius))
        self.context_time = time.perf_counter() - t0
        self._state_cache = None
        if initial_velocities is not None:
            self.set_node_velocities(*initial_velocities)
        elif self.temperature > 0:
            self.thermalize(self.temperature, self.seed)
        self.step = 0
        self.fingerprint = model_fingerprint(model)

    # --- node state -------------------------------------------------------------------
    def set_node_velocities(self, velocities, angular_velocities):
        """Set on-step node velocities at the current positions.

        Parameters
        ----------
        velocities : ndarray, shape (n_nodes, 3)
            Centre velocities, lab frame, nm/ps.
        angular_velocities : ndarray, shape (n_nodes, 3)
            Angular velocities in the body frame (on d1, d2, d3), rad/ps.

        OpenMM stores leapfrog half-step velocities, so the half kick of the current loads is
        taken off (the inverse of :meth:`node_state`); the state then reports exactly these
        velocities at the current step.
        """
        n = self.model.n_nodes
        for name, a in (("velocities", velocities), ("angular_velocities", angular_velocities)):
            if np.shape(a) != (n, 3):
                raise ParameterError(f"{name} must have shape ({n}, 3), got {np.shape(a)}")
        self._state_cache = None
        st = self.context.getState(getPositions=True, getForces=True)
        p = st.getPositions(asNumpy=True)._value
        _, frames = node_poses(p)
        F, tau = particle_forces_to_loads(p, st.getForces(asNumpy=True)._value)
        h = 0.5 * self.dt
        v = np.asarray(velocities, float) - h * F / self.model.mass[:, None]
        w = np.asarray(angular_velocities, float) - h * np.einsum("kab,ka->kb", frames, tau) / self.model.inertia
        u = particle_velocities(frames, self.rs.radius, v, w)
        for k in self.rs.clamped:
            u[3 * k:3 * k + 3] = 0.0
        self.context.setVelocities(u)

    def thermalize(self, temperature, seed=None):
        """Draw Maxwell-Boltzmann node velocities (6 degrees of freedom per free node)."""
        rng = np.random.default_rng(seed)
        kt = kT_of(temperature)
        n = self.model.n_nodes
        v = rng.normal(size=(n, 3)) * np.sqrt(kt / self.model.mass)[:, None]
        w = rng.normal(size=(n, 3)) * np.sqrt(kt / self.model.inertia)
        self.set_node_velocities(v, w)

    def node_pose(self, state=None):
        """``(centres (n,3) nm, frames (n,3,3))`` of the current (or given) state."""
        state = state or self._full_state()
        return node_poses(state.getPositions(asNumpy=True)._value)

    def node_state(self, state=None, on_step=True):
        """``(centres, frames, velocities (lab, nm/ps), angular velocities (body, rad/ps))``.

        OpenMM's Verlet and LangevinMiddle integrators store leapfrog velocities, half a step
        behind the positions. With ``on_step=True`` (default; used for the trajectory) they are
        completed to the positions' time by the half kick of velocity Verlet/RATTLE on each rigid
        node, ``v += dt/2 F/m`` and ``omega += dt/2 J^-1 L^T tau`` (design A4 b), which is what
        the Lax-form engine reports; ``on_step=False`` gives OpenMM's raw half-step velocities.
        """
        state = state or self._full_state()
        p = state.getPositions(asNumpy=True)._value
        u = state.getVelocities(asNumpy=True)._value
        c, f = node_poses(p)
        v, w = node_velocities(p, u)
        if on_step:
            F, tau = particle_forces_to_loads(p, state.getForces(asNumpy=True)._value)
            free = np.ones(self.model.n_nodes)
            free[self.rs.clamped] = 0.0
            h = 0.5 * self.dt * free[:, None]
            v = v + h * F / self.model.mass[:, None]
            w = w + h * np.einsum("kab,ka->kb", f, tau) / self.model.inertia
        return c, f, v, w

    def _full_state(self):
        """State with positions, velocities, parameters and energy; cached until the context changes."""
        if self._state_cache is None:
            self._state_cache = self.context.getState(getPositions=True, getVelocities=True, getParameters=True,
                                                      getEnergy=True, getForces=True)
            self._terms_cache = self._callback_terms()
        return self._state_cache

    def _callback_terms(self):
        """Per-term energies recorded by the fast-path callbacks during the last evaluation, or None."""
        el = self.rs.elastic_callback
        nb = self.rs.nonbonded_callback
        if el is None:
            return None
        return dict(elastic=el.last_energy, nonbonded=sum(nb.last) if nb is not None else 0.0)

    def invalidate(self):
        """Forget the cached state (call after changing the context directly)."""
        self._state_cache = None

    def energies(self):
        """Dict of potential energies per term (kJ/mol), plus ``potential``, ``kinetic``, ``temperature``.

        With the fast path the per-term split comes from the callbacks' own evaluation at this
        state (no extra force evaluations); otherwise each force group is evaluated.
        """
        st = self._full_state()
        out = {}
        pot = st.getPotentialEnergy()._value
        if self._terms_cache is not None:
            out.update(self._terms_cache)
            out["external"] = pot - out["elastic"] - out["nonbonded"]
        else:
            for name, g in GROUPS.items():
                out[name] = self.context.getState(getEnergy=True, groups={g}).getPotentialEnergy()._value
        out["potential"] = pot
        out["kinetic"] = st.getKineticEnergy()._value
        dof = self.rs.degrees_of_freedom
        out["temperature"] = float(kinetic_temperature(out["kinetic"], dof))
        return out

    def current_model(self):
        """The model with the current pose."""
        c, f = self.node_pose()
        return self.model.with_pose(c, f)

    def minimize(self, tolerance=1.0, max_iterations=0, max_rounds=20):
        """Local energy minimisation (tolerance: RMS force, kJ/mol/nm); returns the final potential energy.

        OpenMM's L-BFGS with constraints can stop early on this stiff, constrained system, so it
        is restarted until the energy stops decreasing (at most ``max_rounds`` rounds).
        """
        self._state_cache = None
        E = self.context.getState(getEnergy=True).getPotentialEnergy()._value
        for _ in range(max_rounds):
            openmm.LocalEnergyMinimizer.minimize(self.context, tolerance, max_iterations)
            E_new = self.context.getState(getEnergy=True).getPotentialEnergy()._value
            if not E_new < E - 1e-9 * max(1.0, abs(E)):
                return E_new
            E = E_new
        return E

    def set_clamp_rotation(self, angle, index=0):
        """Turn rotation clamp ``index`` by ``angle`` rad about its axis (magnetic tweezers)."""
        from .loads import set_clamp_rotation

        set_clamp_rotation(self.context, self.rs.load_info["rotation_clamps"][index], angle)
        self._state_cache = None

    # --- checks -----------------------------------------------------------------------
    def _healthy(self, st):
        E = st.getPotentialEnergy()._value
        K = st.getKineticEnergy()._value
        p = st.getPositions(asNumpy=True)._value
        limit = 1e4 * kT_of(max(self.temperature, 300.0)) * self.model.n_nodes
        return np.isfinite(E) and np.isfinite(K) and np.isfinite(p).all() and abs(E) + K < limit

    def _diagnose(self, step):
        """Build the SimulationError for a bad current state: term, node, energies."""
        terms = {}
        for name, g in GROUPS.items():
            try:
                terms[name] = self.context.getState(getEnergy=True, groups={g}).getPotentialEnergy()._value
            except Exception:  # noqa: BLE001 - a NaN can make OpenMM raise
                terms[name] = float("nan")
        el, nb = self.rs.elastic_callback, self.rs.nonbonded_callback
        if el is not None and nb is not None and el.nonbonded is nb:  # fused fast path: split by the callbacks
            terms["elastic"], terms["nonbonded"] = el.last_energy, sum(nb.last)
        bad = [k for k, v in terms.items() if not np.isfinite(v)]
        term = bad[0] if bad else max(terms, key=lambda k: abs(terms[k]))
        p = self.context.getState(getPositions=True).getPositions(asNumpy=True)._value.reshape(-1, 3, 3)
        nonfinite = np.argwhere(~np.isfinite(p).all(axis=(1, 2)))
        if len(nonfinite):
            node = int(nonfinite[0, 0])
        else:
            c, f = node_poses(p.reshape(-1, 3))
            F = np.zeros_like(c)
            tau = np.zeros_like(c)
            m = self.model
            Q = m.closure.Q if m.closure is not None else np.eye(3)
            t = m.closure.t if m.closure is not None else np.zeros(3)
            loads_kernel(c, f, m.params.stiffness, m.params.intrinsic, m.ds, Q, t, m.closure is not None, F, tau)
            mag = np.linalg.norm(F, axis=1) + np.linalg.norm(tau, axis=1)
            mag[~np.isfinite(mag)] = np.inf
            node = int(np.argmax(mag))
        txt = ", ".join(f"{k} {v:.4g}" for k, v in terms.items())
        return SimulationError(f"simulation blew up at step {step}: node {node}, term '{term}' "
                               f"(energies kJ/mol: {txt}); reduce dt or check the loads/model",
                               step=step, node=node, term=term)

    def advance(self, n_steps):
        """Integrate ``n_steps`` steps, checking for NaN/blow-up; on failure, locate the first bad step.

        Raises
        ------
        SimulationError
            Naming the step, node and energy term; the context is left at the first bad step.
        """
        good = self._full_state()
        self.integrator.step(int(n_steps))
        self._state_cache = None
        st = self._full_state()
        if self._healthy(st):
            self.step += int(n_steps)
            return
        self.context.setState(good)
        for i in range(int(n_steps)):
            self.integrator.step(1)
            st = self.context.getState(getEnergy=True, getPositions=True)
            if not self._healthy(st):
                raise self._diagnose(self.step + i + 1)
        raise self._diagnose(self.step + int(n_steps))

    # --- checkpoints ------------------------------------------------------------------
    def save_checkpoint(self, path, n_frames=None, extra=None):
        """Write an OpenMM checkpoint plus step count and model fingerprint (atomically)."""
        meta = dict(format="dnarod-openmm-checkpoint", step=self.step, n_frames=n_frames,
                    fingerprint=self.fingerprint, n_nodes=self.model.n_nodes, dt=self.dt,
                    integrator=self.integrator_name, temperature=self.temperature, extra=extra or {})
        cb = self.rs.load_info.get("torque_callback")
        if cb is not None:
            meta["torque_phi"] = cb.phi.tolist()
            meta["torque_last"] = cb.last_angle.tolist()
        blob = np.frombuffer(self.context.createCheckpoint(), dtype=np.uint8)
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, openmm=blob, meta=np.array(json.dumps(meta)))

    def load_checkpoint(self, path):
        """Restore a checkpoint written by :meth:`save_checkpoint` for this model; returns its metadata."""
        try:
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                blob = z["openmm"].tobytes()
        except (OSError, KeyError, ValueError) as exc:
            raise ParameterError(f"{path}: not a readable dnarod checkpoint ({exc})") from None
        if meta.get("format") != "dnarod-openmm-checkpoint":
            raise ParameterError(f"{path}: not a dnarod OpenMM checkpoint")
        if meta["fingerprint"] != self.fingerprint:
            raise ParameterError(f"{path}: checkpoint belongs to another model ({meta['n_nodes']} nodes, different "
                                 f"parameters, masses or closure); resume with the model it was written for")
        if meta["integrator"] != self.integrator_name or not math.isclose(meta["dt"], self.dt, rel_tol=1e-12):
            raise ParameterError(f"{path}: checkpoint was written with integrator {meta['integrator']} and "
                                 f"dt {meta['dt']} ps, this run uses {self.integrator_name} and dt {self.dt} ps")
        try:
            self.context.loadCheckpoint(blob)
        except Exception as exc:  # noqa: BLE001 - OpenMMException
            raise ParameterError(f"{path}: OpenMM cannot load this checkpoint here ({exc})") from None
        self.step = int(meta["step"])
        self._state_cache = None
        cb = self.rs.load_info.get("torque_callback")
        if cb is not None and "torque_phi" in meta:
            cb.phi[:] = meta["torque_phi"]
            cb.last_angle[:] = meta["torque_last"]
        return meta

    # --- production run -----------------------------------------------------------------
    def run(self, n_steps, outdir, frame_interval=100, energy_interval=None, checkpoint_interval=None,
            resume=False, progress=True, overwrite=False, on_advance=None):
        """Run to a total of ``n_steps`` steps, writing trajectory, energies, checkpoints and final model.

        Parameters
        ----------
        n_steps : int
            Total steps of the run (counted from its start, also when resuming).
        outdir : str or Path
        frame_interval : int
            Steps between trajectory frames (frame 0 is the start).
        energy_interval : int or None
            Steps between CSV rows (default ``frame_interval``).
        checkpoint_interval : int or None
            Steps between checkpoints (default: ten frame intervals); ``0`` for none.
        resume : bool
            Continue from ``outdir/checkpoint.npz``.
        progress : bool
            Show a tqdm progress bar with ETA.
        overwrite : bool
            Start a new run in a directory that already holds a trajectory (it is replaced);
            without it that is an error, so no finished run is lost by accident.
        on_advance : callable or None
            Called as ``on_advance(self)`` after every integration chunk (at most one frame or
            energy interval long), e.g. to turn a rotation clamp gradually.

        Returns
        -------
        dict
            Summary: steps, simulated time (ps), wall time (s), ns/day, mean temperature, files.
        """
        from tqdm import tqdm

        outdir = Path(outdir)
        outdir.mkdir(parents=True, exist_ok=True)
        n_steps = int(n_steps)
        fi = int(frame_interval)
        ei = int(energy_interval or fi)
        ci = 10 * fi if checkpoint_interval is None else int(checkpoint_interval)
        if fi <= 0 or ei <= 0 or ci < 0:
            raise ParameterError("frame_interval and energy_interval must be positive, checkpoint_interval >= 0")
        traj_path, csv_path, chk_path = outdir / "trajectory.dtraj", outdir / "energies.csv", outdir / "checkpoint.npz"
        meta = dict(engine="openmm", dt_ps=self.dt, temperature_K=self.temperature, integrator=self.integrator_name,
                    friction_per_ps=self.friction, platform=self.platform_name, elastic=self.rs.elastic,
                    sequence=(self.model.sequence or "")[:2000], fingerprint=self.fingerprint,
                    inertia_convention="J = m l^2 (1/2, 1/2, 1) about d1,d2,d3; omega body frame")
        if resume:
            if not chk_path.exists():
                raise ParameterError(f"cannot resume: {chk_path} does not exist")
            self.load_checkpoint(chk_path)
            writer = TrajectoryWriter(traj_path, self.model.n_nodes, velocities=True, metadata=meta,
                                      resume_step=self.step)
            rows = _read_csv_rows(csv_path, self.step)
            csv_fh = _open_csv(csv_path, rows)
        else:
            if traj_path.exists() and not overwrite:
                raise ParameterError(f"{traj_path} already exists: resume the run (resume=True, --resume), "
                                     f"choose another output directory, or pass overwrite=True (--overwrite)")
            writer = TrajectoryWriter(traj_path, self.model.n_nodes, velocities=True, metadata=meta)
            csv_fh = _open_csv(csv_path, [])
        csv_w = csv.writer(csv_fh)
        temps = []
        start_step = self.step
        t0 = time.perf_counter()
        bar = tqdm(total=n_steps, initial=self.step, disable=not progress, unit="step", dynamic_ncols=True)
        try:
            if not resume:
                self._report(writer, csv_w, csv_fh, temps, frame=True, energy=True)
            while self.step < n_steps:
                nxt = min(_next_multiple(self.step, fi), _next_multiple(self.step, ei), n_steps)
                if ci:
                    nxt = min(nxt, _next_multiple(self.step, ci))
                before = self.step
                self.advance(nxt - self.step)
                bar.update(self.step - before)
                if on_advance is not None:
                    on_advance(self)
                self._report(writer, csv_w, csv_fh, temps, frame=self.step % fi == 0,
                             energy=self.step % ei == 0)
                if ci and self.step % ci == 0:
                    writer._fh.flush()
                    self.save_checkpoint(chk_path)
        finally:
            bar.close()
            writer.close()
            csv_fh.close()
        wall = time.perf_counter() - t0
        self.current_model().save(outdir / "final_model.npz")
        done = self.step - start_step
        sim_ns = done * self.dt * 1e-3
        return dict(steps=self.step, steps_this_run=done, simulated_ps=self.step * self.dt, wall_s=wall,
                    ns_per_day=sim_ns / wall * 86400 if wall > 0 else float("nan"),
                    mean_temperature=float(np.mean(temps)) if temps else float("nan"), dt_ps=self.dt,
                    omega_max=self.omega_max, trajectory=str(traj_path), energies=str(csv_path),
                    final_model=str(outdir / "final_model.npz"))

    def _report(self, writer, csv_w, csv_fh, temps, frame, energy):
        if frame:
            c, f, v, w = self.node_state()
            writer.write(self.step, self.step * self.dt, c, f, v, w)
        if energy:
            e = self.energies()
            temps.append(e["temperature"])
            csv_w.writerow([self.step, f"{self.step * self.dt:.6f}", repr(e["potential"]), repr(e["kinetic"]),
                            repr(e["potential"] + e["kinetic"]), f"{e['temperature']:.6f}", repr(e["elastic"]),
                            repr(e["nonbonded"]), repr(e["external"])])
            csv_fh.flush()


def _next_multiple(step, interval):
    return (step // interval + 1) * interval


def _read_csv_rows(path, max_step):
    if not Path(path).exists():
        return []
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return [r for r in rows[1:] if r and int(r[0]) <= max_step]


def _open_csv(path, rows):
    """(Re)write the CSV header and kept rows atomically, then open it for appending."""
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(CSV_COLUMNS)
    w.writerows(rows)
    with atomic_path(path) as tmp:
        Path(tmp).write_text(buf.getvalue())
    return open(path, "a", newline="")


def load_energies(path):
    """Read ``energies.csv`` into a dict of arrays (column name -> ndarray)."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    if not rows or rows[0] != CSV_COLUMNS:
        raise DnarodError(f"{path}: not a dnarod energies CSV")
    data = np.array([[float(x) for x in r] for r in rows[1:]]).reshape(-1, len(CSV_COLUMNS))
    return {name: data[:, i] for i, name in enumerate(CSV_COLUMNS)}
