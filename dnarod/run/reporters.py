"""Reporters of the run layer, shared by both engines (duck-typed, in the style of OpenMM's ``app`` reporters).

A reporter has ``interval`` (steps), ``describeNextReport(engine) -> steps until its next report``,
``report(engine, snapshot)``, ``flush()`` and ``close()``. The run loop advances the engine to the
nearest next report, builds one :class:`Snapshot` (the engine's state and energies read once, lazily)
and hands it to every reporter due at that step.

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

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.core.io import atomic_path, writing

#: Columns of ``energies.csv`` (both engines); observables follow when the loads define them.
ENERGY_COLUMNS = ["step", "time_ps", "potential_kJ_mol", "kinetic_kJ_mol", "total_kJ_mol", "temperature_K",
                  "elastic_kJ_mol", "nonbonded_kJ_mol", "external_kJ_mol"]


class Snapshot:
    """The engine's state at one step, read at most once per report (node state, energies)."""

    def __init__(self, engine):
        self.engine = engine
        self.step = int(engine.step)
        self.time_ps = self.step * engine.dt
        self._state = None
        self._energies = None

    @property
    def state(self):
        """``(positions, frames, velocities, angular_velocities)`` (on-step; see the engine protocol): the engine's
        arrays or read-only views, valid for this report only."""
        if self._state is None:
            self._state = self.engine.node_state(copy=False)
        return self._state

    @property
    def energies(self):
        if self._energies is None:
            self._energies = self.engine.energies()
        return self._energies


class _Interval:
    interval = 1

    def describeNextReport(self, engine):  # noqa: N802 - OpenMM reporter protocol name
        """Steps until the next report (always >= 1)."""
        return self.interval - engine.step % self.interval

    def due(self, step):
        return step % self.interval == 0

    def flush(self):
        pass

    def close(self):
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

    def __init__(self, path, n_nodes, interval, velocities=False, metadata=None, resume_step=None,
                 precision="float32"):
        from dnarod.core.trajectory import TrajectoryWriter

        self.path = Path(path)
        self.interval = int(interval)
        self.velocities = bool(velocities)
        self.writer = TrajectoryWriter(self.path, n_nodes, velocities=self.velocities, metadata=metadata,
                                       resume_step=resume_step, precision=precision)

    def report(self, engine, snap):
        pos, frm, v, w = snap.state
        if self.velocities:
            self.writer.write(snap.step, snap.time_ps, pos, frm, v, w)
        else:
            self.writer.write(snap.step, snap.time_ps, pos, frm)

    def flush(self):
        self.writer.flush(sync=False)

    def close(self):
        self.writer.close()


class EnergyReporter(_Interval):
    """Write one row of ``energies.csv`` every ``interval`` steps.

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

    def __init__(self, path, interval, observables=None, resume_step=None):
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
        self._csv = csv.writer(self._fh, lineterminator="\n")
        self.temperatures = []

    def report(self, engine, snap):
        e = snap.energies
        self.temperatures.append(e["temperature"])
        row = [snap.step, f"{snap.time_ps:.6f}", repr(float(e["potential"])), repr(float(e["kinetic"])),
               repr(float(e["potential"] + e["kinetic"])), f"{e['temperature']:.6f}", repr(float(e["elastic"])),
               repr(float(e["nonbonded"])), repr(float(e["external"]))]
        if self.observables is not None:
            obs = self.observables(snap)
            row += [repr(float(obs[c])) for c in self.observables.columns]
        self._failed = True
        with writing(self.path):
            self._csv.writerow(row)
        self._failed = False

    def flush(self):
        self._failed = True
        with writing(self.path):
            self._fh.flush()
        self._failed = False

    def close(self):
        if self._fh.closed:
            return
        if self._failed:  # already reported; the buffered bytes would fail again
            with contextlib.suppress(OSError):
                self._fh.close()
            return
        self._failed = True
        with writing(self.path):
            self._fh.close()


class ProgressReporter(_Interval):
    """A tqdm progress bar (stderr) updated at every report of the other reporters."""

    def __init__(self, total, initial=0, enabled=True):
        from tqdm import tqdm

        self.interval = 1 << 62  # never asks for a report of its own
        self.bar = tqdm(total=int(total), initial=int(initial), disable=not enabled, unit="step",
                        dynamic_ncols=True)
        self._last = int(initial)

    def describeNextReport(self, engine):  # noqa: N802
        return self.interval

    def update(self, step):
        self.bar.update(int(step) - self._last)
        self._last = int(step)

    def report(self, engine, snap):
        self.update(snap.step)

    def close(self):
        self.bar.close()


def load_energies(path):
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
