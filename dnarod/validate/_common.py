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


def ring_writhe_plot(reference_wr, reference_label, samples_csv):
    """Figure of a ring check's writhe histograms, started with the reference Monte Carlo's.

    Parameters
    ----------
    reference_wr : ndarray, shape (k,)
        Writhe samples of the reference worm-like ring Monte Carlo.
    reference_label : str
        Legend entry of those samples.
    samples_csv : str or Path
        The model member's ``samples.csv`` (read with its header as field names).

    Returns
    -------
    fig : matplotlib Figure
    a : matplotlib Axes
        The one axes, for the model's histogram and any marks.
    samples : numpy structured ndarray
        The member's samples.
    """
    from dnarod.analysis.plots import new_figure  # matplotlib only where a check plots

    fig, ax = new_figure(1, 1, width=5.0, height=3.8)
    a = ax[0, 0]
    a.hist(reference_wr, bins=40, density=True, histtype="step", label=reference_label)
    samples = np.genfromtxt(samples_csv, delimiter=",", names=True)
    return fig, a, samples


def save_ring_writhe_plot(fig, a, n_bp, out_dir, name):
    """Label, add the legend to and save a figure of :func:`ring_writhe_plot`; returns ``[path]``."""
    from dnarod.analysis.plots import save_figure

    a.set_xlabel(f"Wr ({n_bp} bp ring)")
    a.set_ylabel("density")
    a.legend(fontsize=7)
    return [save_figure(fig, out_dir, name)]


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


