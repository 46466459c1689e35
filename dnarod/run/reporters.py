"""Reporters of the run layer, shared by both engines (duck-typed, in the style of OpenMM's ``app`` reporters).

A reporter has ``interval`` (steps), ``describeNextReport(engine) -> steps until its next report``,
``report(engine, snapshot)``, ``flush()`` and ``close()``. The run loop advances the engine to the
nearest next report, builds one :class:`Snapshot` (the engine's state and energies read once, lazily)
and hands it to every reporter due at that step. A reporter with ``supports_batch`` true also takes
``report_batch(engine, batch)``: a :class:`ReportBatch` of several reports an engine read in one call
(see :mod:`dnarod.run.loop`).

* :class:`DtrajReporter` -- the ``.dtraj`` trajectory (float32, velocities only if asked);
* :class:`EnergyReporter` -- ``energies.csv``: one header for both engines, units in the column
  names (:data:`ENERGY_COLUMNS`, then observables of the loads);
* :class:`ProgressReporter` -- a tqdm bar on stderr.

Checkpoints are written by the run loop itself after the reporters are flushed, so a checkpoint
never refers to a frame that is not on disk.
"""
from __future__ import annotations

import contextlib
import csv
import io
from pathlib import Path
from typing import Any

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.core.io import atomic_path, writing
from dnarod.core.trajectory import TrajectoryWriter

#: Columns of ``energies.csv`` (both engines); observables follow when the loads define them.
ENERGY_COLUMNS = ["step", "time_ps", "potential_kJ_mol", "kinetic_kJ_mol", "total_kJ_mol", "temperature_K",
                  "elastic_kJ_mol", "nonbonded_kJ_mol", "external_kJ_mol"]


class Snapshot:
    """The engine's state at one step, read at most once per report (node state, energies)."""

    def __init__(self, engine: Any) -> None:
        self.engine = engine
        self.step = int(engine.step)
        self.time_ps = self.step * engine.dt
        self._state: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
        self._energies: dict[str, float] | None = None

    @property
    def state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(positions, frames, velocities, angular_velocities)`` (on-step; see the engine protocol): the engine's
        arrays or read-only views, valid for this report only."""
        if self._state is None:
            self._state = self.engine.node_state(copy=False)
        return self._state

    @property
    def energies(self) -> dict[str, float]:
        """The engine's energies (kJ/mol) and temperature (K) at this step."""
        if self._energies is None:
            self._energies = self.engine.energies()
        return self._energies


class ReportBatch:
    """Reports of several steps read at once (:meth:`~dnarod.engines.openmm.simulation.RodSimulation.advance_reports`):
    what a reporter's ``report_batch`` receives instead of one :class:`Snapshot` per step.

    Attributes
    ----------
    steps : ndarray, shape (k,)
    times_ps : ndarray, shape (k,)
    state : tuple of ndarray
        On-step centres (k, n, 3) nm, frames (k, n, 3, 3), velocities (k, n, 3) nm/ps, angular velocities
        (k, n, 3) rad/ps: read-only, valid for this report only.
    energies : dict of ndarray, shape (k,)
        As :meth:`Snapshot.energies`, one value per step.
    """

    def __init__(self, engine: Any, steps: np.ndarray, state: tuple[np.ndarray, ...],
                 energies: dict[str, np.ndarray]) -> None:
        self.engine = engine
        self.steps = steps
        self.times_ps = steps * engine.dt
        self.state = state
        self.energies = energies


class _Interval:
    interval = 1
    #: True if :meth:`report_batch` takes a :class:`ReportBatch` (the run loop then batches reports when every
    #: reporter can and the engine supports it).
    supports_batch = False

    def describeNextReport(self, engine: Any) -> int:  # noqa: N802 - OpenMM reporter protocol name
        """Steps until the next report (always >= 1)."""
        return self.interval - engine.step % self.interval

    def due(self, step: int) -> bool:
        return step % self.interval == 0

    def flush(self) -> None:
        pass

    def close(self) -> None:
        pass


class DtrajReporter(_Interval):
    """Write frames to a ``.dtraj`` file every ``interval`` steps.

    Parameters
    ----------
    path : Path
    n_nodes : int
    interval : int
        Steps between frames.
    velocities : bool
        Also store velocities (18 instead of 12 numbers per node).
    metadata : dict
    resume_step : int or None
        Continue an existing file, dropping frames after this step.
    precision : {"float32", "float64"}
    """

    def __init__(self, path: str | Path, n_nodes: int, interval: int, velocities: bool = False,
                 metadata: dict[str, Any] | None = None, resume_step: int | None = None,
                 precision: str = "float32") -> None:
        self.path = Path(path)
        self.interval = int(interval)
        self.velocities = bool(velocities)
        self.writer = TrajectoryWriter(self.path, n_nodes, velocities=self.velocities, metadata=metadata,
                                       resume_step=resume_step, precision=precision)

    supports_batch = True

    def report(self, engine: Any, snap: Snapshot) -> None:
        # the writer stores the velocities only if the file has them
        self.writer.write(snap.step, snap.time_ps, *snap.state)

    def report_batch(self, engine: Any, batch: ReportBatch) -> None:
        self.writer.write_frames(batch.steps, batch.times_ps, *batch.state)

    def flush(self) -> None:
        self.writer.flush(sync=False)

    def close(self) -> None:
        self.writer.close()


class EnergyReporter(_Interval):
    """Write one row of ``energies.csv`` every ``interval`` steps.

    Rows are held as numbers and written as text in blocks (every :attr:`BLOCK_ROWS` rows and at every
    :meth:`flush`, which the run loop calls before each checkpoint), so a report costs a tuple rather than a
    formatted, written line: the file always holds every row up to the last checkpoint.

    Parameters
    ----------
    path : Path
    interval : int
    observables : callable or None
        ``observables(snapshot) -> dict`` of extra columns (names with units), e.g. the tweezers
        observables of :mod:`dnarod.physics.observables`; ``observables.columns`` lists their names.
    resume_step : int or None
        Continue an existing file, dropping rows after this step.
    """

    #: Rows held before they are written.
    BLOCK_ROWS = 256

    def __init__(self, path: str | Path, interval: int, observables: Any = None,
                 resume_step: int | None = None) -> None:
        self.path = Path(path)
        self.interval = int(interval)
        extra = list(getattr(observables, "columns", []) if observables else [])
        self.observables = observables if extra else None  # no columns to fill: not called
        self.columns = ENERGY_COLUMNS + extra
        rows = []
        if resume_step is not None and self.path.exists():
            with open(self.path, newline="") as fh:
                text = fh.read()
            # a row cut short by a full disk or a kill has no newline: drop it (the checkpoint is before it)
            old = list(csv.reader(io.StringIO(text[:text.rfind("\n") + 1])))
            if not old or old[0] != self.columns:
                raise DnarodError(f"{self.path}: the energies file has other columns than this run writes; "
                                  f"start a new run with --overwrite")
            rows = [r for r in old[1:] if r and int(r[0]) <= resume_step]
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(self.columns)
        w.writerows(rows)
        with atomic_path(self.path) as tmp:
            Path(tmp).write_text(buf.getvalue())
        with writing(self.path):
            self._fh = open(self.path, "a", newline="")
        self._failed = False
        self._held: list[tuple[Any, ...]] = []
        self.temperatures: list[float] = []

    def report(self, engine: Any, snap: Snapshot) -> None:
        e = snap.energies
        t = e["temperature"]
        self.temperatures.append(t)
        row: tuple[Any, ...] = (snap.step, snap.time_ps, float(e["potential"]), float(e["kinetic"]), t,
                                float(e["elastic"]), float(e["nonbonded"]), float(e["external"]))
        if self.observables is not None:
            obs = self.observables(snap)
            row += tuple(float(obs[c]) for c in self.observables.columns)
        self._held.append(row)
        if len(self._held) >= self.BLOCK_ROWS:
            self._write_held()

    @property
    def supports_batch(self) -> bool:  # type: ignore[override]
        """Batched reports carry no snapshot for observables: only without them."""
        return self.observables is None

    def report_batch(self, engine: Any, batch: ReportBatch) -> None:
        e = batch.energies
        t = e["temperature"].tolist()
        self.temperatures.extend(t)
        self._held.extend(zip(batch.steps.tolist(), batch.times_ps.tolist(), e["potential"].tolist(),
                              e["kinetic"].tolist(), t, e["elastic"].tolist(), e["nonbonded"].tolist(),
                              e["external"].tolist()))
        if len(self._held) >= self.BLOCK_ROWS:
            self._write_held()

    def _write_held(self) -> None:
        """Format and write the rows held: ``repr`` of each energy (exact round trip), time and temperature to
        1e-6."""
        if not self._held:
            return
        lines = []
        for r in self._held:
            pot, kin = r[2], r[3]
            lines.append(",".join([str(r[0]), f"{r[1]:.6f}", repr(pot), repr(kin), repr(pot + kin), f"{r[4]:.6f}",
                                   *map(repr, r[5:])]))
        lines.append("")
        self._failed = True
        with writing(self.path):
            self._fh.write("\n".join(lines))
        self._failed = False
        self._held = []

    def flush(self) -> None:
        self._write_held()
        self._failed = True
        with writing(self.path):
            self._fh.flush()
        self._failed = False

    def close(self) -> None:
        if self._fh.closed:
            return
        if self._failed:  # already reported; the buffered bytes would fail again
            with contextlib.suppress(OSError):
                self._fh.close()
            return
        self._failed = True
        with writing(self.path):
            self._write_held()
            self._fh.close()


class ProgressReporter(_Interval):
    """A tqdm progress bar (stderr) updated at every report of the other reporters."""

    def __init__(self, total: int, initial: int = 0, enabled: bool = True) -> None:
        from tqdm import tqdm

        self.interval = 1 << 62  # never asks for a report of its own
        self.bar = tqdm(total=int(total), initial=int(initial), disable=not enabled, unit="step",
                        dynamic_ncols=True)
        self._last = int(initial)

    def describeNextReport(self, engine: Any) -> int:  # noqa: N802
        return self.interval

    def update(self, step: int) -> None:
        self.bar.update(int(step) - self._last)
        self._last = int(step)

    def report(self, engine: Any, snap: Snapshot) -> None:
        self.update(snap.step)

    def close(self) -> None:
        self.bar.close()


def load_energies(path: str | Path) -> dict[str, np.ndarray]:
    """Read ``energies.csv`` into a dict of arrays (column name -> ndarray)."""
    try:
        with open(path, newline="") as fh:
            rows = list(csv.reader(fh))
    except OSError as exc:
        raise DnarodError(f"{path}: cannot read the energies file ({exc.strerror or exc})") from None
    if not rows or rows[0][:len(ENERGY_COLUMNS)] != ENERGY_COLUMNS:
        raise DnarodError(f"{path}: not a dnarod energies CSV")
    cols = rows[0]
    data = np.array([[float(x) for x in r] for r in rows[1:] if r], dtype=float).reshape(-1, len(cols))
    return {name: data[:, i] for i, name in enumerate(cols)}
