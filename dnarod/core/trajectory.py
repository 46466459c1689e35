"""Trajectories of rod nodes: the in-memory :class:`~dnarod.core.trajectory.Trajectory` and the ``.dtraj`` stream
format.

Both engines (OpenMM and the Lax-form integrator) write the same format, so every analysis
runs on both.

``.dtraj`` format: an ASCII header line ``DTRAJ1 <json>\\n`` padded with spaces to 4096 bytes,
then fixed-size little-endian records, one per frame::

    step, time (ps), positions (n_nodes*3, nm), frames (n_nodes*9, row-major 3x3,
    directors as columns), [velocities (n_nodes*3, nm/ps), angular velocities
    (n_nodes*3, rad/ps, body frame)] if the header says ``"velocities": true``

The JSON header holds ``version``, ``n_nodes``, ``velocities``, ``precision`` and free-form
``metadata``.

* version 2 (written by default): ``step`` int64 and ``time`` float64, then the node data in
  the header's ``precision`` (``"float32"``, the default, or ``"float64"``). float32 keeps
  positions to ~1e-7 relative (0.1 fm at 1 um) and frames orthonormal to ~1e-7, far inside
  every analysis tolerance, and halves the file: 48 bytes per node-frame (72 with
  velocities) against 96 (144) in float64.
* version 1 (older files, still read): every number float64.

Records are appended in blocks of at most :data:`BLOCK_BYTES` (one record per block when a record is larger)
and at every :meth:`TrajectoryWriter.flush` (the run layer flushes before each checkpoint, so a checkpoint
never refers to a frame that is not on disk); a reader ignores a trailing partial record, and
:class:`TrajectoryWriter` with ``resume_step`` truncates to the frames at or before the
checkpointed step, so a resumed run neither loses nor duplicates frames. The exact state a run
resumes from is in its checkpoint, not in the trajectory.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
import contextlib

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.core.io import atomic_path, writing

HEADER_SIZE = 4096
MAGIC = b"DTRAJ1 "
VERSION = 2
PRECISIONS = {"float32": "<f4", "float64": "<f8"}
#: Most bytes of frames a :class:`TrajectoryWriter` holds before writing them (fewer, larger writes).
BLOCK_BYTES = 1 << 20


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
        idx = np.arange(self.n_frames)[index]
        if np.ndim(idx) == 0:
            idx = [int(idx)]
        return Trajectory(self.time[idx], self.positions[idx], self.frames[idx], self.step[idx],
                          None if self.velocities is None else self.velocities[idx],
                          None if self.angular_velocities is None else self.angular_velocities[idx],
                          dict(self.metadata))

    def save(self, path, precision="float64"):
        """Write a ``.dtraj`` file atomically (``precision`` of the node data: "float64" or "float32")."""
        with atomic_path(path) as tmp:
            with TrajectoryWriter(tmp, self.n_nodes, velocities=self.velocities is not None,
                                  metadata=self.metadata, precision=precision) as w:
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


def _record_dtype(header, path="trajectory"):
    """numpy structured dtype of one record described by a header (version 1 or 2)."""
    n = int(header["n_nodes"])
    version = int(header.get("version", 1))
    if version == 1:
        lead, prec = [("step", "<f8"), ("time", "<f8")], "<f8"
    elif version == 2:
        lead = [("step", "<i8"), ("time", "<f8")]
        prec = PRECISIONS.get(header.get("precision", "float32"))
        if prec is None:
            raise DnarodError(f"{path}: unknown .dtraj precision {header.get('precision')!r}")
    else:
        raise DnarodError(f"{path}: .dtraj version {version} is newer than this dnarod reads (1, 2); update dnarod")
    fields = lead + [("positions", prec, (n, 3)), ("frames", prec, (n, 3, 3))]
    if header.get("velocities"):
        fields += [("velocities", prec, (n, 3)), ("angular_velocities", prec, (n, 3))]
    return np.dtype(fields)


def bytes_per_node_frame(velocities=False, precision="float32"):
    """Storage of one node in one frame of a version-2 ``.dtraj`` file, bytes."""
    return (18 if velocities else 12) * np.dtype(PRECISIONS[precision]).itemsize


def _records(raw, dtype):
    nf = len(raw) // dtype.itemsize  # a trailing partial record (crash mid-write) is ignored
    return np.frombuffer(raw[: nf * dtype.itemsize], dtype=dtype)


def load_trajectory(path):
    """Read a ``.dtraj`` file (version 1 or 2) into a :class:`Trajectory` (arrays float64)."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            header = _read_header(fh, path)
            raw = fh.read()
    except IsADirectoryError:
        raise DnarodError(f"{path}: is a directory, not a .dtraj trajectory") from None
    except OSError as exc:
        raise DnarodError(f"{path}: cannot read trajectory ({exc.strerror or exc})") from None
    rec = _records(raw, _record_dtype(header, path))
    has_v = bool(header.get("velocities"))
    f64 = lambda name: rec[name].astype(float)  # noqa: E731 - copies, so the arrays are writable
    return Trajectory(f64("time"), f64("positions"), f64("frames"), rec["step"].astype(np.int64),
                      f64("velocities") if has_v else None, f64("angular_velocities") if has_v else None,
                      header.get("metadata", {}))


def _quiet():
    return contextlib.suppress(OSError)


class TrajectoryWriter:
    """Append frames to a ``.dtraj`` file (version 2), frames written in blocks (and at every flush).

    Use as a context manager or call :meth:`close`. Engines' reporters call :meth:`write` with
    their state.

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
        than ``resume_step`` (the checkpoint's step) and any partial record. The file keeps its
        own version and precision.
    precision : {"float32", "float64"}
        Storage of the node data of a new file.
    block_bytes : int
        Frames are held and written in blocks of at most this many bytes (at least one frame), and at every
        :meth:`flush`.
    """

    def __init__(self, path, n_nodes, velocities=False, metadata=None, resume_step=None, precision="float32",
                 block_bytes=BLOCK_BYTES):
        self.path = Path(path)
        self.n_nodes = int(n_nodes)
        self.velocities = bool(velocities)
        if precision not in PRECISIONS:
            raise DnarodError(f"precision must be 'float32' or 'float64', got {precision!r}")
        self.header = dict(format="dnarod-trajectory", version=VERSION, n_nodes=self.n_nodes,
                           velocities=self.velocities, precision=precision, metadata=metadata or {})
        if resume_step is not None and self.path.exists():
            self._fh = open(self.path, "r+b")
            old = _read_header(self._fh, self.path)
            if old["n_nodes"] != self.n_nodes or bool(old.get("velocities")) != self.velocities:
                self._fh.close()
                raise DnarodError(f"{self.path}: cannot resume, the file holds {old['n_nodes']} nodes "
                                  f"(velocities={old.get('velocities')}) but the run has {self.n_nodes} "
                                  f"(velocities={self.velocities})")
            self.header = old
            self._dtype = _record_dtype(old, self.path)
            rec = _records(self._fh.read(), self._dtype)
            keep = int(np.searchsorted(rec["step"], resume_step, side="right"))
            self._fh.truncate(HEADER_SIZE + keep * self._dtype.itemsize)
            self._fh.seek(0, os.SEEK_END)
        else:
            self._dtype = _record_dtype(self.header, self.path)
            text = MAGIC + json.dumps(self.header).encode("ascii")
            if len(text) >= HEADER_SIZE:
                raise DnarodError("trajectory metadata too large for the .dtraj header (4 kB)")
            with writing(self.path, HEADER_SIZE):
                self._fh = open(self.path, "wb")
                self._fh.write(text.ljust(HEADER_SIZE - 1) + b"\n")
                self._fh.flush()
        self._block = np.zeros(max(1, int(block_bytes) // self._dtype.itemsize), self._dtype)
        # the block's fields, looked up once (a structured field lookup per frame costs more than the copy)
        self._fields = {name: self._block[name] for name in self._dtype.names}
        self._held = 0

    def write(self, step, time, positions, frames, velocities=None, angular_velocities=None):
        """Append one frame (shapes (n_nodes, 3), (n_nodes, 3, 3); nm, ps)."""
        f, i = self._fields, self._held
        n = self.n_nodes
        try:
            if self.velocities and (velocities is None or angular_velocities is None):
                raise DnarodError("this trajectory stores velocities: pass velocities and angular_velocities")
            f["positions"][i] = np.reshape(positions, (n, 3))
            f["frames"][i] = np.reshape(frames, (n, 3, 3))
            if self.velocities:
                f["velocities"][i] = np.reshape(velocities, (n, 3))
                f["angular_velocities"][i] = np.reshape(angular_velocities, (n, 3))
            f["step"][i], f["time"][i] = step, time
        except ValueError as exc:
            if isinstance(exc, DnarodError):
                raise
            raise DnarodError(f"frame does not fit a {n}-node trajectory ({exc})") from None
        self._held = i + 1
        if self._held == len(self._block):
            self._write_held()

    def write_frames(self, steps, times, positions, frames, velocities=None, angular_velocities=None):
        """Append several frames (shapes (k,), (k,), (k, n_nodes, 3), (k, n_nodes, 3, 3); nm, ps): as ``k`` calls
        of :meth:`write`, copied into the block a slice at a time."""
        k = len(steps)
        n = self.n_nodes
        if self.velocities and (velocities is None or angular_velocities is None):
            raise DnarodError("this trajectory stores velocities: pass velocities and angular_velocities")
        f = self._fields
        j = 0
        while j < k:
            i = self._held
            m = min(k - j, len(self._block) - i)
            dst, src = slice(i, i + m), slice(j, j + m)
            try:
                f["positions"][dst] = np.reshape(positions[src], (m, n, 3))
                f["frames"][dst] = np.reshape(frames[src], (m, n, 3, 3))
                if self.velocities:
                    f["velocities"][dst] = np.reshape(velocities[src], (m, n, 3))
                    f["angular_velocities"][dst] = np.reshape(angular_velocities[src], (m, n, 3))
                f["step"][dst], f["time"][dst] = steps[src], times[src]
            except ValueError as exc:
                raise DnarodError(f"frames do not fit a {n}-node trajectory ({exc})") from None
            self._held = i + m
            j += m
            if self._held == len(self._block):
                self._write_held()

    def _write_held(self):
        if self._held:
            data = self._block[:self._held]
            self._failed = True  # until the block is on its way (see close)
            with writing(self.path, data.nbytes):  # a full disk: one line naming the file; the frames before are kept
                self._fh.write(data.data)
                self._fh.flush()
            self._failed = False
            self._held = 0

    def flush(self, sync=False):
        """Write the frames held (and ``fsync`` them with ``sync``)."""
        if not self._fh.closed:
            self._write_held()
            self._failed = True
            with writing(self.path):
                self._fh.flush()
                if sync:
                    os.fsync(self._fh.fileno())
            self._failed = False

    def close(self):
        """Flush and close; after a failed write (already reported) only close, saying nothing more."""
        if self._fh.closed:
            return
        if not getattr(self, "_failed", False):
            try:
                self.flush(sync=True)
            except BaseException:
                with _quiet():
                    self._fh.close()
                raise
        with _quiet():  # a failed flush leaves its bytes buffered: closing tries them again and fails again
            self._fh.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
