"""Base class of the trajectory analyses (the MDAnalysis ``AnalysisBase`` pattern).

An analysis is built on a :class:`~dnarod.core.trajectory.Trajectory` of node poses, ``run()``
selects frames (``start``, ``stop``, ``step``), computes, and returns ``self``; results are
attributes of ``.results``. Unlike MDAnalysis, which calls ``_single_frame`` per frame, the
kernels here see all selected frames at once (arrays ``(n_frames, n_nodes, ...)``) so they
can be vectorised over frames.

The input trajectory is validated once (finite numbers, proper frames, evenly spaced frames)
and every error names the frame and node at fault.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import DnarodError, GeometryError
from dnarod.core.strains import Closure
from dnarod.core.trajectory import Trajectory


class Results(dict):
    """A dict whose keys are also attributes (``results.mean`` is ``results["mean"]``).

    MDAnalysis has the same class (``MDAnalysis.analysis.results.Results``); this copy of the
    idea avoids importing MDAnalysis (about 1.5 s) for analyses of dnarod's own trajectories.
    """

    def __getattr__(self, key):
        try:
            return self[key]
        except KeyError:
            raise AttributeError(f"no result {key!r}; available: {sorted(self)}") from None

    def __setattr__(self, key, value):
        self[key] = value


def check_trajectory(traj, check_spacing=True, atol=1e-6):
    """Validate a trajectory for analysis.

    Parameters
    ----------
    traj : Trajectory
    check_spacing : bool
        Require strictly increasing, evenly spaced frame times (a gap means missing frames).
    atol : float
        Tolerance on the orthonormality of the frames.

    Raises
    ------
    DnarodError
        Empty trajectory, fewer than 2 nodes, missing (unevenly spaced) or repeated frames.
    GeometryError
        Non-finite positions or frames, or frames that are not proper rotations (naming frame
        and node).
    """
    if not isinstance(traj, Trajectory):
        raise DnarodError(f"expected a dnarod Trajectory, got {type(traj).__name__}")
    if traj.n_frames == 0:
        raise DnarodError("the trajectory has no frames")
    if traj.n_nodes < 2:
        raise DnarodError(f"the trajectory has {traj.n_nodes} node(s); an analysis needs at least 2")
    for name, arr in (("position", traj.positions), ("frame", traj.frames)):
        bad = ~np.isfinite(arr.reshape(traj.n_frames, traj.n_nodes, -1)).all(axis=2)
        if bad.any():
            f, k = (int(i) for i in np.argwhere(bad)[0])
            raise GeometryError(f"trajectory frame {f} (time {traj.time[f]:g} ps), base pair {k + 1}: {name} is not finite "
                                f"({int(bad.sum())} bad node poses in {int(bad.any(axis=1).sum())} frames); "
                                f"the run that wrote it blew up or the file is corrupt; analyse the frames "
                                f"before it with stop={f}")
    F = traj.frames
    err = np.abs(np.swapaxes(F, -1, -2) @ F - np.eye(3)).max(axis=(-1, -2))
    if (err > atol).any():
        f, k = (int(i) for i in np.argwhere(err > atol)[0])
        raise GeometryError(f"trajectory frame {f}, base pair {k + 1}: frame is not orthonormal "
                            f"(max |F^T F - I| = {err[f, k]:.2e} > {atol:g})")
    det = np.linalg.det(F)
    if (det < 0).any():
        f, k = (int(i) for i in np.argwhere(det < 0)[0])
        raise GeometryError(f"trajectory frame {f}, base pair {k + 1}: frame is left-handed (det = {det[f, k]:.3f})")
    if check_spacing and traj.n_frames > 2:
        dt = np.diff(traj.time)
        if (dt <= 0).any():
            f = int(np.argmax(dt <= 0)) + 1
            raise DnarodError(f"trajectory frame {f}: time {traj.time[f]:g} ps does not increase "
                              f"(previous frame {traj.time[f - 1]:g} ps); frames are repeated or out of order")
        typical = np.median(dt)
        off = np.abs(dt - typical) > 1e-3 * typical + 1e-9
        if off.any():
            f = int(np.argmax(off)) + 1
            raise DnarodError(f"trajectory frame {f}: time jumps from {traj.time[f - 1]:g} to {traj.time[f]:g} ps "
                              f"but frames are {typical:g} ps apart elsewhere: frames are missing. "
                              f"Pass check_spacing=False (CLI: --allow-gaps) to analyse it anyway")


class AnalysisBase:
    """Base of dnarod's analyses.

    Parameters
    ----------
    trajectory : Trajectory
        Node poses; positions nm, frames with directors as columns.
    check_spacing : bool
        Reject trajectories whose frames are unevenly spaced in time (missing frames).

    Subclasses implement ``_prepare()``, ``_compute(positions, frames, time)`` on the selected
    frames (arrays ``(n_sel, n_nodes, 3)``, ``(n_sel, n_nodes, 3, 3)``, ``(n_sel,)``) and
    ``_conclude()``.
    """

    def __init__(self, trajectory, check_spacing=True):
        check_trajectory(trajectory, check_spacing=check_spacing)
        self._trajectory = trajectory
        self.results = Results()
        self.frame_indices = None

    @property
    def n_frames(self):
        """Number of frames selected by the last :meth:`run`."""
        return 0 if self.frame_indices is None else len(self.frame_indices)

    def run(self, start=None, stop=None, step=None):
        """Run the analysis on frames ``start:stop:step``; returns ``self``."""
        idx = np.arange(self._trajectory.n_frames)[slice(start, stop, step)]
        if idx.size == 0:
            raise DnarodError(f"frame selection start={start}, stop={stop}, step={step} selects no frames "
                              f"of {self._trajectory.n_frames}")
        self.frame_indices = idx
        t = self._trajectory
        self.times = t.time[idx]
        self._prepare()
        self._compute(t.positions[idx], t.frames[idx], t.time[idx])
        self._conclude()
        return self

    def _prepare(self):
        pass

    def _compute(self, positions, frames, time):
        raise NotImplementedError

    def _conclude(self):
        pass


def closure_of(circular, closure=None):
    """The closure to use: ``closure`` if given, identity for a ring, ``None`` for an open chain."""
    if closure is not None:
        return closure
    return Closure.identity() if circular else None


def check_closed(positions, closure, factor=3.0):
    """Raise if a chain analysed as circular is not closed.

    Parameters
    ----------
    positions : ndarray, shape (n_frames, n_nodes, 3)
        nm.
    closure : Closure
    factor : float
        The closing step (last node to the image of node 0) may be at most ``factor`` times
        the median step length.

    Raises
    ------
    GeometryError
        Naming the frame, the gap and the typical step length.
    """
    pos = np.asarray(positions, float)
    img = np.einsum("ij,fj->fi", closure.Q, pos[:, 0]) + closure.t
    gap = np.linalg.norm(img - pos[:, -1], axis=-1)
    steps = np.median(np.linalg.norm(np.diff(pos, axis=1), axis=-1))
    bad = gap > factor * steps
    if bad.any():
        f = int(np.argmax(bad))
        raise GeometryError(f"circular analysis of a chain that is not closed: in frame {f} the last node is "
                            f"{gap[f]:.3g} nm from (the image of) the first, but steps are {steps:.3g} nm long. "
                            f"This looks like a linear chain: analyse it without --circular / circular=True")


def block_estimates(values, n_blocks):
    """Split ``values`` (n_frames, ...) into contiguous blocks along axis 0 and average each.

    Returns
    -------
    ndarray, shape (n_blocks, ...)
        Block means (``n_blocks`` is capped at ``n_frames``).
    """
    values = np.asarray(values, float)
    nb = max(1, min(int(n_blocks), values.shape[0]))
    return np.array([b.mean(axis=0) for b in np.array_split(values, nb, axis=0)])


def standard_error(estimates):
    """Standard error of the mean of independent block estimates (n_blocks, ...); NaN for one block."""
    est = np.asarray(estimates, float)
    if est.shape[0] < 2:
        return np.full(est.shape[1:], np.nan)
    return est.std(axis=0, ddof=1) / np.sqrt(est.shape[0])
