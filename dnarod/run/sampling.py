"""Equilibrium sampling on the run layer: a reporter that keeps per-sample observables, and the run that resumes it.

Protocol members (tweezers chains, rings), exchange replicas and the validation samplers all sample the same way:
run an engine through the one run loop (:func:`dnarod.run.loop.run_engine`), let a :class:`SampleReporter`
compute a row of observables every ``interval`` steps once the equilibration is over, and checkpoint the engine
with the reporter's rows in the checkpoint's metadata (the engine's own checkpoint format, as for
``dnarod simulate``). :func:`run_sampling` resumes from such a checkpoint: the engine continues bit for bit and the
reporter with the rows it had, so an interrupted member gives the same samples as an uninterrupted one.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dnarod.core.errors import ParameterError
from dnarod.run.loop import CHECKPOINT_WALL_S, run_engine


class SampleReporter:
    """Per-sample observables of a run: one row every ``interval`` steps after step ``start``.

    Parameters
    ----------
    columns : sequence of str
        Names of the sampled observables (``time_ps`` is added first).
    interval : int
        Steps between samples (and between calls of ``follow``).
    observe : callable
        ``observe(positions (n, 3) nm, frames (n, 3, 3), snapshot) -> mapping column -> value``: a float, or an
        array (a per-node quantity, kept as the array of samples (n_samples, ...)); ``snapshot`` has ``step``,
        ``time_ps`` and ``energies`` (read only if used).
    start : int
        Last step of the equilibration: samples are taken at ``start + interval``, ``start + 2 interval``, ...
        (``start`` must be a multiple of ``interval``).
    n_samples : int
        Number of samples; the run needs ``start + n_samples * interval`` steps.
    follow : object, optional
        Called at every report, during the equilibration too (``follow.update(positions, frames, step)``), for
        what must be followed between samples (an unwrapped angle, say); its ``state()`` / ``restore(state)``
        travel with the checkpoint.

    Attributes
    ----------
    name : str
        Key of the reporter's state in a checkpoint (``"samples"``).
    """

    name = "samples"

    def __init__(self, columns: Sequence[str], interval: int, observe: Callable[..., Mapping[str, float]],
                 start: int = 0, n_samples: int = 1, follow: Any = None) -> None:
        self.interval = int(interval)
        self.start = int(start)
        if self.interval < 1 or self.start < 0 or self.start % self.interval:
            raise ParameterError(f"sample interval {interval} and start {start}: the interval must be >= 1 step and "
                                 f"the start a multiple of it")
        self.columns = ["time_ps", *[c for c in columns if c != "time_ps"]]
        self.n_samples = int(n_samples)
        self.observe = observe
        self.follow = follow
        self.rows: dict[str, list[float]] = {c: [] for c in self.columns}
        self._spent = (0.0, 0.0)  # wall and CPU seconds of earlier attempts (restored from a checkpoint)
        self._t0, self._c0 = time.perf_counter(), time.process_time()

    @property
    def n_steps(self) -> int:
        """Steps of the whole run: equilibration and sampling."""
        return self.start + self.n_samples * self.interval

    @property
    def n_done(self) -> int:
        return len(self.rows["time_ps"])

    def describeNextReport(self, engine: Any) -> int:  # noqa: N802 - OpenMM reporter protocol name
        return self.interval - int(engine.step) % self.interval

    def due(self, step: int) -> bool:
        return step > 0 and step % self.interval == 0

    def report(self, engine: Any, snapshot: Any) -> None:
        step = int(snapshot.step)
        pose = engine.node_pose() if hasattr(engine, "node_pose") else snapshot.state[:2]
        pos, frm = (np.asarray(a, float) for a in pose)
        if self.follow is not None:
            self.follow.update(pos, frm, step)
        if step <= self.start or self.n_done >= self.n_samples:
            return
        row = self.observe(pos, frm, snapshot)
        self.rows["time_ps"].append(step * float(engine.dt))
        for c in self.columns[1:]:
            v = row[c]
            self.rows[c].append(np.asarray(v, float).tolist() if np.ndim(v) else float(v))

    def arrays(self) -> dict[str, np.ndarray]:
        """The samples so far, column -> array (n_done, ...)."""
        return {c: np.asarray(v, float) for c, v in self.rows.items()}

    def cost(self) -> tuple[float, float]:
        """Wall and CPU seconds spent on this run, earlier attempts included."""
        return (self._spent[0] + time.perf_counter() - self._t0, self._spent[1] + time.process_time() - self._c0)

    def state(self) -> dict[str, Any]:
        wall, cpu = self.cost()
        return {"rows": self.rows, "n_samples": self.n_samples, "interval": self.interval, "start": self.start,
                "wall_s": wall, "cpu_s": cpu,
                "follow": self.follow.state() if self.follow is not None else None}

    def restore(self, state: Mapping[str, Any]) -> None:
        if (state.get("n_samples"), state.get("interval"), state.get("start")) != (self.n_samples, self.interval,
                                                                                    self.start):
            raise ParameterError("checkpoint of a sampling run with another schedule (samples, interval or "
                                 "equilibration); delete it or use a new folder")
        self.rows = {c: list(state["rows"][c]) for c in self.columns}
        self._spent = (float(state.get("wall_s", 0.0)), float(state.get("cpu_s", 0.0)))
        self._t0, self._c0 = time.perf_counter(), time.process_time()
        if self.follow is not None and state.get("follow") is not None:
            self.follow.restore(state["follow"])

    def flush(self) -> None:
        pass

    def close(self) -> None:
        pass


class FollowReporter:
    """Calls ``follow.update(positions, frames, step)`` every ``interval`` steps counted from step ``origin`` (what
    must be followed between the moments a workflow looks at a run: an unwrapped angle, say); no state of its own."""

    def __init__(self, follow: Any, interval: int, origin: int = 0) -> None:
        self.follow, self.interval, self.origin = follow, max(1, int(interval)), int(origin)

    def describeNextReport(self, engine: Any) -> int:  # noqa: N802 - OpenMM reporter protocol name
        return self.interval - (int(engine.step) - self.origin) % self.interval

    def due(self, step: int) -> bool:
        return (step - self.origin) % self.interval == 0

    def report(self, engine: Any, snapshot: Any) -> None:
        pose = engine.node_pose() if hasattr(engine, "node_pose") else snapshot.state[:2]
        self.follow.update(*(np.asarray(a, float) for a in pose), int(snapshot.step))

    def flush(self) -> None:
        pass

    def close(self) -> None:
        pass


class _Progress:
    """Adapts ``progress(i, n)`` (samples done, of n) to the run loop's ``update(step)``."""

    def __init__(self, fn: Callable[[int, int], Any], sampler: SampleReporter) -> None:
        self.fn, self.sampler, self.last = fn, sampler, -1

    def update(self, step: int) -> None:
        if self.sampler.n_done != self.last:
            self.last = self.sampler.n_done
            self.fn(self.sampler.n_done, self.sampler.n_samples)


def run_sampling(engine: Any, sampler: SampleReporter, checkpoint: str | Path | None = None,
                 extra: Mapping[str, Any] | None = None, checkpoint_wall_s: float | None = None,
                 progress: Callable[[int, int], Any] | None = None) -> dict[str, Any]:
    """Run ``engine`` through the run loop until ``sampler`` has its samples, checkpointing both; resume if asked.

    Parameters
    ----------
    engine : dnarod.run.engine.Engine
        At its start pose (step 0), or any pose if ``checkpoint`` exists (it is then restored from it).
    sampler : SampleReporter
    checkpoint : path, optional
        The engine's checkpoint file: written every ``checkpoint_wall_s`` wall seconds (default
        :data:`dnarod.run.loop.CHECKPOINT_WALL_S`) and at the end, with the sampler's rows. If it exists, the engine and the
        sampler resume from it, so the run ends with the samples an uninterrupted run would have.
    extra : mapping, optional
        What identifies the run (settings); stored in the checkpoint and required to match on resume.
    checkpoint_wall_s : float, optional
    progress : callable, optional
        ``progress(samples_done, n_samples)``.

    Returns
    -------
    dict
        ``samples`` (column -> array), ``wall_s``, ``cpu_s`` (earlier attempts included), ``resumed_from`` (step
        or None) and the run loop's summary.

    Raises
    ------
    ParameterError
        A checkpoint of another run (other ``extra``, another schedule, another model), or a corrupt one.
    """
    extra = dict(extra or {})
    resumed = None
    if checkpoint is not None and Path(checkpoint).exists():
        meta = engine.load_checkpoint(checkpoint)
        got = dict(meta.get("extra") or {})
        states = got.pop("reporters", {})
        if got != extra or sampler.name not in states:
            raise ParameterError(f"{checkpoint}: checkpoint of another run (other settings); delete it or use a new "
                                 f"folder")
        sampler.restore(states[sampler.name])
        resumed = int(engine.step)
    bar = _Progress(progress, sampler) if progress is not None else None
    out = run_engine(engine, sampler.n_steps, [sampler], checkpoint, 0, bar, checkpoint_extra=extra,
                     report_start=False,
                     checkpoint_wall_s=CHECKPOINT_WALL_S if checkpoint_wall_s is None else float(checkpoint_wall_s))
    wall, cpu = sampler.cost()
    out.update(samples=sampler.arrays(), wall_s=wall, cpu_s=cpu, resumed_from=resumed)
    return out
