"""Calibration of dnarod's error bars on real runs: over at least 20 independent seeds, the z-scores
``(estimate - exact) / stated error`` of the headline observables have unit variance within its sampling error.

The system is magnetic tweezers without walls: node 0 clamped, the last node pulled along z and rotation-clamped to a
target turned by a fraction of a turn. Its exact averages (extension, clamp torque, lag-1 tangent correlation, hence
the lag-1 persistence length) come from exact free-chain samples reweighted by ``exp((F z - E_clamp)/kT)``
(:func:`dnarod.physics.sampling.tweezers_reference`), independent of any engine. Each seed runs one engine through
the run layer (:func:`dnarod.run.api.make_engine`) from the static pose under the loads, with the friction that
damps the slowest normal mode of the loaded chain critically and an equilibration of ten of its relaxation times
(:mod:`dnarod.physics.relaxation`), and states each mean with :func:`dnarod.analysis.statistics.estimate` (pymbar
autocorrelation error, transient dropped). The test also shows that it can fail: errors that ignore the
correlation of the samples give z-scores far outside the band.

The engine is a parameter: another engine of the run layer (the Monte Carlo sampler, ``make_engine`` with
``spec.engine == "mc"``) joins by adding its name to ``ENGINES``; ``sample_seed`` only needs ``advance(n)`` and
``node_state()`` of the engine protocol (:class:`dnarod.run.engine.Engine`). The fast version (default suite)
runs a 16-bp chain on OpenMM and on the Monte Carlo sampler; the slow ones a 40-bp chain over 40 seeds (both), and
the 16-bp case on the Lax engine.
"""
import numpy as np
import pytest

from dnarod.analysis.statistics import calibration, estimate, function_estimate
from dnarod.core.forcefield import load_forcefield
from dnarod.core.rotations import rotation_about_axis
from dnarod.core.units import PN, kT

TEMPERATURE = 300.0


def tweezers_case(n_bp, force_pN=2.0, clamp_kT=10.0, turns=0.05):
    """Model, loads, clamp target, static start and the slowest mode (friction, relaxation time) of the case."""
    from dnarod.physics.loads import tweezers
    from dnarod.physics.relaxation import relaxation_times
    from dnarod.physics.statics import solve_static

    model = load_forcefield("dna-default").model_from_sequence(n_nodes=n_bp)
    k = clamp_kT * kT(TEMPERATURE)
    target = rotation_about_axis(np.array([0.0, 0.0, 1.0]), 2 * np.pi * turns) @ model.frames[-1]
    loads = tuple(tweezers(model, force_pN, None, k, 0.0, anchor="surface", axis="z", clamp_frame=target))
    start, _ = solve_static(model, loads)
    r = relaxation_times(start, loads, friction=1.0, k=4, temperature=TEMPERATURE)
    w1 = r["omega_slowest"]
    return dict(model=model, loads=loads, target=target, k=k, start=start, force_pN=force_pN,
                friction=2.0 * w1, tau_ps=1.0 / w1)  # critical damping of the slowest mode: relaxation 1/omega_1


def sample_seed(engine, case, seed, n_samples, equilibration_tau=10.0, sample_tau=0.5):
    """One independent run: per-sample extension (nm), clamp torque (pN nm) and lag-1 tangent correlation."""
    from dnarod.run.api import choose_dt, default_omega_max, make_engine
    from dnarod.run.spec import RunSpec

    start, loads = case["start"], case["loads"]
    spec = RunSpec(source=start, engine=engine, temperature=TEMPERATURE, friction=case["friction"], seed=seed,
                   loads=loads, excluded_volume=False, electrostatics=False,
                   platform="Reference" if engine == "openmm" else None, time_ns=1.0)
    if engine == "mc":  # sweeps, not time: the relaxation time in sweeps is the sampler's own (MC_TAU_SWEEPS)
        omega, dt, tau = None, 1.0, MC_TAU_SWEEPS
        sample_tau = MC_SAMPLE_TAU
    else:
        omega = default_omega_max(start, loads)
        dt = choose_dt(spec, start, omega)
        tau = case["tau_ps"] / dt
    eng = make_engine(spec, start, dt, seed, omega)
    eng.advance(int(round(equilibration_tau * tau)))
    stride = max(1, int(round(sample_tau * tau)))
    T = case["target"]
    out = np.empty((n_samples, 3))
    for i in range(n_samples):
        eng.advance(stride)
        pos, frm = eng.node_state()[:2]
        S = frm[-1] @ T.T
        out[i] = (pos[-1, 2] - pos[0, 2], 0.5 * case["k"] * (S[0, 1] - S[1, 0]) / PN,
                  np.einsum("ki,ki->k", frm[:-1, :, 2], frm[1:, :, 2]).mean())
    return out


def z_scores(engine, case, seeds, n_samples, n_reference):
    from dnarod.physics.sampling import tweezers_reference

    ref = tweezers_reference(case["model"], TEMPERATURE, case["force_pN"], n_reference, np.random.default_rng(7),
                             case["k"], case["target"])
    ds = case["model"].ds
    lp = lambda c: -ds / np.log(c)  # noqa: E731
    lp_ref = lp(ref["lag1"][0])
    dlp = ds / (ref["lag1"][0] * np.log(ref["lag1"][0]) ** 2)
    z = {"extension": [], "torque": [], "persistence_length": []}
    naive = []
    flags = []
    for s in seeds:
        x = sample_seed(engine, case, s, n_samples)
        for j, (name, (mref, sref)) in enumerate((("extension", ref["extension_nm"]),
                                                  ("torque", ref["clamp_torque_pN_nm"]),
                                                  ("persistence_length", (lp_ref, dlp * ref["lag1"][1])))):
            e = estimate(x[:, j], what=name)
            if j == 2:  # the mean lag-1 correlation, then lp = -ds / ln C(1) (a per-frame lp would be biased)
                e = function_estimate(e, lp)
            flags.append(e.flag)
            z[name].append((e.mean - mref) / np.hypot(e.error, sref))
            if j == 0:
                naive.append((e.mean - mref) / (x[:, j].std(ddof=1) / np.sqrt(len(x))))
    return z, naive, flags, ref


#: A relaxation time of the short chains' extension under the Monte Carlo sampler, in sweeps (a 16-node sweep is
#: only 16 attempted moves: the extension's integrated autocorrelation time, measured by the estimator in each run,
#: is a few hundred sweeps); equilibration ten of them.
MC_TAU_SWEEPS = 400
#: Monte Carlo samples every quarter of it (correlated samples, as the MD runs' are).
MC_SAMPLE_TAU = 0.25

ENGINES = ["openmm", "mc"]


@pytest.mark.parametrize("engine", ENGINES)
def test_error_bars_are_calibrated_over_20_seeds(engine):
    case = tweezers_case(16)
    z, naive, flags, ref = z_scores(engine, case, range(101, 121), n_samples=400, n_reference=30000)
    assert ref["ess"] > 10000
    pooled = []
    for name, v in z.items():
        var, lo, hi = calibration(v)
        print(f"{engine} 16 bp, 20 seeds: {name} var(z) {var:.2f} (99 % band {lo:.2f}-{hi:.2f}), mean z "
              f"{np.mean(v):+.2f}")
        assert lo < var < hi, (name, var, lo, hi, np.round(v, 2))
        pooled += v
    var, lo, hi = calibration(pooled)  # 60 z-scores (three observables of 20 runs): a tighter band
    assert lo < var < hi, (var, lo, hi)
    assert sum(f is not None for f in flags) <= 3
    print(f"naive errors (samples taken as independent): var(z) of the extension {calibration(naive)[0]:.2f}")
    # the same runs with errors that ignore the autocorrelation: far outside the band
    assert calibration(naive)[0] > calibration(naive)[2]


@pytest.mark.slow
def test_error_bars_of_the_lax_engine_are_calibrated_over_20_seeds():
    """The fast case on the Lax-form engine (about 17 s per seed on one core)."""
    test_error_bars_are_calibrated_over_20_seeds("lax")


@pytest.mark.slow
@pytest.mark.parametrize("engine", ["openmm", "mc"])
def test_error_bars_are_calibrated_over_40_seeds_longer_chain(engine):
    case = tweezers_case(40, force_pN=1.0, clamp_kT=5.0, turns=0.05)
    z, naive, flags, ref = z_scores(engine, case, range(201, 241), n_samples=600, n_reference=200000)
    pooled = []
    for name, v in z.items():
        var, lo, hi = calibration(v)
        print(f"{engine} 40 bp, 40 seeds: {name} var(z) {var:.2f} (99 % band {lo:.2f}-{hi:.2f}), mean z "
              f"{np.mean(v):+.2f}")
        assert lo < var < hi, (name, var, lo, hi)
        pooled += v
    var, lo, hi = calibration(pooled)
    assert lo < var < hi
    assert sum(f is not None for f in flags) <= 6
