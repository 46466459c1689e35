"""The Monte Carlo engine against exact discrete-chain results at full length (slow; the default suite keeps the
30- and 60-node versions in test_mc_engine.py): force-extension of 100 and 1000 bp at 0.1-10 pN (transfer matrix,
:mod:`dnarod.physics.theory.transfer_matrix`) and the tangent correlations that define the persistence length of a
free 300-bp chain (Haar-measure average, :func:`dnarod.physics.thermal.exact_tangent_correlation`), each within 3
calibrated standard errors."""
import numpy as np
import pytest

from dnarod.analysis.statistics import mean_and_error
from dnarod.core.forcefield import load_forcefield
from dnarod.core.units import PN, kT
from dnarod.engines.mc import MCEngine
from dnarod.physics.loads import PullingForce

FF = load_forcefield("dna-default")
FORCES = (0.1, 0.3, 1.0, 3.0, 10.0)


def _extension_series(n, force_pN, n_sweeps, seed, every=1):
    from dnarod.physics.thermal import equilibrium_sample

    model = FF.model_from_sequence(n_nodes=n)
    f = np.array([0.0, 0.0, force_pN * PN])
    start = equilibrium_sample(model, 300.0, seed=seed, align=f)  # an exact free-chain sample, turned along F
    e = MCEngine(start, 300.0, loads=(PullingForce(-1, f), PullingForce(0, -f)), nonbonded=False, seed=seed)
    e.advance(400)
    x = np.empty(n_sweeps // every)
    for s in range(len(x)):
        e.advance(every)
        x[s] = e.pos[-1, 2] - e.pos[0, 2]
    return model, mean_and_error(x)


@pytest.mark.slow
@pytest.mark.parametrize("n,n_sweeps,every", [(100, 30000, 1), (1000, 6000, 1)])
def test_force_extension_exact(n, n_sweeps, every):
    from dnarod.physics.theory.transfer_matrix import force_extension

    model = FF.model_from_sequence(n_nodes=n)
    ref = force_extension(model.params, model.ds, 300.0, n, FORCES)
    bad = []
    for F, r in zip(FORCES, ref):
        _, est = _extension_series(n, F, n_sweeps, 7, every)
        assert est.flag is None, (n, F, est)
        if abs(est.mean - r) >= 3 * est.error:
            bad.append((F, est.mean, est.error, r))
    assert not bad, bad


@pytest.mark.slow
def test_tangent_correlation_exact_300():
    """Free 300-bp chain: <d3(k) . d3(k+s)> at s = 1, 10, 50, 150 (the persistence length's decay)."""
    from dnarod.physics.thermal import exact_tangent_correlation

    n, lags = 300, (1, 10, 50, 150)
    model = FF.model_from_sequence(n_nodes=n)
    e = MCEngine(model, 300.0, nonbonded=False, seed=3)
    e.advance(500)
    x = np.empty((8000, len(lags)))
    for s in range(len(x)):
        e.advance(1)
        d3 = e.frm[:, :, 2]
        for i, lag in enumerate(lags):
            x[s, i] = np.mean(np.einsum("ka,ka->k", d3[: n - lag], d3[lag:]))
    exact = exact_tangent_correlation(model.params, model.ds, kT(300.0), max(lags))
    for i, lag in enumerate(lags):
        est = mean_and_error(x[:, i])
        assert est.flag is None, (lag, est)
        assert abs(est.mean - exact[lag]) < 3 * est.error, (lag, est, exact[lag])
