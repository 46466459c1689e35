"""Conversion between 3DNA step coordinates and dnarod's Cayley strain coordinates.

A step with Cayley strains ``xi = (Omega, Gamma)`` (1/nm, dimensionless) has the relative
transform ``R = cayley(ds Omega)``, ``t = ds Gamma`` (frame-1 components); its 3DNA step
parameters ``p = f(xi)`` are (shift, slide, rise, tilt, roll, twist). Literature stiffnesses
given in 3DNA coordinates (energy ``1/2 dp^T F dp`` in kT per step, p in Angstrom and
degrees) become Cayley stiffnesses through the Jacobian ``J = df/dxi`` at the mean step::

    K = kT J^T F J / ds        (kJ/mol units per unit length, docs/formulation.md §2)

and the intrinsic strains are the exact preimage ``xi0 = f^-1(p0)``, not a linearisation.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.rotations import cayley, cayley_inverse
from dnarod.core.stepparams import from_angstrom_degrees, step_parameters, step_transform, to_angstrom_degrees


def strains_to_step_parameters(xi, ds):
    """3DNA step parameters of steps with the given Cayley strains.

    Parameters
    ----------
    xi : ndarray, shape (..., 6)
        ``(Omega1, Omega2, Omega3, Gamma1, Gamma2, Gamma3)``, 1/nm and dimensionless.
    ds : float
        nm.

    Returns
    -------
    ndarray, shape (..., 6)
        shift, slide, rise (Angstrom); tilt, roll, twist (degrees).
    """
    xi = np.asarray(xi, float)
    R = cayley(ds * xi[..., :3])
    t = ds * xi[..., 3:]
    I = np.broadcast_to(np.eye(3), R.shape)
    return to_angstrom_degrees(step_parameters(I, np.zeros_like(t), R, t))


def step_parameters_to_strains(p, ds):
    """Cayley strains of steps with the given 3DNA parameters (exact inverse of the above).

    Parameters
    ----------
    p : ndarray, shape (..., 6)
        shift, slide, rise (Angstrom); tilt, roll, twist (degrees).
    ds : float
        nm.

    Returns
    -------
    ndarray, shape (..., 6)
    """
    R, t = step_transform(from_angstrom_degrees(p))
    return np.concatenate([cayley_inverse(R, what="step") / ds, t / ds], axis=-1)


def jacobian_strains_to_step_parameters(xi, ds, h=1e-4):
    """``J = d p / d xi`` at ``xi`` (6x6; p in Angstrom and degrees), by 4th-order central differences.

    The map is smooth (rational and trigonometric), so the difference error is about
    ``h^4`` times its fifth derivative: below 1e-12 relative here.
    """
    xi = np.asarray(xi, float)
    J = np.empty((6, 6))
    for j in range(6):
        e = np.zeros(6)
        e[j] = h
        def f(s):
            return strains_to_step_parameters(xi + s * e, ds)
        J[:, j] = (8 * (f(1) - f(-1)) - (f(2) - f(-2))) / (12 * h)
    return J


def stiffness_from_step_coordinates(p0, F, ds, kt):
    """Cayley intrinsic strains and stiffness from a 3DNA Gaussian model of one step.

    Parameters
    ----------
    p0 : array_like, shape (6,)
        Mean step parameters, Angstrom and degrees (shift, slide, rise, tilt, roll, twist).
    F : array_like, shape (6, 6)
        Force constants in kT per (Angstrom or degree)^2, same order, energy ``1/2 dp^T F dp``.
    ds : float
        nm.
    kt : float
        kT in kJ/mol at which ``F`` is expressed.

    Returns
    -------
    xi0 : ndarray, shape (6,)
    K : ndarray, shape (6, 6)
        kJ/mol units per unit length (A: kJ/mol nm, B: kJ/mol, C: kJ/mol/nm).
    """
    xi0 = step_parameters_to_strains(np.asarray(p0, float), ds)
    J = jacobian_strains_to_step_parameters(xi0, ds)
    K = kt * J.T @ np.asarray(F, float) @ J / ds
    return xi0, 0.5 * (K + K.T)


def stiffness_to_step_coordinates(xi0, K, ds, kt):
    """Inverse of :func:`stiffness_from_step_coordinates`: ``(p0, F)`` in Angstrom/degree units and kT."""
    p0 = strains_to_step_parameters(np.asarray(xi0, float), ds)
    J = jacobian_strains_to_step_parameters(xi0, ds)
    Jinv = np.linalg.inv(J)
    F = Jinv.T @ (np.asarray(K, float) * ds / kt) @ Jinv
    return p0, 0.5 * (F + F.T)
