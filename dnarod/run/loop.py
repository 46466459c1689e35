"""The one run loop of both engines: advance to the next report, report, checkpoint, end with a checkpoint."""
from __future__ import annotations

import time

from dnarod.core.errors import ParameterError
from dnarod.run.reporters import Snapshot


def _next_multiple(step, interval):
    return (step // interval + 1) * interval


def run_engine(engine, n_steps, reporters=(), checkpoint=None, checkpoint_interval=0, progress=None,
               duration_ps=None, checkpoint_extra=None, report_start=True, checkpoint_wall_s=None):
    """Advance ``engine`` to a total of ``n_steps`` steps, feeding the reporters and writing checkpoints.

    Parameters
    ----------
    engine : engine (see :mod:`dnarod.run.engine`)
    n_steps : int
        Total steps of the run, counted from its start (a resumed engine continues from ``engine.step``).
    reporters : sequence
        Objects with ``describeNextReport(engine)``, ``due(step)``, ``report(engine, snapshot)``, ``flush()``.
    checkpoint : Path or None
        Checkpoint file: written every ``checkpoint_interval`` steps (0: none in between), at the first report
        after ``checkpoint_wall_s`` wall seconds since the last one, and always at the end, after the reporters
        are flushed. Reporters with ``state()`` (and ``name``) have their state stored in it
        (``meta["extra"]["reporters"][name]``), so they resume with the engine (:mod:`dnarod.run.sampling`).
    progress : ProgressReporter or None
    duration_ps : float or None
        Run length over which rotation clamps spread their turns (passed to ``engine.update_loads``).
    checkpoint_extra : dict or None
        Stored in every checkpoint's metadata.
    checkpoint_wall_s : float or None
        Wall seconds between checkpoints (None: by steps only).
    report_start : bool
        Report the starting state (a new run; a resumed run has it on disk).

    Returns
    -------
    dict
        ``steps`` (total), ``steps_this_run``, ``wall_s``, ``cpu_s``, ``temperatures`` (one per energy row).
    """
    n_steps = int(n_steps)
    ci = int(checkpoint_interval or 0)
    start = int(engine.step)
    t0, c0 = time.perf_counter(), time.process_time()
    reporters = list(reporters)
    update = getattr(engine, "update_loads", None)

    def report_all():
        snap = Snapshot(engine)
        for r in reporters:
            if r.due(snap.step):
                r.report(engine, snap)

    stateful = [r for r in reporters if hasattr(r, "state")]

    def save():
        for r in reporters:
            r.flush()
        extra = dict(checkpoint_extra or {})
        if stateful:
            extra["reporters"] = {r.name: r.state() for r in stateful}
        engine.save_checkpoint(checkpoint, extra=extra)
        return time.perf_counter()

    last_save = t0

    if report_start:
        report_all()
    timed = None  # (step, wall, cpu) after the first advance: the speed leaves out the kernels' first-call compile
    while engine.step < n_steps:
        nxt = n_steps
        for r in reporters:
            nxt = min(nxt, engine.step + r.describeNextReport(engine))
        if checkpoint is not None and ci:
            nxt = min(nxt, _next_multiple(engine.step, ci))
        engine.advance(nxt - engine.step)
        if timed is None:
            timed = (int(engine.step), time.perf_counter(), time.process_time())
        if update is not None:
            update(engine.step * engine.dt, duration_ps)
        report_all()
        if progress is not None:
            progress.update(engine.step)
        if checkpoint is not None and engine.step < n_steps and (
                (ci and engine.step % ci == 0)
                or (checkpoint_wall_s is not None and time.perf_counter() - last_save >= checkpoint_wall_s)):
            last_save = save()
    if checkpoint is not None:
        save()
    else:
        for r in reporters:
            r.flush()
    t1, c1 = time.perf_counter(), time.process_time()
    return dict(steps=int(engine.step), steps_this_run=int(engine.step) - start,
                wall_s=t1 - t0, cpu_s=c1 - c0, timed_steps=int(engine.step) - timed[0] if timed else 0,
                timed_wall_s=t1 - timed[1] if timed else 0.0)


def simulate_engine(engine, n_steps, outdir, frame_interval=100, energy_interval=None, checkpoint_interval=None,
                    resume=False, overwrite=False, velocities=False, precision="float32", metadata=None,
                    observables=None, progress=False, duration_ps=None, checkpoint_extra=None, restored=False):
    """Run an engine into a folder: ``trajectory.dtraj``, ``energies.csv``, ``checkpoint.npz``, ``final_model.npz``.

    The engine-level form of :func:`dnarod.run.run` (which also builds the engine from a
    :class:`~dnarod.run.RunSpec`, writes ``run.json`` and exports): for code that makes its own
    engine (validation, benchmarks, tests).

    Parameters
    ----------
    engine : engine
    n_steps : int
        Total steps (counted from the start, also when resuming).
    outdir : str or Path
    frame_interval, energy_interval : int
        Steps between frames and between energy rows (default: the frame interval).
    checkpoint_interval : int or None
        Steps between checkpoints (default ten frame intervals; 0: only at the end).
    resume : bool
        Continue from ``outdir/checkpoint.npz`` (read before any file is touched); the trajectory and
        CSV are cut back to its step.
    overwrite : bool
        Replace a trajectory already in ``outdir`` (without it that is an error).
    velocities : bool
        Store velocities in the trajectory.
    precision : {"float32", "float64"}
        Trajectory storage.
    metadata : dict
        Trajectory header metadata.
    observables : callable or None
        Extra energies-CSV columns (see :class:`~dnarod.run.reporters.EnergyReporter`).
    restored : bool
        With ``resume``: the engine already holds the checkpoint's state (do not load it again).

    Returns
    -------
    dict
        The loop's summary (:func:`run_engine`) plus ``temperatures`` (K, one per energy row) and
        ``resumed_from``.
    """
    from dnarod.core.io import ensure_dir
    from dnarod.run.reporters import DtrajReporter, EnergyReporter, ProgressReporter

    outdir = ensure_dir(outdir)
    fi = int(frame_interval)
    ei = int(energy_interval or fi)
    ci = 10 * fi if checkpoint_interval is None else int(checkpoint_interval)
    if fi <= 0 or ei <= 0 or ci < 0:
        raise ParameterError(f"frame and energy intervals must be positive and the checkpoint interval >= 0 steps, "
                             f"got {fi}, {ei}, {ci}")
    traj, csv_path, chk = outdir / "trajectory.dtraj", outdir / "energies.csv", outdir / "checkpoint.npz"
    resume_step = None
    if resume:
        if not restored:
            engine.load_checkpoint(chk)
        resume_step = int(engine.step)
    elif traj.exists() and not overwrite:
        raise ParameterError(f"{traj} already exists: resume the run (--resume), choose another output folder, or "
                             f"pass --overwrite")
    reporters, bar = [], None
    try:
        reporters.append(DtrajReporter(traj, engine.model.n_nodes, fi, velocities, metadata, resume_step=resume_step,
                                       precision=precision))
        energy = EnergyReporter(csv_path, ei, observables=observables, resume_step=resume_step)
        reporters.append(energy)
        if progress:
            bar = ProgressReporter(n_steps, engine.step)
        out = run_engine(engine, n_steps, reporters, chk, ci, bar, duration_ps, checkpoint_extra,
                         report_start=resume_step is None)
    finally:
        for r in reporters:
            r.close()
        if bar is not None:
            bar.close()
    engine.current_model().save(outdir / "final_model.npz")
    out.update(temperatures=energy.temperatures, resumed_from=resume_step)
    return out
