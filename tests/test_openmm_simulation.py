"""OpenMM engine: time step, NVE, Langevin, checkpoints, blow-up reports, loads, export, CLI."""
import io

import numpy as np
import pytest
from click.testing import CliRunner
from openmm import app, unit

from dnarod.core.errors import ParameterError, SimulationError
from dnarod.core.forcefield import load_forcefield
from dnarod.physics.loads import Clamp, PullingForce, RotationClamp, Torque, Trap
from dnarod.engines.openmm.particles import particle_forces_to_loads
from dnarod.engines.openmm.simulation import RodSimulation
from dnarod.physics.modes import omega_max
from dnarod.run import load_energies, simulate_engine
from dnarod.core.units import kT
from dnarod.core.trajectory import load_trajectory


@pytest.fixture(scope="module")
def ff():
    return load_forcefield("dna-default")


@pytest.fixture(scope="module")
def dna40(ff):
    return ff.model_from_sequence("ACGTTGCAAC" * 4)


def test_default_dt_and_stability_limit(dna40):
    sim = RodSimulation.create(dna40, integrator="verlet", temperature=0, nonbonded=False, seed=1)
    assert sim.dt == pytest.approx(0.4 / sim.omega_max, rel=1e-12)
    # design A4 analytic bound for the optical bend/shear branch of the uniform rod bounds omega_max
    K, th = dna40.params.stiffness[0], 2 * np.arctan(dna40.params.Omega0[0, 2] * dna40.ds / 2)
    m, J, ds = dna40.mass[0], dna40.inertia[0], dna40.ds
    bound = np.sqrt(4 * K[3, 3] / (m * ds) + (4 * K[0, 0] / np.cos(th / 2) ** 2 / ds + ds * K[3, 3]) / J[0])
    assert 0.5 * bound < sim.omega_max <= bound * (1 + 1e-6)
    with pytest.raises(ParameterError, match="above the stability limit"):
        RodSimulation.create(dna40, integrator="verlet", dt=2.0 / sim.omega_max, nonbonded=False)


def test_nve_conserves_energy(dna40, tmp_path):
    sim = RodSimulation.create(dna40, integrator="verlet", temperature=300, nonbonded=True, seed=2)
    simulate_engine(sim, 3000, tmp_path, frame_interval=100, energy_interval=10, progress=False)
    e = load_energies(tmp_path / "energies.csv")
    kt = kT(300)
    total = e["total_kJ_mol"]
    # bounded O(dt^2) fluctuation, small against the kinetic fluctuation, and no drift
    assert total.std() < 0.1 * e["kinetic_kJ_mol"].std()
    assert np.abs(total - total[0]).max() < 2.0 * kt
    slope = np.polyfit(e["time_ps"], total, 1)[0] * 1000 / kt / dna40.n_nodes  # kT per ns per node
    assert abs(slope) < 0.05


def haar_gaussian_ratio(m, T, n=400000, seed=0):
    """Expected ``var(Omega_i) / (kT K_eff^-1 / ds)_ii`` of one step: the exact step density is the
    Gaussian in the strains times the Haar density of the Cayley chart, ``(1 + |w|^2/4)^-2``
    (independent steps for an open chain); importance sampling, error ~0.3%."""
    K, ds, kt = m.params.stiffness[0], m.ds, kT(T)
    A, B, C = K[:3, :3], K[:3, 3:], K[3:, 3:]
    cov = np.linalg.inv(A - B @ np.linalg.inv(C) @ B.T) * kt / ds
    Om = np.random.default_rng(seed).multivariate_normal(m.params.Omega0[0], cov, size=n)
    wt = (1 + np.sum((Om * ds) ** 2, axis=1) / 4) ** -2
    mu = (wt[:, None] * Om).sum(0) / wt.sum()
    return (wt[:, None] * (Om - mu) ** 2).sum(0) / wt.sum() / np.diag(cov)


def _langevin_check(m, tmp_path, n_steps, omega_dt, seed, strain_tol, elastic="fast"):
    """Kinetic temperature (4 sigma from block averages plus the integrator's bias allowance) and
    the bend/twist strain variances against the exact (Haar-weighted) step density.

    Short chains: the slowest bending modes of a free chain relax in ~gamma/omega_1^2, which is
    tens of ns at 100 nodes with gamma = 1/ps (a 100-node run read bend variances 3% low after
    5 ns for that reason) but ~0.1 ns at 20 nodes.
    """
    sim = RodSimulation.create(m, temperature=300, friction=1.0, nonbonded=False, seed=seed, dt=omega_dt / omega_max(m),
                        elastic=elastic)
    simulate_engine(sim, n_steps, tmp_path, frame_interval=20, energy_interval=20, checkpoint_interval=0,
                    progress=False)
    T = load_energies(tmp_path / "energies.csv")["temperature_K"][50:]
    blocks = T[: len(T) // 10 * 10].reshape(10, -1).mean(axis=1)
    sigma = blocks.std(ddof=1) / np.sqrt(10)
    # LangevinMiddle's velocities are leapfrog half-step velocities, whose kinetic temperature is
    # biased high by O((omega dt)^2) (and grows with the friction): measured +1.1% at omega dt = 0.2
    # and +2.4% at 0.4 with friction 1/ps (100 nodes, 3 ns), +2.4% at 0.2 with 2/ps; allowance
    # 1.5% (omega dt / 0.2)^2 at friction 1/ps.
    bias = 300 * 0.015 * (omega_dt / 0.2) ** 2
    assert abs(T.mean() - 300) < 4 * sigma + bias, (T.mean(), sigma, bias)
    tr = load_trajectory(tmp_path / "trajectory.dtraj")
    Om = np.concatenate([m.strains(p, f)[0] for p, f in zip(tr.positions[50:], tr.frames[50:])])
    K = m.params.stiffness[0]
    K_eff = K[:3, :3] - K[:3, 3:] @ np.linalg.inv(K[3:, 3:]) @ K[3:, :3]
    ratio = Om.var(axis=0) / np.diag(np.linalg.inv(K_eff) * kT(300) / m.ds)
    assert np.all(np.abs(ratio - haar_gaussian_ratio(m, 300)) < strain_tol), ratio


def test_langevin_temperature_and_strain_fluctuations(ff, tmp_path):
    _langevin_check(ff.model_from_sequence("ACGT" * 5), tmp_path, 20000, 0.2, 5, 0.05)


@pytest.mark.slow
def test_langevin_long(ff, tmp_path):
    _langevin_check(ff.model_from_sequence("ACGT" * 8), tmp_path, 200000, 0.2, 6, 0.015)


@pytest.mark.parametrize("platform", ["Reference", "CPU"])
def test_checkpoint_resume_gives_the_same_frames(ff, tmp_path, platform):
    import shutil

    m = ff.model_from_sequence("ACGTTGCAAC" * 2)
    kw = dict(temperature=300, nonbonded=True, seed=11, platform=platform, dt=0.08)
    rk = dict(frame_interval=5, checkpoint_interval=20, progress=False, velocities=True)
    simulate_engine(RodSimulation.create(m, **kw), 60, tmp_path / "full", **rk)
    # interrupted run: checkpoint at 40, frames written up to 50, then a "crash" before the next checkpoint
    simulate_engine(RodSimulation.create(m, **kw), 40, tmp_path / "part", **rk)
    shutil.copy(tmp_path / "part" / "checkpoint.npz", tmp_path / "at40.npz")
    simulate_engine(RodSimulation.create(m, **kw), 50, tmp_path / "part", resume=True, **rk)
    shutil.copy(tmp_path / "at40.npz", tmp_path / "part" / "checkpoint.npz")
    assert load_trajectory(tmp_path / "part" / "trajectory.dtraj").step[-1] == 50
    simulate_engine(RodSimulation.create(m, **kw), 60, tmp_path / "part", resume=True, **rk)
    a = load_trajectory(tmp_path / "full" / "trajectory.dtraj")
    b = load_trajectory(tmp_path / "part" / "trajectory.dtraj")
    assert list(b.step) == list(range(0, 61, 5))
    assert np.array_equal(a.positions, b.positions) and np.array_equal(a.frames, b.frames)
    assert np.array_equal(a.angular_velocities, b.angular_velocities)
    ea, eb = load_energies(tmp_path / "full" / "energies.csv"), load_energies(tmp_path / "part" / "energies.csv")
    assert np.array_equal(ea["step"], eb["step"]) and np.array_equal(ea["total_kJ_mol"], eb["total_kJ_mol"])


def test_checkpoint_from_another_model_is_rejected(ff, tmp_path):
    a = RodSimulation.create(ff.model_from_sequence("ACGTACGTAC"), nonbonded=False, seed=1, dt=0.05)
    simulate_engine(a, 10, tmp_path, frame_interval=5, checkpoint_interval=10, progress=False)
    b = RodSimulation.create(ff.model_from_sequence("ACGTACGTACG"), nonbonded=False, seed=1, dt=0.05)
    with pytest.raises(ParameterError, match="another model"):
        simulate_engine(b, 20, tmp_path, frame_interval=5, resume=True, progress=False)
    assert load_trajectory(tmp_path / "trajectory.dtraj").n_frames == 3  # untouched


def test_blow_up_names_step_node_and_term(ff, tmp_path):
    m = ff.model_from_sequence("ACGTACGTACGTACGTACGT")
    huge = PullingForce(-1, [0.0, 0.0, 5e6])
    sim = RodSimulation.create(m, integrator="verlet", temperature=0, nonbonded=False, loads=[huge], dt=0.05)
    with pytest.raises(SimulationError) as err:
        simulate_engine(sim, 400, tmp_path, frame_interval=2, progress=False)
    e = err.value
    assert e.step is not None and 0 < e.step <= 400 and e.node in (m.n_nodes - 1, m.n_nodes - 2)
    assert e.term in ("elastic", "external") and f"step {e.step}" in str(e)
    tr = load_trajectory(tmp_path / "trajectory.dtraj")  # what was written is intact
    assert tr.n_frames >= 1 and np.isfinite(tr.positions).all() and tr.step[-1] < e.step
    assert tr.step[-1] == (e.step - 1) // 2 * 2  # every report before the bad step, batched or not


def test_bad_inputs(dna40):
    with pytest.raises(ParameterError, match="platform 'CUDA' is not installed"):
        RodSimulation.create(dna40, platform="CUDA", nonbonded=False)
    with pytest.raises(ParameterError, match=r"expected shape \(3,\)"):
        PullingForce(0, [1.0, 2.0])
    with pytest.raises(ParameterError, match="not compatible"):
        PullingForce(0, [0, 0, 1] * unit.nanometer)
    with pytest.raises(ParameterError, match="not compatible"):
        Torque(0, [0, 0, 1] * unit.piconewton)
    with pytest.raises(ParameterError, match="node 99 does not exist"):
        RodSimulation.create(dna40, nonbonded=False, loads=[Trap(99, 10.0)])
    assert PullingForce(0, [0, 0, 1] * unit.piconewton).force[2] == pytest.approx(0.602214076, rel=1e-9)


def test_static_loads(dna40):
    """Each load's energy and node force/torque against its closed form (Reference platform)."""
    m = dna40
    F = np.array([1.0, -2.0, 3.0])
    tau = np.array([0.5, 0.2, -4.0])
    theta = 0.3
    loads = [PullingForce(-1, F), Torque(5, tau), Trap(10, 40.0, centre=m.positions[10] + [0.1, 0, 0]),
             RotationClamp(20, 25.0), Clamp(0)]
    sim = RodSimulation.create(m, integrator="verlet", temperature=0, platform="Reference", nonbonded=False,
                               loads=loads,
                        dt=0.05)
    st = sim.context.getState(getForces=True, getPositions=True, getEnergy=True, groups={3})
    f_node, t_node = particle_forces_to_loads(st.getPositions(asNumpy=True)._value, st.getForces(asNumpy=True)._value)
    assert np.allclose(f_node[-1], F, atol=1e-12) and np.allclose(f_node[5], 0, atol=1e-12)
    assert np.allclose(t_node[5], tau, atol=1e-12)
    assert np.allclose(f_node[10], [4.0, 0, 0], atol=1e-10)
    E0 = st.getPotentialEnergy()._value
    assert E0 == pytest.approx(-F @ m.positions[-1] + 0.5 * 40.0 * 0.01, rel=1e-12)
    sim.set_clamp_rotation(theta)
    E1 = sim.context.getState(getEnergy=True, groups={3}).getPotentialEnergy()._value
    assert E1 - E0 == pytest.approx(25.0 * (1 - np.cos(theta)), rel=1e-10)
    # clamped node 0 has no mass: it does not move in a thermal run
    sim.thermalize(300, seed=1)
    sim.advance(20)
    c, f = sim.node_pose()
    assert np.array_equal(c[0], m.positions[0]) or np.allclose(c[0], m.positions[0], atol=1e-12)


def test_torque_and_rotation_clamp_twist_the_end(ff):
    """A constant torque on a free end: the end turns by tau L / C_eff about the axis (statics)."""
    m = ff.model_from_sequence("A" * 12)
    axis = np.array([0.0, 0.0, 1.0])
    tau = 20.0  # kJ/mol
    sim = RodSimulation.create(m, integrator="verlet", temperature=0, platform="Reference", nonbonded=False,
                        loads=[Clamp(0), Torque(-1, tau * axis)], dt=0.05)
    sim.minimize(tolerance=1e-6)
    c, f = sim.node_pose()
    R = f[-1] @ m.frames[-1].T
    angle = np.arctan2(R[1, 0] - R[0, 1], R[0, 0] + R[1, 1])
    K = m.params.stiffness[0]
    th = 2 * np.arctan(m.params.Omega0[0, 2] * m.ds / 2)
    # twist-stretch coupled, shear/bend decoupled: effective twist stiffness A3 - B33^2/C3 in
    # Cayley coordinates, converted to angle by the chart's Jacobian (dw/dtheta = sec^2(theta/2)).
    # Cayley chart at finite deformation: solve the per-step balance exactly.
    from scipy.optimize import brentq
    A3, B, C3 = K[2, 2], K[2, 5], K[5, 5]
    A3eff = A3 - B**2 / C3

    def moment(dth):
        w = 2 * np.tan((th + dth) / 2)
        # body moment M3 = A3eff (w - w0)/ds balances tau via mu = M (1 + w^2/4) (design A2, w || e3)
        return A3eff * (w - 2 * np.tan(th / 2)) / m.ds * (1 + w**2 / 4) - tau

    per_step = brentq(moment, -0.5, 0.5)
    assert angle == pytest.approx(per_step * m.n_steps, rel=1e-3)


def test_export_opens_in_mdtraj_and_mdanalysis(dna40, tmp_path):
    import MDAnalysis as mda
    import mdtraj as md

    from dnarod.structure.export import export_trajectory
    from dnarod.structure.cg_topology import frames_from_beads

    sim = RodSimulation.create(dna40, temperature=300, nonbonded=False, seed=3)
    simulate_engine(sim, 40, tmp_path, frame_interval=10, progress=False, velocities=True)
    tr = load_trajectory(tmp_path / "trajectory.dtraj")
    c, f, v, w = sim.node_state()
    f32 = lambda a: a.astype(np.float32).astype(float)  # noqa: E731 - the .dtraj stores float32
    assert np.array_equal(tr.positions[-1], f32(c)) and np.array_equal(tr.frames[-1], f32(f))
    assert np.array_equal(tr.angular_velocities[-1], f32(w))
    export_trajectory(tr, tmp_path / "t.pdb", tmp_path / "t.dcd", sequence=dna40.sequence)
    t = md.load(str(tmp_path / "t.dcd"), top=str(tmp_path / "t.pdb"))
    assert t.n_frames == 5 and t.n_residues == 40 and t.n_atoms == 120
    assert [r.name for r in t.topology.residues][:4] == ["DA", "DC", "DG", "DT"]  # strand-I base of each pair
    c2, f2 = frames_from_beads(t.xyz)
    assert np.abs(f2 - tr.frames).max() < 1e-5 and np.abs(c2 - tr.positions).max() < 1e-4
    u = mda.Universe(str(tmp_path / "t.pdb"), str(tmp_path / "t.dcd"))
    assert len(u.trajectory) == 5 and u.atoms.n_atoms == 120 and list(u.residues.resnames[:2]) == ["DA", "DC"]
    u.trajectory[-1]
    assert np.allclose(u.atoms.positions[0::3] / 10, tr.positions[-1], atol=1e-4)


def test_cli_simulate_and_bad_input(tmp_path):
    from dnarod.cli.main import main

    r = CliRunner().invoke(main, ["simulate", "ACGTACGTACGTACGTACGT", "--time", "0.01", "-o", str(tmp_path / "o"),
                                  "--no-progress", "--pull", "5", "--clamp-first", "--seed", "1"])
    assert r.exit_code == 0, r.output
    assert ("elastic path: fast" in r.output or "elastic path: plugin" in r.output) and "ns/day" in r.output
    for name in ("trajectory.dtraj", "energies.csv", "final_model.npz", "trajectory.pdb", "trajectory.dcd"):
        assert (tmp_path / "o" / name).exists()
    r = CliRunner().invoke(main, ["simulate", "ACGTACGTAC", "--dt", "5", "-o", str(tmp_path / "b"), "--no-progress"])
    assert r.exit_code == 2 and "stability limit" in r.output


def test_energy_terms_equal_force_group_evaluations(ff):
    """The per-term split read from the fast-path callbacks equals separate force-group evaluations."""
    from dnarod.engines.openmm.forces import GROUPS

    from dnarod.physics.nonbonded import NonbondedSettings, nonbonded_reference

    m = ff.model_from_sequence("ACGT" * 15)
    nb = NonbondedSettings(n_exclude=3, diameter=1.1)  # short exclusion: Debye-Hueckel acts along the chain
    sim = RodSimulation.create(m, temperature=300, seed=4, nonbonded=nb, loads=[Trap(3, 10.0, [0, 0, -1.0])],
                               elastic="fast")
    sim.advance(5)
    e = sim.energies()
    assert e["nonbonded"] > 0 and e["external"] > 0 and e["elastic"] > 0
    direct = {name: sim.context.getState(getEnergy=True, groups={g}).getPotentialEnergy()._value
              for name, g in GROUPS.items()}
    # the fast path evaluates the non-local terms inside the elastic callback (group "elastic")
    assert direct["nonbonded"] == 0.0
    assert e["elastic"] + e["nonbonded"] == pytest.approx(direct["elastic"], rel=1e-6, abs=1e-6)
    assert e["external"] == pytest.approx(direct["external"], rel=1e-6, abs=1e-6)
    c, _ = sim.node_pose()
    ew, ed, _ = nonbonded_reference(c, False, sim.rs.nonbonded)
    assert e["nonbonded"] == pytest.approx(ew + ed, rel=1e-9)


def test_fast_and_portable_paths_give_the_same_dynamics(ff):
    """Verlet on the Reference platform from the same state: the constrained trajectories agree
    (only the constraint-direction components of the particle forces differ between the paths).

    The triangles stay rigid only to ~2e-8 (measured; the Reference platform's constraint
    accuracy did not improve with a tighter tolerance), and the two paths treat that residual
    deformation differently, so after 20 steps they agree to ~4e-8 (measured), not to round-off.
    """
    m = ff.model_from_sequence("ACGTTGCA")
    rng = np.random.default_rng(8)
    v = rng.normal(size=(m.n_nodes, 3)) * 0.5
    w = rng.normal(size=(m.n_nodes, 3)) * 1.0
    out = []
    for path in ("fast", "portable"):
        sim = RodSimulation.create(m, integrator="verlet", temperature=0, platform="Reference", nonbonded=False,
                            elastic=path, dt=0.02, initial_velocities=(v, w))
        assert sim.rs.elastic == path
        sim.advance(20)
        out.append(sim.node_state())
    for a, b in zip(*out):
        assert np.abs(a - b).max() < 2e-7 * max(1.0, np.abs(a).max())
    names = [r.name for r in sim.rs.topology.residues()]
    assert names == ["AT", "CG", "GC", "TA", "TA", "GC", "CG", "AT"]


def test_screw_closed_portable_path_carries_the_image_and_matches_the_fast_path(ff, tmp_path):
    """A chain closed by a screw on the portable path has node 0's image as three massless particles after the
    nodes' particles: energies by term, Verlet dynamics (with the non-bonded callback and a torque, both seeing
    only the nodes' particles) and a checkpoint round trip agree with the fast path, which has no image."""
    m = ff.model_from_sequence("ACGTTGCAGTCATGCAGGTC", circular=True)
    n = m.n_nodes
    rng = np.random.default_rng(4)
    v = rng.normal(size=(n, 3)) * 0.5
    w = rng.normal(size=(n, 3)) * 1.0
    out = {}
    for path in ("fast", "portable"):
        sim = RodSimulation.create(m, integrator="verlet", temperature=0, platform="Reference", nonbonded=True, dt=0.02,
                            loads=[Torque(3, [0.0, 0.0, 5.0])], elastic=path, initial_velocities=(v, w))
        e0 = sim.energies()
        sim.advance(20)
        out[path] = (sim, e0, sim.node_state(), sim.energies())
    fast, portable = out["fast"][0], out["portable"][0]
    assert fast.rs.system.getNumParticles() == 3 * n and fast.rs.image is None
    assert portable.rs.system.getNumParticles() == 3 * n + 3 and portable.rs.image == 3 * n
    # one topology atom per particle (OpenMM's reporters need it): the image is a last residue IMG
    for sim in (fast, portable):
        top = sim.rs.topology
        assert top.getNumAtoms() == sim.rs.system.getNumParticles()
        pos = sim.context.getState(getPositions=True).getPositions()
        buf = io.StringIO()
        app.PDBFile.writeFile(top, pos, buf)  # raises if the counts differ
        assert buf.getvalue().count("HETATM") + buf.getvalue().count("ATOM  ") == top.getNumAtoms()
    assert [r.name for r in portable.rs.topology.residues()][-1] == "IMG"
    for k in (1, 3):
        for term in ("elastic", "nonbonded", "external", "potential", "kinetic"):
            a, b = out["fast"][k][term], out["portable"][k][term]
            assert b == pytest.approx(a, rel=1e-7, abs=1e-9 * max(1.0, abs(out["fast"][k]["potential"])))
    assert out["fast"][3]["elastic"] > 1.0  # the chain has moved off its rest shape
    for a, b in zip(out["fast"][2], out["portable"][2]):
        assert np.abs(a - b).max() < 2e-7 * max(1.0, np.abs(a).max())
    portable.save_checkpoint(tmp_path / "chk.npz")
    portable.advance(10)
    first = portable.node_state()
    portable.load_checkpoint(tmp_path / "chk.npz")
    portable.advance(10)
    for a, b in zip(first, portable.node_state()):
        assert np.array_equal(a, b)


@pytest.mark.slow
def test_nve_long_drift(ff, tmp_path):
    """5 ns NVE at the default step: drift below 1e-3 kT per node per ns (issue 7 prototype criterion)."""
    m = ff.model_from_sequence("ACGT" * 25)
    sim = RodSimulation.create(m, integrator="verlet", temperature=300, nonbonded=False, seed=9)
    n = int(5000 / sim.dt)
    simulate_engine(sim, n, tmp_path, frame_interval=1000, energy_interval=50, checkpoint_interval=0, progress=False)
    e = load_energies(tmp_path / "energies.csv")
    slope = np.polyfit(e["time_ps"], e["total_kJ_mol"], 1)[0] * 1000 / kT(300) / m.n_nodes
    assert abs(slope) < 1e-3


def test_new_run_does_not_overwrite_an_earlier_one(ff, tmp_path):
    m = ff.model_from_sequence("ACGTACGTAC")
    simulate_engine(RodSimulation.create(m, nonbonded=False, seed=1, dt=0.05), 10, tmp_path, frame_interval=5,
                    progress=False)
    before = (tmp_path / "trajectory.dtraj").read_bytes()
    with pytest.raises(ParameterError, match="already exists"):
        simulate_engine(RodSimulation.create(m, nonbonded=False, seed=2, dt=0.05), 10, tmp_path, frame_interval=5,
                        progress=False)
    assert (tmp_path / "trajectory.dtraj").read_bytes() == before
    simulate_engine(RodSimulation.create(m, nonbonded=False, seed=2, dt=0.05), 10, tmp_path, frame_interval=5,
                    progress=False,
                                                           overwrite=True)
    assert (tmp_path / "trajectory.dtraj").read_bytes() != before


def test_nve_converges_to_the_exact_lax_reference(ff):
    """Same mechanical system as the Lax-form engine: OpenMM Verlet (Reference) from the same
    initial centre velocities and body angular velocities converges at order 2 in dt to the
    exact strain-space DOP853 solution of ``dnarod.engines.lax`` (inertia J = m l^2 (1/2, 1/2, 1))."""
    from dnarod.run.lax import simulate_exact

    m = ff.model_from_sequence("ACGTTGCAAC")
    rng = np.random.default_rng(3)
    v, w = rng.normal(size=(10, 3)) * 0.3, rng.normal(size=(10, 3)) * 0.5
    ref = simulate_exact(m, 2.0, velocities=v, angular_velocities=w, n_frames=3).trajectory
    errs = []
    for dt in (0.01, 0.005):
        sim = RodSimulation.create(m, integrator="verlet", temperature=0, platform="Reference", nonbonded=False, dt=dt,
                            initial_velocities=(v, w))
        sim.advance(int(round(2.0 / dt)))
        c, f, vv, ww = sim.node_state()
        errs.append((np.abs(c - ref.positions[-1]).max(), np.abs(f - ref.frames[-1]).max(),
                     np.abs(vv - ref.velocities[-1]).max(), np.abs(ww - ref.angular_velocities[-1]).max()))
    assert errs[1][0] < 2e-5 and errs[1][1] < 5e-5 and errs[1][3] < 1e-3
    for a, b in zip(*errs):
        assert 3.5 < a / b < 4.5  # second order


def test_blow_up_located_at_the_same_step_over_short_advances(ff):
    """The compiled path keeps its rollback state over several short advances (a run loop's reports): a
    blow-up is replayed from there and named at the same first bad step as when every step is checked."""
    m = ff.model_from_sequence("ACGTACGTACGTACGTACGT")
    strong = PullingForce(-1, [0.0, 0.0, 2e3])  # kJ/mol/nm: blows up after some hundred steps (NVE: deterministic)
    found = []
    for chunk in (1, 7):
        sim = RodSimulation.create(m, integrator="verlet", temperature=0, nonbonded=False, loads=[strong], dt=0.05)
        with pytest.raises(SimulationError) as err:
            for _ in range(3000 // chunk):
                sim.advance(chunk)
        found.append((err.value.step, err.value.node, err.value.term))
    assert found[0][0] > 100 and found[0][0] % 7 != 0 and found[0] == found[1]
