"""Statistics of correlated samples in one home: blocks, the block jackknife, and means of correlated series with
calibrated error bars.

Means of correlated series (:func:`mean_and_error`). Every mean a sampler reports (Monte Carlo sweeps, MD frames)
comes with a standard error from the integrated autocorrelation time of the series, after the transient at its start
is cut off:

* the transient: the criterion of :func:`pymbar.timeseries.detect_equilibration` (Chodera 2016, "A simple method
  for automated equilibration detection in molecular simulations", J. Chem. Theory Comput. 12:1799): the start
  ``t0`` that maximises the number of effectively independent samples left after it, searched over
  :data:`TRANSIENT_ORIGINS` origins in the first half of the series (a transient longer than half the run means
  the run is too short; a late origin whose short tail underestimates the inefficiency must not win);
* the statistical inefficiency ``g = 1 + 2 tau_int`` of the rest: :func:`pymbar.timeseries.statistical_inefficiency`
  (the same paper; Sokal-type sum of the normalised autocorrelation function up to its first zero);
* the standard error ``sqrt(var * g / n)``.

A series with fewer than :data:`MIN_EFFECTIVE_SAMPLES` effectively independent samples after the transient is
flagged: its autocorrelation time (and therefore its error bar) is itself not determined.

pymbar is used through its ``timeseries`` module only (no MBAR); it prints a note about JAX on import, which is
swallowed here.
"""
from __future__ import annotations

import contextlib
import io
import warnings
from dataclasses import dataclass

import numpy as np


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


#: Fewer effectively independent samples than this after the transient and a mean is flagged ``short``.
MIN_EFFECTIVE_SAMPLES = 20
#: Candidate origins of the transient cut (evenly spaced in the first half of the series).
TRANSIENT_ORIGINS = 40


def _timeseries():
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()), \
            warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from pymbar import timeseries
    return timeseries


@dataclass(frozen=True)
class MeanEstimate:
    """A mean with its calibrated standard error.

    Attributes
    ----------
    mean : float
    error : float
        Standard error of the mean (same unit as the series).
    tau : float
        Integrated autocorrelation time, in samples (``(g - 1) / 2``).
    n_eff : float
        Effectively independent samples after the transient (``n / g``).
    flag : str or None
        ``"short"`` when ``n_eff < MIN_EFFECTIVE_SAMPLES`` (the error bar is not reliable), ``"constant"`` for a
        constant series, else ``None``.
    t0 : int
        Samples cut off at the start as transient.
    n : int
        Samples used.
    """

    mean: float
    error: float
    tau: float
    n_eff: float
    flag: str | None
    t0: int
    n: int

    def __iter__(self):
        return iter((self.mean, self.error, self.tau, self.n_eff, self.flag))

    def as_dict(self, prefix=""):
        """JSON-safe dict ``{prefix+"mean": ..., prefix+"err": ..., ...}``."""
        return {f"{prefix}mean": self.mean, f"{prefix}err": self.error, f"{prefix}tau": self.tau,
                f"{prefix}n_eff": self.n_eff, f"{prefix}flag": self.flag, f"{prefix}t0": self.t0,
                f"{prefix}n": self.n}


def mean_and_error(series, discard_transient=True, min_effective=MIN_EFFECTIVE_SAMPLES):
    """Mean, standard error, autocorrelation time and effective sample count of a correlated series.

    Parameters
    ----------
    series : array_like, shape (n,)
        Equally spaced samples (any unit).
    discard_transient : bool
        Cut off the transient (Chodera's criterion, module docstring; default); else use all.
    min_effective : float
        Flag the estimate ``"short"`` below this many effective samples.

    Returns
    -------
    MeanEstimate
        Unpacks as ``(mean, error, tau, n_eff, flag)``.

    Raises
    ------
    ValueError
        For fewer than 4 samples or non-finite values.
    """
    x = np.asarray(series, float).ravel()
    if x.size < 4:
        raise ValueError(f"a mean with an error bar needs at least 4 samples, got {x.size}")
    if not np.isfinite(x).all():
        k = int(np.argmax(~np.isfinite(x)))
        raise ValueError(f"sample {k} of the series is not finite ({x[k]})")
    if np.ptp(x) == 0.0:
        return MeanEstimate(float(x[0]), 0.0, 0.0, float(x.size), "constant", 0, int(x.size))
    ts = _timeseries()
    t0 = 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if discard_transient:
            # Chodera's criterion (the origin that leaves the most effective samples), with origins in the first
            # half only: a late origin whose short tail underestimates g must not win (pymbar scans all of them)
            best = -1.0
            for t in np.unique(np.linspace(0, x.size // 2, TRANSIENT_ORIGINS).astype(int)):
                tail = x[t:]
                if np.ptp(tail) == 0.0:
                    continue
                ne = tail.size / max(1.0, float(ts.statistical_inefficiency(tail, fast=True)))
                if ne > best:
                    best, t0 = ne, int(t)
        y = x[t0:]
        if y.size < 4 or np.ptp(y) == 0.0:
            y, t0 = x, 0
        g = float(ts.statistical_inefficiency(y, fast=True))
    g = max(g, 1.0)
    n = int(y.size)
    err = float(np.sqrt(np.var(y, ddof=1) * g / n))
    n_eff = n / g
    flag = "short" if n_eff < min_effective else None
    return MeanEstimate(float(np.mean(y)), err, 0.5 * (g - 1.0), float(n_eff), flag, t0, n)


def combined_z(a, b):
    """``(a.mean - b.mean) / sqrt(a.error^2 + b.error^2)`` of two :class:`MeanEstimate` (or (mean, error) pairs)."""
    ma, ea = (a.mean, a.error) if isinstance(a, MeanEstimate) else a[:2]
    mb, eb = (b.mean, b.error) if isinstance(b, MeanEstimate) else b[:2]
    s = float(np.hypot(ea, eb))
    return float((ma - mb) / s) if s > 0 else (0.0 if ma == mb else float("inf"))
