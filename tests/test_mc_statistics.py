"""dnarod.analysis.statistics as the samplers use it: calibrated error bars of correlated series (AR(1) with a
known answer), transients, flags, the combined z of two estimates."""
import numpy as np
import pytest

from dnarod.analysis.statistics import combined_z, mean_and_error
from dnarod.core.errors import DnarodError


def _ar1(n, rho, rng):
    e = rng.standard_normal(n)
    x = np.empty(n)
    x[0] = e[0] / np.sqrt(1 - rho * rho)
    for i in range(1, n):
        x[i] = rho * x[i - 1] + e[i]
    return x


def test_error_is_calibrated_on_ar1():
    """Over 60 independent AR(1) series (rho 0.9, tau_int = 9.5) the z-scores of the means have unit spread
    and the autocorrelation time is recovered."""
    rng = np.random.default_rng(1)
    z, taus = [], []
    for _ in range(60):
        r = mean_and_error(_ar1(4000, 0.9, rng))
        z.append(r.mean / r.error)
        taus.append(r.tau)
        assert r.flag is None
    assert 0.75 < np.std(z) < 1.3
    assert np.median(taus) == pytest.approx(9.5, rel=0.2)


def test_transient_removed_and_short_flagged():
    rng = np.random.default_rng(2)
    x = _ar1(3000, 0.5, rng)
    x[:300] += np.linspace(20.0, 0.0, 300)  # a start far from equilibrium
    r = mean_and_error(x)
    assert r.t0 >= 150 and abs(r.mean) < 4 * r.error
    short = mean_and_error(_ar1(200, 0.99, rng))
    assert short.flag is not None and "effectively independent samples" in short.flag
    const = mean_and_error(np.ones(10))
    assert const.mean == 1.0 and const.error == 0.0
    assert "too few" in mean_and_error([1.0, 2.0]).flag
    with pytest.raises(DnarodError):
        mean_and_error([1.0, np.nan, 2.0, 3.0])
    assert combined_z((1.0, 0.3), (0.0, 0.4)) == pytest.approx(2.0)
