"""The Lax-form splitting integrator as an engine of the run layer (:class:`dnarod.run.engine.Engine`)."""
from __future__ import annotations

import json

import numpy as np

from dnarod.core.errors import ParameterError, SimulationError, base_pair
from dnarod.core.io import atomic_path, read_checkpoint
from dnarod.core.model import model_fingerprint
from dnarod.engines.lax.boundary import BoundaryConditions
from dnarod.engines.lax.splitting import SplittingIntegrator, maxwell_state
from dnarod.physics.thermal import kinetic_temperature


class LaxEngine:
    """The Lax-form splitting integrator (:mod:`dnarod.engines.lax.splitting`) as a run-layer engine.

    Parameters
    ----------
    model : RodModel
        Start pose, parameters, masses, inertias, closure.
    dt : float
        Time step, ps.
    temperature : float
        K; Maxwell initial velocities (0: at rest) and, with ``friction > 0``, the thermostat.
    friction : float
        Collision rate, 1/ps; 0 runs NVE (symplectic splitting), > 0 BAOAB Langevin.
    seed : int
        Initial velocities and Langevin noise.
    loads : sequence
        :mod:`dnarod.physics.loads` dataclasses.
    duration_ps : float, optional
        Run length over which rotation clamps' ``turns`` are spread.
    omega_max : float, optional
        rad/ps, if already known (recorded only; the run layer checks the time step).
    fast : bool or str
        numba kernel (default) or the numpy reference (False).
    """

    name = "lax"

    def __init__(self, model, dt, temperature=300.0, friction=1.0, seed=None, loads=(), duration_ps=None,
                 omega_max=None, fast=True):
        self.model = model
        self.temperature = float(temperature)
        if not (np.isfinite(self.temperature) and self.temperature >= 0):
            raise ParameterError(f"temperature must be >= 0 K, got {temperature}")
        friction = float(friction)
        if not (np.isfinite(friction) and friction >= 0):
            raise ParameterError(f"friction must be >= 0 1/ps, got {friction} (a negative friction pumps energy in)")
        self.friction = friction
        self.seed = int(np.random.SeedSequence().entropy % 2**31) if seed is None else int(seed)
        loads = tuple(loads)
        self.boundary = BoundaryConditions.from_loads(loads, duration_ps=duration_ps) if loads \
            else BoundaryConditions()
        state = maxwell_state(model, self.temperature, self.seed, self.boundary)
        langevin = friction > 0
        integ = SplittingIntegrator(model, dt, state=state, boundary=self.boundary,
                                    temperature=self.temperature if langevin else None,
                                    friction=friction if langevin else None, seed=self.seed, fast=fast,
                                    check_stability=False)
        self._attach(integ, omega_max, duration_ps)

    def _attach(self, integ, omega_max, duration_ps):
        self.integ = integ
        self.model = integ.model
        self.boundary = integ.boundary
        self.dt = float(integ.dt)
        self.omega_max = omega_max if omega_max is not None else integ.omega_max
        self.n_dof = 6 * int(integ.free.sum())
        has_loads = hasattr(self.boundary, "resolved") and not self.boundary.empty
        self._resolved = self.boundary.resolved(self.model) if has_loads else None
        self._duration = duration_ps if duration_ps is not None else getattr(self.boundary, "duration_ps", None)

    @classmethod
    def wrap(cls, integrator, temperature=0.0, friction=0.0, seed=None):
        """An engine around an existing :class:`SplittingIntegrator` (its state, boundary and noise)."""
        self = cls.__new__(cls)
        self.temperature = float(temperature)
        self.friction = float(friction)
        self.seed = seed
        self._attach(integrator, None, None)
        return self

    @property
    def step(self):
        return self.integ.step_count

    def advance(self, n_steps):
        """Integrate ``n_steps`` steps (SimulationError names the step, node and quantity on a blow-up)."""
        self.integ.step(int(n_steps))
        if not np.isfinite(self.integ.potential_energy):
            st = self.integ.state
            ke = (np.sum(st.momenta**2, 1) / self.model.mass + np.sum(st.angular_momenta**2 / self.model.inertia, 1))
            node = int(np.argmax(np.where(np.isfinite(ke), ke, np.inf)))
            raise SimulationError(f"simulation blew up at step {self.step}: {base_pair(node)}, term 'elastic' (energy "
                                  f"not finite); reduce dt or check the loads/model", step=self.step, node=node,
                                  term="elastic")

    def node_state(self, copy=True):
        """On-step ``(positions (n, 3) nm, frames (n, 3, 3), velocities (n, 3) nm/ps lab, angular velocities
        (n, 3) rad/ps body)``; ``copy=False``: positions and frames are the integrator's own arrays (valid until
        it advances; the run layer's reports)."""
        s = self.integ.state
        v, w = s.velocities(self.model.mass, self.model.inertia)
        if copy:
            return s.positions.copy(), s.frames.copy(), v, w
        return s.positions, s.frames, v, w

    def energies(self):
        """kJ/mol per term (elastic, nonbonded = 0, external) plus potential, kinetic; temperature K."""
        s = self.integ.state
        elastic = float(self.integ.potential_energy)
        external = 0.0
        if self._resolved is not None:
            angles = self._resolved.clamp_angles(self.step * self.dt, self._duration) \
                if self._resolved.rotation_clamps else None
            external = float(self._resolved.evaluate(s.positions, s.frames, angles)[0])
        ke = self.integ.kinetic_energy()
        return dict(elastic=elastic, nonbonded=0.0, external=external, potential=elastic + external, kinetic=ke,
                    temperature=float(kinetic_temperature(ke, self.n_dof)))

    def current_model(self):
        s = self.integ.state
        return self.model.with_pose(s.positions.copy(), s.frames.copy())

    def update_loads(self, time_ps, duration_ps=None):
        """Rotation clamps turn inside the integrator (from its step count); nothing to do."""

    def save_checkpoint(self, path, extra=None):
        """State, step, time step and the random-number state, atomically (npz)."""
        s = self.integ.state
        meta = dict(format="dnarod-lax-checkpoint", version=2, step=self.step, dt=self.dt,
                    n_nodes=self.model.n_nodes, langevin=self.integ.langevin,
                    fingerprint=model_fingerprint(self.model, pose=False),
                    rng=self.integ.rng.bit_generator.state, extra=extra or {})
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, positions=s.positions, frames=s.frames, momenta=s.momenta,
                         angular_momenta=s.angular_momenta, meta=np.array(json.dumps(meta)))

    def load_checkpoint(self, path):
        """Restore a checkpoint of :meth:`save_checkpoint` for this model and time step; returns its metadata."""
        meta, a = read_checkpoint(path, "dnarod-lax-checkpoint",
                                  ("positions", "frames", "momenta", "angular_momenta"))
        n = self.model.n_nodes
        if meta.get("n_nodes") != n or any(a[k].shape[0] != n for k in a) or \
                meta.get("fingerprint", model_fingerprint(self.model, pose=False)) != \
                model_fingerprint(self.model, pose=False):
            raise ParameterError(f"{path}: checkpoint belongs to another model ({meta.get('n_nodes')} nodes, "
                                 f"different parameters or masses); resume with the model it was written for")
        if not np.isclose(meta.get("dt", np.nan), self.dt, rtol=1e-12, atol=0) or \
                bool(meta.get("langevin")) != self.integ.langevin:
            raise ParameterError(f"{path}: checkpoint was written with dt {meta.get('dt')} ps "
                                 f"({'Langevin' if meta.get('langevin') else 'NVE'}), this run uses dt {self.dt} ps "
                                 f"({'Langevin' if self.integ.langevin else 'NVE'})")
        st = self.integ.state
        for k in a:
            getattr(st, k)[...] = a[k]
        self.integ.step_count = int(meta["step"])
        self.integ.rng.bit_generator.state = meta["rng"]
        self.integ.potential_energy, self.integ.F, self.integ.tau = self.integ._initial_loads()
        return meta
