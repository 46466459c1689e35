"""The one run loop of both engines: advance to the next report, report, checkpoint, end with a checkpoint.

Checkpoints follow one of two schedules: every ``checkpoint_interval`` steps (an explicit choice), or, by
default, by wall time: at the first report after ``checkpoint_wall_s`` seconds since the last checkpoint
(or the start). A checkpoint costs the same whatever the step count, so a wall-time schedule keeps its
share of the run small for small and large models alike while bounding the work an interruption loses.
One is always written at the end, and on a Ctrl-C (SIGINT) the loop finishes the current advance and
report, writes one and then raises :class:`KeyboardInterrupt` (a second Ctrl-C stops at once).

Batched reports: when the engine can read several reports in one call
(:class:`~dnarod.run.engine.BatchReportingEngine`, the OpenMM engine on the compiled path) and every reporter
takes them (``supports_batch``, ``report_batch``; the trajectory and energies reporters without observable
columns), at one interval, the loop advances a batch of reports at a time and hands it to the reporters at once:
the same files, bit for bit, without a Python round trip per report. Checkpoints, the progress bar and Ctrl-C
then act between batches (at most ``MAX_BATCH_REPORTS`` reports and about :data:`BATCH_WALL_S` seconds).
"""
from __future__ import annotations

import signal
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, cast

from dnarod.core.errors import ParameterError
from dnarod.run.reporters import DtrajReporter, EnergyReporter, ProgressReporter, ReportBatch, Snapshot
from dnarod.core.io import ensure_dir
from dnarod.run.engine import BatchReportingEngine, Engine

#: Default wall time between checkpoints, s (a checkpoint is always written at the end and on Ctrl-C): the
#: protocol samplers' interval. A checkpoint of a 1,000-node OpenMM run takes about a millisecond, so
#: checkpointing stays far below 1 % of the run, and an interrupted run loses at most two minutes.
CHECKPOINT_WALL_S = 120.0


#: Longest a batch of reports runs, s (about): checkpoints, the progress bar and Ctrl-C act between batches.
BATCH_WALL_S = 0.5


def _next_multiple(step: int, interval: int) -> int:
    return (step // interval + 1) * interval


class _DeferredInterrupt:
    """Catch the first SIGINT as a flag (main thread only), so the loop can stop at a consistent step;
    a second SIGINT raises :class:`KeyboardInterrupt` at once."""

    def __init__(self):
        self.hit = False
        self._old = None

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            try:
                self._old = signal.signal(signal.SIGINT, self._handler)
            except (ValueError, OSError):  # not settable here (an embedded interpreter)
                self._old = None
        return self

    def _handler(self, signum, frame):
        if self.hit:
            raise KeyboardInterrupt
        self.hit = True

    def __exit__(self, *exc):
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)
        return False


def _batch_interval(engine: Engine, reporters: Sequence[Any], checkpoint_interval: int) -> int:
    """The report interval (steps) if the reports can be read in batches, else 0: the engine offers
    ``advance_reports`` and says it can use it now, every reporter takes batches (``supports_batch``), all report
    at one interval, and a step-scheduled checkpoint falls on reports."""
    ok = getattr(engine, "supports_report_batches", None)
    if not reporters or ok is None or not ok() or not all(getattr(r, "supports_batch", False) for r in reporters):
        return 0
    intervals = {int(r.interval) for r in reporters}
    if len(intervals) != 1:
        return 0
    bi = intervals.pop()
    return bi if bi > 0 and (not checkpoint_interval or checkpoint_interval % bi == 0) else 0


def _report_batch(engine: BatchReportingEngine, reporters: Sequence[Any], k: int, interval: int,
                  duration_ps: float | None) -> float:
    """Advance up to ``k`` reports in one batch and hand it to the reporters; returns the wall seconds per report
    (0.0 if none was made). A blow-up is raised after the good reports are written."""
    t = time.perf_counter()
    steps, state, energies, error = engine.advance_reports(min(k, engine.MAX_BATCH_REPORTS), interval, duration_ps)
    per_report = (time.perf_counter() - t) / len(steps) if len(steps) else 0.0
    if len(steps):
        batch = ReportBatch(engine, steps, state, energies)
        for r in reporters:
            r.report_batch(engine, batch)
    if error is not None:
        raise error
    return per_report


def run_engine(engine: Engine, n_steps: int, reporters: Sequence[Any] = (), checkpoint: str | Path | None = None,
               checkpoint_interval: int = 0, progress: Any = None,
               duration_ps: float | None = None, checkpoint_extra: dict[str, Any] | None = None,
               report_start: bool = True, checkpoint_wall_s: float | None = None) -> dict[str, Any]:
    """Advance ``engine`` to a total of ``n_steps`` steps, feeding the reporters and writing checkpoints.

    Parameters
    ----------
    engine : engine (see :mod:`dnarod.run.engine`)
    n_steps : int
        Total steps of the run, counted from its start (a resumed engine continues from ``engine.step``).
    reporters : sequence
        Objects with ``describeNextReport(engine)``, ``due(step)``, ``report(engine, snapshot)``, ``flush()``;
        optionally ``supports_batch`` and ``report_batch(engine, batch)`` (a
        :class:`~dnarod.run.reporters.ReportBatch`).
    checkpoint : Path or None
        Checkpoint file: written on the schedule below and always at the end, after the reporters are
        flushed (and on a Ctrl-C, at the step the engine has reached). Reporters with ``state()`` (and ``name``)
        have their state stored in it (``meta["extra"]["reporters"][name]``), so they resume with the engine
        (:mod:`dnarod.run.sampling`).
    checkpoint_interval : int
        Steps between checkpoints (0: none on a step schedule).
    progress : ProgressReporter or None
    duration_ps : float or None
        Run length over which rotation clamps spread their turns (passed to ``engine.update_loads``).
    checkpoint_extra : dict or None
        Stored in every checkpoint's metadata.
    report_start : bool
        Report the starting state (a new run; a resumed run has it on disk).
    checkpoint_wall_s : float or None
        With ``checkpoint_interval`` 0: wall seconds between checkpoints (at the first report, or advance,
        after that time since the last one); None or 0: none in between.

    Returns
    -------
    dict
        ``steps`` (total), ``steps_this_run``, ``wall_s``, ``cpu_s``, ``checkpoints`` (written by this call),
        ``timed_steps`` and ``timed_wall_s`` (the steps after the first advance and their wall time: a speed
        without the kernels' first-call compile).
    """
    n_steps = int(n_steps)
    ci = int(checkpoint_interval or 0)
    wall_every = float(checkpoint_wall_s or 0.0) if not ci else 0.0
    if ci < 0 or not wall_every >= 0:
        raise ParameterError(f"checkpoint intervals must be >= 0, got {checkpoint_interval} steps, "
                             f"{checkpoint_wall_s} s")
    start = int(engine.step)
    t0, c0 = time.perf_counter(), time.process_time()
    reporters = list(reporters)
    update = getattr(engine, "update_loads", None)
    n_checkpoints = 0

    def report_all() -> None:
        snap = Snapshot(engine)
        for r in reporters:
            if r.due(snap.step):
                r.report(engine, snap)

    stateful = [r for r in reporters if hasattr(r, "state")]

    last_save = t0

    def save() -> None:
        nonlocal n_checkpoints, last_save
        assert checkpoint is not None
        for r in reporters:
            r.flush()
        extra = dict(checkpoint_extra or {})
        if stateful:
            extra["reporters"] = {r.name: r.state() for r in stateful}
        engine.save_checkpoint(checkpoint, extra=extra)
        n_checkpoints += 1
        last_save = time.perf_counter()

    def checkpoint_due() -> bool:
        if checkpoint is None or engine.step >= n_steps or interrupt.hit:
            return False
        return bool((ci and engine.step % ci == 0) or (wall_every and time.perf_counter() - last_save >= wall_every))

    bi = _batch_interval(engine, reporters, ci)
    per_report = 0.0  # wall seconds per report of the last batch
    # (step, wall) after the first advance: the speed leaves out the kernels' first-call compile
    timed: tuple[int, float] | None = None
    with _DeferredInterrupt() as interrupt:
        if report_start:
            report_all()
        while engine.step < n_steps and not interrupt.hit:
            if bi and engine.step % bi == 0 and n_steps - engine.step >= bi:
                # reports read by the engine in batches, handed to the reporters at once
                k = (n_steps - engine.step) // bi
                if ci:
                    k = min(k, (_next_multiple(engine.step, ci) - engine.step) // bi)
                if timed is None:
                    k = 1  # the first report alone (the speed is timed after it, as after a first advance)
                elif per_report:
                    k = min(k, max(1, int(BATCH_WALL_S / per_report)))
                per_report = _report_batch(cast(BatchReportingEngine, engine), reporters, k, bi, duration_ps) \
                    or per_report
                if timed is None:
                    timed = (int(engine.step), time.perf_counter())
                if progress is not None:
                    progress.update(engine.step)
                if checkpoint_due():
                    save()
                continue
            nxt = n_steps
            for r in reporters:
                nxt = min(nxt, engine.step + r.describeNextReport(engine))
            if checkpoint is not None and ci:
                nxt = min(nxt, _next_multiple(engine.step, ci))
            elif checkpoint is not None and wall_every and not reporters:
                # without reporters to stop at, advance at most the steps that fit in the time left to the next
                # checkpoint at the rate so far (one step first, to measure it)
                now = time.perf_counter()
                rate = (engine.step - start) / max(now - t0, 1e-9)
                nxt = min(nxt, engine.step + max(1, int(rate * (wall_every - (now - last_save)))))
            engine.advance(nxt - engine.step)
            if timed is None:
                timed = (int(engine.step), time.perf_counter())
            if update is not None:
                update(engine.step * engine.dt, duration_ps)
            report_all()
            if progress is not None:
                progress.update(engine.step)
            if checkpoint_due():
                save()
        for r in reporters:
            r.flush()
        if checkpoint is not None:
            save()
        if interrupt.hit:
            raise KeyboardInterrupt
    t1 = time.perf_counter()
    return dict(steps=int(engine.step), steps_this_run=int(engine.step) - start, wall_s=t1 - t0,
                cpu_s=time.process_time() - c0, checkpoints=n_checkpoints,
                timed_steps=int(engine.step) - timed[0] if timed else 0, timed_wall_s=t1 - timed[1] if timed else 0.0)


def simulate_engine(engine: Engine, n_steps: int, outdir: str | Path, frame_interval: int = 100,
                    energy_interval: int | None = None, checkpoint_interval: int | None = None,
                    resume: bool = False, overwrite: bool = False, velocities: bool = False,
                    precision: str = "float32", metadata: dict[str, Any] | None = None,
                    observables: Any = None, progress: bool = False, duration_ps: float | None = None,
                    checkpoint_extra: dict[str, Any] | None = None, restored: bool = False,
                    checkpoint_wall_s: float = CHECKPOINT_WALL_S) -> dict[str, Any]:
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
        Steps between checkpoints (0: only at the end); None (default): by wall time, every
        ``checkpoint_wall_s`` seconds.
    checkpoint_wall_s : float
        Wall seconds between checkpoints when ``checkpoint_interval`` is None (0: only at the end).
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
    outdir = Path(ensure_dir(outdir))
    fi = int(frame_interval)
    ei = int(energy_interval or fi)
    ci = 0 if checkpoint_interval is None else int(checkpoint_interval)
    wall = float(checkpoint_wall_s or 0.0) if checkpoint_interval is None else 0.0
    if fi <= 0 or ei <= 0 or ci < 0 or not wall >= 0:
        raise ParameterError(f"frame and energy intervals must be positive and the checkpoint interval >= 0 steps "
                             f"(or >= 0 s), got {fi}, {ei}, {checkpoint_interval if ci else wall}")
    traj, csv_path, chk = outdir / "trajectory.dtraj", outdir / "energies.csv", outdir / "checkpoint.npz"
    resume_step = None
    if resume:
        if not restored:
            engine.load_checkpoint(chk)
        resume_step = int(engine.step)
    elif traj.exists() and not overwrite:
        raise ParameterError(f"{traj} already exists: resume the run (--resume), choose another output folder, or "
                             f"pass --overwrite")
    reporters: list[Any] = []
    bar = None
    try:
        reporters.append(DtrajReporter(traj, engine.model.n_nodes, fi, velocities, metadata, resume_step=resume_step,
                                       precision=precision))
        energy = EnergyReporter(csv_path, ei, observables=observables, resume_step=resume_step)
        reporters.append(energy)
        if progress:
            bar = ProgressReporter(n_steps, engine.step)
        out = run_engine(engine, n_steps, reporters, chk, ci, bar, duration_ps, checkpoint_extra,
                         report_start=resume_step is None, checkpoint_wall_s=wall)
    finally:
        for r in reporters:
            r.close()
        if bar is not None:
            bar.close()
    engine.current_model().save(outdir / "final_model.npz")
    out.update(temperatures=energy.temperatures, resumed_from=resume_step)
    return out
