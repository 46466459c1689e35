"""3DNA's base-pair frame conventions for left-handed DNA and B-Z junctions.

3DNA's ``analyze`` (Lu & Olson 2003, Nucleic Acids Res. 31:5108) keeps the Tsukuba base-pair
frame (Olson et al. 2001, J. Mol. Biol. 313:229: y toward strand I, z along the mean base
normal of strand I) but reverses it where the helix is left-handed, so that Z-DNA reads
with positive rise and negative twist. The reversal is a rotation by 180 degrees about the
frame's y axis (x and z negated, y kept); it changes the sign of shift, rise, tilt and twist
of a step. Two rules, both re-implemented here from their description and checked against
3DNA's tables (``data/structures/3dna_examples``):

* whole structure (:func:`global_z_reversal`): if in every base pair that is not the last of
  a helix, and that has Watson-Crick geometry, both base normals point against the direction
  from this pair's base to the next pair's base on the same strand, every base frame is
  reversed (a left-handed structure, e.g. Z-DNA); the base-pair parameters then change sign
  in shear, stagger, buckle and opening as well.
* step by step (:func:`bz_step_flips`): for two consecutive pair frames with x axes and z
  axes opposite but y axes alike (a B-Z junction), the frame on the Z side (the one whose
  normal points against the step) is reversed for this step; for two frames with all axes
  alike but both normals pointing against the step (a Z step inside a right-handed
  structure) both are reversed for this step. 3DNA v2.0 applies this to every step (v2.3 and
  later only to steps between two Watson-Crick pairs); the tables in ``data/`` are v2.0's.

Node frames for a rod model must run along the helix: :func:`node_reversal` reverses every
pair frame that 3DNA reverses for any of its steps, so that the steps of the node frames
equal 3DNA's steps wherever the two rules agree on a pair.

Units: nm and rad. Frames have axes as columns. Vectorised over leading axes (frames of a
trajectory).
"""
from __future__ import annotations

import numpy as np

from dnarod.core.stepparams import step_parameters_with_midframe
from dnarod.structure.findpair import check_wc_wobble

#: Rotation by 180 degrees about y, applied on the right of a frame: x and z reversed.
REVERSE = np.diag([-1.0, 1.0, -1.0])
HELIX_END, ISOLATED = 9, 1


def helix_markers(lengths):
    """3DNA's per-pair helix markers: 9 on the last pair of a helix, 1 on an isolated pair, else 0.

    The very last pair of the structure is 0 unless it is isolated (as 3DNA's find_pair writes).

    Parameters
    ----------
    lengths : list of int
        Pairs per helix, in order.

    Returns
    -------
    ndarray of int, shape (sum(lengths),)
    """
    out = []
    for n in lengths:
        out += [ISOLATED] if n == 1 else [0] * (n - 1) + [HELIX_END]
    if out and out[-1] == HELIX_END:
        out[-1] = 0
    return np.array(out, dtype=int)


def wc_info(bp_params, frames1, frames2f, antiparallel, letters):
    """3DNA's pair class in ``analyze``: 2 Watson-Crick, 1 WC geometry, 0 other.

    Parameters
    ----------
    bp_params : ndarray, shape (n, 6)
        nm, rad (unreversed).
    frames1, frames2f : ndarray, shape (n, 3, 3)
        Strand I and strand II base frames (strand II with y, z reversed where antiparallel).
    antiparallel : ndarray of bool, shape (n,)
    letters : list of str
        Two parent letters per pair (strand I, strand II).

    Returns
    -------
    ndarray of int, shape (n,)
    """
    out = np.zeros(len(letters), dtype=int)
    for k, lt in enumerate(letters):
        if (antiparallel[k] and frames1[k][:, 0] @ frames2f[k][:, 0] > 0
                and frames1[k][:, 1] @ frames2f[k][:, 1] > 0):
            p = bp_params[k]
            out[k] = check_wc_wobble(lt, 10 * p[0], 10 * p[1], np.degrees(p[5]))
    return out


def global_z_reversal(frames1, origins1, frames2f, origins2, wc, markers):
    """3DNA's whole-structure rule: True if the structure reads left-handed (all frames reversed).

    Parameters
    ----------
    frames1, frames2f : ndarray, shape (..., n, 3, 3)
        Strand I and (y, z reversed where antiparallel) strand II base frames, all pairs of all
        helices in order.
    origins1, origins2 : ndarray, shape (..., n, 3)
    wc : ndarray of int, shape (n,)
        :func:`wc_info`.
    markers : ndarray of int, shape (n,)
        :func:`helix_markers`.

    Returns
    -------
    ndarray of bool, shape (...)
    """
    n = np.shape(origins1)[-2]
    counted = np.asarray(markers) == 0
    if n < 2 or not counted.any():
        return np.zeros(np.shape(origins1)[:-2], dtype=bool)
    ok = []
    for F, O in ((frames1, origins1), (frames2f, origins2)):
        d = np.diff(O, axis=-2)  # base j -> j+1 on this strand
        d = np.concatenate([d, d[..., -1:, :]], axis=-2)  # the last pair uses the previous step
        back = np.einsum("...ji,...ji->...j", d, F[..., :, 2]) < 0
        ok.append(back & (np.asarray(wc) != 0))
    ok = np.concatenate([ok[0][..., counted], ok[1][..., counted]], axis=-1)
    return ok.all(axis=-1)


def bz_step_flips(frames, origins):
    """3DNA's step rule: which of the two pair frames of each step it reverses.

    Parameters
    ----------
    frames : ndarray, shape (..., n, 3, 3)
        Pair frames.
    origins : ndarray, shape (..., n, 3)

    Returns
    -------
    flips : ndarray of bool, shape (..., n - 1, 2)
        (first, second) frame reversed for the step.
    junction : ndarray of bool, shape (..., n - 1)
        The step joins a right- and a left-handed pair (B-Z junction).
    """
    F1, F2 = frames[..., :-1, :, :], frames[..., 1:, :, :]
    def dot(a, b):
        return np.einsum("...i,...i->...", a, b)
    x1, y1, z1 = F1[..., :, 0], F1[..., :, 1], F1[..., :, 2]
    x2, y2, z2 = F2[..., :, 0], F2[..., :, 1], F2[..., :, 2]
    dorg = origins[..., 1:, :] - origins[..., :-1, :]
    junction = (dot(x1, x2) < 0) & (dot(z1, z2) < 0) & (dot(y1, y2) > 0)
    second_z = dot(dorg, z1) > 0
    zstep = ~junction & (dot(x1, x2) > 0) & (dot(z1, z2) > 0) & (dot(y1, y2) > 0) & (dot(dorg, z1) < 0) \
        & (dot(dorg, z2) < 0)
    flips = np.stack([(junction & ~second_z) | zstep, (junction & second_z) | zstep], axis=-1)
    return flips, junction


def reverse_frames(frames, mask):
    """``frames`` with x and z negated where ``mask`` (broadcast over the last two axes)."""
    return np.where(np.asarray(mask)[..., None, None], frames @ REVERSE, frames)


def reverse_pair_parameters(params):
    """Base-pair (or step) parameters of the same pair with both frames reversed: shear, stagger,
    buckle, opening (shift, rise, tilt, twist) change sign."""
    p = np.array(params, dtype=float)
    p[..., [0, 2, 3, 5]] *= -1
    return p


def step_parameters_3dna(frames, origins):
    """Step parameters with 3DNA's step rule (:func:`bz_step_flips`) applied.

    Parameters
    ----------
    frames : ndarray, shape (..., n, 3, 3)
    origins : ndarray, shape (..., n, 3)

    Returns
    -------
    params : ndarray, shape (..., n - 1, 6)
        nm, rad.
    flips : ndarray of bool, shape (..., n - 1, 2)
    junction : ndarray of bool, shape (..., n - 1)
    """
    flips, junction = bz_step_flips(frames, origins)
    A = reverse_frames(frames[..., :-1, :, :], flips[..., 0])
    B = reverse_frames(frames[..., 1:, :, :], flips[..., 1])
    p = step_parameters_with_midframe(A, origins[..., :-1, :], B, origins[..., 1:, :])[0]
    return p, flips, junction


def node_reversal(flips, segments):
    """Pair frames a rod model reverses: those 3DNA reverses for any of their steps within a helix.

    Parameters
    ----------
    flips : ndarray of bool, shape (n - 1, 2)
        :func:`bz_step_flips` of all pairs in order.
    segments : list of (int, int)
        ``[start, stop)`` pair ranges of the helices.

    Returns
    -------
    reversed : ndarray of bool, shape (n,)
    disagree : list of int
        Steps (0-based, global) inside a helix whose node frames differ from 3DNA's choice
        for that step (a pair reversed for one of its steps but not for the other).
    """
    n = len(flips) + 1
    rev = np.zeros(n, dtype=bool)
    for a, b in segments:
        for k in range(a, b - 1):
            rev[k] |= flips[k, 0]
            rev[k + 1] |= flips[k, 1]
    disagree = [k for a, b in segments for k in range(a, b - 1)
                if (rev[k], rev[k + 1]) != (bool(flips[k, 0]), bool(flips[k, 1]))]
    return rev, disagree
