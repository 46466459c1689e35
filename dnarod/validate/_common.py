"""Shared helpers of the validation checks: statistics, plots, JSON-safe results.

Every check returns a plain dict ``{"passed": bool, ...}`` whose other entries are measured
values and the tolerances they are compared with (names ending in ``_tol`` or ``tolerance``),
so ``results.json`` can be read by scripts without knowing the check.
"""
from __future__ import annotations

import io
import math

import numpy as np

from dnarod.core.io import atomic_path
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


def jackknife(estimator, blocks):
    """Block-jackknife estimate and standard error.

    Parameters
    ----------
    estimator : callable
        Maps a list of per-block summaries (each whatever ``blocks`` holds) to an estimate (array).
    blocks : list
        One summary per block of consecutive frames (time blocks longer than the correlation time).

    Returns
    -------
    estimate, standard_error : ndarray
        Estimate from all blocks, and the jackknife standard error over the blocks.
    """
    nb = len(blocks)
    full = np.asarray(estimator(blocks), float)
    loo = np.array([np.asarray(estimator(blocks[:i] + blocks[i + 1:]), float) for i in range(nb)])
    se = np.sqrt((nb - 1) / nb * np.sum((loo - loo.mean(axis=0)) ** 2, axis=0))
    return full, se


def split_blocks(arrays, n_blocks):
    """Split arrays (same leading length, the frames) into ``n_blocks`` consecutive blocks.

    Returns a list of tuples, one per block, of the arrays' slices.
    """
    n = len(arrays[0])
    edges = np.linspace(0, n, n_blocks + 1).astype(int)
    return [tuple(a[edges[i]:edges[i + 1]] for a in arrays) for i in range(n_blocks)]


def rotation_angle(A, B):
    """Rotation angle (rad) between frames ``A`` and ``B``, shape (..., 3, 3) -> (...).

    Uses ``2 asin(|A - B|_F / sqrt(8))``, accurate for tiny angles (no arccos of 1 - eps).
    """
    d = np.linalg.norm(np.asarray(A) - np.asarray(B), axis=(-2, -1))
    return 2.0 * np.arcsin(np.clip(d / np.sqrt(8.0), 0.0, 1.0))


def new_figure(ncols=1, nrows=1, width=6.0, height=4.0):
    """A matplotlib figure (Agg backend, no display)."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(nrows, ncols, figsize=(width * ncols, height * nrows), squeeze=False)
    return fig, axes


def save_figure(fig, out_dir, name):
    """Write ``fig`` to ``out_dir/name`` (PNG) atomically and close it; returns ``name``."""
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    with atomic_path(f"{out_dir}/{name}") as tmp:
        with open(tmp, "wb") as fh:
            fh.write(buf.getvalue())
    return name
