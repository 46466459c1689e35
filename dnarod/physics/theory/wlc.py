"""Worm-like-chain force-extension references (inputs in pN, nm; kT in pN nm).

Used by the ``force_extension`` validation check. Formulas and sources are listed in
``data/physical/wlc_formulas.md``: Marko & Siggia (1995) Macromolecules 28:8759; Bouchiat et al.
(1999) Biophys J 76:409 (7-parameter correction, relative error ~1e-4 against the exact WLC);
Odijk (1995) Macromolecules 28:7016; the extensible form replaces l by ``x/L - F/S``.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

BOUCHIAT = (-0.5164228, -2.737418, 16.07497, -38.87607, 39.49944, -14.17718)  # a2..a7


def marko_siggia_force(l, lp, kt):
    """Force (pN) at relative extension ``l`` of the inextensible WLC (Marko-Siggia interpolation)."""
    l = np.asarray(l, float)
    return kt / lp * (0.25 / (1 - l) ** 2 - 0.25 + l)


def bouchiat_force(l, lp, kt):
    """Force (pN) at relative extension ``l`` (Bouchiat et al. 1999 correction of Marko-Siggia)."""
    l = np.asarray(l, float)
    poly = sum(a * l ** (i + 2) for i, a in enumerate(BOUCHIAT))
    return marko_siggia_force(l, lp, kt) + kt / lp * poly


def extensible_wlc_extension(force, lp, stretch_modulus, kt):
    """Relative extension x/L of the extensible WLC at ``force`` (pN), Bouchiat form with l = x/L - F/S.

    Parameters
    ----------
    force : float or array
        pN (> 0).
    lp : float
        Bending persistence length, nm.
    stretch_modulus : float
        pN.
    kt : float
        pN nm.

    Returns
    -------
    float or ndarray
    """
    def one(F):
        l = brentq(lambda x: bouchiat_force(x, lp, kt) - F, 0.0, 1.0 - 1e-12, xtol=1e-14)
        return l + F / stretch_modulus

    f = np.asarray(force, float)
    return np.vectorize(one)(f) if f.ndim else one(float(f))


def odijk_extension(force, lp, stretch_modulus, kt):
    """Relative extension of the Odijk (1995) high-force extensible WLC: ``1 - sqrt(kT/(F lp))/2 + F/S``."""
    f = np.asarray(force, float)
    return 1.0 - 0.5 * np.sqrt(kt / (f * lp)) + f / stretch_modulus
