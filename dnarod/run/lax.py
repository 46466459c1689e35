"""Running the Lax-form engine from Python: NVE and Langevin runs with trajectories, energies and checkpoints.

``simulate_nve``/``simulate_langevin`` are thin wrappers over the run layer's one loop
(:func:`dnarod.run.run_engine` with :class:`dnarod.engines.lax.engine.LaxEngine` and its reporters), writing the
shared formats, so every analysis runs on both engines:

* ``.dtraj`` trajectory with centre velocities (lab, nm/ps) and body angular velocities (rad/ps),
  in float64 here (these functions serve the validation, which compares exact numbers; the
  ``dnarod simulate`` runs store float32);
* energies CSV with the run layer's header (:data:`dnarod.run.reporters.ENERGY_COLUMNS`);
* checkpoint ``.npz`` (written atomically, every ``checkpoint_interval`` steps and at the end):
  state, step, time step and the random-number state, so a resumed run continues bit-for-bit as if
  uninterrupted; the trajectory and CSV are cut back to the checkpoint's step on resume.

A blow-up (NaN, a step rotating to 180 deg) stops the run with :class:`~dnarod.core.errors.SimulationError` naming the
step, the node and the quantity; everything written before stays on disk.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.core.io import atomic_path
from dnarod.physics.thermal import kinetic_temperature, node_kinetic_energy
from dnarod.core.trajectory import load_trajectory
from dnarod.engines.lax.engine import LaxEngine
from dnarod.engines.lax.splitting import RigidState, SplittingIntegrator, maxwell_state
from dnarod.run.loop import run_engine
from dnarod.run.reporters import ENERGY_COLUMNS, DtrajReporter, EnergyReporter, ProgressReporter


@dataclass
class SimulationResult:
    """Outcome of a run.

    Attributes
    ----------
    state : RigidState
        Final state.
    step : int
        Steps done in total (including those before a resume).
    energies : ndarray, shape (n_reports, 6)
        Reported rows of this call (step, time ps, potential, kinetic, total kJ/mol, temperature K).
    trajectory_path : Path or None
    omega_max : float or None
        rad/ps, of the initial pose (None if not computed).
    integrator : SplittingIntegrator
    """

    state: RigidState
    step: int
    energies: np.ndarray
    trajectory_path: Path | None
    omega_max: float | None
    integrator: SplittingIntegrator

    def trajectory(self):
        """The written trajectory as a :class:`~dnarod.core.trajectory.Trajectory` (requires ``out``)."""
        if self.trajectory_path is None:
            raise DnarodError("this run wrote no trajectory; pass out=PATH")
        return load_trajectory(self.trajectory_path)


class _Rows:
    """Reporter keeping the energy rows in memory (for :attr:`SimulationResult.energies`)."""

    def __init__(self, interval):
        self.interval = int(interval)
        self.rows = []

    def describeNextReport(self, engine):  # noqa: N802 - reporter protocol
        return self.interval - engine.step % self.interval

    def due(self, step):
        return step % self.interval == 0

    def report(self, engine, snap):
        e = snap.energies
        self.rows.append([snap.step, snap.time_ps, e["potential"], e["kinetic"], e["potential"] + e["kinetic"],
                          e["temperature"]])

    def flush(self):
        pass

    def close(self):
        pass


def _simulate(model, dt, n_steps, *, state, boundary, temperature, friction, seed, out, report_interval,
              energy_csv, checkpoint, checkpoint_interval, resume, fast, allow_unstable, check_stability,
              metadata, progress):
    n_steps = int(n_steps)
    if n_steps < 0:
        raise DnarodError(f"n_steps must be >= 0, got {n_steps}")
    report_interval = max(1, int(report_interval))
    if resume and checkpoint is None:
        raise DnarodError("resume=True needs the checkpoint path")
    integ = SplittingIntegrator(model, dt, state=state, boundary=boundary,
                                temperature=temperature if friction else None, friction=friction, seed=seed, fast=fast,
                                check_stability=check_stability, allow_unstable=allow_unstable)
    engine = LaxEngine.wrap(integ, temperature=temperature or 0.0, friction=friction or 0.0, seed=seed)
    resume_step = None
    if resume and Path(checkpoint).exists():
        engine.load_checkpoint(checkpoint)
        resume_step = engine.step
    meta = dict(engine="lax", dt_ps=dt, ensemble="langevin" if friction else "nve", temperature_K=temperature,
                friction_per_ps=friction, n_nodes=model.n_nodes, **(metadata or {}))
    rows = _Rows(report_interval)
    reporters = [rows]
    bar = None
    try:
        if out is not None:
            reporters.append(DtrajReporter(out, model.n_nodes, report_interval, velocities=True, metadata=meta,
                                           resume_step=resume_step, precision="float64"))
        if energy_csv is not None:
            reporters.append(EnergyReporter(energy_csv, report_interval, resume_step=resume_step))
        if progress:
            bar = ProgressReporter(n_steps, engine.step)
        run_engine(engine, n_steps, reporters, checkpoint, checkpoint_interval if checkpoint is not None else 0,
                   bar, report_start=resume_step is None)
    finally:
        for r in reporters:
            r.close()
        if bar is not None:
            bar.close()
    return SimulationResult(integ.state, integ.step_count, np.array(rows.rows), None if out is None else Path(out),
                            integ.omega_max, integ)


def simulate_nve(model, dt, n_steps, state=None, temperature=None, seed=None, boundary=None, out=None,
                 report_interval=100, energy_csv=None, checkpoint=None, checkpoint_interval=None, resume=False,
                 fast=True, allow_unstable=False, check_stability=True, metadata=None, progress=False):
    """Constant-energy run with the symplectic splitting (docs/formulation.md §7).

    Parameters
    ----------
    model : RodModel
    dt : float
        Time step, ps (must be below ``2/omega_max``; about ``0.25/omega_max`` for accuracy).
    n_steps : int
        Total steps of the run, counted from 0 (a resumed run continues up to ``n_steps``).
    state : RigidState, optional
        Initial state; default the model's pose with Maxwell momenta at ``temperature`` (K) if
        given (drift removed), else at rest.
    seed : int, optional
        For the initial velocities.
    boundary : BoundaryConditions, optional
    out : path, optional
        ``.dtraj`` trajectory (frames every ``report_interval`` steps, with velocities).
    energy_csv : path, optional
    checkpoint : path, optional
        Written every ``checkpoint_interval`` steps and at the end.
    resume : bool
        Continue from ``checkpoint`` if it exists.
    fast : bool
        numba kernel (default) or numpy reference.

    Returns
    -------
    SimulationResult

    Raises
    ------
    SimulationError
        Unstable time step, or a blow-up (step, node and quantity named; output so far kept).
    """
    if state is None and temperature is not None:
        state = maxwell_state(model, temperature, seed, boundary)
    return _simulate(model, dt, n_steps, state=state, boundary=boundary, temperature=temperature, friction=None,
                     seed=seed, out=out, report_interval=report_interval, energy_csv=energy_csv,
                     checkpoint=checkpoint, checkpoint_interval=checkpoint_interval, resume=resume, fast=fast,
                     allow_unstable=allow_unstable, check_stability=check_stability, metadata=metadata,
                     progress=progress)


def simulate_langevin(model, dt, n_steps, temperature, friction=1.0, seed=None, state=None, boundary=None, out=None,
                      report_interval=100, energy_csv=None, checkpoint=None, checkpoint_interval=None, resume=False,
                      fast=True, allow_unstable=False, check_stability=True, metadata=None, progress=False):
    """Langevin run (BAOAB on lab momenta and body angular momenta) at ``temperature`` (K).

    Parameters are those of :func:`simulate_nve` plus ``friction`` (collision rate, 1/ps) and
    ``seed`` (initial Maxwell velocities and the noise). Returns :class:`SimulationResult`.
    """
    if temperature is None or not temperature >= 0:
        raise DnarodError(f"temperature must be >= 0 K, got {temperature}")
    if state is None:
        state = maxwell_state(model, temperature, seed, boundary)
    return _simulate(model, dt, n_steps, state=state, boundary=boundary, temperature=temperature, friction=friction,
                     seed=seed, out=out, report_interval=report_interval, energy_csv=energy_csv,
                     checkpoint=checkpoint, checkpoint_interval=checkpoint_interval, resume=resume, fast=fast,
                     allow_unstable=allow_unstable, check_stability=check_stability, metadata=metadata,
                     progress=progress)


def simulate_exact(model, t_end, velocities=None, angular_velocities=None, temperature=None, seed=None,
                   boundary=None, rtol=1e-10, atol=1e-10, n_frames=101, out=None, energy_csv=None):
    """Reference run of the exact strain-space system with DOP853 (docs/formulation.md §6-7).

    Initial velocities: given, or Maxwell at ``temperature`` (K), or at rest. Writes the same
    ``.dtraj`` and energies CSV as the splitting runs. Returns :class:`.exact.ExactResult`.
    """
    from dnarod.engines.lax.exact import integrate_exact

    if velocities is None and angular_velocities is None and temperature is not None:
        st = maxwell_state(model, temperature, seed, boundary)
        velocities, angular_velocities = st.velocities(model.mass, model.inertia)
    res = integrate_exact(model, t_end, velocities, angular_velocities, boundary, rtol, atol, n_frames)
    if out is not None:
        res.trajectory.save(out)
    if energy_csv is not None:
        from dnarod.engines.lax.boundary import BoundaryConditions

        tr = res.trajectory
        ke = node_kinetic_energy(model.mass, model.inertia, tr.velocities, tr.angular_velocities)
        temp = kinetic_temperature(ke, 6 * model.n_nodes)
        F_ext = (boundary or BoundaryConditions()).resolve(model.n_nodes, model.circular)[1]
        ext = -np.einsum("ki,fki->f", F_ext, tr.positions)  # dead forces; dead torques have no potential
        lines = [",".join(ENERGY_COLUMNS) + "\n"] + [
            f"{i},{t:.6f},{E - k!r},{k!r},{E!r},{T:.6f},{E - k - x!r},0.0,{x!r}\n"
            for i, (t, E, k, T, x) in enumerate(zip(tr.time, map(float, res.energy), map(float, ke),
                                                    map(float, temp), map(float, ext)))]
        with atomic_path(energy_csv) as tmp:
            Path(tmp).write_text("".join(lines))
    return res
