"""3DNA step parameters (Tsukuba convention) between two rigid frames, and their inverse.

The six step parameters (shift, slide, rise, tilt, roll, twist) of Olson et al. (2001),
J. Mol. Biol. 313:229, computed with the construction of Lu & Olson (2003), Nucleic Acids
Res. 31:5108 (3DNA): the hinge is ``z1 x z2``; both frames are rotated by half the
roll-tilt angle about it onto a common z; twist is the angle between their y axes; the
roll-tilt split follows the angle between the hinge and the mid-step y axis; the
translations are the origin difference in the mid-step frame. The inverse is the
El Hassan & Calladine (1995) composition ``Rz(tw/2 - phi) Ry(gamma) Rz(tw/2 + phi)``.

These are written here rather than imported because no maintained Python package
exposes 3DNA's step-parameter kernel (3DNA and x3dna-dssr are standalone C programs).

Internal units: nm and rad, order ``(shift, slide, rise, tilt, roll, twist)``. Convert at
the edges with :func:`to_angstrom_degrees` / :func:`from_angstrom_degrees`.
Frames have the axes x, y, z as columns. All functions are vectorised over leading axes.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.rotations import rotation_about_axis

STEP_PARAMETER_NAMES = ("shift", "slide", "rise", "tilt", "roll", "twist")


def to_angstrom_degrees(p):
    """Convert ``(..., 6)`` step parameters from (nm, rad) to (Angstrom, degrees)."""
    p = np.array(p, dtype=float)
    p[..., :3] *= 10.0
    p[..., 3:] = np.degrees(p[..., 3:])
    return p


def from_angstrom_degrees(p):
    """Convert ``(..., 6)`` step parameters from (Angstrom, degrees) to (nm, rad)."""
    p = np.array(p, dtype=float)
    p[..., :3] /= 10.0
    p[..., 3:] = np.radians(p[..., 3:])
    return p


def _signed_angle(va, vb, vref):
    """Angle from va to vb after projection onto the plane normal to unit vref (3DNA vec_ang)."""
    pa = va - np.einsum("...i,...i->...", va, vref)[..., None] * vref
    pb = vb - np.einsum("...i,...i->...", vb, vref)[..., None] * vref
    s = np.einsum("...i,...i->...", np.cross(pa, pb), vref)
    c = np.einsum("...i,...i->...", pa, pb)
    return np.arctan2(s, c)


def step_parameters_with_midframe(L1, o1, L2, o2):
    """Step parameters and the mid-step frame between frames 1 and 2.

    Parameters
    ----------
    L1, L2 : ndarray, shape (..., 3, 3)
        Frames (axes as columns).
    o1, o2 : ndarray, shape (..., 3)
        Origins, nm.

    Returns
    -------
    params : ndarray, shape (..., 6)
        shift, slide, rise (nm); tilt, roll, twist (rad).
    mid_frame : ndarray, shape (..., 3, 3)
    mid_origin : ndarray, shape (..., 3)
    """
    L1 = np.asarray(L1, float)
    L2 = np.asarray(L2, float)
    o1 = np.asarray(o1, float)
    o2 = np.asarray(o2, float)
    z1, z2 = L1[..., :, 2], L2[..., :, 2]
    hinge = np.cross(z1, z2)
    hn = np.linalg.norm(hinge, axis=-1)
    gamma = np.arctan2(hn, np.einsum("...i,...i->...", z1, z2))
    # With parallel z axes the hinge is arbitrary (roll = tilt = 0); use x1.
    small = hn < 1e-12
    hinge = np.where(small[..., None], L1[..., :, 0], hinge / np.where(small, 1.0, hn)[..., None])
    R1p = rotation_about_axis(hinge, 0.5 * gamma) @ L1
    R2p = rotation_about_axis(hinge, -0.5 * gamma) @ L2
    zm = R2p[..., :, 2]
    y1, y2 = R1p[..., :, 1], R2p[..., :, 1]
    ym = y1 + y2
    ym /= np.linalg.norm(ym, axis=-1)[..., None]
    xm = np.cross(ym, zm)
    twist = _signed_angle(y1, y2, zm)
    phi = _signed_angle(hinge, ym, zm)
    roll = gamma * np.cos(phi)
    tilt = gamma * np.sin(phi)
    d = o2 - o1
    def dot(a):
        return np.einsum("...i,...i->...", d, a)
    params = np.stack([dot(xm), dot(ym), dot(zm), tilt, roll, twist], axis=-1)
    mid = np.stack([xm, ym, zm], axis=-1)
    return params, mid, 0.5 * (o1 + o2)


def step_parameters(L1, o1, L2, o2):
    """Step parameters (shift, slide, rise in nm; tilt, roll, twist in rad), shape ``(..., 6)``."""
    return step_parameters_with_midframe(L1, o1, L2, o2)[0]


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    out = np.zeros(np.shape(a) + (3, 3))
    out[..., 0, 0] = c
    out[..., 0, 1] = -s
    out[..., 1, 0] = s
    out[..., 1, 1] = c
    out[..., 2, 2] = 1.0
    return out


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    out = np.zeros(np.shape(a) + (3, 3))
    out[..., 0, 0] = c
    out[..., 0, 2] = s
    out[..., 2, 0] = -s
    out[..., 2, 2] = c
    out[..., 1, 1] = 1.0
    return out


def step_transform(params):
    """Relative rotation and translation of frame 2 in frame 1 from step parameters.

    Parameters
    ----------
    params : array_like, shape (..., 6)
        shift, slide, rise (nm); tilt, roll, twist (rad).

    Returns
    -------
    R : ndarray, shape (..., 3, 3)
        ``L1^T L2``.
    t : ndarray, shape (..., 3)
        ``L1^T (o2 - o1)``, nm.
    """
    p = np.asarray(params, float)
    tilt, roll, twist = p[..., 3], p[..., 4], p[..., 5]
    gamma = np.hypot(tilt, roll)
    phi = np.arctan2(tilt, roll)
    R = _rz(0.5 * twist - phi) @ _ry(gamma) @ _rz(0.5 * twist + phi)
    Rm = _rz(0.5 * twist - phi) @ _ry(0.5 * gamma) @ _rz(phi)
    t = np.einsum("...ij,...j->...i", Rm, p[..., :3])
    return R, t
