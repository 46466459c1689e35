"""Base-pair parameters and base-pair (middle) frames in the 3DNA convention.

3DNA (Lu & Olson 2003) treats a base pair like a step from the strand II base to the
strand I base: the strand II base frame has its y and z axes reversed (when the two base
normals are antiparallel, as in any Watson-Crick-like pair), and the step construction of
:func:`dnarod.core.stepparams.step_parameters_with_midframe` applied to (strand II, strand I)
gives shear, stretch, stagger (its shift, slide, rise), buckle, propeller, opening (its
tilt, roll, twist) and the base-pair frame (its mid-step frame). The step kernel is
imported, not repeated. :func:`base_frames_from_pair` is the exact inverse (used by the
rebuild).

Units: nm and rad inside; frames with axes as columns. Vectorised over leading axes.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.stepparams import step_parameters_with_midframe, step_transform

BP_PARAMETER_NAMES = ("shear", "stretch", "stagger", "buckle", "propeller", "opening")
FLIP = np.array([1.0, -1.0, -1.0])


def flip_strand2(frames2, frames1=None):
    """Reverse the y and z axes of strand II base frames (only where the normals are antiparallel).

    Parameters
    ----------
    frames2 : ndarray, shape (..., 3, 3)
    frames1 : ndarray, shape (..., 3, 3), optional
        Strand I base frames; if given, frames whose z axes are parallel to strand I's are
        left unchanged (3DNA's rule for parallel pairs).
    """
    frames2 = np.asarray(frames2, float)
    flipped = frames2 * FLIP
    if frames1 is None:
        return flipped
    anti = np.einsum("...i,...i->...", frames1[..., :, 2], frames2[..., :, 2]) < 0
    return np.where(anti[..., None, None], flipped, frames2)


def pair_parameters(frames1, origins1, frames2, origins2):
    """Base-pair parameters and the base-pair frame from the two base frames.

    Parameters
    ----------
    frames1, frames2 : ndarray, shape (..., 3, 3)
        Base frames of the strand I and strand II bases (as fitted, unflipped).
    origins1, origins2 : ndarray, shape (..., 3)
        Base origins, nm.

    Returns
    -------
    params : ndarray, shape (..., 6)
        shear, stretch, stagger (nm); buckle, propeller, opening (rad).
    bp_frames : ndarray, shape (..., 3, 3)
        Middle (base-pair) frames.
    bp_origins : ndarray, shape (..., 3)
        Middle origins, nm.
    """
    f2 = flip_strand2(frames2, np.asarray(frames1, float))
    return step_parameters_with_midframe(f2, origins2, frames1, origins1)


def base_frames_from_pair(bp_frames, bp_origins, params):
    """Inverse of :func:`pair_parameters`: the two base frames from the pair frame and parameters.

    Parameters
    ----------
    bp_frames : ndarray, shape (..., 3, 3)
    bp_origins : ndarray, shape (..., 3)
        nm.
    params : ndarray, shape (..., 6)
        shear, stretch, stagger (nm); buckle, propeller, opening (rad).

    Returns
    -------
    frames1, origins1, frames2, origins2
        Strand I and strand II base frames (strand II unflipped, as a fit would give them)
        and origins (nm).
    """
    p = np.asarray(params, float)
    R, t = step_transform(p)
    # The mid frame of the pair expressed in the first (strand II, flipped) base frame.
    eye = np.broadcast_to(np.eye(3), R.shape)
    _, Rm, _ = step_parameters_with_midframe(eye, np.zeros_like(t), R, t)
    first = np.asarray(bp_frames, float) @ np.swapaxes(Rm, -1, -2)
    second = first @ R
    half = 0.5 * np.einsum("...ij,...j->...i", first, t)
    o_first = np.asarray(bp_origins, float) - half
    o_second = np.asarray(bp_origins, float) + half
    return second, o_second, first * FLIP, o_first
