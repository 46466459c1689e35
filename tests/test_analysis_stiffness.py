"""The stiffness fit recovers a known stiffness from exact equilibrium samples (design A5 iii), and the
tangent correlations of such samples match the exact transfer formula."""
import numpy as np
import pytest

from dnarod.analysis.polymer import TangentCorrelation
from dnarod.physics.sampling import sample_chains, sample_steps
from dnarod.analysis.stiffness import StiffnessFit, stiffness_from_samples
from dnarod.core.forcefield import load_forcefield
from dnarod.core.parameters import StepParameters
from dnarod.physics.thermal import persistence_length, reweighted_covariance_expected, tangent_correlation
from dnarod.core.units import kT

KT = kT(300.0)


def soft_step():
    """dna-default with bending and twist 12x softer: |ds Omega| fluctuates by ~0.3, so the Haar
    factor matters (the naive Gaussian estimate is visibly wrong)."""
    K, xi0 = load_forcefield("dna-default").table["*"]
    K = K.copy()
    K[:3, :] /= np.sqrt(12.0)
    K[:, :3] /= np.sqrt(12.0)
    return K, xi0


def z_scores(est, err, true):
    iu = np.triu_indices(6)
    return ((est - true) / err)[iu]


def test_sampler_density_is_exact():
    """Rejection sampling: the reweighted covariance identity holds (first check of the sampler)."""
    K, xi0 = soft_step()
    rng = np.random.default_rng(11)
    xi = sample_steps(K, xi0, 0.34, KT, 200_000, rng)
    # Independent check of the marginal: <R_33> of the samples equals the exact quadrature.
    from dnarod.core.rotations import cayley
    from dnarod.physics.thermal import mean_rotation

    R = cayley(0.34 * xi[:, :3])
    exact = mean_rotation(StepParameters(K, xi0), 0.34, KT)[0]
    err = R.std(axis=0) / np.sqrt(len(xi))
    assert np.all(np.abs(R.mean(axis=0) - exact) < 5 * err + 1e-12)


def test_stiffness_fit_recovers_known_stiffness_soft_set():
    K, xi0 = soft_step()
    rng = np.random.default_rng(2024)
    n = 200_000
    xi = sample_steps(K, xi0, 0.34, KT, n, rng)
    blocks = np.array_split(xi, 20)
    est = [stiffness_from_samples(b, 0.34, KT) for b in blocks]
    mean, cov, Kfit = stiffness_from_samples(xi, 0.34, KT)
    Kerr = np.std([e[2] for e in est], axis=0, ddof=1) / np.sqrt(20)
    merr = np.std([e[0] for e in est], axis=0, ddof=1) / np.sqrt(20)
    assert np.abs(z_scores(Kfit, Kerr, K)).max() < 5
    assert np.abs((mean - xi0) / merr).max() < 5
    # Relative accuracy actually reached on the diagonal (statistical, ~sqrt(2/n)):
    assert np.abs(np.diag(Kfit) / np.diag(K) - 1).max() < 0.015
    # The naive (unweighted) Gaussian must fail on this soft set: the test can fail.
    _, cov_naive, K_naive = stiffness_from_samples(xi, 0.34, KT, reweight=False)
    naive_err = np.std([stiffness_from_samples(b, 0.34, KT, reweight=False)[2] for b in blocks], axis=0,
                       ddof=1) / np.sqrt(20)
    assert np.abs(z_scores(K_naive, naive_err, K)).max() > 10
    # And the reweighted covariance is the exact identity kT (ds K)^-1.
    exp_cov = reweighted_covariance_expected(StepParameters(K, xi0), 0.34, KT)[0]
    cov_err = np.std([e[1] for e in est], axis=0, ddof=1) / np.sqrt(20)
    assert np.abs(z_scores(cov, cov_err, exp_cov)).max() < 5


def test_stiffness_fit_on_chains_per_step_type_and_forcefield_round_trip(tmp_path):
    """Chains built from exact samples (olson1998, a sequence) -> StiffnessFit per step type."""
    ff = load_forcefield("olson1998")
    seq = "ACGTTGCA" * 3 + "A"
    params = ff.step_parameters(seq)
    rng = np.random.default_rng(7)
    traj = sample_chains(params, ff.ds, KT, 1500, rng)
    fit = StiffnessFit(traj, ff.ds, 300.0, sequence=seq, n_blocks=15).run()
    types = fit.results.types
    assert set(types) == set(params.names) | {"*"}
    for name in ("AC", "TT", "GC"):
        t = types[name]
        true_K, true_xi0 = ff.table[name]
        assert np.abs(z_scores(t["stiffness"], t["stiffness_err"], true_K)).max() < 5
        assert np.abs((t["mean"] - true_xi0) / t["mean_err"]).max() < 5
    # Uniform file of one type: dnarod loads it back exactly.
    fit.write_forcefield(tmp_path / "ac.toml", "AC", ff_name="fit-ac")
    back = load_forcefield(tmp_path / "ac.toml")
    assert back.kind == "uniform" and back.name == "fit-ac"
    assert np.allclose(back.table["*"][0], types["AC"]["stiffness"], rtol=1e-10, atol=1e-9)
    assert np.allclose(back.table["*"][1], types["AC"]["mean"], rtol=1e-10, atol=1e-12)
    # Per-step-type set (sequence-cayley): loads back to the same (xi0, K).
    path = fit.write_sequence_forcefield(tmp_path / "seqff.toml", ff_name="fit-seq")
    seqff = load_forcefield(path)
    assert seqff.kind == "sequence-cayley"
    for name in set(params.names):
        K2, xi2 = seqff.table[name]
        assert np.allclose(K2, types[name]["stiffness"], rtol=1e-10, atol=1e-9)
        assert np.allclose(xi2, types[name]["mean"], rtol=1e-10, atol=1e-12)
    assert seqff.model_from_sequence(seq).n_nodes == len(seq)


def test_tangent_correlation_of_exact_samples_matches_transfer_formula():
    ff = load_forcefield("dna-default")
    n_steps = 40
    params = ff.step_parameters(n_steps=n_steps)
    rng = np.random.default_rng(5)
    traj = sample_chains(params, ff.ds, KT, 1000, rng)
    tc = TangentCorrelation(traj, ff.ds, n_max=30, n_blocks=20).run()
    r = tc.results
    exact = tangent_correlation(params, ff.ds, KT, 30)
    z = (r.correlation[1:] - exact[1:]) / r.correlation_err[1:]
    assert np.abs(z).max() < 4.5
    assert np.abs(r.correlation[30] - exact[30]) < 0.01  # ~0.02 statistical resolution stated by the errors
    lp = persistence_length(params, ff.ds, KT)
    assert abs(r.persistence_length - lp) < 4.5 * r.persistence_length_err
    assert r.persistence_length_err < 0.05 * lp


def _fit_lax_langevin(tmp_path, n_nodes, n_steps, seed, skip, n_blocks):
    """Run the Lax-form BAOAB engine on dna-default (dt 0.04 ps, friction 2/ps, a frame every 4 ps),
    fit the Haar-reweighted stiffness and check it against the force field's."""
    from dnarod.run.lax import simulate_langevin
    from dnarod.core.trajectory import Trajectory

    ff = load_forcefield("dna-default")
    simulate_langevin(ff.model_from_sequence(n_nodes=n_nodes), 0.04, n_steps, 300.0, friction=2.0, seed=seed,
                      out=tmp_path / "lax.dtraj", report_interval=100)
    traj = Trajectory.load(tmp_path / "lax.dtraj")[skip:]
    t = StiffnessFit(traj, ff.ds, 300.0, n_blocks=n_blocks).run().results.types["*"]
    K, xi0 = ff.table["*"]
    assert np.abs(z_scores(t["stiffness"], t["stiffness_err"], K)).max() < 5
    assert np.abs((t["mean"] - xi0) / t["mean_err"]).max() < 5
    assert np.abs(np.diag(t["stiffness"]) / np.diag(K) - 1).max() < 0.05


def test_stiffness_fit_recovers_forcefield_from_short_lax_langevin_run(tmp_path):
    """21 nodes, 1.6 ns, 400 frames (8000 step samples); 20 ps dropped. Measured over seeds 3-5:
    max |z| 3.3-3.8 over the 21 entries of K, diagonal within 2.1%."""
    _fit_lax_langevin(tmp_path, n_nodes=21, n_steps=40_000, seed=3, skip=5, n_blocks=10)


@pytest.mark.slow
def test_stiffness_fit_recovers_forcefield_from_lax_langevin_run(tmp_path):
    """41 nodes, 8 ns, first 100 frames (400 ps) dropped (measured max |z| = 1.7, diagonal within 1.5%)."""
    _fit_lax_langevin(tmp_path, n_nodes=41, n_steps=200_000, seed=1, skip=100, n_blocks=20)
