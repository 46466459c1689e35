"""Simulations of a rod model with OpenMM: minimisation, NVE, Langevin, node state, checkpoints.

Conventions shared with the Lax-form integrator (so the two engines can be compared):

* node k is a rigid body of mass ``m_k`` and principal inertia ``J_k = m_k l_k^2 (1/2, 1/2, 1)``
  about (d1, d2, d3) (the model's ``inertia``; see :mod:`dnarod.engines.openmm.particles`);
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

:class:`RodSimulation` is the OpenMM engine of the run layer (:mod:`dnarod.run`): it advances,
reports its node state and energies by term, and writes/restores checkpoints; trajectories,
energies CSV, checkpoints on a schedule and the run directory are the run layer's reporters.
"""
from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import openmm

from dnarod.core.seeds import resolve_seed
from dnarod.core.errors import ParameterError, SimulationError, base_pair
from dnarod.core.io import atomic_path
from dnarod.physics import modes
from dnarod.physics.modes import DEFAULT_OMEGA_DT, MAX_OMEGA_DT
from dnarod.core.model import RodModel, model_fingerprint
from dnarod.core.io import read_checkpoint
from dnarod.physics.thermal import kinetic_temperature
from dnarod.core.units import kT as kT_of
from dnarod.core.units import md_value
from dnarod.core.kernels import loads_kernel
from dnarod.engines.openmm.forces import GROUPS
from dnarod.engines.openmm.particles import (closure_image_positions, node_poses, node_velocities,
                                             particle_forces_to_loads, particle_positions, particle_velocities)
from dnarod.engines.openmm.platforms import choose_platform
from dnarod.engines.openmm.system import RodSystem, build_system
from dnarod.physics.nonbonded import scales_temperature
from dnarod.physics.loads import RotationClamp, clamp_angle
from dnarod.engines.openmm.plugin import rigid_body_integrator
from dnarod.engines.openmm.loads import set_clamp_rotation


def _checked_dt(dt: float | None, omega: float) -> float:
    """The time step (ps): ``dt`` checked against the stability limit ``MAX_OMEGA_DT / omega``, or the default
    ``DEFAULT_OMEGA_DT / omega`` (``omega`` the fastest mode, rad/ps)."""
    limit = MAX_OMEGA_DT / omega
    dt = DEFAULT_OMEGA_DT / omega if dt is None else float(dt)
    if not (np.isfinite(dt) and dt > 0):
        raise ParameterError(f"dt must be a positive time in ps, got {dt}")
    if dt > limit:
        raise ParameterError(f"dt = {dt:.4g} ps is above the stability limit {limit:.4g} ps of this model "
                             f"(fastest mode omega_max = {omega:.4g} rad/ps, limit 1.8/omega_max); "
                             f"use dt <= {DEFAULT_OMEGA_DT / omega:.3g} ps (the default)")
    return dt


class RodSimulation:
    """The OpenMM engine: a :class:`~dnarod.core.model.RodModel` in an OpenMM Context, advanced by a given integrator.

    Like OpenMM's ``app.Simulation``, it takes the System (a :class:`~dnarod.engines.openmm.system.RodSystem`), the
    integrator and the platform as given; :meth:`create` is the policy that chooses them (platform, time step,
    integrator, elastic path) from a model and a few settings.

    Parameters
    ----------
    model : RodModel
        Starting pose.
    system : RodSystem
        From :func:`dnarod.engines.openmm.system.build_system` (forces added before this call are part of it).
    integrator : openmm.Integrator
        Its step size is the engine's ``dt`` (ps).
    platform : openmm.Platform
    properties : dict, optional
        Platform properties.
    temperature : float
        K: the thermostat's (for the kinetic temperature and the initial velocities).
    friction : float
        1/ps (0: NVE).
    seed : int
        Seed of the initial velocities (the integrator carries its own noise seed).
    omega_max : float
        Fastest normal mode of the start pose, rad/ps (recorded).
    kind : {"langevin", "verlet"}
        What the integrator is (recorded in checkpoints).
    initial_velocities : tuple (v (n,3) nm/ps lab, omega (n,3) rad/ps body) or None
        Default: Maxwell at ``temperature`` (at rest at 0 K).
    platform_reason : str, optional
        Why this platform (reported by ``dnarod simulate``).
    """

    name = "openmm"

    # OpenMM's Simulation takes system, integrator and platform; the rest are what the engine records
    def __init__(self, model: RodModel, system: RodSystem, integrator: Any, platform: Any,
                 properties: dict[str, str] | None = None, *, temperature: float = 300.0, friction: float = 1.0,
                 seed: int = 0, omega_max: float = float("nan"), kind: str = "langevin",
                 initial_velocities: tuple[np.ndarray, np.ndarray] | None = None,
                 platform_reason: str | None = None) -> None:
        self.model = model
        self.rs = system
        self.integrator = integrator
        self.integrator_name = kind
        self.temperature = float(temperature)
        self.friction = float(friction)
        self.seed = int(seed)
        self.omega_max = float(omega_max)
        self.dt = float(integrator.getStepSize().value_in_unit(openmm.unit.picosecond)) \
            if hasattr(integrator.getStepSize(), "value_in_unit") else float(integrator.getStepSize())
        self.platform_name = platform.getName()
        self.platform_reason = platform_reason
        self.loads = tuple(system.loads)
        t0 = time.perf_counter()
        self.context = openmm.Context(system.system, integrator, platform, properties or {})
        self.set_particle_positions(particle_positions(model.positions, model.frames, system.radius))
        self.context_time = time.perf_counter() - t0
        self._state_cache: Any = None
        self._terms_cache: dict[str, float] | None = None
        self._report_cache: tuple[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], Any] | None = None
        self._rollback: tuple[int, Any] | None = None
        self._plugin_reports: bool | None = None
        self._batch_buffer: np.ndarray | None = None
        self._batch_energies: np.ndarray | None = None
        self._limit: float | None = None
        if initial_velocities is not None:
            self.set_node_velocities(*initial_velocities)
        elif self.temperature > 0:
            self.thermalize(self.temperature, self.seed)
        else:  # at rest on-step: the leapfrog velocities start half a kick back (else the run is first order)
            self.set_node_velocities(np.zeros((model.n_nodes, 3)), np.zeros((model.n_nodes, 3)))
        self.step = 0
        self.fingerprint = model_fingerprint(model, pose=False)

    def __del__(self) -> None:
        # The Context refers to its System and Integrator: it must go first. Left in a reference cycle (an exception's
        # traceback holding a simulation, say), the collector could otherwise free the Integrator before the
        # Context, whose destructor then crashes the process.
        self.__dict__.pop("context", None)

    @classmethod
    # mirrors the run settings (RunSpec): one keyword per setting of the engine it builds
    def create(cls, model: RodModel, integrator: str = "langevin", temperature: float = 300.0,
               dt: float | None = None, friction: float = 1.0, platform: str | None = None, elastic: str = "auto",
               nonbonded: Any = True, loads: Sequence[Any] = (), seed: int | None = None,
               threads: int | None = None, constraint_tolerance: float = 1e-8,
               initial_velocities: tuple[np.ndarray, np.ndarray] | None = None, omega_max: float | None = None,
               precision: str | None = None, extra_forces: Sequence[Any] = ()) -> RodSimulation:
        """The engine for a model with the default policies: the platform (:func:`~.platforms.choose_platform`),
        the time step (``DEFAULT_OMEGA_DT / omega_max``, :mod:`dnarod.physics.modes`), the elastic path and the
        integrator (the compiled rigid-body integrator with the plugin, else OpenMM's LangevinMiddle or Verlet).

        Parameters
        ----------
        model : RodModel
            Starting pose (velocities are thermal at ``temperature``, or zero for NVE with ``temperature=0``).
        integrator : {"langevin", "verlet"}
            Langevin at ``temperature`` or velocity Verlet (NVE).
        temperature : float
            K.
        dt : float or None
            ps; default ``DEFAULT_OMEGA_DT / omega_max``. Values above ``MAX_OMEGA_DT / omega_max``
            raise :class:`~dnarod.core.errors.ParameterError`.
        friction : float
            1/ps (Langevin).
        platform : str or None
            OpenMM platform name ("CPU", "Reference", "CUDA", "OpenCL", "HIP"); ``None`` for the
            automatic choice of :func:`dnarod.engines.openmm.platforms.choose_platform` (GPU, else the CPU
            fast path); the choice and its reason are in ``platform_name``, ``platform_reason``.
        elastic : {"auto", "plugin", "fast", "portable"}
        nonbonded : bool or NonbondedSettings
        loads : sequence
            External loads (:mod:`dnarod.physics.loads` dataclasses, the tweezers Walls included).
        seed : int or None
            Seed of initial velocities and of the Langevin noise.
        threads : int or None
            CPU platform threads.
        constraint_tolerance : float
        initial_velocities : tuple (v (n,3) nm/ps lab, omega (n,3) rad/ps body) or None
        omega_max : float, optional
            Fastest mode of the start pose under the loads, rad/ps, if known.
        precision : {"single", "mixed", "double"} or None
            GPU platforms' precision (default mixed).
        extra_forces : sequence of openmm.Force
            Further forces on the particles (3 per node, :func:`dnarod.engines.openmm.particles.particle_positions`),
            added to the System before the Context is created.

        Returns
        -------
        RodSimulation
        """
        temperature = float(temperature)
        if not (np.isfinite(temperature) and temperature >= 0):
            raise ParameterError(f"temperature must be >= 0 K, got {temperature}")
        if integrator not in ("langevin", "verlet"):
            raise ParameterError(f"integrator must be 'langevin' or 'verlet', got {integrator!r}")
        loads = tuple(loads)
        plat, props, reason = choose_platform(platform, model.n_nodes, elastic, threads, precision)
        omega = float(omega_max) if omega_max is not None else modes.omega_max(model, loads=loads)
        dt = _checked_dt(dt, omega)
        friction = float(friction)
        if integrator == "langevin" and not (np.isfinite(friction) and friction >= 0):
            raise ParameterError(f"friction must be >= 0 1/ps, got {friction} (a negative friction pumps energy in)")
        seed = resolve_seed(seed)
        # the non-bonded energy scales (WCA kT, Bjerrum length) need a temperature: a run started
        # at rest (0 K) uses the reference one, so the potential does not depend on the start
        rs = build_system(model, plat.getName(), elastic, nonbonded, loads,
                          scales_temperature(temperature))
        for f in extra_forces:  # added before the Context exists, so every elastic path (plugin included) sees them
            rs.system.addForce(f)
        if rs.elastic == "plugin":
            # Compiled rigid-body integrator (same leapfrog velocity convention; no constraints applied). Its steps
            # run on the device where the platform has the plugin's kernels (rs.device), else as host code.
            integ = rigid_body_integrator(rs.radius, dt, temperature, friction if integrator == "langevin" else 0.0,
                                          seed)
        elif integrator == "langevin":
            integ = openmm.LangevinMiddleIntegrator(temperature, friction, dt)
            integ.setRandomNumberSeed(seed)
        else:
            integ = openmm.VerletIntegrator(dt)
        integ.setConstraintTolerance(constraint_tolerance)
        return cls(model, rs, integ, plat, props, temperature=temperature, friction=friction, seed=seed,
                   omega_max=omega, kind=integrator, initial_velocities=initial_velocities, platform_reason=reason)

    # --- node state -------------------------------------------------------------------
    def set_particle_positions(self, particles: np.ndarray) -> None:
        """Set the positions of the nodes' particles, shape (3 n_nodes, 3) nm (the closure image particles of
        the portable path of a circular chain, if any, follow node 0)."""
        x = np.asarray(particles, float)
        if self.rs.image is not None:
            x = np.vstack([x, closure_image_positions(x, self.model.closure)])
        self.invalidate()
        self.context.setPositions(x)

    def node_particles(self, array: Any) -> np.ndarray:
        """The rows of a per-particle array (positions, velocities, forces) that belong to the nodes, (3 n_nodes, 3)."""
        return md_value(array)[:3 * self.model.n_nodes]

    def set_node_velocities(self, velocities: np.ndarray, angular_velocities: np.ndarray) -> None:
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
        self.invalidate()
        st = self.context.getState(getPositions=True, getForces=True)
        p = self.node_particles(st.getPositions(asNumpy=True))
        _, frames = node_poses(p)
        F, tau = particle_forces_to_loads(p, self.node_particles(st.getForces(asNumpy=True)))
        h = 0.5 * self.dt
        v = np.asarray(velocities, float) - h * F / self.model.mass[:, None]
        w = np.asarray(angular_velocities, float) - h * np.einsum("kab,ka->kb", frames, tau) / self.model.inertia
        u = particle_velocities(frames, self.rs.radius, v, w)
        for k in self.rs.clamped:
            u[3 * k:3 * k + 3] = 0.0
        if self.rs.image is not None:  # massless image particles (OpenMM does not integrate them)
            u = np.vstack([u, np.zeros((3, 3))])
        self.context.setVelocities(u)

    def thermalize(self, temperature: float, seed: int | None = None) -> None:
        """Draw Maxwell-Boltzmann node velocities (6 degrees of freedom per free node)."""
        rng = np.random.default_rng(seed)
        kt = kT_of(temperature)
        n = self.model.n_nodes
        v = rng.normal(size=(n, 3)) * np.sqrt(kt / self.model.mass)[:, None]
        w = rng.normal(size=(n, 3)) * np.sqrt(kt / self.model.inertia)
        self.set_node_velocities(v, w)

    def node_pose(self, state: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """``(centres (n,3) nm, frames (n,3,3))`` of the current (or given) state."""
        if state is None:
            rep = self._node_report()
            if rep is not None:
                return rep[0][0].copy(), rep[0][1].copy()
        state = state or self._full_state()
        return node_poses(self.node_particles(state.getPositions(asNumpy=True)))

    def node_state(self, state: Any = None, on_step: bool = True,
                   copy: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(centres, frames, velocities (lab, nm/ps), angular velocities (body, rad/ps))``.

        ``copy=False`` (the run layer's reports): on the compiled path, read-only views of the node report,
        valid until the context changes (no copies of the four arrays).

        OpenMM's Verlet and LangevinMiddle integrators store leapfrog velocities, half a step
        behind the positions. With ``on_step=True`` (default; used for the trajectory) they are
        completed to the positions' time by the half kick of velocity Verlet/RATTLE on each rigid
        node, ``v += dt/2 F/m`` and ``omega += dt/2 J^-1 L^T tau`` (docs/formulation.md §7), which is what
        the Lax-form engine reports; ``on_step=False`` gives OpenMM's raw half-step velocities.
        """
        if state is None and on_step:
            rep = self._node_report()
            if rep is not None:
                if not copy:  # the report's arrays are read-only
                    return rep[0]
                c, f, v, w = rep[0]
                return c.copy(), f.copy(), v.copy(), w.copy()
        state = state or self._full_state()
        p = self.node_particles(state.getPositions(asNumpy=True))
        u = self.node_particles(state.getVelocities(asNumpy=True))
        c, f = node_poses(p)
        v, w = node_velocities(p, u)
        if on_step:
            F, tau = particle_forces_to_loads(p, self.node_particles(state.getForces(asNumpy=True)))
            free = np.ones(self.model.n_nodes)
            free[self.rs.clamped] = 0.0
            h = 0.5 * self.dt * free[:, None]
            v = v + h * F / self.model.mass[:, None]
            w = w + h * np.einsum("kab,ka->kb", f, tau) / self.model.inertia
        return c, f, v, w

    def _full_state(self) -> Any:
        """State with positions, velocities, parameters and energy; cached until the context changes."""
        if self._state_cache is None:
            self._state_cache = self.context.getState(getPositions=True, getVelocities=True, getParameters=True,
                                                      getEnergy=True, getForces=True)
            self._terms_cache = self._callback_terms()
        return self._state_cache

    def _callback_terms(self) -> dict[str, float] | None:
        """Per-term energies recorded by the fast-path callbacks during the last evaluation, or None."""
        el = self.rs.elastic_callback
        nb = self.rs.nonbonded_callback
        if el is None:
            return None
        return dict(elastic=el.last_energy, nonbonded=sum(nb.last) if nb is not None else 0.0)

    def invalidate(self) -> None:
        """Forget the cached state (call after changing the context directly)."""
        self._state_cache = None
        self._report_cache = None
        self._rollback = None

    def _node_report(self) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], Any] | None:
        """``((centres, frames, velocities, angular velocities), energies)`` from the compiled integrator's
        ``getNodeReport``, or None.

        Available when the compiled integrator evaluates the SMK force (and the node-pair force, if the
        System has one) itself: then the node state, on-step velocities and energies by term come from
        one pass over the nodes in C++ (no OpenMM State, no particle arrays in numpy), and the loads it
        computes are reused by the next step. Arrays (read-only, C-contiguous views of one buffer): centres
        (n, 3, nm), frames (n, 3, 3), on-step velocities (n, 3, lab, nm/ps), on-step angular velocities (n, 3,
        body, rad/ps); energies: SMK, WCA, Debye-Hueckel, every other force, kinetic (kJ/mol), then 1.0 if every
        node value is finite. Cached until the context changes.
        """
        if self._report_cache is None:
            if not self._reports_in_plugin():
                return None
            n = self.model.n_nodes
            buf = np.empty(18 * n)
            energies = self.integrator.getNodeReport(buf)
            buf.flags.writeable = False  # node_state(copy=False) hands out views of it
            arrays = (buf[:3 * n].reshape(n, 3), buf[3 * n:12 * n].reshape(n, 3, 3), buf[12 * n:15 * n].reshape(n, 3),
                      buf[15 * n:].reshape(n, 3))
            self._report_cache = (arrays, energies)
        return self._report_cache

    def _reports_in_plugin(self) -> bool:
        """True if :meth:`_node_report` can be used (the compiled integrator evaluates all dnarod forces); fixed
        when the Context is made, so asked once."""
        if self._plugin_reports is None:
            integ = self.integrator
            self._plugin_reports = bool(self.rs.elastic == "plugin" and integ.usesFusedElasticForce()
                                        and (self.rs.nonbonded_callback is None or integ.usesFusedPairForce()))
        return self._plugin_reports

    def energies(self) -> dict[str, float]:
        """Dict of potential energies per term (kJ/mol), plus ``potential``, ``kinetic``, ``temperature``.

        With the fast path the per-term split comes from the callbacks' own evaluation at this
        state (no extra force evaluations); otherwise each force group is evaluated.
        """
        rep = self._node_report()
        if rep is not None:
            e_smk, e_wca, e_dh, e_other, kinetic = rep[1][:5]
            return dict(elastic=e_smk, nonbonded=e_wca + e_dh, external=e_other,
                        potential=e_smk + e_wca + e_dh + e_other, kinetic=kinetic,
                        temperature=float(kinetic_temperature(kinetic, self.rs.degrees_of_freedom)))
        st = self._full_state()
        out: dict[str, float] = {}
        pot = md_value(st.getPotentialEnergy())
        if self._terms_cache is not None:
            out.update(self._terms_cache)
            out["external"] = pot - out["elastic"] - out["nonbonded"]
        else:
            for name, g in GROUPS.items():
                out[name] = md_value(self.context.getState(getEnergy=True, groups={g}).getPotentialEnergy())
        out["potential"] = pot
        out["kinetic"] = md_value(st.getKineticEnergy())
        dof = self.rs.degrees_of_freedom
        out["temperature"] = float(kinetic_temperature(out["kinetic"], dof))
        return out

    def current_model(self) -> RodModel:
        """The model with the current pose."""
        c, f = self.node_pose()
        return self.model.with_pose(c, f)

    def minimize(self, tolerance: float = 1.0, max_iterations: int = 0, max_rounds: int = 20) -> float:
        """Local energy minimisation (tolerance: RMS force, kJ/mol/nm); returns the final potential energy.

        OpenMM's L-BFGS with constraints can stop early on this stiff, constrained system, so it
        is restarted until the energy stops decreasing (at most ``max_rounds`` rounds).
        """
        self.invalidate()
        E = md_value(self.context.getState(getEnergy=True).getPotentialEnergy())
        for _ in range(max_rounds):
            openmm.LocalEnergyMinimizer.minimize(self.context, tolerance, max_iterations)
            E_new = md_value(self.context.getState(getEnergy=True).getPotentialEnergy())
            if not E_new < E - 1e-9 * max(1.0, abs(E)):
                return E_new
            E = E_new
        return E

    def set_clamp_rotation(self, angle: float, index: int = 0) -> None:
        """Turn rotation clamp ``index`` by ``angle`` rad about its axis (magnetic tweezers)."""
        set_clamp_rotation(self.context, self.rs.load_info["rotation_clamps"][index], angle)
        self.invalidate()

    def update_loads(self, time_ps: float, duration_ps: float | None = None) -> None:
        """Turn every rotation clamp with ``turns``/``turns_per_ns`` to its angle at ``time_ps`` (run layer hook)."""
        clamps = self.rs.load_info.get("rotation_clamps") or []
        if not clamps:
            return
        # build_load_forces lists the rotation clamps in the order of the loads
        for info, load in zip(clamps, [x for x in self.loads if isinstance(x, RotationClamp)]):
            if load.turns or load.turns_per_ns is not None:
                set_clamp_rotation(self.context, info, clamp_angle(load, time_ps, duration_ps))
        self.invalidate()

    # --- checks -----------------------------------------------------------------------
    def _energy_limit(self) -> float:
        """Potential plus kinetic energy above which a state counts as blown up, kJ/mol."""
        return 1e4 * kT_of(max(self.temperature, 300.0)) * self.model.n_nodes

    def _report_healthy(self) -> bool:
        rep = self._node_report()
        assert rep is not None  # only asked on the compiled path
        return self._energies_healthy(rep[1])

    def _energies_healthy(self, e: Any) -> bool:
        """The node report's energies (see :meth:`_node_report`) are finite and below the blow-up limit."""
        E, K = e[0] + e[1] + e[2] + e[3], e[4]
        if self._limit is None:
            self._limit = self._energy_limit()
        return e[5] == 1.0 and math.isfinite(E) and math.isfinite(K) and abs(E) + K < self._limit

    def _healthy(self, st: Any) -> bool:
        E = md_value(st.getPotentialEnergy())
        K = md_value(st.getKineticEnergy())
        p = md_value(st.getPositions(asNumpy=True))
        return np.isfinite(E) and np.isfinite(K) and np.isfinite(p).all() and abs(E) + K < self._energy_limit()

    def _diagnose(self, step: int) -> SimulationError:
        """Build the SimulationError for a bad current state: term, node, energies."""
        terms: dict[str, float] = {}
        for name, g in GROUPS.items():
            try:
                terms[name] = md_value(self.context.getState(getEnergy=True, groups={g}).getPotentialEnergy())
            except Exception:  # noqa: BLE001 - a NaN can make OpenMM raise
                terms[name] = float("nan")
        el, nb = self.rs.elastic_callback, self.rs.nonbonded_callback
        # fused fast path: split by the callbacks
        if el is not None and getattr(el, "nonbonded", None) is nb and nb is not None:
            terms["elastic"], terms["nonbonded"] = el.last_energy, sum(nb.last)
        bad = [k for k, v in terms.items() if not np.isfinite(v)]
        term = bad[0] if bad else max(terms, key=lambda k: abs(terms[k]))
        p = self.node_particles(self.context.getState(getPositions=True).getPositions(asNumpy=True)).reshape(-1, 3, 3)
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
        return SimulationError(f"simulation blew up at step {step}: {base_pair(node)}, term '{term}' "
                               f"(energies kJ/mol: {txt}); reduce dt or check the loads/model",
                               step=step, node=node, term=term)

    #: Most steps the compiled path keeps a rollback state for before it reads a new one (:meth:`advance`).
    ROLLBACK_STEPS = 1000

    def advance(self, n_steps: int) -> None:
        """Integrate ``n_steps`` steps, checking for NaN/blow-up; on failure, locate the first bad step.

        Raises
        ------
        SimulationError
            Naming the step, node and energy term; the context is left at the first bad step.
        """
        n_steps = int(n_steps)
        fast = self._reports_in_plugin()
        # The state to go back to if the run blows up. On the compiled path it is kept over several short
        # advances (a run loop advancing a few steps per report would otherwise read it every report), up to
        # ROLLBACK_STEPS steps back; a blow-up is then replayed from there, one step at a time.
        rollback = self._keep_rollback() if fast else (self.step, self._full_state())
        self.integrator.step(n_steps)
        self.invalidate()
        if self._report_healthy() if fast else self._healthy(self._full_state()):
            self.step += n_steps
            self._rollback = rollback if fast else None
            return
        raise self._locate_failure(rollback, self.step + n_steps)

    def _keep_rollback(self) -> tuple[int, Any]:
        """The compiled path's rollback state: kept while it is less than ROLLBACK_STEPS steps back, else read now
        (positions, velocities and parameters are all it needs: cheap)."""
        if self._rollback is None or not 0 <= self.step - self._rollback[0] < self.ROLLBACK_STEPS:
            self._rollback = (self.step, self.context.getState(getPositions=True, getVelocities=True,
                                                               getParameters=True))
        return self._rollback

    def _locate_failure(self, rollback: tuple[int, Any], end_step: int) -> SimulationError:
        """Replay from ``rollback`` one step at a time to the first bad step (at most ``end_step``); the error
        names it (the context is left there)."""
        good_step, good = rollback
        self.context.setState(good)
        for i in range(end_step - good_step):
            self.integrator.step(1)
            st = self.context.getState(getEnergy=True, getPositions=True)
            if not self._healthy(st):
                return self._diagnose(good_step + i + 1)
        return self._diagnose(end_step)

    #: Most reports one :meth:`advance_reports` call holds (its buffer: 18 doubles per node and report).
    MAX_BATCH_REPORTS = 64
    #: Bytes of reports one call holds at most (at least one report): a buffer that stays in the processor's cache
    #: while the reporters read it (batches of 16 reports cost about 1.5 % less than of 64 at 1,000 nodes).
    BATCH_BYTES = 2 << 20

    def advance_reports(self, n_reports: int, interval: int, duration_ps: float | None = None
                        ) -> tuple[np.ndarray, tuple[np.ndarray, ...], dict[str, np.ndarray], SimulationError | None]:
        """Advance ``n_reports`` times ``interval`` steps, reading the node report after each (the run layer's
        batched reports; the compiled path only, see :meth:`supports_report_batches`).

        Equivalent to ``n_reports`` calls of :meth:`advance` (``interval`` steps) each followed by
        :meth:`node_state` and :meth:`energies` (and :meth:`update_loads` at the report's time), bit for bit,
        without the Python work of a report per call: with loads that do not change in time, one call of the
        compiled integrator does them all. At most :attr:`MAX_BATCH_REPORTS` reports and :attr:`BATCH_BYTES`
        of them per call, and at most about :attr:`ROLLBACK_STEPS` steps (a blow-up is replayed from the state at
        its start); the steps returned say how many were done.

        Returns
        -------
        steps : ndarray, shape (k,)
            The step of each report (k <= n_reports: fewer if the run blew up).
        state : tuple of ndarray
            On-step centres (k, n, 3) nm, frames (k, n, 3, 3), velocities (k, n, 3) nm/ps (lab), angular
            velocities (k, n, 3) rad/ps (body): read-only views of the engine's buffer, valid until the next call.
        energies : dict of ndarray, shape (k,)
            As :meth:`energies`, one value per report.
        error : SimulationError or None
            The blow-up after the last good report (naming its step, node and term; the context is left at that
            step), to be raised once the good reports are written.
        """
        n_reports, interval = int(n_reports), int(interval)
        if not self._reports_in_plugin():
            raise ParameterError("advance_reports needs the compiled path (supports_report_batches())")
        if not 1 <= n_reports <= self.MAX_BATCH_REPORTS or interval < 1:
            raise ParameterError(f"advance_reports: 1 to {self.MAX_BATCH_REPORTS} reports of >= 1 steps, got "
                                 f"{n_reports} of {interval}")
        n = self.model.n_nodes
        # a blow-up is replayed from the rollback state: at most about ROLLBACK_STEPS steps per call
        n_reports = max(1, min(n_reports, self.ROLLBACK_STEPS // interval, self.BATCH_BYTES // (8 * 18 * n)))
        if (self._batch_buffer is None or self._batch_energies is None
                or self._batch_buffer.shape != (self.MAX_BATCH_REPORTS, 18 * n)):
            self._batch_buffer = np.empty((self.MAX_BATCH_REPORTS, 18 * n))
            self._batch_energies = np.empty((self.MAX_BATCH_REPORTS, 6))
        buf, e_arr = self._batch_buffer, self._batch_energies
        buf.flags.writeable = True
        error = None
        integ = self.integrator
        if self._limit is None:
            self._limit = self._energy_limit()
        rollback = self._keep_rollback()
        start = self.step
        if not self.rs.load_info.get("rotation_clamps"):
            # every report in one call (the loads do not change with time)
            k = integ.stepAndReport(n_reports, interval, buf, e_arr, self._limit)
            if k < n_reports:
                self._rollback = None
                error = self._locate_failure(rollback, start + (k + 1) * interval)
            self.step = start + k * interval
        else:
            # turned to each report's time, then read again, as the run loop's advance-update-report
            k = 0
            while k < n_reports:
                if integ.stepAndReport(1, interval, buf[k], e_arr[k], self._limit) < 1:
                    self._rollback = None
                    error = self._locate_failure(rollback, self.step + interval)
                    break
                self.step += interval
                self.update_loads(self.step * self.dt, duration_ps)  # forgets the rollback state: keep it
                e_arr[k] = integ.getNodeReport(buf[k])
                k += 1
                self._rollback = rollback
                rollback = self._keep_rollback()
        self._state_cache = self._report_cache = None
        buf.flags.writeable = False
        steps = start + interval * np.arange(1, k + 1, dtype=np.int64)
        b = buf[:k]
        state = (b[:, :3 * n].reshape(k, n, 3), b[:, 3 * n:12 * n].reshape(k, n, 3, 3),
                 b[:, 12 * n:15 * n].reshape(k, n, 3), b[:, 15 * n:].reshape(k, n, 3))
        e_arr = e_arr[:k].copy()
        # the same sums in the same order as energies(), so both give the same bits
        energies = dict(elastic=e_arr[:, 0], nonbonded=e_arr[:, 1] + e_arr[:, 2], external=e_arr[:, 3],
                        potential=e_arr[:, 0] + e_arr[:, 1] + e_arr[:, 2] + e_arr[:, 3], kinetic=e_arr[:, 4],
                        temperature=np.asarray(kinetic_temperature(e_arr[:, 4], self.rs.degrees_of_freedom), float))
        return steps[:k], state, energies, error

    def supports_report_batches(self) -> bool:
        """True if :meth:`advance_reports` can be used (the compiled integrator evaluates every dnarod force)."""
        return self._reports_in_plugin()

    # --- checkpoints ------------------------------------------------------------------
    def save_checkpoint(self, path: str | Path, n_frames: int | None = None,
                        extra: dict[str, Any] | None = None) -> None:
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

    def load_checkpoint(self, path: str | Path) -> dict[str, Any]:
        """Restore a checkpoint written by :meth:`save_checkpoint` for this model; returns its metadata."""
        meta, arrays = read_checkpoint(path, "dnarod-openmm-checkpoint", ("openmm",))
        blob = arrays["openmm"].tobytes()
        if meta.get("fingerprint") != self.fingerprint or meta.get("n_nodes") != self.model.n_nodes:
            raise ParameterError(f"{path}: checkpoint belongs to another model ({meta['n_nodes']} nodes, different "
                                 f"parameters, masses or closure); resume with the model it was written for")
        if meta.get("integrator") != self.integrator_name or not math.isclose(meta["dt"], self.dt, rel_tol=1e-12):
            raise ParameterError(f"{path}: checkpoint was written with integrator {meta['integrator']} and "
                                 f"dt {meta['dt']} ps, this run uses {self.integrator_name} and dt {self.dt} ps")
        try:
            self.context.loadCheckpoint(blob)
        except Exception as exc:  # noqa: BLE001 - OpenMMException
            raise ParameterError(f"{path}: OpenMM cannot load this checkpoint here ({exc})") from None
        self.step = int(meta["step"])
        self.invalidate()
        cb = self.rs.load_info.get("torque_callback")
        if cb is not None and "torque_phi" in meta:
            cb.phi[:] = meta["torque_phi"]
            cb.last_angle[:] = meta["torque_last"]
        return meta


def static_load_fn(model: RodModel, loads: Sequence[Any] = (), angles: Sequence[float] | None = None
                   ) -> Callable[[np.ndarray, np.ndarray], tuple[float, np.ndarray, np.ndarray]]:
    """The OpenMM engine's own node loads as a function ``(positions, frames) -> (nan, F, tau)`` for
    :func:`dnarod.physics.statics.solve_static` (Reference platform, double precision, the portable elastic path
    and the OpenMM translation of the loads; rotation clamps at ``angles``, rad), so the solved pose is this
    engine's equilibrium. Forces kJ/mol/nm and torques kJ/mol, (n, 3) each."""
    sim = RodSimulation.create(model, integrator="verlet", temperature=0.0, dt=1e-3, platform="Reference",
                        elastic="portable", nonbonded=False, loads=loads, omega_max=1.0)
    for i, a in enumerate(() if angles is None else angles):
        sim.set_clamp_rotation(float(a), i)
    radius = sim.rs.radius

    def fn(pos: np.ndarray, frm: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        x = particle_positions(pos, frm, radius)
        sim.set_particle_positions(x)
        st = sim.context.getState(getForces=True)
        F, tau = particle_forces_to_loads(x, sim.node_particles(st.getForces(asNumpy=True)))
        return np.nan, F, tau

    return fn
