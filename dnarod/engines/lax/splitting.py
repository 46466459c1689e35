"""Fixed-step symplectic splitting of the node dynamics (docs/formulation.md §7) and its BAOAB Langevin form.

Kick-drift-kick on SE(3)^N (the RATTLE / NO_SQUISH family)::

    P_k += dt/2 F_k ;  pi_k += dt/2 L_k^T tau_k               (kick: lab momentum, body angular momentum)
    r_k += dt P_k / m_k
    free rotor, exact sub-flows R_a(h): L <- L Rot_a(h pi_a/J_a), pi <- Rot_a(h pi_a/J_a)^T pi
        in the order R1(dt/2) R2(dt/2) R3(dt) R2(dt/2) R1(dt/2)
    recompute F, tau (dnarod.core.energy.loads) ; kick again

It is time-reversible and symplectic, conserves total momentum and angular momentum to
roundoff, keeps frames orthogonal, and is second order. Langevin dynamics use BAOAB with the
Ornstein-Uhlenbeck step on the lab momenta (variance m kT) and body angular momenta (variance
J_a kT). The leapfrog stability limit is ``dt < 2 / omega_max`` with ``omega_max^2`` the largest
eigenvalue of ``M^-1 H``; :func:`omega_max` computes it from force differences.

Two implementations share this driver: the numpy reference (:func:`dnarod.core.energy.loads` plus
vectorised updates, below) and the numba kernel in :mod:`.fast` (tested equal to it).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from dnarod.core.energy import loads as _loads
from dnarod.core.errors import DnarodError, GeometryError, SimulationError, base_pair, step_name
from dnarod.core.rotations import MAX_CAYLEY_ANGLE
from dnarod.core.docs import fill_doc
from dnarod.core.strains import step_geometry
from dnarod.core.units import kT as _kT
from dnarod.engines.lax.boundary import BoundaryConditions
from dnarod.engines.lax.splitting_limits import MOMENTUM_LIMIT
from dnarod.physics.modes import omega_max as _omega_max
from dnarod.engines.lax.kernel import NumbaKernel
from dnarod.core.model import RodModel


@fill_doc
@dataclass
class RigidState:
    """Phase-space state of the nodes.

    Attributes
    ----------
    %(pose)s
    momenta : ndarray, shape (n, 3)
        Lab linear momenta, amu nm/ps.
    angular_momenta : ndarray, shape (n, 3)
        Body angular momenta ``J omega``, amu nm^2/ps.
    """

    positions: np.ndarray
    frames: np.ndarray
    momenta: np.ndarray
    angular_momenta: np.ndarray

    def copy(self) -> RigidState:
        """An independent copy (arrays copied)."""
        return RigidState(self.positions.copy(), self.frames.copy(), self.momenta.copy(), self.angular_momenta.copy())

    @classmethod
    def from_model(cls, model: RodModel, velocities: np.ndarray | None = None,
                   angular_velocities: np.ndarray | None = None) -> RigidState:
        """State of the model's pose with lab centre velocities (nm/ps) and body angular velocities (rad/ps)."""
        n = model.n_nodes
        v = np.zeros((n, 3)) if velocities is None else np.asarray(velocities, float)
        w = np.zeros((n, 3)) if angular_velocities is None else np.asarray(angular_velocities, float)
        if v.shape != (n, 3) or w.shape != (n, 3):
            raise DnarodError(f"velocities and angular velocities must have shape ({n}, 3), got {v.shape}, {w.shape}")
        return cls(model.positions.copy(), model.frames.copy(), model.mass[:, None] * v, model.inertia * w)

    def velocities(self, mass: np.ndarray, inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lab centre velocities (n, 3) nm/ps and body angular velocities (n, 3) rad/ps."""
        return self.momenta / mass[:, None], self.angular_momenta / inertia

    def kinetic_energy(self, mass: np.ndarray, inertia: np.ndarray) -> float:
        """kJ/mol."""
        return 0.5 * float(np.sum(self.momenta**2 / mass[:, None]) + np.sum(self.angular_momenta**2 / inertia))

    def total_momentum(self) -> tuple[np.ndarray, np.ndarray]:
        """Lab momentum (3,) and angular momentum about the origin (3,)."""
        L = np.cross(self.positions, self.momenta) + np.einsum("kij,kj->ki", self.frames, self.angular_momenta)
        return self.momenta.sum(0), L.sum(0)


def maxwell_state(model: RodModel, temperature: float, seed: int | None = None,
                  boundary: BoundaryConditions | None = None, remove_drift: bool = True) -> RigidState:
    """Maxwell-Boltzmann momenta at ``temperature`` (K) for the model's pose.

    Lab momenta have variance ``m kT`` per component, body angular momenta ``J_a kT``. For a free
    open chain the total momentum and angular momentum are removed when ``remove_drift``.
    Clamped nodes are at rest.

    Returns
    -------
    RigidState
    """
    rng = np.random.default_rng(seed)
    kt = _kT(temperature)
    n = model.n_nodes
    P = rng.standard_normal((n, 3)) * np.sqrt(model.mass * kt)[:, None]
    pi = rng.standard_normal((n, 3)) * np.sqrt(model.inertia * kt)
    clamp = (boundary or BoundaryConditions()).resolve(n, model.circular, any_node=True)[0]
    P[clamp] = 0.0
    pi[clamp] = 0.0
    state = RigidState(model.positions.copy(), model.frames.copy(), P, pi)
    if remove_drift and not clamp.any():
        _remove_drift(state, model)
    return state


def _remove_drift(state: RigidState, model: RodModel) -> None:
    """Remove total momentum and (for open chains) total angular momentum by a rigid-body velocity."""
    m = model.mass
    state.momenta -= m[:, None] * (state.momenta.sum(0) / m.sum())
    if model.circular:
        return
    rc = (m[:, None] * state.positions).sum(0) / m.sum()
    x = state.positions - rc
    Lb = np.einsum("kij,kj->ki", state.frames, state.angular_momenta)
    Ltot = (np.cross(x, state.momenta) + Lb).sum(0)
    Ilab = np.einsum("kij,kj,klj->il", state.frames, model.inertia, state.frames)
    Ilab += np.sum(m * np.einsum("ki,ki->k", x, x)) * np.eye(3) - np.einsum("k,ki,kj->ij", m, x, x)
    Om = np.linalg.solve(Ilab, Ltot)
    state.momenta -= m[:, None] * np.cross(Om, x)
    state.angular_momenta -= model.inertia * np.einsum("kji,j->ki", state.frames, Om)


# ---------------------------------------------------------------------------------------------
# numpy reference sub-steps
# ---------------------------------------------------------------------------------------------
ROTOR_SEQUENCE = ((0, 0.5), (1, 0.5), (2, 1.0), (1, 0.5), (0, 0.5))


def rotor_flow(frames: np.ndarray, pi: np.ndarray, inv_inertia: np.ndarray, h: float) -> None:
    """Free-rotor flow for time ``h`` by the symmetric composition R1 R2 R3 R2 R1 (in place)."""
    for a, frac in ROTOR_SEQUENCE:
        b, d = (a + 1) % 3, (a + 2) % 3
        phi = frac * h * pi[:, a] * inv_inertia[:, a]
        c, s = np.cos(phi), np.sin(phi)
        cb, cd = frames[:, :, b].copy(), frames[:, :, d].copy()
        frames[:, :, b] = c[:, None] * cb + s[:, None] * cd
        frames[:, :, d] = c[:, None] * cd - s[:, None] * cb
        pb, pd = pi[:, b].copy(), pi[:, d].copy()
        pi[:, b] = c * pb + s * pd
        pi[:, d] = c * pd - s * pb


def _bad_step(positions, frames, closure):
    """First step whose rotation is at or beyond the Cayley limit, or None."""
    R, e = step_geometry(positions, frames, closure)
    den = 1.0 + np.trace(R, axis1=1, axis2=2)
    bad = ~(den > 2.0 * (1.0 + np.cos(MAX_CAYLEY_ANGLE))) | ~np.isfinite(e).all(1)
    return int(np.argmax(bad)) if bad.any() else None


class NumpyKernel:
    """Reference implementation of the splitting steps (vectorised numpy, :func:`dnarod.core.energy.loads`)."""

    def __init__(self, model: RodModel, ext_force: np.ndarray, ext_torque: np.ndarray, free: np.ndarray) -> None:
        self.model = model
        self.F_ext, self.tau_ext, self.free = ext_force, ext_torque, free

    def loads(self, state: RigidState) -> tuple[float, np.ndarray, np.ndarray]:
        """Elastic energy (kJ/mol), lab forces and torques (n, 3) with the external loads, zero on clamped nodes."""
        m = self.model
        E, F, tau = _loads(state.positions, state.frames, m.params, m.ds, m.closure)
        F += self.F_ext
        tau += self.tau_ext
        return E, F * self.free[:, None], tau * self.free[:, None]

    # the kernel interface (as the numba kernel's): state, loads, inverse masses and the Langevin terms as arrays
    def run(self, state: RigidState, F: np.ndarray, tau: np.ndarray, dt: float, n_steps: int, inv_m: np.ndarray,
            inv_J: np.ndarray, c: float | None = None, sig_P: np.ndarray | None = None,
            sig_pi: np.ndarray | None = None, noise: np.ndarray | None = None) -> tuple[int, int, int, float]:
        """Advance ``n_steps``; returns (status, step, node, E). status 0 = ok, 1 = failure at (step, node)."""
        E = np.nan
        h = 0.5 * dt
        for i in range(n_steps):
            state.momenta += h * F
            state.angular_momenta += h * np.einsum("kji,kj->ki", state.frames, tau)
            if noise is None:
                state.positions += dt * state.momenta * inv_m[:, None]
                rotor_flow(state.frames, state.angular_momenta, inv_J, dt)
            else:
                assert c is not None and sig_P is not None and sig_pi is not None
                state.positions += h * state.momenta * inv_m[:, None]
                rotor_flow(state.frames, state.angular_momenta, inv_J, h)
                state.momenta[:] = c * state.momenta + sig_P[:, None] * noise[i, :3].T
                state.angular_momenta[:] = c * state.angular_momenta + sig_pi * noise[i, 3:].T
                state.positions += h * state.momenta * inv_m[:, None]
                rotor_flow(state.frames, state.angular_momenta, inv_J, h)
            k = _bad_step(state.positions, state.frames, self.model.closure)
            if k is not None:
                return 1, i, k, E
            E, F[:], tau[:] = self.loads(state)
            state.momenta += h * F
            state.angular_momenta += h * np.einsum("kji,kj->ki", state.frames, tau)
            bad = ~((np.einsum("ki,ki->k", state.momenta, state.momenta) < MOMENTUM_LIMIT**2)
                    & (np.einsum("ki,ki->k", state.angular_momenta, state.angular_momenta) < MOMENTUM_LIMIT**2))
            if bad.any():
                return 2, i, int(np.argmax(bad)), E
        return 0, n_steps, -1, E


# ---------------------------------------------------------------------------------------------
# stability limit
# ---------------------------------------------------------------------------------------------
def omega_max(model: RodModel, positions: np.ndarray | None = None, frames: np.ndarray | None = None,
              boundary: BoundaryConditions | None = None, tol: float = 1e-9) -> float:
    """Largest normal-mode angular frequency ``omega_max`` (rad/ps) of a pose with its boundary conditions.

    ``omega_max^2`` is the largest eigenvalue of ``M^-1/2 H M^-1/2``; computed by
    :func:`dnarod.physics.modes.omega_max` (the one home: banded Hessian, bisection on Cholesky
    factorisability, exact to ``tol`` relative in ``omega^2``).

    Parameters
    ----------
    model : RodModel
    positions, frames : ndarray, optional
        Pose (default: the model's).
    boundary : BoundaryConditions, optional
        Clamped nodes are excluded; traps and rotation clamps add stiffness.
    tol : float
        Relative tolerance of the eigenvalue.

    Returns
    -------
    float
        rad/ps.
    """
    loads = () if boundary is None else boundary
    return _omega_max(model, loads, positions, frames, rtol=tol)


# ---------------------------------------------------------------------------------------------
# driver
# ---------------------------------------------------------------------------------------------
class SplittingIntegrator:
    """Kick-drift-rotor-kick integrator (NVE) or BAOAB Langevin integrator of a rod model.

    Parameters
    ----------
    model : RodModel
        Parameters, masses, inertias, closure (its pose is the default initial pose).
    dt : float
        Time step, ps.
    state : RigidState, optional
        Initial state (default: the model's pose at rest).
    boundary : BoundaryConditions, optional
    temperature : float, optional
        K; with ``friction`` switches on BAOAB Langevin dynamics.
    friction : float, optional
        Collision rate, 1/ps.
    seed : int, optional
        Seed of the Langevin noise (numpy ``default_rng``).
    fast : bool or {"blocked", "scalar"}
        Use the numba kernel (default: the SIMD-blocked one of :mod:`.fast_blocked`; ``"scalar"``
        the per-node one of :mod:`.fast`) or, with False, the numpy reference.
    check_stability : bool
        Compute ``dt_crit = 2/omega_max`` of the initial pose and refuse ``dt >= dt_crit``.
    allow_unstable : bool
        Only warn (``RuntimeWarning``) instead of raising when ``dt >= dt_crit``.

    Raises
    ------
    SimulationError
        If ``dt`` is at or above the stability limit (unless ``allow_unstable``).
    """

    # one keyword per integrator setting, as OpenMM integrators take them
    def __init__(self, model: RodModel, dt: float, state: RigidState | None = None,
                 boundary: BoundaryConditions | None = None, temperature: float | None = None,
                 friction: float | None = None, seed: int | None = None, fast: bool | str = True,
                 check_stability: bool = True, allow_unstable: bool = False,
                 noise_chunk_bytes: int = 8 << 20) -> None:
        if not (np.isfinite(dt) and dt > 0):
            raise DnarodError(f"time step dt must be a positive number of ps, got {dt}")
        self.model = model
        self.dt = float(dt)
        self.boundary = boundary or BoundaryConditions()
        self.state = RigidState.from_model(model) if state is None else state.copy()
        # one load vocabulary (dnarod.physics.loads): clamps of any node, dead forces/torques, traps, rotation clamps
        self.loads = self.boundary.resolved(model, self.state.positions, self.state.frames)
        clamp = self.loads.clamped
        self.F_dead, self.tau_dead = self.loads.force.copy(), self.loads.torque.copy()
        F_ext, tau_ext = self.F_dead.copy(), self.tau_dead.copy()
        self.free = (~clamp).astype(float)
        self.inv_m = self.free / model.mass
        self.inv_J = self.free[:, None] / model.inertia
        moving = (np.abs(self.state.momenta).sum(1) + np.abs(self.state.angular_momenta).sum(1) > 0) & clamp
        if moving.any():
            k = int(np.flatnonzero(moving)[0])
            raise DnarodError(f"node {k} is clamped but has nonzero initial momentum; a clamped node is at rest")
        self.langevin = temperature is not None or friction is not None
        if self.langevin:
            if temperature is None or friction is None:
                raise DnarodError("Langevin dynamics need both temperature (K) and friction (1/ps)")
            if not (temperature >= 0 and friction > 0 and np.isfinite(friction)):
                raise DnarodError(f"need temperature >= 0 K and friction > 0 1/ps, got {temperature}, {friction}")
            kt = _kT(temperature)
            self.c = float(np.exp(-friction * self.dt))
            self.sig_P = np.sqrt((1 - self.c**2) * model.mass * kt) * self.free
            self.sig_pi = np.sqrt((1 - self.c**2) * model.inertia * kt) * self.free[:, None]
        self.temperature, self.friction = temperature, friction
        self.rng = np.random.default_rng(seed)
        self.noise_chunk = max(1, int(noise_chunk_bytes // (48 * model.n_nodes)))
        self.step_count = 0
        self.omega_max: float | None = None
        self._pd: tuple[float, np.ndarray, np.ndarray] | None = None
        if self.loads.position_dependent:  # traps, rotation clamps: re-evaluated every step (see _run_loaded)
            self._pd = self._position_dependent_loads(0.0)
            F_ext += self._pd[1]
            tau_ext += self._pd[2]
        if check_stability:
            self.omega_max = _omega_max(model, self.loads, self.state.positions, self.state.frames,
                                        angles=self.loads.clamp_angles(0.0, self.boundary.duration_ps))
            dt_crit = 2.0 / self.omega_max
            if self.dt >= dt_crit:
                msg = (f"time step dt = {self.dt:g} ps is at or above the stability limit dt_crit = 2/omega_max = "
                       f"{dt_crit:.4g} ps (omega_max = {self.omega_max:.4g} rad/ps); the run would blow up. "
                       f"Use dt <= {0.25 / self.omega_max:.3g} ps (omega_max dt = 0.25) for accurate dynamics")
                if not allow_unstable:
                    raise SimulationError(msg, step=0, node=None, term="dt")
                warnings.warn(msg, RuntimeWarning, stacklevel=2)
        if fast:
            if fast not in (True, "blocked", "scalar"):
                raise DnarodError(f"fast must be True, False, 'blocked' or 'scalar', got {fast!r}")
            self.kernel: NumbaKernel | NumpyKernel = NumbaKernel(model, F_ext, tau_ext, self.free,
                                                                 blocked=(fast != "scalar"))
        else:
            self.kernel = NumpyKernel(model, F_ext, tau_ext, self.free)
        self.potential_energy, self.F, self.tau = self._initial_loads()

    def _position_dependent_loads(self, time_ps: float) -> tuple[float, np.ndarray, np.ndarray]:
        """Energy (kJ/mol) and lab loads of the traps and rotation clamps (dead loads excluded) at the
        current state, rotation clamps turned to their angle at ``time_ps``."""
        s = self.state
        angles = self.loads.clamp_angles(time_ps, self.boundary.duration_ps)
        E, F, tau = self.loads.evaluate(s.positions, s.frames, angles)
        return E + float(np.sum(self.F_dead * s.positions)), F - self.F_dead, tau - self.tau_dead

    def _run_loaded(self, n_steps: int, extra: dict[str, Any]) -> tuple[int, int, int, float]:
        """Steps with position-dependent loads: the kernel's closing half kick used the loads of the
        start of the step; it is corrected by ``dt/2 (f_new - f_old)``, which gives exactly the
        velocity-Verlet (BAOAB) step with the full loads."""
        h = 0.5 * self.dt
        k = self.kernel
        E = np.nan
        for i in range(n_steps):
            ex = dict(extra)
            if "noise" in ex:
                ex["noise"] = extra["noise"][i:i + 1]
            status, ii, node, E = k.run(self.state, self.F, self.tau, self.dt, 1, self.inv_m, self.inv_J, **ex)
            if status != 0:
                return status, i + ii, node, E
            assert self._pd is not None  # set in __init__ when the loads depend on the position
            _, F_old, tau_old = self._pd
            self._pd = self._position_dependent_loads((self.step_count + i + 1) * self.dt)
            dF = (self._pd[1] - F_old) * self.free[:, None]
            dtau = (self._pd[2] - tau_old) * self.free[:, None]
            self.state.momenta += h * dF
            self.state.angular_momenta += h * np.einsum("kji,kj->ki", self.state.frames, dtau)
            self.F += dF
            self.tau += dtau
            k.F_ext[:] = self.F_dead + self._pd[1]
            k.tau_ext[:] = self.tau_dead + self._pd[2]
        return 0, n_steps, -1, E

    def _initial_loads(self) -> tuple[float, np.ndarray, np.ndarray]:
        try:
            return self.kernel.loads(self.state)
        except GeometryError as exc:
            raise SimulationError(f"step {self.step_count}: {exc}", step=self.step_count, term="rotation") from None

    # ------------------------------------------------------------------------------------
    def kinetic_energy(self) -> float:
        """kJ/mol."""
        return self.state.kinetic_energy(self.model.mass, self.model.inertia)

    def total_energy(self) -> float:
        """Elastic + trap + rotation-clamp + kinetic energy minus the work potential of the dead forces, kJ/mol."""
        return (self.potential_energy + self.external_energy + self.kinetic_energy()
                - float(np.sum(self.F_dead * self.state.positions)))

    @property
    def external_energy(self) -> float:
        """Energy of the traps and rotation clamps at the current state, kJ/mol (``potential_energy`` is
        the elastic energy only)."""
        return 0.0 if self._pd is None else self._pd[0]

    def step(self, n_steps: int = 1) -> None:
        """Advance ``n_steps`` steps (in place).

        Raises
        ------
        SimulationError
            Naming the step, the node and the quantity (rotation at or beyond pi, non-finite
            momentum) when the run blows up; the state is the last one reached.
        """
        n_steps = int(n_steps)
        done = 0
        while done < n_steps:
            chunk = min(n_steps - done, self.noise_chunk) if self.langevin else n_steps - done
            extra: dict[str, Any] = {}
            if self.langevin:
                extra = dict(c=self.c, sig_P=self.sig_P, sig_pi=self.sig_pi,
                             noise=self.rng.standard_normal((chunk, 6, self.model.n_nodes)))
            if self._pd is not None:
                status, i, node, E = self._run_loaded(chunk, extra)
            else:
                status, i, node, E = self.kernel.run(self.state, self.F, self.tau, self.dt, chunk, self.inv_m,
                                                     self.inv_J, **extra)
            if status != 0:
                step = self.step_count + i + 1
                self.step_count += max(i, 0)
                if status == 1:
                    term = "rotation between neighbouring frames"
                    what = (f"the rotation of {step_name(node, self.model.n_nodes)} is at or beyond 180 deg or "
                            f"not finite")
                else:
                    term = "momentum"
                    what = f"the momentum of {base_pair(node)} is not finite or above {MOMENTUM_LIMIT:g}"
                raise SimulationError(
                    f"time step {step}: the run blew up at {base_pair(node)}: {what} (t = {step * self.dt:g} ps); "
                    f"reduce dt (stability limit 2/omega_max) or check the initial state",
                    step=step, node=node, term=term)
            self.potential_energy = E
            done += chunk
            self.step_count += chunk
