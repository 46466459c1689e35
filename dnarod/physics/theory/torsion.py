"""Elastic theory of a stretched, twisted rod: the Moroz-Nelson effective torsional stiffness and related
estimates with the model's own parameters."""
from __future__ import annotations

import numpy as np

from dnarod.core.units import kT


def moroz_nelson(C, A, force_pN, kt_pn_nm):
    """Moroz-Nelson effective torsional persistence length (nm), third order in 1/K0."""
    M = C / A
    K0 = np.sqrt(A * np.asarray(force_pN, float) / kt_pn_nm)
    return C * (1 - M / (4 * K0) + (M * M - 2 * M) / (16 * K0 ** 2)
                - (4 * M ** 3 - 16 * M * M + 21 * M) / (256 * K0 ** 3))


def bare_twist_persistence(model, temperature):
    """C (nm) of a uniform model at constant force: ``sec^4(theta0/2) / ((K^-1)_33 kT)``."""
    K = model.params.stiffness[0]
    th0 = 2.0 * np.arctan(0.5 * model.ds * model.params.Omega0[0, 2])
    return float(np.cos(0.5 * th0) ** -4 / (np.linalg.inv(K)[2, 2] * kT(temperature)))


def twist_friction(model, temperature, C_nm):
    """Collision rate (1/ps) critically damping the slowest twist mode of a chain clamped at one end.

    The twist angle obeys a wave equation with torsional rigidity ``kT C`` and rotational inertia per length
    ``J3/ds``; with one end clamped and the other (almost) free the slowest mode has ``q = pi/(2L)``, so
    ``omega = q sqrt(kT C ds / J3)`` and critical damping is ``2 omega``.
    """
    L = model.ds * model.n_steps
    w = np.pi / (2 * L) * np.sqrt(kT(temperature) * C_nm * model.ds / float(np.mean(model.inertia[:, 2])))
    return float(2 * w)
