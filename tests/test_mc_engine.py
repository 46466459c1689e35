"""The Monte Carlo engine (dnarod.engines.mc): its energy is the OpenMM engine's, its moves keep detailed balance
(exact free-chain results), topology and checkpoints; and the transfer-matrix force-extension it is checked against."""
import numpy as np
import pytest

from dnarod.analysis.statistics import mean_and_error
from dnarod.engines.mc import MCEngine
from dnarod.core.forcefield import load_forcefield
from dnarod.physics.loads import Clamp, PullingForce, RotationClamp, Torque, Trap
from dnarod.physics.nonbonded import NonbondedSettings
from dnarod.core.units import kT
from dnarod.physics.thermal import equilibrium_sample, exact_tangent_correlation
from dnarod.core.units import PN

FF = load_forcefield("dna-default")


def _chain(n, seed=None):
    m = FF.model_from_sequence(n_nodes=n)
    return m if seed is None else equilibrium_sample(m, 300.0, seed=seed)


def _openmm_energy(model, pos, frm, loads, nb):
    """Energies of the OpenMM engine (Reference platform; walls, if among the loads, in the external term)."""
    from dnarod.engines.openmm.particles import particle_positions
    from dnarod.engines.openmm.simulation import RodSimulation

    sim = RodSimulation(model, temperature=300.0, nonbonded=nb, loads=loads, platform="Reference")
    sim.set_particle_positions(particle_positions(pos, frm, sim.rs.radius))
    return sim.energies()


def _perturbed(model, rng, keep0=True):
    from dnarod.core.rotations import cayley

    pos = model.positions + 0.02 * rng.standard_normal(model.positions.shape)
    frm = np.einsum("kab,kbc->kac", cayley(0.05 * rng.standard_normal((model.n_nodes, 3))), model.frames)
    if keep0:
        pos[0], frm[0] = model.positions[0], model.frames[0]
    return pos, frm


@pytest.mark.parametrize("nb", [True, False])
def test_energy_equals_openmm_coil(nb):
    """An open chain cut from a writhed ring has many non-bonded pairs: every term equals the OpenMM engine's."""
    model = _compact_open_chain()
    settings = NonbondedSettings() if nb else False
    e = MCEngine(model, 300.0, nonbonded=settings, seed=1)
    mm = _openmm_energy(model, model.positions, model.frames, (), settings)
    mc = e.energies()
    if nb:
        assert mc["nonbonded"] > 0.1  # pairs within the cutoff exist
    for k in ("elastic", "nonbonded", "external", "potential"):
        assert mc[k] == pytest.approx(mm[k], rel=1e-9, abs=1e-9)


def test_energy_equals_openmm_tweezers_loads():
    """Tweezers member (clamp, pulling force, rotation clamp, walls) plus a dead torque and a trap, random pose."""
    from dnarod.physics.nonbonded import member_nonbonded
    from dnarod.workflows.protocols.tweezers import build_member

    mb = build_member(dict(n_bp=120, force_pN=1.0, turns=1.0))
    model = mb["model"]
    loads = list(mb["loads"]) + [Torque(60, [0.0, 0.0, 2.0 * PN]), Trap(30, 5.0)]
    nb = member_nonbonded(mb["settings"])
    pos, frm = _perturbed(model, np.random.default_rng(0))
    pos[-1, 2] -= 2.0  # bring the bead plane below a few nodes and some particles below the surface
    pos[5:8, 2] = pos[0, 2] - 0.1
    e = MCEngine(model, 300.0, loads=loads, nonbonded=nb, seed=1)
    e.pos[:], e.frm[:] = pos, frm
    e._setup_caches()
    mm = _openmm_energy(model, pos, frm, loads, nb)
    mc = e.energies()
    assert mc["external"] > 1.0
    for k in ("elastic", "nonbonded", "external", "potential"):
        assert mc[k] == pytest.approx(mm[k], rel=1e-9, abs=1e-9)


def test_energy_equals_openmm_ring():
    from dnarod.core.model import RodModel

    base = FF.model_from_sequence(n_nodes=150)
    from dnarod.core.parameters import StepParameters

    p = base.params
    params = StepParameters(np.concatenate([p.stiffness, p.stiffness[:1]]),
                            np.concatenate([p.intrinsic, p.intrinsic[:1]]), list(p.names) + [p.names[0]])
    ring = RodModel.ring(params, base.ds, base.mass, base.inertia, linking_number=14)
    e = MCEngine(ring, 300.0, nonbonded=NonbondedSettings(), seed=2)
    e.advance(30)
    model = e.current_model()
    mm = _openmm_energy(model, model.positions, model.frames, (), NonbondedSettings())
    mc = e.energies()
    assert mc["nonbonded"] > 0.0
    for k in ("elastic", "nonbonded", "potential"):
        assert mc[k] == pytest.approx(mm[k], rel=1e-9, abs=1e-9)


def test_local_energy_changes_add_up():
    """The running energy (sum of accepted local changes) equals the recomputed one after many moves of all
    types, with non-bonded terms, loads and walls."""
    from dnarod.physics.nonbonded import member_nonbonded
    from dnarod.workflows.protocols.tweezers import build_member

    mb = build_member(dict(n_bp=200, force_pN=0.5, turns=1.5))
    model = mb["model"]
    loads = list(mb["loads"]) + [Torque(100, [0.0, 0.0, 3.0 * PN])]
    e = MCEngine(model, 300.0, loads=loads, nonbonded=member_nonbonded(mb["settings"]), seed=4)
    e.advance(300)
    E = e.energies()
    assert e.running[0] == pytest.approx(E["elastic"], rel=1e-9)
    assert e.running[1] == pytest.approx(E["nonbonded"], abs=1e-8)
    assert e.running[2] == pytest.approx(E["external"], rel=1e-9, abs=1e-8)
    acc = e.acceptance()
    assert all(0.05 < acc[k] < 0.95 for k in ("node", "crankshaft", "twist")), acc


def test_bare_chain_runs():
    """No non-bonded terms at all (no n_exclude): the engine samples."""
    e = MCEngine(_chain(50), 300.0, nonbonded=False, seed=1)
    e.advance(20)
    assert e.energies()["nonbonded"] == 0.0
    assert not e.topology_preserved
    e2 = MCEngine(_chain(50), 300.0, nonbonded=NonbondedSettings(excluded_volume=False, electrostatics=False),
                  seed=1)
    e2.advance(5)


def test_bad_input():
    from dnarod.core.errors import ParameterError

    with pytest.raises(ParameterError, match="temperature"):
        MCEngine(_chain(20), 0.0)
    with pytest.raises(ParameterError, match="unknown Monte Carlo move"):
        MCEngine(_chain(20), 300.0, moves={"teleport": 1.0})


def _tangent_samples(n_nodes, n_sweeps, seed, lag_max):
    model = _chain(n_nodes)
    e = MCEngine(model, 300.0, nonbonded=False, seed=seed, tune_sweeps=200)
    e.advance(400)
    out = np.empty((n_sweeps, lag_max + 1))
    for s in range(n_sweeps):
        e.advance(1)
        d3 = e.frm[:, :, 2]
        for lag in range(lag_max + 1):
            out[s, lag] = np.mean(np.einsum("ka,ka->k", d3[: n_nodes - lag], d3[lag:]))
    return model, out


def test_tangent_correlation_exact():
    """Free chain: <d3(k) . d3(k+n)> equals the exact Haar-measure value within 3 calibrated errors."""
    lags = (1, 5, 20, 40)
    model, x = _tangent_samples(60, 3000, 7, max(lags))
    exact = exact_tangent_correlation(model.params, model.ds, kT(300.0), max(lags))
    for lag in lags:
        est = mean_and_error(x[:, lag])
        assert est.flag is None, (lag, est)
        assert abs(est.mean - exact[lag]) < 3 * est.error + 1e-12, (lag, est, exact[lag])


def _pulled_extension(n_nodes, force_pN, n_sweeps, seed):
    model = _chain(n_nodes)
    f = np.array([0.0, 0.0, force_pN * PN])
    e = MCEngine(model, 300.0, loads=(PullingForce(-1, f), PullingForce(0, -f)), nonbonded=False, seed=seed)
    e.advance(300)
    x = np.empty(n_sweeps)
    for s in range(n_sweeps):
        e.advance(1)
        x[s] = e.pos[-1, 2] - e.pos[0, 2]
    return model, mean_and_error(x)


@pytest.mark.parametrize("force_pN", [0.3, 10.0])
def test_force_extension_exact_short(force_pN):
    """30-bp free chain pulled at both ends: the mean extension equals the transfer-matrix value within 3
    calibrated standard errors."""
    from dnarod.physics.theory.transfer_matrix import force_extension

    model, est = _pulled_extension(30, force_pN, 4000, 11)
    ref = force_extension(model.params, model.ds, 300.0, 30, force_pN)[0]
    assert est.flag is None
    assert abs(est.mean - ref) < 3 * est.error, (est, ref)


def test_transfer_matrix_against_reweighted_exact_samples():
    """The transfer matrix against an independent route: exact i.i.d. free-chain samples
    (dnarod.thermal) reweighted by exp(F x / kT), 12 nodes at 2 pN."""
    from dnarod.core.strains import chain_from_strains
    from dnarod.physics.thermal import sample_open_chain_strains
    from dnarod.physics.theory.transfer_matrix import force_extension

    model = _chain(12)
    rng = np.random.default_rng(5)
    xi = sample_open_chain_strains(model.params, model.ds, kT(300.0), rng, n_chains=40000)
    # node 0 with a Haar-random frame: z seen from it is uniform on the sphere
    u = rng.standard_normal((len(xi), 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    x = np.empty(len(xi))
    for i, s in enumerate(xi):
        p, _ = chain_from_strains(s[:, :3], s[:, 3:], model.ds)
        x[i] = (p[-1] - p[0]) @ u[i]
    F = 2.0 * PN
    w = np.exp(F * x / kT(300.0))
    mean = float((w * x).sum() / w.sum())
    # delta-method error of the ratio estimator
    err = float(np.sqrt(np.sum((w * (x - mean)) ** 2)) / w.sum())
    ref = force_extension(model.params, model.ds, 300.0, 12, 2.0)[0]
    assert abs(mean - ref) < 3 * err, (mean, err, ref)


def _compact_open_chain():
    """A 200-node hairpin (two straight arms joined by a 20-step half circle, arms 4.3 nm apart) with a little
    thermal noise: many non-bonded pairs within the Debye-Hueckel cutoff."""
    from dnarod.core.strains import chain_from_strains

    base = FF.model_from_sequence(n_nodes=200)
    Om = base.params.Omega0.copy()
    Ga = base.params.Gamma0.copy()
    Om[90:110, 2] = 0.0  # untwisted U-turn, so the bend stays in one plane
    Om[90:110, 0] = np.pi / (20 * base.ds)
    pos, frm = chain_from_strains(Om, Ga, base.ds)
    pos, frm = _perturbed(base.with_pose(pos, frm), np.random.default_rng(1), keep0=False)
    return base.with_pose(pos, frm)


def _ring(n, lk):
    from dnarod.core.model import RodModel
    from dnarod.core.parameters import StepParameters

    base = FF.model_from_sequence(n_nodes=n)
    p = base.params
    params = StepParameters(np.concatenate([p.stiffness, p.stiffness[:1]]),
                            np.concatenate([p.intrinsic, p.intrinsic[:1]]), list(p.names) + [p.names[0]])
    return RodModel.ring(params, base.ds, base.mass, base.inertia, linking_number=lk)


def test_ring_keeps_linking_number():
    """A supercoiled 300-bp ring with excluded volume: Lk = Tw + Wr stays the integer it started with over a
    run in which the writhe moves by more than a turn."""
    from dnarod.physics.writhe import twist, writhe

    ring = _ring(300, 26)  # relaxed Lk0 ~ 28.6: sigma ~ -0.09, writhes
    e = MCEngine(ring, 300.0, nonbonded=NonbondedSettings(), seed=3)
    wr = []
    for _ in range(30):
        e.advance(40)
        p, f = e.pos, e.frm
        wr.append(writhe(p))
        lk = twist(p, f[:, :, 0]) + wr[-1]
        assert abs(lk - 26) < 1e-6, lk
    assert np.ptp(wr) > 0.5


def test_checkpoint_continues_bit_for_bit(tmp_path):
    model = _chain(60, seed=2)
    loads = (Clamp(0), PullingForce(-1, [0, 0, PN]), RotationClamp(-1, 250.0))
    a = MCEngine(model, 300.0, loads=loads, nonbonded=NonbondedSettings(), seed=9)
    a.advance(30)
    a.save_checkpoint(tmp_path / "c.npz", extra={"x": 1})
    a.advance(20)
    b = MCEngine(model, 300.0, loads=loads, nonbonded=NonbondedSettings(), seed=123)
    meta = b.load_checkpoint(tmp_path / "c.npz")
    assert meta["extra"] == {"x": 1} and b.step == 30
    b.advance(20)
    assert np.array_equal(a.pos, b.pos) and np.array_equal(a.frm, b.frm)
    from dnarod.core.errors import ParameterError

    c = MCEngine(_chain(61), 300.0, seed=1)
    with pytest.raises(ParameterError, match="another model"):
        c.load_checkpoint(tmp_path / "c.npz")
