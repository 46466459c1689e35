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

from conftest import uniform_ring

FF = load_forcefield("dna-default")


def _chain(n, seed=None):
    m = FF.model_from_sequence(n_nodes=n)
    return m if seed is None else equilibrium_sample(m, 300.0, seed=seed)


def _openmm_energy(model, pos, frm, loads, nb):
    """Energies of the OpenMM engine (Reference platform; walls, if among the loads, in the external term)."""
    from dnarod.engines.openmm.particles import particle_positions
    from dnarod.engines.openmm.simulation import RodSimulation

    sim = RodSimulation.create(model, temperature=300.0, nonbonded=nb, loads=loads, platform="Reference")
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
    ring = uniform_ring(150, 14)
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


def test_force_extension_exact_clamped_start():
    """30-bp chain held at node 0 (d3 along the force, as on a tweezers surface) and pulled at its last node: the
    chain relaxes by the clamped-chain moves (hinge pairs, end twists, crankshafts, node moves); the mean extension
    equals the transfer-matrix value of a held start within 3 calibrated standard errors."""
    from dnarod.physics.theory.transfer_matrix import force_extension

    model = _chain(30)
    e = MCEngine(model, 300.0, loads=(Clamp(0), PullingForce(-1, [0.0, 0.0, 1.0 * PN])), nonbonded=False, seed=12)
    assert e.moves["hinge"] > 0 and e.moves["end_twist"] > 0 and e.moves["pivot"] == 0
    e.advance(300)
    x = np.empty(40000)
    for s in range(len(x)):
        e.advance(1)
        x[s] = e.pos[-1, 2] - e.pos[0, 2]
    est = mean_and_error(x)
    ref = force_extension(model.params, model.ds, 300.0, 30, 1.0, start_cos=float(model.frames[0][2, 2]))[0]
    free = force_extension(model.params, model.ds, 300.0, 30, 1.0)[0]
    assert est.flag is None
    assert abs(ref - free) > 6 * est.error  # the held start is distinguishable from a free one
    assert abs(est.mean - ref) < 3 * est.error, (est, ref)


def test_transfer_matrix_held_start_converged():
    """The held-start partition function is converged in the Legendre degree (a change below 1e-8)."""
    from dnarod.physics.theory.transfer_matrix import force_extension

    model = _chain(100)
    for F in (0.1, 10.0):
        a = force_extension(model.params, model.ds, 300.0, 100, F, start_cos=1.0)[0]
        b = force_extension(model.params, model.ds, 300.0, 100, F, start_cos=1.0, lmax=90, n_c=180, order=20)[0]
        assert a == pytest.approx(b, rel=1e-8)


def test_arc_closest_approach_exact():
    """The distance of closest approach along a rotation's path (the topology check) against a fine scan of the
    path, for random points, axes and angles up to pi."""
    from dnarod.engines.mc.kernels import arc_min2

    rng = np.random.default_rng(3)
    for _ in range(200):
        a, b = rng.standard_normal(3) * 3, rng.standard_normal(3) * 3
        u = rng.standard_normal(3)
        u /= np.linalg.norm(u)
        th = rng.uniform(-np.pi, np.pi)
        phi = np.linspace(0.0, th, 20001)[:, None]
        path = a * np.cos(phi) + np.cross(u, a) * np.sin(phi) + u * (u @ a) * (1.0 - np.cos(phi))  # Rodrigues
        scan = float(np.min(np.sum((path - b) ** 2, axis=1)))
        assert arc_min2(*a, *b, *u, th) == pytest.approx(scan, rel=1e-6, abs=1e-9)


def _tail_torque_reference(e):
    """Per-step tail-torque estimates of MCEngine.tail_torque_z, in numpy (all pairs; core step loads)."""
    from dnarod.core.kernels import step_loads

    pos, frm, n = e.pos, e.frm, e.model.n_nodes
    nb = e.numbers
    pi, pj = np.triu_indices(n, nb["n_exclude"] + 1)
    d = pos[pj] - pos[pi]
    r = np.linalg.norm(d, axis=1)
    keep = r < nb["cutoff"]
    pi, pj, d, r = pi[keep], pj[keep], d[keep], r[keep]
    s6 = (nb["sigma"] / r) ** 6
    g = np.where(r < nb["rc_wca"], 24 * nb["eps"] * (2 * s6 * s6 - s6) / r**2, 0.0)
    g += np.where(r < nb["rc_dh"], nb["a_dh"] * np.exp(-nb["kappa"] * r) * (nb["kappa"] * r + 1) / r**3, 0.0)
    pf = g[:, None] * d  # force on j from i
    assert len(pi) > 50  # a folded pose: many pairs
    out = np.full(n - 1, np.nan)
    for k in range(n - 1):
        sl = np.zeros(13)
        step_loads(pos, frm, e.K, e.xi0, e.model.ds, k, False, k + 1, np.eye(3), np.zeros(3), sl)
        p = pos[k + 1]
        Z = sl[11]
        Z += float(np.sum(np.cross(pos[pj] - p, pf)[:, 2] * ((pi <= k) & (pj > k))))
        for j in range(k + 1, n):
            G = e.force[j] - e.trap_k[j] * (pos[j] - e.trap_c[j])
            Z += np.cross(pos[j] - p, G)[2] + e.tq_mag[j] * e.tq_axis[j, 2]
        out[k] = -Z
    return out


def test_tail_torque_profile_matches_reference():
    """The compiled per-step tail torques equal a plain numpy evaluation (pairs across every step, step loads,
    loads of the tail) on a folded tweezers pose with many non-bonded pairs."""
    from dnarod.physics.nonbonded import member_nonbonded
    from dnarod.workflows.protocols.tweezers import build_member

    mb = build_member(dict(n_bp=200, force_pN=1.0, turns=1.0))
    folded = _compact_open_chain()
    loads = list(mb["loads"]) + [Torque(150, [0.3 * PN, 0.0, 2.0 * PN]), Trap(120, 3.0)]
    model = mb["model"].with_pose(folded.positions - folded.positions[0] + mb["model"].positions[0],
                                  folded.frames)
    e = MCEngine(mb["model"], 300.0, loads=loads, nonbonded=member_nonbonded(mb["settings"]), seed=1)
    e.pos[:], e.frm[:] = model.positions, model.frames
    e._setup_caches()
    got = e.tail_torque_z(profile=True)
    ref = _tail_torque_reference(e)
    assert np.isfinite(got).all()
    assert np.allclose(got, ref, rtol=1e-9, atol=1e-9 * np.abs(ref).max())


def test_tail_torque_weights_are_functions_of_the_heights():
    """The weights of the tail-torque steps (MCEngine.tail_torque_weights) on a pose with a hairpin: the steps
    inside it dropped, the others kept; unchanged when any tail is turned rigidly about a lab z axis (the condition
    under which the weighted average keeps the identity exact); the weighted estimate is the mean of the kept
    steps' values."""
    from dnarod.physics.nonbonded import member_nonbonded
    from dnarod.workflows.protocols.tweezers import build_member

    mb = build_member(dict(n_bp=200, force_pN=1.0, turns=1.0))
    e = MCEngine(mb["model"], 300.0, loads=mb["loads"], nonbonded=member_nonbonded(mb["settings"]), seed=1)
    # a hairpin in height: nodes 100..119 run back down to node 80's height, 3 nm to the side, the rest follows
    z = e.pos[:, 2].copy()
    e.pos[100:120, 2] = z[100] - (z[100:120] - z[100])
    e.pos[100:120, 0] += 3.0
    e.pos[120:, 2] = z[120:] - 2.0 * (z[120] - z[100])
    e._setup_caches()
    w = e.tail_torque_weights()
    assert w[:70].all() and w[150:].all() and not w[80:140].any()
    prof = e.tail_torque_z(profile=True)
    keep = np.isfinite(prof) & (w > 0)
    assert e.tail_torque_z(weighted=True) == pytest.approx(np.mean(prof[keep]), rel=1e-12)
    assert e.tail_torque_z() == pytest.approx(np.nanmean(prof), rel=1e-12)
    rng = np.random.default_rng(3)
    for k in (5, 60, 150):
        a = rng.uniform(-np.pi, np.pi)
        R = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
        c = e.pos[k + 1].copy()
        e.pos[k + 1:] = (e.pos[k + 1:] - c) @ R.T + c
        e.frm[k + 1:] = np.einsum("ab,kbc->kac", R, e.frm[k + 1:])
        assert np.array_equal(e.tail_torque_weights(), w)


def test_tail_torque_estimates_the_clamp_torque():
    """Tweezers chain (60 bp, 2 pN, 0.5 turn, walls, non-bonded terms): the tail-torque estimator and the clamp's own
    torque have the same mean within 3 combined calibrated errors, and the estimator's error is several times
    smaller for the same run."""
    from dnarod.analysis.statistics import combined_z
    from dnarod.physics.nonbonded import member_nonbonded
    from dnarod.workflows.protocols.tweezers import build_member

    mb = build_member(dict(n_bp=60, force_pN=2.0, turns=0.5))
    e = MCEngine(mb["model"], 300.0, loads=mb["loads"], nonbonded=member_nonbonded(mb["settings"]), seed=5)
    e.advance(300)
    tc, tt = np.empty(12000), np.empty(12000)
    for i in range(len(tc)):
        e.advance(1)
        tc[i] = e.clamp_torque_z() / PN
        tt[i] = e.tail_torque_z() / PN
    a, b = mean_and_error(tc), mean_and_error(tt)
    assert a.flag is None and b.flag is None
    assert abs(combined_z(a, b)) < 3.0, (a, b)
    assert b.error < 0.5 * a.error, (a, b)
    assert b.mean > 5.0  # half a turn on 60 bp: a torque far from zero


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


def test_ring_keeps_linking_number():
    """A supercoiled 300-bp ring with excluded volume: Lk = Tw + Wr stays the integer it started with over a
    run in which the writhe moves by more than a turn."""
    from dnarod.physics.writhe import twist, writhe

    ring = uniform_ring(300, 26)  # relaxed Lk0 ~ 28.6: sigma ~ -0.09, writhes
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


def test_turn_ladder_swaps_keep_energies_and_topology():
    """A ladder of three rungs (40 bp, 2 pN, turns 0.1, 0.2, 0.3): swaps are accepted, every rung's running energy
    still equals its recomputed energy, and the twist ramp of the swap map is inverted by its opposite."""
    from dnarod.engines.mc.ladder import TurnLadder, twist_ramp
    from dnarod.physics.nonbonded import member_nonbonded
    from dnarod.workflows.protocols.tweezers import build_member

    turns = [0.1, 0.2, 0.3]
    engines = []
    for i, t in enumerate(turns):
        mb = build_member(dict(n_bp=40, force_pN=2.0, turns=t))  # one chain, its clamp target turned by t
        engines.append(MCEngine(mb["model"], 300.0, loads=mb["loads"], nonbonded=member_nonbonded(mb["settings"]),
                                seed=10 + i))
    lad = TurnLadder(engines, turns, seed=1)
    for _ in range(40):
        lad.advance(5)
        lad.exchange()
    assert lad.accepts.sum() > 0 and sorted(lad.labels) == [0, 1, 2]
    for e in engines:
        E = e.energies()
        assert e.running[0] == pytest.approx(E["elastic"], rel=1e-9)
        assert e.running[2] == pytest.approx(E["external"], rel=1e-9, abs=1e-8)
    f = engines[0].frm
    assert np.allclose(twist_ramp(twist_ramp(f, 0.37), -0.37), f, atol=1e-12)
