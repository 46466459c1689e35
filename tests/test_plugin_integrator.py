"""The compiled rigid-body integrator (dnarod.engines.openmm.plugin.rigid_body_integrator).

References: the Lax-form engine's splitting integrator (the same scheme, numpy/numba) and the exact
strain-space solution (DOP853) for NVE; the Maxwell-Boltzmann distribution for the thermostat; OpenMM's own
checkpoints for bit-for-bit resume. Skipped (with the reason) when the plugin is not usable here, except
under CI=true, where that is a failure.
"""
import os

import numpy as np
import openmm
import pytest

from dnarod.core.forcefield import load_forcefield
from dnarod.engines.openmm import particles as P
from dnarod.engines.openmm import plugin
from dnarod.core.units import kT as kT_of


@pytest.fixture(scope="module")
def mod():
    st = plugin.status()
    if st.available:
        return plugin.module()
    if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
        pytest.fail(f"CI: the compiled plugin must be usable here: {st.reason}")
    pytest.skip(f"compiled plugin not usable: {st.reason}")


@pytest.fixture(scope="module")
def dodecamer():
    from dnarod.validate.engines import default_model

    return default_model()


def nve_run(model, v, w, dt, t_report):
    from dnarod.engines.openmm.simulation import RodSimulation

    sim = RodSimulation.create(model, integrator="verlet", temperature=0.0, dt=dt, platform="Reference",
                               elastic="plugin",
                        nonbonded=False, initial_velocities=(v, w), seed=0)
    assert sim.integrator.usesFusedElasticForce()
    out = []
    for t in t_report:
        s = int(round(t / dt))
        if s > sim.step:
            sim.advance(s - sim.step)
        out.append(sim.node_state())
    return out


def test_nve_equals_lax_splitting_and_converges_at_second_order(mod, dodecamer):
    from dnarod.engines.lax import RigidState, SplittingIntegrator, integrate_exact
    from dnarod.engines.lax.splitting import maxwell_state

    model = dodecamer
    v, w = maxwell_state(model, 300.0, seed=1).velocities(model.mass, model.inertia)
    t_end = 0.4
    dts = [0.02, 0.01, 0.005]
    ex = integrate_exact(model, t_end, v, w, rtol=1e-12, atol=1e-12, t_eval=[t_end])
    errs = []
    for dt in dts:
        c, f, vv, ww = nve_run(model, v, w, dt, [t_end])[-1]
        lax = SplittingIntegrator(model, dt, state=RigidState.from_model(model, v, w), check_stability=False)
        lax.step(int(round(t_end / dt)))
        lv, lw = lax.state.velocities(model.mass, model.inertia)
        # The same scheme as the Lax-form splitting: equal to roundoff, positions, frames and on-step velocities.
        assert np.max(np.abs(c - lax.state.positions)) < 1e-11
        assert np.max(np.abs(f - lax.state.frames)) < 1e-11
        assert np.max(np.abs(vv - lv)) < 1e-9 and np.max(np.abs(ww - lw)) < 1e-9
        errs.append(np.max(np.abs(c - ex.trajectory.positions[-1])))
    order = np.polyfit(np.log(dts), np.log(errs), 1)[0]
    assert 1.9 < order < 2.1, (errs, order)


def free_nodes_context(mod, n, temperature, friction, dt, seed, platform="CPU"):
    """n nodes (650 amu, l = 0.6 nm) with no forces, far apart."""
    system = openmm.System()
    for _ in range(3 * n):
        system.addParticle(650.0 / 3)
    radius = np.full(n, 0.6)
    integ = plugin.rigid_body_integrator(radius, dt, temperature, friction, seed)
    ctx = openmm.Context(system, integ, openmm.Platform.getPlatformByName(platform))
    rng = np.random.default_rng(seed)
    centres = 10.0 * rng.normal(size=(n, 3))
    from scipy.spatial.transform import Rotation

    frames = Rotation.random(n, random_state=seed).as_matrix()
    ctx.setPositions(P.particle_positions(centres, frames, radius))
    return ctx, integ


def test_thermostat_samples_maxwell_boltzmann(mod):
    """Free rigid nodes under the Langevin thermostat: each translational and body-rotational velocity component
    is normal with variance kT/m and kT/J_a (second and fourth moments)."""
    n, T = 400, 300.0
    ctx, integ = free_nodes_context(mod, n, T, friction=5.0, dt=0.1, seed=3)
    integ.step(50)
    kt = kT_of(T)
    J = 650.0 * 0.36 * np.array([0.5, 0.5, 1.0])
    vs, ws = [], []
    for _ in range(40):
        integ.step(5)
        st = ctx.getState(getPositions=True, getVelocities=True)
        v, w = P.node_velocities(st.getPositions(asNumpy=True)._value, st.getVelocities(asNumpy=True)._value)
        vs.append(v * np.sqrt(650.0 / kt))
        ws.append(w * np.sqrt(J / kt))
    z = np.concatenate([np.concatenate(vs).ravel(), np.concatenate(ws).ravel()])
    # 96,000 draws, correlated over ~1 sample (friction 5/ps, 0.5 ps apart): standard errors ~0.005 and ~0.02.
    assert abs(np.mean(z)) < 0.03
    assert abs(np.var(z) - 1.0) < 0.03
    assert abs(np.mean(z**4) / np.var(z) ** 2 - 3.0) < 0.1
    # Rigid triangles: the kinetic energy OpenMM reports is the nodes' 3 kT on average.
    ke = ctx.getState(getEnergy=True).getKineticEnergy()._value
    assert abs(ke / (n * 3 * kt) - 1.0) < 0.15


def test_checkpoint_resume_is_bit_for_bit(mod):
    from dnarod.engines.openmm.simulation import RodSimulation

    model = load_forcefield("dna-default").model_from_sequence("ACGTACGTTGCAACGTACGT")
    sim = RodSimulation.create(model, temperature=300.0, elastic="plugin", nonbonded=True, seed=11, platform="CPU")
    sim.advance(30)
    blob = sim.context.createCheckpoint()
    state30 = sim.context.getState(getPositions=True, getVelocities=True, getParameters=True)
    sim.advance(40)
    a = sim.context.getState(getPositions=True, getVelocities=True)
    sim.context.loadCheckpoint(blob)
    sim.invalidate()
    sim.advance(40)
    b = sim.context.getState(getPositions=True, getVelocities=True)
    assert np.array_equal(a.getPositions(asNumpy=True)._value, b.getPositions(asNumpy=True)._value)
    assert np.array_equal(a.getVelocities(asNumpy=True)._value, b.getVelocities(asNumpy=True)._value)
    # The same positions and velocities without the integrator's random-number state (an OpenMM State holds
    # none) continue differently: the checkpoint really carries that state.
    sim.context.setState(state30)
    sim.invalidate()
    sim.advance(40)
    c = sim.context.getState(getPositions=True)
    assert not np.array_equal(a.getPositions(asNumpy=True)._value, c.getPositions(asNumpy=True)._value)


def test_triangles_stay_rigid_and_clamped_nodes_stay_put(mod):
    from dnarod.physics.loads import Clamp, PullingForce
    from dnarod.engines.openmm.simulation import RodSimulation

    model = load_forcefield("dna-default").model_from_sequence("ACGTACGTTGCAACGTACGT")
    sim = RodSimulation.create(model, temperature=300.0, elastic="plugin", seed=4, platform="CPU",
                        loads=[Clamp(0), PullingForce(-1, [0.0, 0.0, 5.0])])
    assert sim.integrator.usesFusedElasticForce()
    p0 = sim.context.getState(getPositions=True).getPositions(asNumpy=True)._value.copy()
    sim.advance(200)
    p = sim.context.getState(getPositions=True).getPositions(asNumpy=True)._value
    assert np.array_equal(p[:3], p0[:3])
    side = np.linalg.norm(p.reshape(-1, 3, 3)[:, [0, 1, 2]] - p.reshape(-1, 3, 3)[:, [1, 2, 0]], axis=2)
    assert np.max(np.abs(side - 0.6 * np.sqrt(3))) < 1e-12
    c, _ = sim.node_pose()
    assert c[-1, 2] - c[0, 2] > p0[-3:].mean(0)[2] - p0[:3].mean(0)[2] - 1.0  # pulled, not collapsed


def test_nve_with_loads_and_nonbonded_conserves_energy(mod):
    """Forces OpenMM evaluates (non-bonded PythonForce, an external pull) enter the rigid update correctly: the
    shadow energy is conserved at small dt (drift far below the energy's fluctuation)."""
    from dnarod.physics.loads import PullingForce
    from dnarod.engines.openmm.simulation import RodSimulation

    model = load_forcefield("dna-default").ring(n_nodes=60)
    energies = []
    sim = RodSimulation.create(model, integrator="verlet", temperature=300.0, dt=0.01, elastic="plugin", seed=2,
                        platform="CPU", loads=[PullingForce(5, [0.0, 0.0, 2.0])])
    assert sim.integrator.usesFusedElasticForce() and sim.rs.nonbonded is not None
    for _ in range(40):
        sim.advance(10)
        _, _, v, w = sim.node_state()
        ke = 0.5 * np.sum(model.mass[:, None] * v**2) + 0.5 * np.sum(model.inertia * w**2)
        st = sim.context.getState(getEnergy=True)
        energies.append(st.getPotentialEnergy()._value + ke)
    energies = np.array(energies)
    pe_scale = 3 * model.n_nodes * kT_of(300.0)
    assert np.ptp(energies) < 1e-3 * pe_scale, np.ptp(energies)


def test_node_state_kept_between_calls_matches_particles_and_is_dropped_when_they_change(mod):
    """NVE: one call of 40 steps equals 40 calls of one step bit for bit (the node state is kept between calls);
    after positions and velocities are set from outside, the integrator starts from them, not from its kept
    state."""
    from dnarod.engines.openmm.simulation import RodSimulation

    model = load_forcefield("dna-default").model_from_sequence("ACGTACGTTGCAACGTACGT")
    runs = []
    for chunks in ([40], [1] * 40):
        sim = RodSimulation.create(model, integrator="verlet", temperature=300.0, elastic="plugin", seed=3,
                                   platform="CPU",
                            nonbonded=False)
        for k in chunks:
            sim.integrator.step(k)
        runs.append(sim.context.getState(getPositions=True, getVelocities=True))
    for get in ("getPositions", "getVelocities"):
        assert np.array_equal(getattr(runs[0], get)(asNumpy=True)._value, getattr(runs[1], get)(asNumpy=True)._value)
    s20 = None
    sim = RodSimulation.create(model, integrator="verlet", temperature=300.0, elastic="plugin", seed=3, platform="CPU",
                        nonbonded=False)
    sim.integrator.step(20)
    s20 = sim.context.getState(getPositions=True, getVelocities=True)
    sim.integrator.step(20)
    first = sim.context.getState(getPositions=True).getPositions(asNumpy=True)._value
    sim.context.setState(s20)
    sim.integrator.step(20)
    again = sim.context.getState(getPositions=True).getPositions(asNumpy=True)._value
    assert np.max(np.abs(again - first)) < 1e-9  # restarted from s20 (read back from the particles: roundoff)
    assert np.max(np.abs(again - runs[0].getPositions(asNumpy=True)._value)) < 1e-9
    # Positions alone or velocities alone set after steps (the integrator is told through stateChanged): the next
    # steps start from the particles as set, as a fresh Context given the same particles does.
    p20, v20 = (s20.getPositions(asNumpy=True)._value, s20.getVelocities(asNumpy=True)._value)
    for setter, value in (("setVelocities", 0.5 * v20), ("setPositions", p20)):
        sim = RodSimulation.create(model, integrator="verlet", temperature=300.0, elastic="plugin", seed=3,
                                   platform="CPU", nonbonded=False)
        sim.integrator.step(20)
        sim.integrator.step(3)  # kept node state now differs from s20
        p, v = (p20, sim.context.getState(getVelocities=True).getVelocities(asNumpy=True)._value) \
            if setter == "setPositions" else (sim.context.getState(getPositions=True).getPositions(asNumpy=True)._value,
                                              0.5 * v20)
        getattr(sim.context, setter)(value)
        sim.integrator.step(20)
        got = sim.context.getState(getPositions=True).getPositions(asNumpy=True)._value
        fresh = RodSimulation.create(model, integrator="verlet", temperature=300.0, elastic="plugin", seed=3,
                                     platform="CPU", nonbonded=False)
        fresh.context.setPositions(p)
        fresh.context.setVelocities(v)
        fresh.integrator.step(20)
        want = fresh.context.getState(getPositions=True).getPositions(asNumpy=True)._value
        assert np.max(np.abs(got - want)) < 1e-12, setter
        assert np.max(np.abs(got - again)) > 1e-6, setter  # and not the run that kept its state


def test_langevin_temperature_and_strain_fluctuations_on_plugin(mod, tmp_path):
    """The run layer's Langevin check (kinetic temperature; bend/twist variances against the exact Haar-weighted
    density) on the plugin path, at omega dt = 0.2 over 5 ns (the rigid-body integrator's stored velocities
    are unbiased here: measured 298.9-300.5 K over five seeds)."""
    from test_openmm_simulation import _langevin_check

    model = load_forcefield("dna-default").model_from_sequence("ACGT" * 5)
    _langevin_check(model, tmp_path, 100000, 0.2, 5, 0.05, elastic="plugin")


def test_context_reinitialize_keeps_state_and_continues(mod):
    """Context.reinitialize(preserveState=True) re-binds the integrator: positions and velocities are kept, the
    elastic energy equals dnarod.core.energy at them, and the run continues exactly as without the re-initialisation
    (the checkpoint carries the random-number and node state); a force added before reinitialize is applied."""
    from dnarod.core.energy import energy
    from dnarod.engines.openmm.forces import GROUPS
    from dnarod.engines.openmm.simulation import RodSimulation

    model = load_forcefield("dna-default").model_from_sequence("ACGTACGTTGCAACGTACGT")
    ends = []
    for reinit in (False, True):
        sim = RodSimulation.create(model, temperature=300.0, elastic="plugin", nonbonded=True, seed=7, platform="CPU")
        sim.advance(25)
        if reinit:
            before = sim.context.getState(getPositions=True, getVelocities=True)
            sim.context.reinitialize(preserveState=True)
            sim.invalidate()
            after = sim.context.getState(getPositions=True, getVelocities=True)
            for get in ("getPositions", "getVelocities"):
                assert np.array_equal(getattr(before, get)(asNumpy=True)._value,
                                      getattr(after, get)(asNumpy=True)._value)
            assert sim.integrator.usesFusedElasticForce() and sim.integrator.usesFusedPairForce()
            c, f = sim.node_pose()
            e_ref = energy(c, f, model.params, model.ds, model.closure)
            e_ctx = sim.context.getState(getEnergy=True, groups={GROUPS["elastic"]}).getPotentialEnergy()._value
            assert abs(e_ctx - e_ref) <= 1e-10 * abs(e_ref)
            assert abs(sim.energies()["elastic"] - e_ref) <= 1e-10 * abs(e_ref)
        sim.advance(25)
        ends.append(sim.context.getState(getPositions=True, getVelocities=True))
    for get in ("getPositions", "getVelocities"):
        assert np.array_equal(getattr(ends[0], get)(asNumpy=True)._value, getattr(ends[1], get)(asNumpy=True)._value)
    # A force added to the System afterwards (as the tweezers protocol adds its walls) is evaluated by OpenMM.
    push = openmm.CustomExternalForce("-0.5*x")
    for i in range(3 * model.n_nodes):
        push.addParticle(i, [])
    push.setForceGroup(GROUPS["external"])
    sim.rs.system.addForce(push)
    sim.context.reinitialize(preserveState=True)
    sim.invalidate()
    v0 = sim.node_state()[2][:, 0].mean()
    sim.advance(40)
    assert np.isclose(sim.energies()["external"],
                      sim.context.getState(getEnergy=True, groups={GROUPS["external"]}).getPotentialEnergy()._value,
                      rtol=1e-12, atol=1e-9)
    assert sim.node_state()[2][:, 0].mean() > v0  # pushed along +x (1.5 kJ/mol/nm per node, 40 steps)


@pytest.mark.parametrize("integrator", ["langevin", "verlet"])
def test_node_report_equals_the_openmm_state_path(mod, integrator):
    """The integrator's node report (node state, on-step velocities, energies by term, kinetic energy) equals what
    the OpenMM State and the numpy particle code give at the same state, before the first step (read from the
    particles), after steps (the kept node state) and with a force OpenMM evaluates; asking for reports does not
    change the trajectory."""
    from dnarod.engines.openmm.forces import GROUPS
    from dnarod.physics.loads import PullingForce
    from dnarod.engines.openmm.simulation import RodSimulation

    from dnarod.physics.nonbonded import NonbondedSettings

    # small enough for Debye-Hueckel across the ring: a 5-Debye-length cutoff excludes 12 neighbours each side
    # (the default 12 Debye lengths would exclude all 29)
    model = load_forcefield("dna-default").ring(n_nodes=30)
    for loads in ([], [PullingForce(3, [0.0, 0.0, 5.0])]):
        ends = []
        for report in (True, False):
            sim = RodSimulation.create(model, integrator=integrator, temperature=300.0, elastic="plugin", seed=9,
                                platform="CPU", loads=loads, nonbonded=NonbondedSettings(cutoff_debye=5.0))
            assert sim._reports_in_plugin()
            for k in (0, 7, 1, 12):
                if k:
                    sim.advance(k)
                if not report:
                    continue
                fast, e = sim.node_state(), sim.energies()
                st = sim._full_state()
                ref = sim.node_state(st)
                for a, b, tol in zip(fast, ref, (1e-12, 1e-12, 1e-10, 1e-9)):
                    assert np.max(np.abs(a - b)) <= tol * max(1.0, np.max(np.abs(b)))
                kin = st.getKineticEnergy()._value
                assert abs(e["kinetic"] - kin) <= 1e-10 * kin
                assert abs(e["potential"] - st.getPotentialEnergy()._value) <= 1e-9 * max(1.0, abs(e["potential"]))
                for term in ("elastic", "nonbonded", "external"):
                    ref_e = sim.context.getState(getEnergy=True, groups={GROUPS[term]}).getPotentialEnergy()._value
                    assert abs(e[term] - ref_e) <= 1e-9 * max(1.0, abs(ref_e)), term
                assert e["nonbonded"] != 0.0 and (e["external"] != 0.0) == bool(loads)
            ends.append(sim.context.getState(getPositions=True, getVelocities=True))
        for get in ("getPositions", "getVelocities"):
            assert np.array_equal(getattr(ends[0], get)(asNumpy=True)._value,
                                  getattr(ends[1], get)(asNumpy=True)._value)


def threaded_context(mod, model, threads, friction, seed, chunk=16):
    """A CPU Context of the full model (SMK + node pairs) on the compiled integrator with `threads` threads."""
    from dnarod.engines.openmm.system import build_system

    rs = build_system(model, "CPU", "plugin", True, (), 300.0)
    integ = plugin.rigid_body_integrator(rs.radius, 0.05, 300.0, friction, seed)
    integ.setNodesPerChunk(chunk)
    ctx = openmm.Context(rs.system, integ, openmm.Platform.getPlatformByName("CPU"), {"Threads": str(threads)})
    ctx.setPositions(P.particle_positions(model.positions, model.frames, rs.radius))
    ctx.setVelocitiesToTemperature(300.0, 5)
    return ctx, integ


@pytest.mark.parametrize("circular", [False, True])
def test_results_do_not_depend_on_the_number_of_threads(mod, circular):
    """The node update and the SMK loads in chunks (each with its own random-number stream) on one or two threads:
    bit for bit the same trajectory, in NVE and with the thermostat, also across a checkpoint; in NVE also the
    trajectory of one chunk (every node gets the same loads in the same order)."""
    ff = load_forcefield("dna-default")
    model = ff.ring(n_nodes=100) if circular else ff.model_from_sequence("ACGT" * 25)
    for friction in (0.0, 1.0):
        ends = []
        for threads, chunk in ((1, 16), (2, 16), (1, 1024)):
            if friction and chunk == 1024:
                continue  # other random-number streams
            ctx, integ = threaded_context(mod, model, threads, friction, 3, chunk)
            assert integ.getNumThreads() == threads and integ.usesFusedElasticForce()
            integ.step(20)
            blob = ctx.createCheckpoint()
            integ.step(20)
            a = ctx.getState(getPositions=True, getVelocities=True)
            ctx.loadCheckpoint(blob)
            integ.step(20)
            b = ctx.getState(getPositions=True, getVelocities=True)
            for get in ("getPositions", "getVelocities"):
                assert np.array_equal(getattr(a, get)(asNumpy=True)._value, getattr(b, get)(asNumpy=True)._value)
            ends.append(a)
        for e in ends[1:]:
            for get in ("getPositions", "getVelocities"):
                assert np.array_equal(getattr(ends[0], get)(asNumpy=True)._value, getattr(e, get)(asNumpy=True)._value)
    # One chunk: one thread whatever the platform's Threads.
    _, integ = threaded_context(mod, model, 2, 1.0, 8, chunk=1024)
    assert integ.getNumThreads() == 1
