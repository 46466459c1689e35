"""Rotation kernels: hat/axial maps, the Cayley map and its inverse, frame checks.

This is the one home of the Cayley chart used by the strain map (docs/formulation.md §2). All kernels
are vectorised over leading axes: a vector argument has shape ``(..., 3)`` and a matrix
argument ``(..., 3, 3)``. Angles are in radians.

The Cayley (Gibbs) vector of a rotation by angle theta about the unit axis n is
``w = 2 tan(theta/2) n``; it is defined for every rotation with theta < pi.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import GeometryError

#: Largest rotation angle (rad) between neighbouring frames that the Cayley chart accepts.
#: At pi the chart is undefined; within ``MAX_CAYLEY_ANGLE`` of it the strain is > 2e4 / ds.
MAX_CAYLEY_ANGLE = np.pi - 1e-4


def hat(v):
    """Skew matrix of a vector: ``hat(v) @ x == cross(v, x)``.

    Parameters
    ----------
    v : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    v = np.asarray(v, dtype=float)
    out = np.zeros(v.shape + (3,))
    out[..., 0, 1] = -v[..., 2]
    out[..., 0, 2] = v[..., 1]
    out[..., 1, 0] = v[..., 2]
    out[..., 1, 2] = -v[..., 0]
    out[..., 2, 0] = -v[..., 1]
    out[..., 2, 1] = v[..., 0]
    return out


def axial(S):
    """Axial vector of a matrix, ``(S32, S13, S21)``; inverse of :func:`hat` on skew matrices.

    Parameters
    ----------
    S : array_like, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (..., 3)
    """
    S = np.asarray(S, dtype=float)
    return np.stack([S[..., 2, 1], S[..., 0, 2], S[..., 1, 0]], axis=-1)


def cayley(w):
    """Rotation matrix of a Cayley vector: ``I + (hat(w) + hat(w)^2/2) / (1 + |w|^2/4)``.

    Parameters
    ----------
    w : array_like, shape (..., 3)
        Cayley vectors (dimensionless; ``|w| = 2 tan(theta/2)``).

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Proper rotation matrices.
    """
    w = np.asarray(w, dtype=float)
    W = hat(w)
    den = 1.0 + 0.25 * np.einsum("...i,...i->...", w, w)
    return np.eye(3) + (W + 0.5 * W @ W) / den[..., None, None]


def cayley_inverse(R, what="rotation"):
    """Cayley vector of a rotation: ``w = 2 axial(R - R^T) / (1 + tr R)``.

    Parameters
    ----------
    R : array_like, shape (..., 3, 3)
        Rotation matrices.
    what : str
        Name used in the error message (for example ``"step"``).

    Returns
    -------
    ndarray, shape (..., 3)

    Raises
    ------
    GeometryError
        If a rotation angle is at or beyond ``MAX_CAYLEY_ANGLE`` (the chart is undefined at pi),
        or a matrix holds non-finite values. The message gives the index.
    """
    R = np.asarray(R, dtype=float)
    den = 1.0 + np.trace(R, axis1=-2, axis2=-1)
    limit = 2.0 * (1.0 + np.cos(MAX_CAYLEY_ANGLE))
    bad = ~(den > limit)  # also catches NaN
    if np.any(bad):
        idx = np.argwhere(np.atleast_1d(bad))[0]
        loc = tuple(int(i) for i in idx) if R.ndim > 2 else ()
        cos_t = np.clip((np.atleast_1d(den)[tuple(idx)] - 2.0) / 2.0, -1, 1)
        raise GeometryError(
            f"{_where(what, loc)}: rotation between neighbouring frames is "
            f"{np.degrees(np.arccos(cos_t)) if np.isfinite(cos_t) else 'not finite'} deg, at or beyond "
            f"180 deg, where the Cayley strain is undefined; check the frame order and orientation "
            f"(neighbouring base-pair frames turn by about 34 deg)"
        )
    return 2.0 * axial(R - np.swapaxes(R, -1, -2)) / den[..., None]


def cayley_T(w):
    """Inverse right-trivialised derivative of the Cayley map, ``T(w) = I - hat(w)/2 + w w^T/4``.

    With ``R = cayley(w)``, a body-frame virtual rotation ``dTheta`` of the second frame changes
    ``w`` by ``T(w)^T dTheta``; ``T^T = R T`` (docs/formulation.md §4).

    Parameters
    ----------
    w : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    w = np.asarray(w, dtype=float)
    return np.eye(3) - 0.5 * hat(w) + 0.25 * w[..., :, None] * w[..., None, :]


def rotation_about_axis(axis, angle):
    """Rotation matrix by ``angle`` (rad) about an axis (Rodrigues' formula).

    Parameters
    ----------
    axis : array_like, shape (..., 3)
        Rotation axes; normalised here (a zero axis is an error).
    angle : array_like, shape (...)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    axis = np.asarray(axis, dtype=float)
    norm = np.linalg.norm(axis, axis=-1)
    if not np.all(norm > 0):
        raise GeometryError("rotation axis has zero length (or is not finite)")
    axis = axis / norm[..., None]
    angle = np.asarray(angle, dtype=float)
    K = hat(axis)
    s = np.sin(angle)[..., None, None]
    c = np.cos(angle)[..., None, None]
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)


def _where(what, loc):
    """The item a message names: a step or a node numbered from 1 as `dnarod steps` does (base pair k+1, step k+1
    between base pairs k+1 and k+2), any other ``what`` with its index as given."""
    from dnarod.core.errors import base_pair, step_name

    if len(loc) == 1 and what == "step":
        return step_name(loc[0])
    if len(loc) == 1 and what == "node":
        return base_pair(loc[0])
    return f"{what} {loc[0] if len(loc) == 1 else loc}"


def check_frames(frames, atol=1e-6, what="node"):
    """Check that frames are proper rotations (orthonormal, right-handed, finite).

    Parameters
    ----------
    frames : array_like, shape (n, 3, 3)
        Directors as columns.
    atol : float
        Tolerance on ``|F^T F - I|`` (max entry).
    what : str
        Name used in error messages.

    Returns
    -------
    ndarray, shape (n, 3, 3)
        The frames as a float array.

    Raises
    ------
    GeometryError
        Naming the first bad frame and what is wrong with it.
    """
    F = np.asarray(frames, dtype=float)
    if F.ndim != 3 or F.shape[1:] != (3, 3):
        raise GeometryError(f"frames must have shape (n_nodes, 3, 3), got {F.shape}")
    finite = np.isfinite(F).all(axis=(1, 2))
    if not finite.all():
        k = int(np.argmin(finite))
        raise GeometryError(f"{_where(what, (k,))}: frame has non-finite entries")
    err = np.abs(np.swapaxes(F, 1, 2) @ F - np.eye(3)).max(axis=(1, 2))
    if np.any(err > atol):
        k = int(np.argmax(err))
        raise GeometryError(
            f"{_where(what, (k,))}: frame is not orthonormal (max |F^T F - I| = {err[k]:.2e} > {atol:g}); "
            f"directors must be unit, mutually orthogonal columns (re-orthonormalise, e.g. with "
            f"scipy.spatial.transform.Rotation.from_matrix)"
        )
    det = np.linalg.det(F)
    if np.any(det < 0):
        k = int(np.argmin(det))
        raise GeometryError(
            f"{_where(what, (k,))}: frame is left-handed (det = {det[k]:.3f}); directors d1, d2, d3 must "
            f"satisfy d3 = d1 x d2"
        )
    return F
