"""Shared helpers of the validation checks: statistics, plots, JSON-safe results.

Every check returns a plain dict ``{"passed": bool, ...}`` whose other entries are measured
values and the tolerances they are compared with (names ending in ``_tol`` or ``tolerance``),
so ``results.json`` can be read by scripts without knowing the check.
"""
from __future__ import annotations


import numpy as np

from dnarod.core.io import jsonable as _jsonable


def jsonable(obj):
    """JSON-safe results (:func:`dnarod.core.io.jsonable`; NaN/inf as strings)."""
    return _jsonable(obj, nonfinite="repr")


def observed_order(h, err):
    """Least-squares slope of log(err) against log(h) (the observed order of convergence).

    Parameters
    ----------
    h : array_like, shape (k,)
        Step sizes.
    err : array_like, shape (k,)
        Errors (positive).

    Returns
    -------
    float
    """
    h, err = np.asarray(h, float), np.asarray(err, float)
    ok = (err > 0) & np.isfinite(err)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(h[ok]), np.log(err[ok]), 1)[0])


def pairwise_orders(h, err):
    """Orders ``log(e_i/e_{i+1}) / log(h_i/h_{i+1})`` between consecutive step sizes, shape (k-1,)."""
    h, err = np.asarray(h, float), np.asarray(err, float)
    return np.log(err[:-1] / err[1:]) / np.log(h[:-1] / h[1:])


def rotation_angle(A, B):
    """Rotation angle (rad) between frames ``A`` and ``B``, shape (..., 3, 3) -> (...).

    Uses ``2 asin(|A - B|_F / sqrt(8))``, accurate for tiny angles (no arccos of 1 - eps).
    """
    d = np.linalg.norm(np.asarray(A) - np.asarray(B), axis=(-2, -1))
    return 2.0 * np.arcsin(np.clip(d / np.sqrt(8.0), 0.0, 1.0))


