"""The one estimator of a correlated mean (dnarod.analysis.statistics.estimate) against series whose answer is known:
AR(1) processes (exact mean 0, exact variance of the mean), transients, drifts and runs too short; the relaxation
times of the modes (dnarod.physics.relaxation) against the beam formulas."""
import numpy as np
import pytest

from dnarod.analysis.statistics import (MIN_EFFECTIVE_SAMPLES, Estimate, calibration, estimate, function_estimate,
                                        mean_and_error)
from dnarod.core.errors import DnarodError


def ar1(n, phi, rng):
    """Stationary AR(1) of unit variance: statistical inefficiency (1 + phi) / (1 - phi)."""
    e = rng.standard_normal(n) * np.sqrt(1 - phi * phi)
    x = np.empty(n)
    x[0] = rng.standard_normal()
    for i in range(1, n):
        x[i] = phi * x[i - 1] + e[i]
    return x


def test_errors_of_stationary_series_are_calibrated():
    """z-scores of 200 AR(1) means (g = 19, 105 effective samples each) have unit variance within the chi-square
    band, and the stated error is the exact one on average."""
    rng = np.random.default_rng(11)
    phi, n = 0.9, 2000
    g = (1 + phi) / (1 - phi)
    z, err, flags = [], [], 0
    for _ in range(200):
        e = estimate(ar1(n, phi, rng))
        z.append(e.mean / e.error)
        err.append(e.error)
        flags += e.flag is not None
    assert flags <= 10  # a few false alarms (the blocks' 1 % test, g overestimated below 50 effective samples)
    var, lo, hi = calibration(z)
    assert lo < var < hi, (var, lo, hi)
    exact = np.sqrt(g / n)  # the exact standard error of the mean (to O(1/n))
    assert np.mean(err) == pytest.approx(exact, rel=0.1)
    # ignoring the correlation (the error of independent samples) is 4.4 times too small: that would fail
    assert calibration(np.array(z) * np.sqrt(g))[0] > hi


def test_too_short_series_is_flagged_not_silently_small():
    rng = np.random.default_rng(3)
    flagged = [estimate(ar1(150, 0.95, rng)).flag for _ in range(20)]  # ~4 independent samples each
    assert all(f is not None and "effectively independent" in f for f in flagged)
    m, err, tau, n_eff, flag = mean_and_error(ar1(150, 0.95, rng))
    assert flag is not None and n_eff < MIN_EFFECTIVE_SAMPLES and tau > 1


def test_transient_is_dropped_and_reported():
    rng = np.random.default_rng(5)
    n = 4000
    t = np.arange(n)
    drops, z_kept, z_all = [], [], []
    for _ in range(20):
        x = ar1(n, 0.8, rng) + 30.0 * np.exp(-t / 100.0)  # a start 30 sigma off, relaxing over ~5 % of the run
        e = estimate(x)
        drops.append(e.n_dropped)
        z_kept.append(e.mean / e.error)
        z_all.append(x.mean() / np.sqrt(9.0 / n))  # the exact error of the stationary part
    assert min(drops) >= 300 and max(drops) <= n // 2  # the transient (30 e^(-t/100) > 1.5 sigma up to t ~ 300) goes
    assert max(np.abs(z_kept)) < 4.0
    assert min(z_all) > 10.0  # kept in, it biases the mean by many standard errors


def test_stationary_series_keeps_its_start():
    rng = np.random.default_rng(8)
    drops = [estimate(ar1(2000, 0.9, rng)).n_dropped for _ in range(30)]
    assert sum(d > 0 for d in drops) <= 3  # the start-offset test (3.5 standard errors) rarely fires on noise


def test_drift_and_modes_slower_than_the_run_are_flagged():
    rng = np.random.default_rng(2)
    n = 4000
    drift = ar1(n, 0.5, rng) + 0.5 * np.sin(np.pi * np.arange(n) / n)  # a mode half a period long in the run
    e = estimate(drift, transient=False)
    assert e.flag is not None and "blocks" in e.flag and e.error == e.error_blocks > e.error_autocorrelation
    # a mode frozen over the run is invisible to the series: only the model's relaxation time can flag it
    e = estimate(ar1(n, 0.5, rng), relaxation_samples=10 * n)
    assert e.flag is not None and "slowest relaxation" in e.flag
    # a known slow variance is added in quadrature
    base = estimate(ar1(n, 0.5, np.random.default_rng(1)))
    more = estimate(ar1(n, 0.5, np.random.default_rng(1)), slow_variance=9 * base.error ** 2)
    assert more.error == pytest.approx(np.sqrt(10) * base.error, rel=1e-12)


def test_edge_cases():
    e = estimate(np.full(50, 2.5))
    assert e.mean == 2.5 and e.error == 0.0 and e.flag is None
    assert np.isnan(estimate([1.0, 2.0]).error) and estimate([1.0, 2.0]).flag is not None
    with pytest.raises(DnarodError, match="not finite"):
        estimate([1.0, np.nan, 2.0, 3.0, 4.0])
    with pytest.raises(DnarodError, match="no samples"):
        estimate([])
    rng = np.random.default_rng(0)
    e = estimate(1.0 + 0.01 * rng.standard_normal(400))
    f = function_estimate(e, np.log)
    assert isinstance(f, Estimate) and f.mean == pytest.approx(np.log(e.mean))
    assert f.error == pytest.approx(e.error / e.mean, rel=1e-6)
    assert e.scaled(-2.0).error == pytest.approx(2 * e.error) and e.scaled(-2.0).mean == pytest.approx(-2 * e.mean)


def test_mode_relaxation_times_against_beams():
    """Slowest modes of the free chain (a free beam, beta_1 L = 4.730) and of the tweezers chain (node 0 clamped,
    bead pulled: a cantilever under tension, slower), and the damped-oscillator rates."""
    from dnarod.core.forcefield import load_forcefield
    from dnarod.core.units import PN, kT
    from dnarod.physics.loads import tweezers
    from dnarod.physics.relaxation import decay_rate, relaxation_times, slowest_modes
    from dnarod.physics.statics import solve_static
    from dnarod.physics.thermal import persistence_length

    ff = load_forcefield("dna-default")
    m = ff.model_from_sequence(n_nodes=120)
    L, rho = m.ds * m.n_steps, float(np.mean(m.mass)) / m.ds
    A = kT(300) * persistence_length(m.params, m.ds, kT(300))
    w, unstable = slowest_modes(m, (), k=4)
    assert unstable == 0
    w_beam = np.sqrt(A / rho) * (4.730040744862704 / L) ** 2
    assert w[0] == pytest.approx(w[1], rel=1e-6)  # two bending directions
    assert w[0] == pytest.approx(w_beam, rel=0.05)  # the discrete chain against the continuum beam
    F = 1.0
    loads = list(tweezers(m, F, None, None, 0.0, anchor="surface", axis="z"))
    st, _ = solve_static(m, loads)
    r = relaxation_times(st, loads, friction=1.0, k=4)
    # cantilever under tension: omega^2 between the tension-free cantilever's and a string's (clamped-free)
    lo = (A * (1.8751 / L) ** 4) / rho
    string = (F * PN * (np.pi / (2 * L)) ** 2) / rho
    assert lo + 0.8 * string < r["omega_slowest"] ** 2 < lo + 1.6 * string + A * (np.pi / (2 * L)) ** 4 / rho
    assert r["omega_slowest"] < w[0]  # slower than the free chain despite the tension
    assert r["tau_slowest_ps"] == pytest.approx(1.0 / decay_rate(r["omega_slowest"], 1.0), rel=1e-12)
    # overdamped and underdamped limits
    assert decay_rate(1e-3, 1.0) == pytest.approx(1e-6, rel=1e-5)
    assert decay_rate(5.0, 1.0) == pytest.approx(0.5)
    assert decay_rate(1.0, 0.0) == 0.0
