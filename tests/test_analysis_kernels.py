"""Analysis kernels against slow references (loops, independent formulas)."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dnarod.analysis.base import block_estimates, standard_error
from dnarod.analysis.polymer import EndToEnd, TangentCorrelation, tangent_correlation_frames
from dnarod.analysis.steps import StepAnalysis, frame_step_parameters, frame_strains
from dnarod.analysis.stiffness import haar_weight, weighted_moments
from dnarod.core.stepparams import step_parameters
from dnarod.core.strains import Closure, chain_from_strains, strains_dot_form
from dnarod.core.trajectory import Trajectory


def random_trajectory(seed, n_frames=7, n_nodes=9, ds=0.34):
    """Random open chains (one per frame): B-DNA-like twist plus random bends and shears."""
    rng = np.random.default_rng(seed)
    pos = np.empty((n_frames, n_nodes, 3))
    frm = np.empty((n_frames, n_nodes, 3, 3))
    for f in range(n_frames):
        Om = rng.normal(0, 0.5, (n_nodes - 1, 3)) + [0, 0, 1.8]
        Ga = rng.normal(0, 0.1, (n_nodes - 1, 3)) + [0, 0, 1]
        pos[f], frm[f] = chain_from_strains(Om, Ga, ds, r0=rng.normal(size=3),
                                            frame0=Rotation.random(random_state=seed * 100 + f).as_matrix())
    return Trajectory(np.arange(n_frames) * 2.0, pos, frm)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_frame_step_parameters_match_loop(seed):
    t = random_trajectory(seed)
    fast = frame_step_parameters(t.positions, t.frames)
    slow = np.array([[step_parameters(t.frames[f, k], t.positions[f, k], t.frames[f, k + 1], t.positions[f, k + 1])
                      for k in range(t.n_nodes - 1)] for f in range(t.n_frames)])
    assert np.abs(fast - slow).max() < 1e-13


def test_frame_step_parameters_circular_closure_step():
    t = random_trajectory(5)
    Q = Rotation.from_rotvec([0.1, -0.2, 0.3]).as_matrix()
    c = Closure(Q, np.array([0.1, 0.2, 0.3]))
    fast = frame_step_parameters(t.positions, t.frames, c)
    assert fast.shape == (t.n_frames, t.n_nodes, 6)
    for f in range(t.n_frames):
        ref = step_parameters(t.frames[f, -1], t.positions[f, -1], Q @ t.frames[f, 0], Q @ t.positions[f, 0] + c.t)
        assert np.abs(fast[f, -1] - ref).max() < 1e-13


@pytest.mark.parametrize("seed", [0, 1])
def test_frame_strains_match_dot_product_reference(seed):
    t = random_trajectory(seed)
    Om, Ga = frame_strains(t.positions, t.frames, 0.34)
    for f in range(t.n_frames):
        O2, G2 = strains_dot_form(t.positions[f], t.frames[f], 0.34)
        assert np.abs(Om[f] - O2).max() < 1e-11 and np.abs(Ga[f] - G2).max() < 1e-12


def test_step_analysis_table_round_trip(tmp_path):
    t = random_trajectory(3, n_frames=4, n_nodes=5)
    a = StepAnalysis(t, 0.34, sequence="ACGTA").run(start=1)
    assert a.results.names == ["AC", "CG", "GT", "TA"]
    a.write_csv(tmp_path / "s.csv")
    data = np.genfromtxt(tmp_path / "s.csv", delimiter=",", names=True, dtype=None, encoding="ascii")
    assert len(data) == 3 * 4
    assert list(np.unique(data["frame"])) == [1, 2, 3]
    f, k = 2, 3
    row = data[(data["frame"] == f) & (data["step"] == k + 1)][0]  # steps numbered from 1, as `dnarod steps`
    p = step_parameters(t.frames[f, k], t.positions[f, k], t.frames[f, k + 1], t.positions[f, k + 1])
    assert abs(row["rise_A"] - 10 * p[2]) < 1e-6 and abs(row["twist_deg"] - np.degrees(p[5])) < 1e-5
    assert row["step_type"] == "TA"


@pytest.mark.parametrize("circular", [False, True])
def test_tangent_correlation_kernel_matches_triple_loop(circular):
    t = random_trajectory(4, n_frames=5, n_nodes=8)
    d3 = t.frames[..., 2]
    nmax = 6 if not circular else 4
    fast = tangent_correlation_frames(d3, nmax, circular)
    nf, n = d3.shape[:2]
    slow = np.zeros((nf, nmax + 1))
    for f in range(nf):
        for lag in range(nmax + 1):
            vals = []
            for k in range(n if circular else n - lag):
                vals.append(float(np.dot(d3[f, k], d3[f, (k + lag) % n])))
            slow[f, lag] = sum(vals) / len(vals)
    assert np.abs(fast - slow).max() < 1e-14


def test_tangent_correlation_blocks_and_persistence_fit():
    t = random_trajectory(6, n_frames=20, n_nodes=10)
    tc = TangentCorrelation(t, 0.34, n_blocks=4).run()
    r = tc.results
    t0 = r.dropped_frames
    kept = r.per_frame[t0:]
    blocks = np.array([b.mean(axis=0) for b in np.array_split(kept, 4)])
    assert np.allclose(r.correlation_blocks, blocks, atol=1e-15)  # the blocks of the long-lag fit's error
    assert np.allclose(r.correlation, kept.mean(axis=0), atol=1e-15)
    # each lag's error is the one estimator's over the kept frames (dnarod.analysis.statistics.estimate)
    from dnarod.analysis.statistics import estimate

    assert r.correlation_err[1] == pytest.approx(estimate(r.per_frame[:, 1]).error, rel=1e-12)
    assert r.correlation_err[3] == pytest.approx(estimate(kept[:, 3], transient=False).error, rel=1e-12)
    # lp from the fit ln C(n) = -n ds / lp over the leading lags with C > 0.1
    C = r.correlation
    use = [n for n in range(1, len(C)) if all(C[1:n + 1] > 0.1)]
    slope = sum(n * np.log(C[n]) for n in use) / sum(n * n for n in use)
    assert r.persistence_length == pytest.approx(-0.34 / slope, rel=1e-12)
    assert r.n_fit == len(use)


def test_end_to_end_matches_loop():
    t = random_trajectory(7, n_frames=12)
    ee = EndToEnd(t, n_blocks=3).run()
    d = [np.sqrt(sum((t.positions[f, -1, i] - t.positions[f, 0, i]) ** 2 for i in range(3))) for f in range(12)]
    assert np.allclose(ee.results.distance, d, atol=1e-14)
    assert ee.results.mean == pytest.approx(np.mean(d[ee.results.mean_estimate.n_dropped:]), abs=1e-14)
    assert ee.results.mean_square == pytest.approx(np.mean(np.square(d)), abs=1e-13)
    from dnarod.analysis.statistics import estimate

    e = estimate(d)  # the one estimator (12 frames: flagged as too short for an error bar)
    assert ee.results.mean_err == pytest.approx(e.error, rel=1e-12) and ee.results.mean_estimate.flag is not None


def test_block_helpers_against_hand_computation():
    x = np.arange(10.0) ** 2
    b = block_estimates(x, 3)  # array_split: sizes 4, 3, 3
    assert np.allclose(b, [np.mean(x[:4]), np.mean(x[4:7]), np.mean(x[7:])])
    assert standard_error(b) == pytest.approx(np.std(b, ddof=1) / np.sqrt(3))
    assert np.isnan(standard_error(b[:1]))


def test_haar_weight_and_weighted_moments_match_loops():
    rng = np.random.default_rng(0)
    xi = rng.normal(size=(50, 6))
    W = haar_weight(xi[:, :3], 0.34)
    for i in range(50):
        assert W[i] == pytest.approx((1 + 0.34**2 * sum(xi[i, :3] ** 2) / 4) ** 2, rel=1e-14)
    mean, cov = weighted_moments(xi, W)
    m_ref = sum(W[i] * xi[i] for i in range(50)) / W.sum()
    c_ref = sum(W[i] * np.outer(xi[i] - m_ref, xi[i] - m_ref) for i in range(50)) / W.sum()
    assert np.allclose(mean, m_ref, atol=1e-14) and np.allclose(cov, c_ref, atol=1e-14)


def test_exact_tangent_correlation_average_over_starts():
    from dnarod.physics.thermal import exact_tangent_correlation
    from dnarod.core.forcefield import load_forcefield
    from dnarod.physics.thermal import mean_rotation, tangent_correlation
    from dnarod.core.units import kT

    ff = load_forcefield("dna-default")
    p = ff.step_parameters(n_steps=12)
    assert np.allclose(exact_tangent_correlation(p, ff.ds, kT(300), 8), tangent_correlation(p, ff.ds, kT(300), 8),
                       atol=1e-14)
    seqff = load_forcefield("olson1998")
    p = seqff.step_parameters("ACGTTGCAAG")
    Rm = mean_rotation(p, seqff.ds, kT(300))
    got = exact_tangent_correlation(p, seqff.ds, kT(300), 5, exclude_ends=1)
    nodes = list(range(1, 9))  # 10 nodes, one left out at each end
    for n in range(6):
        vals = []
        for k in nodes[:len(nodes) - n]:
            P = np.eye(3)
            for j in range(k, k + n):
                P = P @ Rm[j]
            vals.append(P[2, 2])
        assert got[n] == pytest.approx(np.mean(vals), abs=1e-14)
