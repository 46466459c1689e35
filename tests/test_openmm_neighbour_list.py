"""The Verlet neighbour list of the non-local terms against the all-pairs reference, on coiled
and plectonemic configurations, across moves that do and do not trigger a rebuild."""
import numpy as np
import pytest

from dnarod.core.forcefield import load_forcefield
from dnarod.engines.openmm.nonbonded import NonbondedCallback, VerletList
from dnarod.physics.nonbonded import NonbondedSettings, nonbonded_reference
from dnarod.physics.testsystems import gaussian_coil, plectoneme_centres


@pytest.fixture(scope="module")
def coil():
    """A thermal coil of 600 bp at 300 K, squeezed 4x towards its centre of mass so that many
    non-excluded pairs fall inside both cutoffs."""
    m = load_forcefield("dna-default").model_from_sequence("ACGT" * 150)
    c = gaussian_coil(m, seed=3).positions
    return c.mean(0) + 0.25 * (c - c.mean(0))


def plectoneme():
    return plectoneme_centres(700, radius=1.05, pitch=6.0)


def _check(cb, c, circular, numbers):
    ew, ed, F = cb.evaluate(c)
    ew0, ed0, F0 = nonbonded_reference(c, circular, numbers)
    assert ew == pytest.approx(ew0, rel=1e-12, abs=1e-12) and ed == pytest.approx(ed0, rel=1e-12, abs=1e-12)
    assert np.abs(F - F0).max() <= 1e-10 * max(np.abs(F0).max(), 1e-300)
    return ew0, ed0


@pytest.mark.parametrize("config", ["coil", "plectoneme"])
@pytest.mark.parametrize("salt", [0.15, 0.02])
def test_verlet_list_equals_all_pairs_through_moves(config, salt, coil):
    c0 = coil if config == "coil" else plectoneme()
    v = NonbondedSettings(salt=salt, skin=1.0).resolve(0.34, 300.0)
    cb = NonbondedCallback(len(c0), False, v)
    ew0, ed0 = _check(cb, c0, False, v)
    assert ed0 > 0 and (ew0 > 0 or salt < 0.1)  # both terms act (at 20 mM n_exclude = 32 spares the coil WCA)
    assert cb.verlet.builds == 1
    rng = np.random.default_rng(7)
    c = c0.copy()
    # moves below half the skin: the list is reused and still exact
    for _ in range(4):
        d = rng.normal(size=c.shape)
        d *= 0.12 / np.linalg.norm(d, axis=1, keepdims=True).max()
        c = c + d
        _check(cb, c, False, v)
    assert np.sqrt(((c - c0) ** 2).sum(1)).max() < 0.5 and cb.verlet.builds == 1
    # a node moved by more than half the skin: rebuilt, exact again
    c[len(c) // 3] = c0[len(c) // 3] + [0.6, 0.0, 0.0]
    _check(cb, c, False, v)
    assert cb.verlet.builds == 2


def test_zero_skin_rebuilds_every_evaluation(coil):
    v = NonbondedSettings(skin=0.0).resolve(0.34, 300.0)
    vl = VerletList(len(coil), v["cutoff"], 0.0, False, v["n_exclude"])
    vl.update(coil)
    vl.update(coil)
    assert vl.builds == 2


def test_a_skin_would_miss_pairs_without_the_rebuild_rule(coil):
    """The rebuild rule matters: with the list frozen, a move of 0.6 nm brings pairs inside the
    cutoff that the stale list does not hold, so the energies would differ. (A 5-Debye-length cutoff: with the
    default 12 the missed pairs sit where the shifted energy is ~e^-12 of its contact value, below the test's
    resolution.)"""
    from dnarod.engines.openmm.nonbonded import pair_kernel

    v = NonbondedSettings(skin=1.0, cutoff_debye=5.0).resolve(0.34, 300.0)
    vl = VerletList(len(coil), v["cutoff"], 1.0, False, v["n_exclude"])
    pi, pj, m = vl.update(coil)
    c = coil + np.random.default_rng(1).normal(scale=0.6, size=coil.shape)
    F = np.zeros_like(c)
    stale = pair_kernel(c, pi, pj, m, v["eps"], v["sigma"], v["rc_wca"], v["a_dh"], v["kappa"], v["rc_dh"], F)
    ew0, ed0, _ = nonbonded_reference(c, False, v)
    assert abs(stale[1] - ed0) > 1e-6 * ed0
    pi, pj, m = vl.update(c)  # the rule rebuilds here
    F[:] = 0
    fresh = pair_kernel(c, pi, pj, m, v["eps"], v["sigma"], v["rc_wca"], v["a_dh"], v["kappa"], v["rc_dh"], F)
    assert fresh == pytest.approx((ew0, ed0), rel=1e-12)


def test_list_grows_past_its_initial_capacity():
    """A dense plectoneme at low salt holds more pairs than the initial buffer (16 per node)."""
    c = plectoneme_centres(400, radius=1.05, pitch=3.0)
    v = NonbondedSettings(salt=0.005, skin=1.0).resolve(0.34, 300.0)
    cb = NonbondedCallback(len(c), False, v)
    _check(cb, c, False, v)
    assert cb.verlet.m > 16 * len(c) + 1024


def test_engine_energies_and_forces_equal_all_pairs_on_a_coil():
    """Through OpenMM (Reference platform, fast path): after Langevin steps that move the coil,
    the non-bonded energy and node forces of the engine's callback equal the all-pairs reference."""
    from dnarod.engines.openmm.particles import node_poses, particle_forces_to_loads
    from dnarod.engines.openmm.simulation import RodSimulation

    m = load_forcefield("dna-default").model_from_sequence("ACGT" * 60)
    m = gaussian_coil(m, seed=5)
    c = m.positions
    m = m.with_pose(c.mean(0) + 0.5 * (c - c.mean(0)), m.frames)  # denser (strains change; fine here)
    nb = NonbondedSettings(salt=0.05)
    sim = RodSimulation.create(m, temperature=300, seed=2, nonbonded=nb, platform="Reference", dt=0.02, elastic="fast")
    sim.advance(50)
    sim.energies()
    assert sim.rs.elastic_callback.nonbonded is sim.rs.nonbonded_callback  # fused into the elastic callback
    st = sim.context.getState(getPositions=True)
    p = st.getPositions(asNumpy=True)._value
    centres, _ = node_poses(p)
    ew0, ed0, F0 = nonbonded_reference(centres, False, sim.rs.nonbonded)
    assert ed0 > 0
    assert sum(sim.rs.nonbonded_callback.last) == pytest.approx(ew0 + ed0, rel=1e-9)
    # the forces of the fused callback minus those of the elastic term alone are the non-local ones
    from dnarod.engines.openmm.forces import elastic_particle_kernel

    el = sim.rs.elastic_callback
    out = np.zeros_like(p)
    elastic_particle_kernel(np.ascontiguousarray(p), el.radius, el.K, el.xi0, el.ds, el.Q, el.t, el.circular, out)
    _, fused = el(st)
    F, tau = particle_forces_to_loads(p, fused - out)
    assert np.abs(F - F0).max() <= 1e-8 * np.abs(F0).max()
    assert np.abs(tau).max() <= 1e-8 * np.abs(F0).max()


def test_gaussian_coil_samples_the_step_covariance_without_close_pairs():
    from scipy.spatial import cKDTree

    from dnarod.core.units import kT

    m = load_forcefield("dna-default").model_from_sequence("ACGT" * 750)
    c = gaussian_coil(m, seed=11, min_distance=2.3, n_exclude=12)
    pairs = cKDTree(c.positions).query_pairs(2.3, output_type="ndarray")
    assert not len(pairs) or np.abs(pairs[:, 1] - pairs[:, 0]).max() <= 12
    Om, Ga = c.strains()
    xi = np.concatenate([Om, Ga], axis=1) - m.params.intrinsic
    expected = np.diag(kT(300) * np.linalg.inv(m.ds * m.params.stiffness[0]))
    # 2999 independent steps: the variance estimates scatter by sqrt(2/2999) = 2.6%; redraws are rare
    assert np.all(np.abs(xi.var(axis=0) / expected - 1) < 0.1)


def test_plectoneme_is_a_chain_of_rise_ds_and_bad_skin_is_rejected():
    from dnarod.core.errors import ParameterError

    c = plectoneme_centres(500, ds=0.34)
    d = np.linalg.norm(np.diff(c, axis=0), axis=1)
    assert len(c) == 500 and np.all(np.abs(d / 0.34 - 1) < 0.4)
    with pytest.raises(ParameterError, match="skin"):
        NonbondedSettings(skin=-1.0).resolve(0.34, 300.0)
