"""Trajectories of rod nodes: the in-memory :class:`Trajectory` and the ``.dtraj`` stream format.

Both engines (OpenMM and the Lax-form integrator) write the same format, so every analysis
runs on both.

``.dtraj`` format (version 1): an ASCII header line ``DTRAJ1 <json>\\n`` padded with spaces
to 4096 bytes, then fixed-size little-endian float64 records, one per frame::

    step, time (ps), positions (n_nodes*3, nm), frames (n_nodes*9, row-major 3x3,
    directors as columns), [velocities (n_nodes*3, nm/ps), angular velocities
    (n_nodes*3, rad/ps, body frame)] if the header says ``"velocities": true``

The JSON header holds ``n_nodes``, ``velocities`` and free-form ``metadata``. Records are
appended and flushed one at a time; a reader ignores a trailing partial record, and
:meth:`TrajectoryWriter.open` with ``resume_step`` truncates to the frames at or before the
checkpointed step, so a resumed run neither loses nor duplicates frames.
Frames are stored in float64 and come back bit-exact.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import DnarodError
from .io_utils import atomic_path

HEADER_SIZE = 4096
MAGIC = b"DTRAJ1 "


@dataclass
class Trajectory:
    """Node poses over time.

    Attributes
    ----------
    time : ndarray, shape (n_frames,)
        ps.
    positions : ndarray, shape (n_frames, n_nodes, 3)
        nm.
    frames : ndarray, shape (n_frames, n_nodes, 3, 3)
        Directors as columns.
    step : ndarray, shape (n_frames,), int
        Integrator step of each frame.
    velocities : ndarray, shape (n_frames, n_nodes, 3), optional
        Centre velocities, nm/ps.
    angular_velocities : ndarray, shape (n_frames, n_nodes, 3), optional
        Body-frame angular velocities, rad/ps.
    metadata : dict
    """

    time: np.ndarray
    positions: np.ndarray
    frames: np.ndarray
    step: np.ndarray = None
    velocities: np.ndarray = None
    angular_velocities: np.ndarray = None
    metadata: dict = field(default_factory=dict)

    def __post_init__(self):
        self.time = np.asarray(self.time, float)
        self.positions = np.asarray(self.positions, float)
        self.frames = np.asarray(self.frames, float)
        nf = self.time.shape[0]
        if self.positions.ndim != 3 or self.positions.shape[0] != nf or self.positions.shape[2] != 3:
            raise DnarodError(f"positions must have shape (n_frames={nf}, n_nodes, 3), got {self.positions.shape}")
        if self.frames.shape != self.positions.shape + (3,):
            raise DnarodError(f"frames must have shape {self.positions.shape + (3,)}, got {self.frames.shape}")
        self.step = np.arange(nf) if self.step is None else np.asarray(self.step, dtype=np.int64)

    @property
    def n_frames(self):
        return self.positions.shape[0]

    @property
    def n_nodes(self):
        return self.positions.shape[1]

    def __len__(self):
        return self.n_frames

    def __getitem__(self, index):
        sel = lambda a: None if a is None else a[index]
        idx = np.arange(self.n_frames)[index]
        if np.ndim(idx) == 0:
            idx = [int(idx)]
        return Trajectory(self.time[idx], self.positions[idx], self.frames[idx], self.step[idx],
                          None if self.velocities is None else self.velocities[idx],
                          None if self.angular_velocities is None else self.angular_velocities[idx],
                          dict(self.metadata))

    def save(self, path):
        """Write a ``.dtraj`` file atomically."""
        with atomic_path(path) as tmp:
            with TrajectoryWriter(tmp, self.n_nodes, velocities=self.velocities is not None,
                                  metadata=self.metadata) as w:
                for i in range(self.n_frames):
                    w.write(int(self.step[i]), self.time[i], self.positions[i], self.frames[i],
                            None if self.velocities is None else self.velocities[i],
                            None if self.angular_velocities is None else self.angular_velocities[i])

    @classmethod
    def load(cls, path):
        """Read a ``.dtraj`` file (a trailing partial record is ignored)."""
        return load_trajectory(path)


def _read_header(fh, path):
    raw = fh.read(HEADER_SIZE)
    if len(raw) < HEADER_SIZE or not raw.startswith(MAGIC):
        raise DnarodError(f"{path}: not a dnarod .dtraj trajectory (bad or truncated header)")
    try:
        return json.loads(raw[len(MAGIC):].decode("ascii").strip())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DnarodError(f"{path}: corrupt .dtraj header ({exc})") from None


def _record_size(header):
    n = header["n_nodes"]
    return 2 + 12 * n + (6 * n if header.get("velocities") else 0)


def load_trajectory(path):
    """Read a ``.dtraj`` file into a :class:`Trajectory`."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            header = _read_header(fh, path)
            raw = fh.read()
    except OSError as exc:
        raise DnarodError(f"{path}: cannot read trajectory ({exc})") from None
    n = header["n_nodes"]
    rs = _record_size(header)
    nf = len(raw) // (8 * rs)  # a trailing partial record (crash mid-write) is ignored
    data = np.frombuffer(raw[: nf * rs * 8], dtype="<f8")
    rec = data[: nf * rs].reshape(nf, rs)
    pos = rec[:, 2:2 + 3 * n].reshape(nf, n, 3)
    frm = rec[:, 2 + 3 * n:2 + 12 * n].reshape(nf, n, 3, 3)
    vel = ang = None
    if header.get("velocities"):
        vel = rec[:, 2 + 12 * n:2 + 15 * n].reshape(nf, n, 3)
        ang = rec[:, 2 + 15 * n:2 + 18 * n].reshape(nf, n, 3)
    return Trajectory(rec[:, 1].copy(), pos.copy(), frm.copy(), rec[:, 0].astype(np.int64),
                      None if vel is None else vel.copy(), None if ang is None else ang.copy(),
                      header.get("metadata", {}))


class TrajectoryWriter:
    """Append frames to a ``.dtraj`` file, one flushed record per frame.

    Use as a context manager or call :meth:`close`. A reporter-style object: engines call
    :meth:`write` with their state.

    Parameters
    ----------
    path : str or Path
    n_nodes : int
    velocities : bool
        Also store centre and body angular velocities.
    metadata : dict
        Free-form JSON-serialisable data (model name, dt, ...).
    resume_step : int, optional
        Open an existing file for appending, first dropping every frame with a step greater
        than ``resume_step`` (the checkpoint's step) and any partial record.
    """

    def __init__(self, path, n_nodes, velocities=False, metadata=None, resume_step=None):
        self.path = Path(path)
        self.n_nodes = int(n_nodes)
        self.velocities = bool(velocities)
        self.header = dict(format="dnarod-trajectory", version=1, n_nodes=self.n_nodes,
                           velocities=self.velocities, metadata=metadata or {})
        self._rs = _record_size(self.header)
        if resume_step is not None and self.path.exists():
            self._fh = open(self.path, "r+b")
            old = _read_header(self._fh, self.path)
            if old["n_nodes"] != self.n_nodes or bool(old.get("velocities")) != self.velocities:
                self._fh.close()
                raise DnarodError(f"{self.path}: cannot resume, the file holds {old['n_nodes']} nodes "
                                  f"(velocities={old.get('velocities')}) but the run has {self.n_nodes}")
            raw = self._fh.read()
            nf = len(raw) // (8 * self._rs)
            data = np.frombuffer(raw[: nf * self._rs * 8], dtype="<f8")
            steps = data[: nf * self._rs].reshape(nf, self._rs)[:, 0]
            keep = int(np.searchsorted(steps, resume_step, side="right"))
            self._fh.truncate(HEADER_SIZE + keep * self._rs * 8)
            self._fh.seek(0, os.SEEK_END)
        else:
            self._fh = open(self.path, "wb")
            text = MAGIC + json.dumps(self.header).encode("ascii")
            if len(text) >= HEADER_SIZE:
                self._fh.close()
                raise DnarodError("trajectory metadata too large for the .dtraj header (4 kB)")
            self._fh.write(text.ljust(HEADER_SIZE - 1) + b"\n")
            self._fh.flush()

    def write(self, step, time, positions, frames, velocities=None, angular_velocities=None):
        """Append one frame (shapes (n_nodes, 3), (n_nodes, 3, 3); nm, ps)."""
        parts = [np.array([step, time], float), np.asarray(positions, float).reshape(-1),
                 np.asarray(frames, float).reshape(-1)]
        if self.velocities:
            if velocities is None or angular_velocities is None:
                raise DnarodError("this trajectory stores velocities: pass velocities and angular_velocities")
            parts += [np.asarray(velocities, float).reshape(-1), np.asarray(angular_velocities, float).reshape(-1)]
        rec = np.concatenate(parts)
        if rec.size != self._rs:
            raise DnarodError(f"frame has {rec.size} numbers, expected {self._rs} for {self.n_nodes} nodes")
        self._fh.write(rec.astype("<f8").tobytes())
        self._fh.flush()

    def close(self):
        if not self._fh.closed:
            self._fh.flush()
            os.fsync(self._fh.fileno())
            self._fh.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
