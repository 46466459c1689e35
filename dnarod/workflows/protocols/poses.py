"""Poses a protocol member starts from or leaves behind: saved and loaded atomically, keyed by their bytes, and
turned by extra turns (a member continuing another at other turns)."""
from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import numpy.typing as npt

from dnarod.core.errors import DnarodError
from dnarod.core.io import atomic_path


#: File of a member's last pose (written by :func:`dnarod.workflows.protocols.tweezers.run_member`).
FINAL_POSE = "final_pose.npz"


#: File of a chained member's start pose (the previous member's final pose with the turns added).
START_POSE = "start_pose.npz"


def add_turns(positions: npt.ArrayLike, frames: npt.ArrayLike,
              delta_turns: float) -> tuple[np.ndarray, np.ndarray]:
    """The pose with ``delta_turns`` extra turns of twist spread evenly along the chain.

    Node ``i`` of ``n`` is turned about its own d3 by ``2 pi delta_turns i / (n - 1)``; positions are kept, so
    the writhe is unchanged and the twist (hence the linking number) grows by ``delta_turns`` while node 0 (the
    clamped surface node) keeps its frame and the last node turns by the whole increment, as the magnets turn
    the bead (about +z when the last node's d3 is along the pull, which the clamp holds to thermal accuracy).

    Parameters
    ----------
    positions : ndarray, shape (n, 3)
        nm (returned unchanged, as a copy).
    frames : ndarray, shape (n, 3, 3)
        Directors as columns.
    delta_turns : float

    Returns
    -------
    positions, frames : ndarray
    """
    P = np.array(positions, float)
    F = np.array(frames, float)
    n = len(F)
    if n < 2:
        raise DnarodError("add_turns: a chain needs at least two nodes")
    phi = 2.0 * np.pi * float(delta_turns) * np.arange(n) / (n - 1)
    c, s = np.cos(phi), np.sin(phi)
    d1, d2 = F[:, :, 0].copy(), F[:, :, 1].copy()
    F[:, :, 0] = c[:, None] * d1 + s[:, None] * d2
    F[:, :, 1] = -s[:, None] * d1 + c[:, None] * d2
    return P, F


def pose_sha256(positions: npt.ArrayLike, frames: npt.ArrayLike) -> str:
    """SHA-256 (hex) of a pose's float64 bytes (the key of a chained member's start)."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(positions, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(frames, dtype=np.float64).tobytes())
    return h.hexdigest()


def save_pose(path: str | Path, positions: npt.ArrayLike, frames: npt.ArrayLike) -> None:
    """Write a pose (positions nm, frames) to ``path`` (``.npz``) atomically."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, positions=np.asarray(positions, float), frames=np.asarray(frames, float))


def load_pose(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """``(positions, frames)`` from a file written by :func:`save_pose`."""
    with np.load(path) as z:
        return z["positions"], z["frames"]
