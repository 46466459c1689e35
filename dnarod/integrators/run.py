"""Running the Lax-form engine: NVE and Langevin runs with trajectories, energies and checkpoints.

Outputs are the shared formats, so every analysis runs on both engines:

* ``.dtraj`` trajectory (:class:`dnarod.trajectory.TrajectoryWriter`) with centre velocities
  (lab, nm/ps) and body angular velocities (rad/ps);
* energies CSV: ``step, time_ps, potential_kJ_mol, kinetic_kJ_mol, total_kJ_mol, temperature_K``;
* checkpoint ``.npz`` (written atomically): state, step, time and the random-number state, so a
  resumed run continues bit-for-bit as if uninterrupted; the trajectory and CSV are cut back to
  the checkpoint's step on resume (no lost or duplicated frames).

A blow-up (NaN, a step rotating to 180 deg) stops the run with :class:`SimulationError` naming the
step, the node and the quantity; everything written before stays on disk.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DnarodError, SimulationError
from ..io_utils import atomic_path
from ..thermal import kinetic_temperature, node_kinetic_energy
from ..trajectory import Trajectory, TrajectoryWriter, load_trajectory
from .splitting import RigidState, SplittingIntegrator, maxwell_state

CSV_HEADER = "step,time_ps,potential_kJ_mol,kinetic_kJ_mol,total_kJ_mol,temperature_K\n"


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
        Rows of the energies CSV (step, time ps, potential, kinetic, total kJ/mol, temperature K).
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
        """The written trajectory as a :class:`Trajectory` (requires ``out``)."""
        if self.trajectory_path is None:
            raise DnarodError("this run wrote no trajectory; pass out=PATH")
        return load_trajectory(self.trajectory_path)


def _energy_row(integ, n_free_dof):
    ke = integ.kinetic_energy()
    pe = integ.potential_energy
    tot = integ.total_energy()
    temp = kinetic_temperature(ke, n_free_dof)
    return [integ.step_count, integ.step_count * integ.dt, pe, ke, tot, temp]


def save_checkpoint(path, integ):
    """Write the integrator's state, step and RNG state to ``path`` (npz, atomic)."""
    s = integ.state
    meta = dict(format="dnarod-lax-checkpoint", version=1, step=integ.step_count, dt=integ.dt,
                n_nodes=integ.model.n_nodes, langevin=integ.langevin,
                rng=integ.rng.bit_generator.state)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, positions=s.positions, frames=s.frames, momenta=s.momenta,
                     angular_momenta=s.angular_momenta, meta=np.array(json.dumps(meta)))


def load_checkpoint(path):
    """Read a checkpoint: ``(RigidState, meta dict)``."""
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            if meta.get("format") != "dnarod-lax-checkpoint":
                raise DnarodError(f"{path}: not a dnarod Lax-engine checkpoint")
            state = RigidState(z["positions"].copy(), z["frames"].copy(), z["momenta"].copy(),
                               z["angular_momenta"].copy())
    except (OSError, KeyError, ValueError) as exc:
        if isinstance(exc, DnarodError):
            raise
        raise DnarodError(f"{path}: cannot read checkpoint ({exc})") from None
    return state, meta


def _truncate_csv(path, step):
    lines = Path(path).read_text().splitlines(keepends=True)
    keep = [lines[0]] + [ln for ln in lines[1:] if ln.strip() and int(float(ln.split(",")[0])) <= step]
    with atomic_path(path) as tmp:
        Path(tmp).write_text("".join(keep))


def _simulate(model, dt, n_steps, *, state, boundary, temperature, friction, seed, out, report_interval,
              energy_csv, checkpoint, checkpoint_interval, resume, fast, allow_unstable, check_stability,
              metadata, progress):
    n_steps = int(n_steps)
    if n_steps < 0:
        raise DnarodError(f"n_steps must be >= 0, got {n_steps}")
    report_interval = max(1, int(report_interval))
    resumed_meta = None
    if resume:
        if checkpoint is None:
            raise DnarodError("resume=True needs the checkpoint path")
        if Path(checkpoint).exists():
            state, resumed_meta = load_checkpoint(checkpoint)
            if resumed_meta["n_nodes"] != model.n_nodes or abs(resumed_meta["dt"] - dt) > 1e-15 * dt:
                raise DnarodError(f"{checkpoint}: checkpoint of {resumed_meta['n_nodes']} nodes at dt = "
                                  f"{resumed_meta['dt']} ps does not match this run ({model.n_nodes} nodes, dt = {dt})")
    integ = SplittingIntegrator(model, dt, state=state, boundary=boundary, temperature=temperature if friction else None,
                                friction=friction, seed=seed, fast=fast, check_stability=check_stability,
                                allow_unstable=allow_unstable)
    n_free_dof = 6 * int(integ.free.sum())
    start = 0
    if resumed_meta is not None:
        start = int(resumed_meta["step"])
        integ.step_count = start
        integ.rng.bit_generator.state = resumed_meta["rng"]
    meta = dict(engine="dnarod-lax-splitting", dt_ps=dt, ensemble="langevin" if friction else "nve",
                temperature_K=temperature, friction_per_ps=friction, n_nodes=model.n_nodes, **(metadata or {}))
    writer = None
    csv = None
    rows = []
    try:
        if out is not None:
            writer = TrajectoryWriter(out, model.n_nodes, velocities=True, metadata=meta,
                                      resume_step=start if resumed_meta is not None else None)
        if energy_csv is not None:
            if resumed_meta is not None and Path(energy_csv).exists():
                _truncate_csv(energy_csv, start)
                csv = open(energy_csv, "a")
            else:
                csv = open(energy_csv, "w")
                csv.write(CSV_HEADER)

        def report():
            row = _energy_row(integ, n_free_dof)
            rows.append(row)
            if writer is not None:
                v, w = integ.state.velocities(model.mass, model.inertia)
                writer.write(integ.step_count, integ.step_count * dt, integ.state.positions, integ.state.frames, v, w)
            if csv is not None:
                csv.write(",".join(f"{x:.17g}" if isinstance(x, float) else str(x) for x in row) + "\n")
                csv.flush()
            if not np.isfinite(row[4]):
                ke = (np.sum(integ.state.momenta**2, 1) / model.mass
                      + np.sum(integ.state.angular_momenta**2 / model.inertia, 1))
                node = int(np.argmax(np.where(np.isfinite(ke), ke, np.inf)))
                raise SimulationError(f"step {integ.step_count}: total energy is not finite (largest kinetic energy "
                                      f"at node {node})", step=integ.step_count, node=node, term="energy")

        if resumed_meta is None:
            report()
        bar = None
        if progress:
            from tqdm import tqdm
            bar = tqdm(total=n_steps, initial=start, unit="step")
        target = n_steps
        while integ.step_count < target:
            nxt = min(target, (integ.step_count // report_interval + 1) * report_interval)
            if checkpoint is not None and checkpoint_interval:
                nxt = min(nxt, (integ.step_count // checkpoint_interval + 1) * checkpoint_interval)
            before = integ.step_count
            integ.step(nxt - integ.step_count)
            if bar is not None:
                bar.update(integ.step_count - before)
            if integ.step_count % report_interval == 0 or integ.step_count == target:
                report()
            if checkpoint is not None and (integ.step_count == target or
                                           (checkpoint_interval and integ.step_count % checkpoint_interval == 0)):
                save_checkpoint(checkpoint, integ)
        if bar is not None:
            bar.close()
    finally:
        if writer is not None:
            writer.close()
        if csv is not None:
            csv.close()
    return SimulationResult(integ.state, integ.step_count, np.array(rows), None if out is None else Path(out),
                            integ.omega_max, integ)


def simulate_nve(model, dt, n_steps, state=None, temperature=None, seed=None, boundary=None, out=None,
                 report_interval=100, energy_csv=None, checkpoint=None, checkpoint_interval=None, resume=False,
                 fast=True, allow_unstable=False, check_stability=True, metadata=None, progress=False):
    """Constant-energy run with the symplectic splitting (design A4 b).

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
    """Reference run of the exact strain-space system with DOP853 (design A3, A4 a).

    Initial velocities: given, or Maxwell at ``temperature`` (K), or at rest. Writes the same
    ``.dtraj`` and energies CSV as the splitting runs. Returns :class:`.exact.ExactResult`.
    """
    from .exact import integrate_exact

    if velocities is None and angular_velocities is None and temperature is not None:
        st = maxwell_state(model, temperature, seed, boundary)
        velocities, angular_velocities = st.velocities(model.mass, model.inertia)
    res = integrate_exact(model, t_end, velocities, angular_velocities, boundary, rtol, atol, n_frames)
    if out is not None:
        res.trajectory.save(out)
    if energy_csv is not None:
        tr = res.trajectory
        ke = node_kinetic_energy(model.mass, model.inertia, tr.velocities, tr.angular_velocities)
        temp = kinetic_temperature(ke, 6 * model.n_nodes)
        lines = [CSV_HEADER] + [f"{i},{t:.17g},{E - k:.17g},{k:.17g},{E:.17g},{T:.17g}\n"
                                for i, (t, E, k, T) in enumerate(zip(tr.time, res.energy, ke, temp))]
        with atomic_path(energy_csv) as tmp:
            Path(tmp).write_text("".join(lines))
    return res
