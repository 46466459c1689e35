"""One load vocabulary: both engines translate dnarod.physics.loads and give the same answer on one loaded system."""
import numpy as np
import pytest

from dnarod.core.errors import DnarodError, ParameterError
from dnarod.core.forcefield import load_forcefield
from dnarod.physics.loads import (Clamp, PullingForce, RotationClamp, Torque, Trap, clamp_angle, resolve_loads,
                                  rotation_clamp_load)
from dnarod.core.rotations import rotation_about_axis


@pytest.fixture(scope="module")
def model():
    return load_forcefield("dna-default").model_from_sequence("GCGAATTCGCGATC")


def perturbed(model, seed=3, scale=0.02):
    rng = np.random.default_rng(seed)
    pos = model.positions + scale * rng.standard_normal(model.positions.shape)
    frm = np.array([rotation_about_axis(a / np.linalg.norm(a), scale * 3) @ f
                    for a, f in zip(rng.standard_normal((model.n_nodes, 3)), model.frames)])
    return pos, frm


def loaded_set(model):
    n = model.n_nodes
    return (PullingForce(-1, [0.5, -0.3, 6.0]), Torque(-1, [0.1, 0.2, 1.5]),
            Trap(0, 200.0, centre=model.positions[0] + [0.01, 0.0, -0.02]),
            RotationClamp(0, 300.0, axis=[0.0, 0.0, 1.0], turns=0.25), Clamp(n // 2))


def test_rotation_clamp_load_matches_finite_differences():
    rng = np.random.default_rng(0)
    L = rotation_about_axis(np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8]), 0.7)
    T = rotation_about_axis(np.array([1.0, 0.0, 0.0]), 0.2)
    k = 40.0
    E, tau = rotation_clamp_load(L, T, k)
    theta = np.arccos((np.trace(T.T @ L) - 1) / 2)
    assert E == pytest.approx(k * (1 - np.cos(theta)), rel=1e-12)
    h = 1e-6
    fd = [-(rotation_clamp_load(rotation_about_axis(np.eye(3)[a], h) @ L, T, k)[0]
            - rotation_clamp_load(rotation_about_axis(np.eye(3)[a], -h) @ L, T, k)[0]) / (2 * h) for a in range(3)]
    assert np.abs(tau - fd).max() < 1e-8 * np.abs(tau).max()
    del rng


def test_both_engines_give_identical_loads_at_a_configuration(model):
    """OpenMM forces (Reference, double) summed to node loads == elastic + ResolvedLoads at a random pose."""
    from dnarod.engines.openmm.particles import particle_forces_to_loads, particle_positions
    from dnarod.engines.openmm.simulation import RodSimulation

    loads = loaded_set(model)[:4]  # the torque callback's energy is path dependent; forces compared below
    pos, frm = perturbed(model)
    sim = RodSimulation.create(model, integrator="verlet", temperature=0.0, dt=0.001, platform="Reference",
                        elastic="portable", nonbonded=False, loads=loads)
    angle = 0.9
    sim.set_clamp_rotation(angle, 0)
    x = particle_positions(pos, frm, sim.rs.radius)
    sim.context.setPositions(x)
    f = sim.context.getState(getForces=True).getForces(asNumpy=True)._value
    F_mm, tau_mm = particle_forces_to_loads(x, f)
    rl = resolve_loads(loads, model)
    _, F_el, tau_el = model.loads(pos, frm)
    _, F_ex, tau_ex = rl.evaluate(pos, frm, [angle])
    scale = max(np.abs(F_el + F_ex).max(), np.abs(tau_el + tau_ex).max() / model.ds)
    assert np.abs(F_mm - (F_el + F_ex)).max() < 1e-8 * scale
    assert np.abs(tau_mm - (tau_el + tau_ex)).max() < 1e-8 * scale * model.ds


def _lax_run(model, loads, dt, n_steps, v, w):
    from dnarod.engines.lax import BoundaryConditions, RigidState, SplittingIntegrator

    bc = BoundaryConditions.from_loads(loads, duration_ps=dt * n_steps)
    integ = SplittingIntegrator(model, dt, state=RigidState.from_model(model, v, w), boundary=bc,
                                check_stability=False)
    e0 = integ.total_energy()
    integ.step(n_steps)
    return integ.state.positions.copy(), integ.state.frames.copy(), e0, integ.total_energy()


def _openmm_run(model, loads, dt, n_steps, v, w):
    from dnarod.engines.openmm.simulation import RodSimulation

    sim = RodSimulation.create(model, integrator="verlet", temperature=0.0, dt=dt, platform="Reference",
                        elastic="fast", nonbonded=False, loads=loads, initial_velocities=(v, w),
                        constraint_tolerance=1e-12)
    sim.advance(n_steps)
    return sim.node_pose()


def test_both_engines_agree_on_a_loaded_nve_run(model):
    """Pull + dead torque + trap + rotation clamp + interior clamp, NVE from one state: the engines agree to
    well below their O(dt^2) error (1e-7 nm), and the Lax run conserves its energy."""
    rng = np.random.default_rng(7)
    n = model.n_nodes
    loads = loaded_set(model)
    v = 0.3 * rng.standard_normal((n, 3))
    w = 0.5 * rng.standard_normal((n, 3))
    v[n // 2] = 0.0
    w[n // 2] = 0.0
    # OpenMM's dead torque is a PythonForce (path-dependent energy) and its rotation clamp is turned
    # once per step; keep the clamp fixed (turns=0) here so both engines integrate the same forces.
    loads = loads[:3] + (RotationClamp(0, 300.0, axis=[0.0, 0.0, 1.0]),) + loads[4:]
    t_end = 0.2
    diffs = []
    for dt in (0.004, 0.002):
        steps = int(round(t_end / dt))
        p_lax, f_lax, e0, e1 = _lax_run(model, loads, dt, steps, v, w)
        p_mm, f_mm = _openmm_run(model, loads, dt, steps, v, w)
        diffs.append(np.abs(p_lax - p_mm).max())
        assert abs(e1 - e0) < 1e-3 * abs(e0)   # loose: the dead torque's work is not in total_energy
        assert np.abs(p_lax[n // 2] - model.positions[n // 2]).max() == 0.0   # the clamp holds
        assert np.abs(p_lax - model.positions).max() > 1e-2                  # a real motion
    # measured: 1.9e-9 and 8.8e-10 nm (both are second-order RATTLE-type schemes of the same forces)
    assert max(diffs) < 1e-7, diffs


def test_turning_rotation_clamp_turns_the_node_in_the_lax_engine(model):
    """A stiff clamp turned by 0.05 turns over the run leaves the node turned by about that much."""
    from dnarod.engines.lax import BoundaryConditions, SplittingIntegrator

    n = model.n_nodes
    rc = RotationClamp(-1, 2000.0, turns=0.05)
    bc = BoundaryConditions.from_loads((Clamp(0), rc), duration_ps=20.0)
    integ = SplittingIntegrator(model, 0.01, boundary=bc, temperature=0.0, friction=5.0, seed=1)
    integ.step(2000)
    L0, L1 = model.frames[-1], integ.state.frames[-1]
    R = L1 @ L0.T
    ax = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    turned = 2 * np.arctan2(ax @ L0[:, 2], 1 + np.trace(R)) / (2 * np.pi)
    assert 0.03 < turned < 0.05
    assert clamp_angle(rc, 20.0, 20.0) == pytest.approx(2 * np.pi * 0.05)
    del n


@pytest.mark.parametrize("loads, match", [
    ((Clamp(3), PullingForce(3, [1.0, 0, 0])), "absorbed by the clamp"),
    ((Trap(40, 10.0),), "does not exist"),
    ((RotationClamp(1, 10.0), RotationClamp(1, 5.0)), "already has a rotation clamp"),
    (("pull",), "unknown load"),
])
def test_bad_loads_are_refused_the_same_way_by_both_engines(model, loads, match):
    from dnarod.engines.lax import BoundaryConditions, SplittingIntegrator
    from dnarod.engines.openmm.simulation import RodSimulation

    with pytest.raises(DnarodError, match=match):
        SplittingIntegrator(model, 0.01, boundary=BoundaryConditions.from_loads(loads), check_stability=False)
    with pytest.raises(DnarodError, match=match):
        RodSimulation.create(model, integrator="verlet", temperature=0.0, dt=0.01, platform="Reference",
                      nonbonded=False, loads=loads)


def test_load_misuse_messages():
    with pytest.raises(ParameterError, match="turns.*turns_per_ns"):
        RotationClamp(0, 1.0, turns=1.0, turns_per_ns=2.0)
    with pytest.raises(ParameterError, match="run length"):
        clamp_angle(RotationClamp(0, 1.0, turns=1.0), 5.0)
    with pytest.raises(ParameterError, match="positive"):
        Trap(0, -1.0)


def test_lax_position_dependent_loads_are_velocity_verlet(model):
    """With a trap and a rotation clamp (re-evaluated each step, closing half kick corrected) the Lax run keeps
    its second order: the energy error (elastic + trap + clamp + kinetic - F.r) falls about 4x when dt halves."""
    rng = np.random.default_rng(3)
    n = model.n_nodes
    loads = (PullingForce(-1, [0.5, -0.3, 6.0]), Trap(0, 200.0, centre=model.positions[0] + [0.01, 0.0, -0.02]),
             RotationClamp(0, 300.0), Clamp(n // 2))
    v = 0.3 * rng.standard_normal((n, 3))
    w = 0.5 * rng.standard_normal((n, 3))
    v[n // 2] = w[n // 2] = 0.0
    errs = []
    for dt in (0.008, 0.004):
        from dnarod.engines.lax import BoundaryConditions, RigidState, SplittingIntegrator

        integ = SplittingIntegrator(model, dt, state=RigidState.from_model(model, v, w),
                                    boundary=BoundaryConditions.from_loads(loads), check_stability=False)
        e0 = integ.total_energy()
        err = 0.0
        for _ in range(int(round(0.4 / dt))):
            integ.step(1)
            err = max(err, abs(integ.total_energy() - e0))
        assert integ.external_energy > 0.0
        errs.append(err)
    assert 3.0 < errs[0] / errs[1] < 5.0, errs
