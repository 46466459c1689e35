"""Statistics of correlated samples in one home: the mean of a time series with its error, its transient and its
warnings (:func:`~dnarod.analysis.statistics.estimate`, :func:`~dnarod.analysis.statistics.mean_and_error`); blocks
and the block jackknife.

The error of the mean of a time series comes from its autocorrelation (pymbar's ``timeseries``, Chodera et al.,
J. Chem. Theory Comput. 3:26 (2007); Chodera, J. Chem. Theory Comput. 12:1799 (2016) for the transient):

1. **Transient.** If the start of the series (its first sixteenth, eighth or quarter) is offset from its second
   half by more than :data:`TRANSIENT_Z` standard errors, the start is not in equilibrium: it is dropped up to where
   the number of effectively independent samples of the rest is largest (``pymbar.timeseries.detect_equilibration``,
   at most half the series); how many samples were dropped is reported. The test comes first because the heuristic
   alone, applied to a stationary series, drops a start chosen by its noise and leaves errors too small (measured on
   AR(1) series with 26 effective samples: z-scores of variance 3.4 with it, 1.2 without; ``tests/test_statistics.py``).
2. **Error.** ``sigma sqrt(g / N)`` over the ``N`` kept samples, with the statistical inefficiency
   ``g = 1 + 2 sum_t rho(t) (1 - t/N)`` summed until the autocorrelation first crosses zero
   (``pymbar.timeseries.statistical_inefficiency``); the integrated autocorrelation time is ``tau = g / 2`` samples
   (Sokal's convention, the one of :func:`dnarod.analysis.polymer.integrated_autocorrelation_time`) and the number
   of effectively independent samples ``n_eff = N / g``.
3. **Checks** (each sets the ``flag``, a one-line reason; ``None`` when the estimate can be trusted):

   * ``n_eff`` below :data:`MIN_EFFECTIVE_SAMPLES`: too few independent samples for the autocorrelation to be
     estimated (the estimate of ``g`` itself is then biased low);
   * more than half the series dropped as transient: the series may still be drifting;
   * batch means: the kept samples in :data:`CHECK_BLOCKS` consecutive blocks give a standard error larger than the
     autocorrelation estimate beyond the 99 % quantile of its chi-square law: there are correlations longer than
     the autocorrelation sum saw (a drift, a slow mode); the error is then the larger, the blocks' one;
   * ``relaxation_samples`` (the slowest relaxation time of the system in samples, e.g. from its normal modes,
     :mod:`dnarod.physics.relaxation`): a kept series shorter than :data:`RELAXATION_TIMES_REQUIRED` of them.
     No estimator computed from one run sees a mode that hardly moves during it (its contribution is a constant
     offset of the run), so a run that short is flagged whatever its autocorrelation looks like.

4. **Slow contributions known from outside** (``slow_variance``): a variance of the mean that the run cannot show
   (modes slower than the run, computed from the model, see :func:`dnarod.analysis.polymer.lag1_slow_modes`) is
   added in quadrature.
"""
from __future__ import annotations

import contextlib
import logging
import math
from dataclasses import asdict, dataclass

import numpy as np

from dnarod.core.errors import DnarodError

#: Fewest effectively independent samples (``N / g``) for an error bar that is not flagged.
MIN_EFFECTIVE_SAMPLES = 50
#: Blocks of the batch-means check of the autocorrelation estimate.
CHECK_BLOCKS = 8
#: One-sided quantile of the batch-means check (chi-square with ``CHECK_BLOCKS - 1`` degrees of freedom).
CHECK_QUANTILE = 0.99
#: Offset of the series' start (its first sixteenth, eighth or quarter) from its second half, in standard errors, above
#: which a transient is looked for and dropped (below it nothing is dropped: see :func:`estimate`).
TRANSIENT_Z = 3.5
#: Fewest slowest relaxation times a run must span for its error bar not to be flagged.
RELAXATION_TIMES_REQUIRED = 5.0


@contextlib.contextmanager
def _quiet_pymbar():
    """pymbar logs a warning at import (and one about JAX): held back, the flags here say what they warn about."""
    log = logging.getLogger("pymbar")
    old = log.level
    log.setLevel(logging.ERROR)
    try:
        yield
    finally:
        log.setLevel(old)


def _timeseries():
    with _quiet_pymbar():
        from pymbar import timeseries
    return timeseries


@dataclass(frozen=True)
class Estimate:
    """The mean of a time series with its error (:func:`estimate`).

    Attributes
    ----------
    mean, error : float
        Mean of the kept samples and its standard error (NaN when it cannot be estimated).
    tau : float
        Integrated autocorrelation time, samples (``g / 2``).
    n_eff : float
        Effectively independent samples among the kept ones, ``N / g``.
    flag : str or None
        Why the error bar is not to be trusted (``None``: no reason found).
    n_samples, n_dropped : int
        Samples kept, and dropped at the start as transient.
    inefficiency : float
        Statistical inefficiency ``g``.
    error_autocorrelation, error_blocks : float
        The autocorrelation error and the batch-means one (NaN with too few samples for the blocks).
    error_slow : float
        Added in quadrature from ``slow_variance`` (0 without).
    """

    mean: float
    error: float
    tau: float
    n_eff: float
    flag: str | None
    n_samples: int
    n_dropped: int
    inefficiency: float
    error_autocorrelation: float
    error_blocks: float
    error_slow: float = 0.0

    def __iter__(self):
        """Unpacks as ``(mean, error, tau, n_eff, flag)``."""
        return iter((self.mean, self.error, self.tau, self.n_eff, self.flag))

    @property
    def t0(self) -> int:
        """Samples dropped at the start as its transient (``n_dropped``)."""
        return self.n_dropped

    def as_dict(self, prefix=""):
        """The fields as a dict, keys prefixed by ``prefix`` (a JSON-ready record)."""
        return {prefix + k: v for k, v in asdict(self).items()}

    def scaled(self, factor):
        """The estimate of ``factor`` times the series (mean and errors scaled; factor may be negative)."""
        f = float(factor)
        return Estimate(self.mean * f, self.error * abs(f), self.tau, self.n_eff, self.flag, self.n_samples,
                        self.n_dropped, self.inefficiency, self.error_autocorrelation * abs(f),
                        self.error_blocks * abs(f), self.error_slow * abs(f))


def _join(*flags):
    out = "; ".join(f for f in flags if f)
    return out or None


def _start_offset_z(x, ts):
    """Largest offset of the first 1/16, 1/8 and 1/4 of ``x`` from its second half, in standard errors (the second
    half's variance and statistical inefficiency for both parts: the null hypothesis is a stationary series)."""
    n = len(x)
    h = x[n // 2:]
    if float(np.ptp(h)) == 0.0:
        return float("inf") if float(np.ptp(x)) > 0 else 0.0
    s = float(h.std(ddof=1)) * math.sqrt(float(ts.statistical_inefficiency(h, fast=False, mintime=3)))
    z = 0.0
    for f in (16, 8, 4):
        w = x[:max(2, n // f)]
        z = max(z, abs(float(w.mean() - h.mean())) / (s * math.sqrt(1.0 / len(w) + 1.0 / len(h))))
    return z


def estimate(series, *, transient=True, min_effective=MIN_EFFECTIVE_SAMPLES, relaxation_samples=None,
             slow_variance=0.0, what="the series"):
    """Mean of a correlated time series with an error from its autocorrelation, transient removed, checked.

    Parameters
    ----------
    series : array_like, shape (n,)
        Equally spaced samples of one observable.
    transient : bool
        Detect and drop the start's transient (``pymbar.timeseries.detect_equilibration``).
    min_effective : float
        Flag below this many effectively independent samples.
    relaxation_samples : float, optional
        Slowest relaxation time of the sampled system, in samples: flag a kept series shorter than
        :data:`RELAXATION_TIMES_REQUIRED` of them.
    slow_variance : float
        Variance of the mean from correlations the run cannot show (same units squared), added in quadrature.
    what : str
        Name of the observable in the flags.

    Returns
    -------
    Estimate

    Raises
    ------
    DnarodError
        Empty or non-finite series.
    """
    x = np.asarray(series, float).ravel()
    n = len(x)
    if n == 0:
        raise DnarodError(f"{what}: no samples to average")
    if not np.isfinite(x).all():
        k = int(np.argmin(np.isfinite(x)))
        raise DnarodError(f"{what}: sample {k} is not finite ({x[k]}); the run blew up or the observable is undefined "
                          f"there")
    slow = math.sqrt(max(float(slow_variance), 0.0))
    if n < 4:
        return Estimate(float(x.mean()), float("nan"), float("nan"), float(n), f"{what}: {n} sample(s), too few for an "
                        f"error bar", n, 0, float("nan"), float("nan"), float("nan"), slow)
    if float(np.ptp(x)) == 0.0:  # constant: exact mean (a quantity the run does not vary)
        return Estimate(float(x[0]), slow, 0.5, float(n), None, n, 0, 1.0, 0.0, 0.0, slow)
    ts = _timeseries()
    t0 = 0
    flags = []
    if transient and n >= 16:
        z_start = _start_offset_z(x, ts)
        if z_start > TRANSIENT_Z:
            t0 = min(int(ts.detect_equilibration(x, fast=True, nskip=max(1, n // 200))[0]), n // 2)
            if t0 == 0 or t0 == n // 2:
                flags.append(f"{what}: the start differs from the second half by {z_start:.1f} standard errors and no "
                             f"transient ending in the first half was found: the series drifts")
    y = x[t0:]
    N = len(y)
    if float(np.ptp(y)) == 0.0:
        t0, y, N = 0, x, n
    g = float(ts.statistical_inefficiency(y, fast=False, mintime=3))
    var = float(y.var(ddof=1))
    err_ac = math.sqrt(var * g / N)
    n_eff = N / g
    err_b = float("nan")
    err = err_ac
    if N >= 2 * CHECK_BLOCKS:
        b = np.array([v.mean() for v in np.array_split(y, CHECK_BLOCKS)])
        err_b = float(b.std(ddof=1) / math.sqrt(CHECK_BLOCKS))
        from scipy.stats import chi2

        limit = chi2.ppf(CHECK_QUANTILE, CHECK_BLOCKS - 1) / (CHECK_BLOCKS - 1)
        if err_ac > 0 and (err_b / err_ac) ** 2 > limit:
            flags.append(f"{what}: correlations longer than the autocorrelation estimate sees ({CHECK_BLOCKS} blocks "
                         f"give +-{err_b:.3g} against +-{err_ac:.3g}; a drift or a slow mode): error from the blocks")
            err = err_b
    if n_eff < min_effective:
        flags.append(f"{what}: {n_eff:.1f} effectively independent samples (fewer than {min_effective:g}; "
                     f"autocorrelation time {0.5 * g:.3g} samples of {N}): the run is too short for an error bar")
    if relaxation_samples is not None and np.isfinite(relaxation_samples) and \
            N < RELAXATION_TIMES_REQUIRED * float(relaxation_samples):
        flags.append(f"{what}: the kept samples span {N / float(relaxation_samples):.3g} slowest relaxation times "
                     f"(fewer than {RELAXATION_TIMES_REQUIRED:g}): modes slower than the run are invisible to its "
                     f"error bar")
    err = math.sqrt(err * err + slow * slow)
    return Estimate(float(y.mean()), err, 0.5 * g, n_eff, _join(*flags), N, t0, g, err_ac, err_b, slow)


def mean_and_error(series):
    """:func:`estimate` of a correlated time series with its defaults; unpacks as ``(mean, error, tau, n_eff, flag)``.

    Parameters
    ----------
    series : array_like, shape (n,)

    Returns
    -------
    Estimate
        ``mean`` and ``error`` after the start's transient, ``tau`` (samples), ``n_eff`` (effectively independent
        samples), ``flag`` (why the error bar is not to be trusted, or None), ``t0`` (samples dropped).
    """
    return estimate(series)


def combined_z(a, b):
    """``(a.mean - b.mean) / sqrt(a.error^2 + b.error^2)`` of two estimates (or ``(mean, error)`` pairs): the
    difference of two independent measurements in their combined standard errors."""
    ma, ea = (a.mean, a.error) if isinstance(a, Estimate) else tuple(a)[:2]
    mb, eb = (b.mean, b.error) if isinstance(b, Estimate) else tuple(b)[:2]
    s = math.hypot(ea, eb)
    return float((ma - mb) / s) if s > 0 else (0.0 if ma == mb else float("inf"))


def function_estimate(est, f, what=None):
    """An :class:`Estimate` of ``f(mean)`` by first-order propagation (``|f'(mean)| error``, central difference).

    Parameters
    ----------
    est : Estimate
    f : callable
        Smooth scalar function.

    Returns
    -------
    Estimate
        Mean ``f(est.mean)``, errors scaled by ``|f'(est.mean)|``; NaN where f is not finite.
    """
    m = est.mean
    h = 1e-6 * max(abs(m), 1e-12) if not np.isfinite(est.error) or est.error == 0 else 1e-3 * est.error
    d = (f(m + h) - f(m - h)) / (2 * h)
    v = f(m)
    if not (np.isfinite(v) and np.isfinite(d)):
        return Estimate(float("nan"), float("nan"), est.tau, est.n_eff, est.flag, est.n_samples, est.n_dropped,
                        est.inefficiency, float("nan"), float("nan"), float("nan"))
    a = abs(float(d))
    return Estimate(float(v), est.error * a, est.tau, est.n_eff, est.flag, est.n_samples, est.n_dropped,
                    est.inefficiency, est.error_autocorrelation * a, est.error_blocks * a, est.error_slow * a)


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


def calibration(z):
    """Variance of z-scores and its acceptance band: ``(var, low, high)``, the band being the central 99 % of the
    sample variance of ``len(z)`` independent standard normal values (chi-square law). A calibrated error bar gives
    z-scores of unit variance.

    Parameters
    ----------
    z : array_like, shape (m,)
        ``(estimate - reference) / stated error`` of independent runs, the reference exact.

    Returns
    -------
    tuple of float
    """
    from scipy.stats import chi2

    z = np.asarray(z, float)
    m = len(z)
    return float(np.mean(z * z)), float(chi2.ppf(0.005, m) / m), float(chi2.ppf(0.995, m) / m)
